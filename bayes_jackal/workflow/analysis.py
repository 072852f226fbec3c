"""The whole analysis of a set of logs, as ``bayes-jackal analyse`` runs it.

:func:`analyse_logs` takes ROS bags (``.bag``, ``.mcap``, ``.db3``, bag
folders) and experiment files (``.csv``, ``.mat``, ``.nc``: what
:func:`bayes_jackal.io.load_experiment` reads) and writes into one
folder:

- ``experiments/<name>.nc``: every input that could be read, with its
  provenance (a bad input is reported with its reason and skipped);
- ``grid_onestep.png``, ``grid_simulation.png``, ``grid.json``: the thesis'
  grid searches of the yaw channel (ch. 9-1-2 and ch. 5) over the robot's
  prior ranges of d_lat and d_long (with ``prior_overrides``' damping
  ranges), log-spaced, 1000 and 100 values per axis
  (:func:`bayes_jackal.thesis.prior_grid`); a minimum on a grid's edge
  gets a ``grid-edge`` warning in grid.json;
- ``posteriors/<family>.nc`` and ``compare.json``: the pooled posterior of
  the damping and the noise on every channel all experiments measure, for
  each noise family, with its evidence (:func:`compare_families`); each
  family is saved as it finishes, so an interruption keeps those done;
- ``posterior.nc``, ``posterior.json``: the posterior of the family of
  highest evidence, the main result;
- ``prior.json``: the Active Inference prior exported from that same
  posterior, at embedding order 2 or the highest the family and the
  precision's conditioning allow (:data:`bayes_jackal.dem.export.AUTO_ORDER`,
  :func:`bayes_jackal.dem.allowed_orders`; 0 for white noise): the
  prior follows the model the data support best;
- ``state_estimation/`` and ``state_estimation.json``: with two or more
  runs, each run's filters driven by the prior of the best family given the
  other runs, scored (:mod:`bayes_jackal.filters.left_out`: its files and
  cost). The posterior without each run is the best family's pooled
  posterior reweighted by PSIS, or, where its Pareto k-hat is above 0.7,
  a new posterior on the other runs; ``state_estimation=False`` skips it;
- with ``groups``: ``population/units/``, ``population.json`` and
  ``population.png``, each group's damping and their population with the
  best family (:func:`bayes_jackal.population`);
- ``report.html``: the report of every family's posterior, best first,
  with the sections "Groups of runs" (with ``groups``) and "State
  estimation with this prior".

The demo (:mod:`bayes_jackal.workflow.demo`) is this function on the shipped bags.
Not to be confused with :func:`bayes_jackal.thesis.analyse`, the thesis'
ch. 7 residual analysis.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from .._runtime import (
    DEFAULT_FAMILIES,
    GRID_METHODS,
    SHORT_MEMORY,
    STATE_ESTIMATION,
    DataError,
    describe,
    write_json,
)
from ..dem import export_prior, write_prior
from ..filters import SUMMARY, LeaveOneOut, leave_one_out
from ..inference import (
    Comparison,
    Executor,
    ProcessExecutor,
    SamplerSettings,
    compare_families,
    keep_warnings,
    plan_units,
    population_posterior,
)
from ..io import Experiment, ReadOptions, RunGroups, as_run_groups, ingest_logs
from ..likelihood import LikelihoodOptions, resolve_channels
from ..model import RobotProfile, load_profile
from ..posterior import criticise, save_posterior, summarize
from ..report import (
    population_highlight,
    population_section,
    save_grid_plot,
    save_population_plot,
    state_estimation_highlight,
    state_estimation_section,
    write_report,
)
from ..thesis import grid_search, prior_grid

__all__ = ["analyse_logs"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)


def _common_truth(experiments: list[Experiment]) -> dict | None:
    """The true damping all experiments share (simulated runs), else None."""
    truths = [{key: (e.truth or {}).get(key) for key in ("d_lat", "d_long")} for e in experiments]
    shared = truths[0]
    return shared if None not in shared.values() and all(t == shared for t in truths) else None


def _grids(experiments, robot, folder: Path, priors=None, progress=True) -> dict:
    """The thesis' grid searches over the prior ranges; surfaces as PNG, minima in grid.json."""
    summaries = {}
    for method in GRID_METHODS:
        d_lat, d_long = (prior_grid(robot, name, method, priors) for name in ("d_lat", "d_long"))
        result = grid_search(experiments, robot, d_lat, d_long, method=method, progress=progress)
        best_lat, best_long, _ = result.argmin()
        save_grid_plot(result, folder / f"grid_{method}.png")
        edges = ", ".join(f"{name} {side}" for name, side in result.edges().items())
        _log.info(
            f"  {method} MSE grid minimum: d_lat = {best_lat:.4g}, d_long = {best_long:.4g} N s/m"
            + (f" (on the grid's edge: {edges})" if edges else "")
            + (f"; {result.caveat}" if result.caveat else "")
        )
        summaries[method] = result.summary()
    payload = {"truth": _common_truth(experiments), **summaries}
    write_json(folder / "grid.json", payload)
    return summaries


