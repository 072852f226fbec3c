"""The embedded demo: shipped simulated bags through the whole pipeline.

``bayes_jackal/data/demo/`` holds two thesis-like runs (one per series, v1, v2)
written as ROS1 bags (bz2 chunks) by :func:`make_demo_bags`, simulated with
known truth d_lat = 110, d_long = 30 N s/m and Gaussian process noise of
sigma_h = 0.047 s; ``manifest.json`` labels them as simulated and holds the
truth. :func:`run_demo` ingests them, runs the thesis' grid searches,
compares white and Gaussian noise by evidence (the Gaussian posterior is the
main result), exports the Active Inference prior and writes the report.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable
from importlib import resources
from pathlib import Path

from . import __version__
from ._files import atomic_path
from .bags import read_bag, write_bag
from .evidence import compare_families
from .experiment import Experiment, write_netcdf
from .export import export_prior, write_prior
from .gridsearch import damping_grid, grid_search
from .inference import SamplerSettings
from .kernels import as_rng
from .plots import save_grid_plot
from .posterior import save_posterior, summarize
from .report import write_report
from .robot import RobotProfile, load_profile
from .simulate import NoiseSettings, simulate_series

__all__ = ["DEMO_FAMILIES", "DEMO_TRUTH", "demo_folder", "make_demo_bags", "run_demo"]

DEMO_TRUTH = {"d_lat": 110.0, "d_long": 30.0}
DEMO_COUNTS = {"v1": 1, "v2": 1}
DEMO_SEED = 2026
#: Families the demo compares: the thesis' question, coloured or not.
DEMO_FAMILIES = ("white", "gaussian")
MANIFEST = "manifest.json"
#: 4 x the 5 parameters, DESIGN §4's minimum: ~30 % faster than the default 32
#: on the demo's pooled posterior (89 s against 120 s) at the same criterion.
DEMO_WALKERS = 20


def demo_folder() -> Path:
    """The installed folder of the demo bags and their manifest."""
    return Path(str(resources.files("bayes_jackal.data") / "demo"))


def make_demo_bags(folder: str | Path, robot: RobotProfile | None = None) -> Path:
    """Simulate the demo runs and write them as bags with a manifest (maintainers only).

    Returns
    -------
    Path
        The manifest.
    """
    folder = Path(folder)
    robot = robot or load_profile()
    rng = as_rng(DEMO_SEED)
    runs = simulate_series(robot, **DEMO_TRUTH, counts=DEMO_COUNTS, rng=rng)
    manifest = {
        "simulated": True,
        "note": "SIMULATED thesis-like runs with known truth, not measurements",
        "generator": f"bayes_jackal {__version__} bayes_jackal.demo.make_demo_bags",
        "seed": DEMO_SEED,
        "runs": {},
    }
    for run, child in zip(runs, rng.spawn(len(runs)), strict=True):
        path = write_bag(run, folder / f"{run.name}.bag", robot, "ros1", child, "bz2")
        manifest["runs"][run.name] = {"bag": path.name, "series": run.series, "truth": run.truth}
    path = folder / MANIFEST
    with atomic_path(path) as temporary:
        temporary.write_text(json.dumps(manifest, indent=2))
    return path


def _ingest(folder: Path, robot: RobotProfile, say: Callable[[str], None]) -> list[Experiment]:
    """The shipped bags as experiments, labelled with their series and truth."""
    source = demo_folder()
    manifest = json.loads((source / MANIFEST).read_text())
    experiments = []
    for name, run in manifest["runs"].items():
        experiment = read_bag(source / run["bag"], robot)
        experiment = dataclasses.replace(experiment, series=run["series"], truth=run["truth"])
        write_netcdf(experiment, folder / "experiments" / f"{name}.nc")
        start, stop = experiment.steady_window
        say(
            f"  ingested {run['bag']}: {len(experiment.t)} samples, steady window "
            f"{start:.2f}-{stop:.2f} s"
        )
        experiments.append(experiment)
    return experiments


def _grids(experiments, robot, folder: Path, say: Callable[[str], None]) -> dict:
    searches = {
        "onestep": damping_grid(1, 1000, 1),  # ch. 9-1-2, at the full resolution
        "simulation": damping_grid(10, 1000, 10),  # ch. 5, the thesis' grid
    }
    summaries = {}
    for method, values in searches.items():
        result = grid_search(experiments, robot, values, values, method=method)
        d_lat, d_long, _ = result.argmin()
        save_grid_plot(result, folder / f"grid_{method}.png")
        say(f"  {method} MSE grid minimum: d_lat = {d_lat:g}, d_long = {d_long:g} N s/m")
        summaries[method] = result.summary()
    (folder / "grid.json").write_text(json.dumps({"truth": DEMO_TRUTH, **summaries}, indent=2))
    return summaries


def run_demo(folder: str | Path, say: Callable[[str], None], progress: bool = True) -> dict:
    """Run the demo into ``folder``; return the main results.

    Parameters
    ----------
    folder : str or Path
        Output folder (created).
    say : callable
        Receives the progress and summary lines.
    progress : bool
        Show emcee's progress bars.

    Returns
    -------
    dict
        ``posterior`` (the Gaussian summary), ``comparison`` and ``files``.
    """
    folder = Path(folder)
    robot = load_profile()
    say(
        f"bayes-jackal {__version__} demo on SIMULATED thesis-like runs shipped as ROS1 bags "
        f"(truth d_lat = {DEMO_TRUTH['d_lat']:g}, d_long = {DEMO_TRUTH['d_long']:g} N s/m, "
        f"Gaussian process noise sigma_h = {NoiseSettings().width} s) -> {folder}/"
    )
    experiments = _ingest(folder, robot, say)
    say("thesis grid searches (ch. 5 and 9-1-2):")
    _grids(experiments, robot, folder, say)
    say(f"posterior and evidence of {' and '.join(DEMO_FAMILIES)} noise, pooled over the runs:")
    comparison = compare_families(
        experiments,
        robot,
        DEMO_FAMILIES,
        SamplerSettings(walkers=DEMO_WALKERS, progress=progress),
        DEMO_SEED,
        on_family=lambda family, e, _: say(
            f"  {family}: log evidence {e.log_evidence:.2f} +- {e.error:.3f}"
        ),
        processes=os.cpu_count() or 1,
    )
    posteriors = {
        family: save_posterior(idata, folder / "posteriors" / f"{family}.nc")
        for family, idata in comparison.posteriors.items()
    }
    gaussian = comparison.posteriors["gaussian"]
    save_posterior(gaussian, folder / "posterior.nc")
    summary = summarize(gaussian)
    (folder / "posterior.json").write_text(json.dumps(summary, indent=2))
    result = comparison.to_dict()
    (folder / "compare.json").write_text(json.dumps(result, indent=2))
    prior = write_prior(
        export_prior(gaussian, order=2, source=str(posteriors["gaussian"])), folder / "prior.json"
    )
    say("writing the report (figures as PNG and SVG)...")
    report = write_report([posteriors["gaussian"], posteriors["white"]], folder / "report.html")
    return {
        "posterior": summary,
        "comparison": result,
        "files": {"report": report, "prior": prior, "posterior": folder / "posterior.nc"},
    }
