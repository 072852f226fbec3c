"""The embedded demo: shipped simulated bags through the whole pipeline.

``bayes_jackal/data/demo/`` holds two thesis-like runs (one per series, v1, v2)
written as ROS1 bags (bz2 chunks) by :func:`make_demo_bags`, simulated with
known truth d_lat = 110, d_long = 30 N s/m and Gaussian process noise of
sigma_h = 0.047 s, their motion-capture poses with a lab system's noise
(0.5 mm, 0.002 rad: :data:`bayes_jackal.io.bag_writer.POSE_NOISE`);
``manifest.json`` labels them as simulated and holds the truth
(:func:`bayes_jackal.io.bag_truth`); ``<run>.states.npz`` holds each
run's true states (vx, vy [m/s], yaw rate [rad/s] on the bag's IMU stamps),
against which the analysis scores the filters' state estimates. :func:`run_demo` runs
:func:`bayes_jackal.workflow.analyse_logs` on them, as ``bayes-jackal
analyse`` does on a user's logs: ingest, the thesis' grid searches, white
against Gaussian noise by evidence on every channel (the posterior of the
family of highest evidence is the main result), the
Active Inference prior and the report.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import numpy as np

from .. import __version__
from .._runtime import (
    CHANNELS,
    DEFAULT_FAMILIES,
    REPORT_FORMATS,
    STATE_ESTIMATION,
    as_rng,
    write_json,
)
from ..inference import SamplerSettings
from ..io import NoiseSettings, bag_truth, simulate_series, write_bag
from ..model import RobotProfile, load_profile
from .analysis import analyse_logs
from .pipeline import Analysis

__all__ = [
    "DEMO_FAMILIES",
    "DEMO_TRUTH",
    "demo_folder",
    "demo_labels",
    "make_demo_bags",
    "run_demo",
]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)

DEMO_TRUTH = {"d_lat": 110.0, "d_long": 30.0}
DEMO_COUNTS = {"v1": 1, "v2": 1}
DEMO_SEED = 2026
#: Families the demo compares: the thesis' question, coloured or not.
DEMO_FAMILIES = DEFAULT_FAMILIES
MANIFEST = "manifest.json"


def demo_folder() -> Path:
    """The installed folder of the demo bags and their manifest.

    Examples
    --------
    >>> import json
    >>> from bayes_jackal.workflow import demo_folder
    >>> sorted(path.name for path in demo_folder().iterdir())
    ['manifest.json', 'v1_01.bag', 'v1_01.states.npz', 'v2_01.bag', 'v2_01.states.npz']
    >>> manifest = json.loads((demo_folder() / "manifest.json").read_text())
    >>> manifest["simulated"], manifest["runs"]["v1_01"]["truth"]["d_lat"]
    (True, 110.0)
    """
    return Path(str(resources.files("bayes_jackal.data") / "demo"))


def make_demo_bags(folder: str | Path, robot: RobotProfile | None = None) -> Path:
    """Simulate the demo runs and write them as bags with a manifest (maintainers only).

    Returns
    -------
    Path
        The manifest.

    Examples
    --------
    The bags are made again from the fixed seed: the same runs and truth as
    the shipped ones (about 3 s: two full runs, bz2-compressed):

    >>> import json
    >>> import tempfile
    >>> from bayes_jackal.workflow import demo_folder, make_demo_bags
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     manifest = json.loads(make_demo_bags(folder).read_text())
    >>> shipped = json.loads((demo_folder() / "manifest.json").read_text())
    >>> sorted(manifest["runs"]), manifest["runs"] == shipped["runs"]
    (['v1_01', 'v2_01'], True)
    """
    folder = Path(folder)
    robot = robot or load_profile()
    rng = as_rng(DEMO_SEED)
    runs = simulate_series(robot, **DEMO_TRUTH, counts=DEMO_COUNTS, rng=rng)
    manifest = {
        "simulated": True,
        "note": "SIMULATED thesis-like runs with known truth, not measurements",
        "generator": f"bayes_jackal {__version__} bayes_jackal.workflow.make_demo_bags",
        "seed": DEMO_SEED,
        "runs": {},
    }
    for run, child in zip(runs, rng.spawn(len(runs)), strict=True):
        path = write_bag(run, folder / f"{run.name}.bag", robot, "ros1", child, "bz2")
        states = folder / f"{run.name}.states.npz"
        np.savez_compressed(
            states, t=run.t, **{c: run.truth_arrays[f"{c}_state"] for c in CHANNELS}
        )
        manifest["runs"][run.name] = {
            "bag": path.name,
            "states": states.name,
            "series": run.series,
            "truth": bag_truth(run),
        }
    return write_json(folder / MANIFEST, manifest)


def run_demo(
    folder: str | Path,
    *,
    progress: bool = True,
    state_estimation: bool = STATE_ESTIMATION,
    figure_formats: Sequence[str] = REPORT_FORMATS,
) -> Analysis:
    """Run :func:`bayes_jackal.workflow.analyse_logs` on the shipped bags into ``folder``.

    The runs keep their simulated series labels, truth and true states from
    the manifest, so the filters' state estimates are scored against the truth.

    Parameters
    ----------
    folder : str or Path
        Output folder (created).
    progress : bool
        Show the chains' progress on stderr.
    state_estimation : bool
        Score the filters on each run with the prior fitted to the other run
        (:func:`~bayes_jackal.workflow.analyse_logs`). Of two runs each is
        half the data, too much for the pooled posterior's PSIS reweighting
        (Pareto k-hat above 0.7), so each is usually refit: two more
        posteriors, side by side, ~20 s on 2 cores.
    figure_formats : sequence of str
        As in :func:`~bayes_jackal.workflow.analyse_logs`.

    Returns
    -------
    Analysis
        As :func:`~bayes_jackal.workflow.analyse_logs` returns.

    Examples
    --------
    The demo takes about a minute on 2 cores, so its call is not run here
    (``tests/test_workflow.py`` runs it and checks the truth is recovered):

    >>> import tempfile
    >>> from bayes_jackal.workflow import DEMO_FAMILIES, run_demo
    >>> DEMO_FAMILIES
    ('white', 'gaussian')
    >>> result = run_demo(tempfile.mkdtemp(), progress=False)  # doctest: +SKIP
    >>> result.best, result.to_dict()["channels"]  # doctest: +SKIP
    ('gaussian', ['yaw', 'vx', 'vy'])
    """
    labels = demo_labels()
    _log.info(
        f"bayes-jackal {__version__} demo on SIMULATED thesis-like runs shipped as ROS1 bags "
        f"(truth d_lat = {DEMO_TRUTH['d_lat']:g}, d_long = {DEMO_TRUTH['d_long']:g} N s/m, "
        f"Gaussian process noise sigma_h = {NoiseSettings().width} s) -> {folder}/"
    )
    return analyse_logs(
        list(labels),
        folder,
        robot=load_profile(),
        families=DEMO_FAMILIES,
        settings=SamplerSettings(progress=progress),
        seed=DEMO_SEED,
        labels=labels,
        state_estimation=state_estimation,
        figure_formats=figure_formats,
    )


def demo_labels() -> dict[str, dict]:
    """Each shipped bag's path and its labels from the manifest: series, truth, true states.

    ``analyse_logs(..., labels=demo_labels())`` gives the ingested runs
    their simulated truth (:class:`~bayes_jackal.io.Experiment`'s
    ``truth`` and ``truth_arrays``).

    Examples
    --------
    >>> from pathlib import Path
    >>> from bayes_jackal.workflow import demo_labels
    >>> labels = demo_labels()
    >>> [Path(path).name for path in labels]
    ['v1_01.bag', 'v2_01.bag']
    >>> run = next(iter(labels.values()))
    >>> run["series"], run["truth"]["d_lat"], sorted(run["truth_arrays"])
    ('v1', 110.0, ['vx_state', 'vy_state', 'yaw_state'])
    """
    source = demo_folder()
    manifest = json.loads((source / MANIFEST).read_text())
    labels = {}
    for run in manifest["runs"].values():
        with np.load(source / run["states"]) as states:
            arrays = {f"{c}_state": states[c] for c in CHANNELS}
        labels[str(source / run["bag"])] = {
            "series": run["series"],
            "truth": run["truth"],
            "truth_arrays": arrays,
        }
    return labels