def _usable(
    experiments: list[Experiment],
    robot: RobotProfile,
    options: LikelihoodOptions,
    family: str,
) -> tuple[list[Experiment], dict[str, str]]:
    """The experiments a likelihood can take, each alone; the others' reasons, by source.

    Checked before the grids, so that a log no model can use (poses that do
    not cover its samples, a channel too short) is named and skipped, not
    found after minutes of work.
    """
    usable, failed = [], {}
    for experiment in experiments:
        try:
            options.likelihood([experiment], robot, family)
        except DataError as exc:
            failed[experiment.source] = describe(exc, experiment.source)
            _log.info(f"  skipped {failed[experiment.source]}")
        else:
            usable.append(experiment)
    return usable, failed


def analyse_logs(
    paths: Sequence[str | Path],
    out: str | Path,
    *,
    robot: RobotProfile | None = None,
    families: Sequence[str] | None = None,
    settings: SamplerSettings | None = None,
    seed: int | None = None,
    processes: int | None = None,
    executor: Executor | None = None,
    prior_overrides: Mapping[str, tuple[float, float]] | None = None,
    likelihood_options: LikelihoodOptions | None = None,
    read_options: ReadOptions | None = None,
    labels: Mapping[str, Mapping] | None = None,
    state_estimation: bool = STATE_ESTIMATION,
    groups: RunGroups | Mapping[str, str] | str | Path | None = None,
) -> dict:
    """Ingest logs, run the grids, compare the noise families, export the prior, report.

    See the module text for the files written under ``out``.

    Parameters
    ----------
    paths : sequence of str or Path
        Bags and experiment files (see :func:`ingest_logs`).
    out : str or Path
        Output folder (created).
    robot : RobotProfile, optional
        Default: the Jackal profile.
    families : sequence of str, optional
        Noise families to compare. By default white and gaussian, and the
        short-memory exponential family too where white beats gaussian, so
        that colour of a few samples, which gaussian's smooth kernel fits
        worse than white, is not read as "not coloured".
    settings : SamplerSettings, optional
        Walkers, step cap and progress display of each family's chain.
    seed : int, optional
        Seeds every chain and the evidence: same seed, same numbers.
    processes : int, optional
        Families sampled at once (default: one per core), without ``executor``.
    executor : Executor, optional
        Where the families run (:mod:`bayes_jackal.inference.executors`), e.g. a
        ``DaskExecutor`` of a Dask cluster; default: local processes.
    prior_overrides : mapping, optional
        Prior ranges by parameter name, e.g. ``{"sigma_h": (0.01, 3.0)}``
        [natural units], as in :func:`bayes_jackal.inference.sample_posterior`.
    likelihood_options : LikelihoodOptions, optional
        The channels (default: every channel all experiments measure), the
        noise sharing, sensor model and engine.
    read_options, labels
        As in :func:`~bayes_jackal.io.ingest_logs`: the window, the longest
        dropout and how experiment files are read; fields of each input.
    state_estimation : bool
        With two or more runs, take the best family's posterior given every
        run but one and score the filters on the one left out, for each run
        (:func:`bayes_jackal.filters.leave_one_out`): the pooled
        posterior reweighted by PSIS, or refit with this analysis' sampler
        settings, seed, priors, likelihood options and executor where the
        reweighting's Pareto k-hat is above 0.7. False skips it.
    groups : RunGroups, mapping, str or Path, optional
        Each run's group (a groups CSV, as in :func:`bayes_jackal.population`):
        each group's damping and their population with the best family,
        saved as ``population.json``, ``population.png`` and
        ``population/units/``, and a section of the report.

    Returns
    -------
    dict
        ``experiments`` (name -> file, source, samples, rate [Hz], channels,
        steady window), ``failed`` (input -> reason), ``channels``,
        ``grids`` (method -> :meth:`~bayes_jackal.thesis.GridResult.summary`,
        with its ``grid-edge`` ``warnings``), ``comparison`` (``compare.json``),
        ``best`` (the family of highest evidence), ``posterior`` (its
        summary), ``warnings`` (objects with ``kind`` and ``message``: a
        family's chain that did not converge, then every family's
        model-criticism warnings, with its ``family``, then each left-out
        run's chain that did not converge (for a reweighting, the pooled
        chain's), with its ``left_out``),
        ``state_estimation`` (``state_estimation.json``:
        :meth:`~bayes_jackal.filters.LeaveOneOut.to_dict`) and
        ``files`` (report, prior, posterior, state_estimation (None when
        not run), folder).

    Raises
    ------
    InputError
        When no input can be read (each reason in the message), or for bad
        options.

    Warns
    -----
    Warning
        The warnings raised while the families were compared (in worker
        processes too), each once, also when the comparison fails; the
        convergence warnings go into the result's ``warnings`` instead.

    Examples
    --------
    The whole analysis of one short simulated run (8 s), white noise only on
    the yaw channel, in this process. The chain is capped at 100 steps on
    purpose, to keep the example quick, and says it did not converge; the
    thesis' grid searches and the report take most of its ~7 s (the
    doctests skip it, as it writes files; tests/test_leave_one_out.py runs it):

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.inference import SamplerSettings, SerialExecutor
    >>> from bayes_jackal.likelihood import LikelihoodOptions
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import Series, simulate_experiment
    >>> from bayes_jackal.io import write_csv
    >>> from bayes_jackal.workflow import analyse_logs
    >>> run = simulate_experiment(load_profile(), 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:  # doctest: +SKIP
    ...     result = analyse_logs(
    ...         [write_csv(run, Path(folder) / "short.csv")],
    ...         Path(folder) / "analysis",
    ...         families=("white",),
    ...         likelihood_options=LikelihoodOptions(channels=("yaw",)),
    ...         settings=SamplerSettings(max_steps=100, design_points=64),
    ...         seed=1,
    ...         executor=SerialExecutor(),
    ...     )
    ...     written = sorted(path.name for path in (Path(folder) / "analysis").iterdir())
    >>> result["best"], list(result["experiments"]), result["failed"]  # doctest: +SKIP
    ('white', ['short'], {})
    >>> result["warnings"][0]["message"]  # doctest: +SKIP
    'white: NOT CONVERGED: 100 steps are fewer than 50 autocorrelation times ...'
    >>> written  # doctest: +SKIP
    ['compare.json', 'experiments', 'grid.json', 'grid_onestep.png', 'grid_simulation.png',
     'posterior.json', 'posterior.nc', 'posteriors', 'prior.json', 'report.html', 'report_figures']
    """
    folder = Path(out)
    robot = robot or load_profile()
    settings = settings or SamplerSettings()
    settings.check_evidence_steps()  # before the logs are read and the grids written
    if groups is not None:  # a bad groups file refused before a log is read or copied
        groups = as_run_groups(groups)
    experiments, failed = ingest_logs(
        paths,
        robot,
        folder / "experiments",
        read_options=read_options,
        progress=settings.progress,
        labels=labels,
    )
    if not experiments:
        raise DataError(
            f"none of the {len(failed)} inputs could be used: " + "; ".join(failed.values()),
            field="inputs",
        )
    options = LikelihoodOptions.of(likelihood_options)
    automatic, families = (
        families is None,
        tuple(DEFAULT_FAMILIES if families is None else families),
    )
    experiments, unusable = _usable(experiments, robot, options, families[0])
    failed |= unusable
    if not experiments:
        raise DataError(
            f"none of the {len(failed)} inputs could be used: " + "; ".join(failed.values()),
            field="inputs",
        )
    options = dataclasses.replace(
        options, channels=resolve_channels(experiments, options.channels)
    )
    if groups is not None:  # runs the groups do not name refused before any work
        plan_units(experiments, groups, noise=options.noise)
    channels = options.channels
    _log.info("thesis grid searches of the yaw channel (ch. 5 and 9-1-2) over the prior ranges:")
    grids = _grids(experiments, robot, folder, prior_overrides, settings.progress)
    _log.info(
        f"posterior and evidence of {', '.join(families)} noise on {', '.join(channels)}, "
        f"pooled over {len(experiments)} experiment(s):"
    )

    paths_by_family = {family: folder / "posteriors" / f"{family}.nc"
                       for family in (*families, SHORT_MEMORY)}  # fmt: skip
    executor = executor or ProcessExecutor(processes or os.cpu_count() or 1)

    def finished(family, evidence, idata) -> None:
        criticise(idata)  # cached in its attrs: the saved file and the report reuse it
        save_posterior(idata, paths_by_family[family])  # kept if interrupted, reused on a rerun
        _log.info(f"  {family}: log evidence {evidence.log_evidence:.2f} +- {evidence.error:.3f}")

    def compare(families: tuple[str, ...]) -> Comparison:
        return compare_families(experiments, robot, families, settings, seed,
                                prior_overrides=prior_overrides, on_family=finished,
                                reuse=paths_by_family, executor=executor,
                                likelihood_options=options)  # fmt: skip

    try:
        with keep_warnings() as kept:
            comparison = compare(families)
            if automatic and comparison.best == "white" and SHORT_MEMORY not in families:
                _log.info(f"  white beat gaussian: {SHORT_MEMORY} (short-memory colour) is "
                    "compared too, as gaussian's smooth kernel fits colour of a few samples worse "
                    "than white does")  # fmt: skip
                families = (*families, SHORT_MEMORY)
                comparison = compare(families)
    finally:
        # The convergence warnings go into the result; the others reach the user,
        # also those raised before the comparison failed.
        kept.issue()
    best = comparison.best
    idata = comparison.posteriors[best]
    save_posterior(idata, folder / "posterior.nc")
    summary = summarize(idata)
    write_json(folder / "posterior.json", summary)
    result = comparison.to_dict()
    write_json(folder / "compare.json", result)
    # The highest order the best family allows, up to export.AUTO_ORDER.
    prior = write_prior(
        export_prior(idata, order=None, source=str(paths_by_family[best])), folder / "prior.json"
    )
    if state_estimation:
        # Each run's posterior without it: the best family's pooled posterior reweighted
        # (PSIS), or refit where the reweighting is unreliable.
        left_out = leave_one_out(experiments, robot, best, folder, pooled=idata,
                                 pooled_source=str(paths_by_family[best]), settings=settings,
                                 seed=seed, prior_overrides=prior_overrides,
                                 likelihood_options=options, executor=executor)  # fmt: skip
    else:
        left_out = LeaveOneOut(best, skipped="turned off (--no-state-estimation)")
    sections = [functools.partial(state_estimation_section, left_out)]
    highlights = [state_estimation_highlight(left_out)]
    campaign = None
    if groups is not None:
        _log.info(f"each group's damping and their population ({best} noise):")
        campaign = population_posterior(
            experiments, robot, groups=groups, family=best, settings=settings, seed=seed,
            prior_overrides=prior_overrides, likelihood_options=options, executor=executor,
            out=folder / "population",
        ).to_dict()  # fmt: skip
        write_json(folder / "population.json", campaign)
        save_population_plot(campaign, folder / "population.png")
        sections.insert(0, functools.partial(population_section, campaign))
        highlights.insert(0, population_highlight(campaign))
    _log.info("writing the report (figures as PNG and SVG)...")
    ranked = [best, *(family for family in families if family != best)]
    report = write_report(
        [paths_by_family[family] for family in ranked],
        folder / "report.html",
        sections=sections,
        highlights=[line for line in highlights if line],
    )
    convergence = [{"kind": "not-converged", "message": message} for message in kept.convergence]
    convergence_left_out = [
        {"kind": "not-converged", "message": f"leaving out {run}: {message}", "left_out": run}
        for run, record in left_out.runs.items()
        for message in record["warnings"]
    ]
    return {
        "experiments": {
            e.name: {
                "file": str(folder / "experiments" / f"{e.name}.nc"),
                "source": e.source,
                "samples": len(e.t),
                "rate": 1.0 / e.dt,
                "channels": list(e.channels),
                "steady_window": e.steady_window,
            }
            for e in experiments
        },
        "failed": failed,
        "channels": list(channels),
        "grids": grids,
        "comparison": result,
        "best": best,
        "posterior": summary,
        "warnings": convergence + result["warnings"] + convergence_left_out,
        "state_estimation": left_out.to_dict(),
        "population": campaign,
        "files": {
            "report": str(report),
            "prior": str(prior),
            "posterior": str(folder / "posterior.nc"),
            "state_estimation": str(folder / SUMMARY) if left_out.skipped is None else None,
            "population": None if campaign is None else str(folder / "population.json"),
            "folder": str(folder),
        },
    }
