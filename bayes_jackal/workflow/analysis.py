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
- ``residuals.csv``: every run's one-step residuals under the best
  family's posterior (:mod:`bayes_jackal.workflow.stages.residual_table`);
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

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from .._runtime import REPORT_FORMATS, STATE_ESTIMATION
from ..inference import Executor, ProcessExecutor, SamplerSettings
from ..io import ReadOptions, RunGroups
from ..likelihood import LikelihoodOptions
from ..model import RobotProfile
from .context import RunContext
from .pipeline import Analysis, run_pipeline

__all__ = ["analyse_logs"]


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
    figure_formats: Sequence[str] = REPORT_FORMATS,
) -> Analysis:
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
    figure_formats : tuple of str
        The figure files written beside the report in ``report_figures/``
        (``--formats``): PNG alone by default, ``("png", "svg")`` for vector
        figures too.

    Returns
    -------
    Analysis
        Each stage's typed result (:data:`~bayes_jackal.workflow.PIPELINE`);
        its ``to_dict()`` is the ``--json`` object of ``analyse``:
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
        :meth:`~bayes_jackal.filters.LeaveOneOut.to_dict`), ``population``
        (``population.json``, None without groups) and ``files``
        (report, posterior, prior, state_estimation (None when not run),
        population, residuals, folder).

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
    >>> summary = result.to_dict()  # doctest: +SKIP
    >>> result.best, list(summary["experiments"]), summary["failed"]  # doctest: +SKIP
    ('white', ['short'], {})
    >>> summary["warnings"][0]["message"]  # doctest: +SKIP
    'white: NOT CONVERGED: 100 steps are fewer than 50 autocorrelation times ...'
    >>> written  # doctest: +SKIP
    ['compare.json', 'experiments', 'grid.json', 'grid_onestep.png', 'grid_simulation.png',
     'posterior.json', 'posterior.nc', 'posteriors', 'prior.json', 'report.html', 'report_figures',
     'residuals.csv']
    """
    context = RunContext(
        inputs=paths,
        out=out,
        executor=executor or ProcessExecutor(processes or os.cpu_count() or 1),
        robot=robot,
        families=families,
        settings=settings,
        seed=seed,
        prior_overrides=prior_overrides,
        likelihood_options=likelihood_options,
        read_options=read_options,
        labels=labels,
        state_estimation=state_estimation,
        groups=groups,
        figure_formats=figure_formats,
    )
    return run_pipeline(context)
