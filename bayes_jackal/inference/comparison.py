"""Noise-filter families compared by evidence, on one group of experiments or on many at once.

:func:`compare_groups` samples one posterior per (group, family) and
estimates its evidence by bridge sampling
(:func:`~bayes_jackal.inference.bridge_sampling`), one job each on an
executor (:mod:`bayes_jackal.inference.executors`): every job of every group is
submitted at once, so a campaign of many runs keeps every worker of a
cluster busy, and each group's :class:`Comparison` comes back as soon as its
families are done. :func:`compare_families` is its case of one group. A
job's chain is seeded by ``seed`` and its bridge's proposal draws by
``[seed, the family's index in FAMILIES]``: its result depends on nothing
else, not on the executor nor on the other groups or families.

A :class:`Comparison` holds each family's posterior and log evidence for one
data set, names the best family, gives Bayes factors between any two, and
answers whether the noise is coloured (:func:`colour_verdict`). Bayes
factors are read on Kass & Raftery's (1995) scale, in natural-log units:
below 1 not worth more than a bare mention, 1-3 positive, 3-5 strong, above
5 very strong.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import warnings
from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import numpy as np

from .._runtime import (
    DAMPING_MODEL,
    ENGINE,
    HDI_PROB,
    MAX_STEPS,
    NOISE,
    PREDICTIVE_ACF,
    PRIOR_BOUNDARY,
    SENSOR,
    STEADY,
    WALKERS,
    DataError,
    InputError,
    az,
    silenced,
)
from ..io import Experiment, as_experiments
from ..likelihood import LogPosterior, Prior, ResidualLikelihood
from ..model import FAMILIES, RobotProfile
from ..posterior import Evidence, Posterior, interval, load_posterior, store_comparison, summarize
from .evidence import bridge_sampling, evidence_strength, nested_sampling
from .executors import Executor, ProcessExecutor, SerialExecutor
from .options import FitOptions
from .sampler_warnings import ConvergenceWarning, KeptWarnings, keep_warnings
from .sampling import run_identity, sample_posterior

__all__ = [
    "COLOURED_LOG_BF",
    "WHITE_LOG_BF",
    "Comparison",
    "colour_verdict",
    "compare",
    "compare_families",
    "compare_groups",
    "width_floor",
]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)

K = TypeVar("K", bound=Hashable)

#: The order tasks are handed to the executor: the families that usually take
#: longest first, so that the short ones fill the workers at the end (a
#: family's numbers do not depend on it). The boxcar and triangular kernels'
#: spectra have zeros (longer spectral grids) and their width posteriors mix
#: slowest; white noise has no width. Measured on a 300 s run, 2 cores:
#: moving-average 7,000 steps (tau 108), triangular 3,800, exponential 2,900,
#: gaussian 2,800 and white 3,900 at half the cost per step; in this order
#: the five took 152 s, in the order of FAMILIES 190 s.
_LONGEST_FIRST = ("moving-average", "triangular", "exponential", "gaussian", "white")
#: Sampler settings that only change the display, not a family's result.
_DISPLAY_SETTINGS = ("progress", "progress_label", "progress_line")


@dataclass(frozen=True)
class _FamilyFit:
    """One family's result in one group: its evidence, posterior, nested check and warnings."""

    family: str
    evidence: Evidence
    posterior: az.InferenceData
    nested: Evidence | None
    kept: KeptWarnings


@dataclass(frozen=True)
class _FamilyRun:
    """Everything one family's posterior and evidence need (picklable for a process).

    ``lines`` (progress lines shared by the jobs running at once) and
    ``label`` (put before the family on its progress bar) only change the
    display; ``starts`` (family -> parameter values) warm-starts a family's
    MAP search (:func:`~bayes_jackal.inference.sample_posterior`).
    """

    experiments: list[Experiment]
    fit: FitOptions
    cross_check: bool
    lines: int = 1
    label: str = ""
    starts: Mapping[str, np.ndarray] | None = None

    def _starts(self, family: str) -> np.ndarray | None:
        return None if self.starts is None else self.starts.get(family)

    def _model(self, family: str) -> tuple[ResidualLikelihood, Prior]:
        fit = self.fit
        likelihood = fit.likelihood_options.likelihood(self.experiments, fit.robot, family)
        return likelihood, Prior.for_likelihood(likelihood, fit.robot, fit.prior_overrides)

    def task(self, family: str) -> dict:
        """Everything that defines ``family``'s result, part by part (JSON-ready).

        The chain's identity (:func:`bayes_jackal.inference.run_identity`),
        the sampler settings but the display, and the cross-check.
        """
        likelihood, prior = self._model(family)
        settings = self.fit.settings
        sampler = {
            key: value
            for key, value in dataclasses.asdict(settings).items()
            if key not in _DISPLAY_SETTINGS
        }
        walkers = settings.n_walkers(len(prior.names))
        identity = run_identity(likelihood, prior, walkers, self.fit.seed, self._starts(family))
        task = identity | {"sampler": sampler, "cross_check": self.cross_check}
        return json.loads(json.dumps(task))

    def __call__(self, job: tuple[int, str]):
        """The family's :class:`_FamilyFit`.

        ``job`` is (position, family): the position picks the progress line.
        The result, kept in the posterior's attributes, is that of
        :meth:`_stored`; the convergence messages are stored there, the
        other warnings raised come back as :class:`KeptWarnings`.
        """
        position, family = job
        with keep_warnings() as kept:
            likelihood, prior = self._model(family)
            # One labelled progress line per family (processes share the terminal).
            fit = self.fit.with_settings(
                progress_label=f"{self.label}{family:>14s}", progress_line=position % self.lines
            )
            # The families' chains run at once: their start searches are not told.
            with silenced(__package__):
                idata = sample_posterior(
                    likelihood,
                    fit.settings,
                    fit.seed,
                    prior_overrides=fit.prior_overrides,
                    starts=self._starts(family),
                )
            draws, lp = Posterior.of(idata).draws()
            # Keyed on the family, not on which others are compared: results are reusable.
            key = list(FAMILIES).index(family)
            rng = np.random.default_rng(None if fit.seed is None else [fit.seed, key])
            evidence = bridge_sampling(LogPosterior(likelihood, prior), np.log(draws), lp, rng)
            nested = nested_sampling(likelihood, prior, rng) if self.cross_check else None
        store_comparison(
            idata,
            evidence=evidence,
            nested=nested,
            messages=kept.convergence,
            task=self.task(family),
        )
        return self._stored(family, idata, kept)

    @staticmethod
    def _stored(
        family: str, idata: az.InferenceData, kept: KeptWarnings | None = None
    ) -> _FamilyFit:
        """The family's result from the posterior's attributes, with ``kept``."""
        metadata = Posterior.of(idata).metadata
        return _FamilyFit(
            family, metadata.evidence, idata, metadata.evidence_nested, kept or KeptWarnings()
        )

    def reuse(self, family: str, path: Path):
        """The result saved in ``path`` when its task is this one's, else None (saying why)."""
        if not path.exists():
            return None
        try:
            idata = load_posterior(path)
            stored = Posterior.of(idata).metadata.task or {}
        except (DataError, ValueError) as exc:
            _log.info(f"  recomputing {family}: {exc}")
            return None
        if not stored:
            _log.info(f"  recomputing {family}: {path} holds no record of its settings")
            return None
        task = self.task(family)
        differ = [part for part in task if stored.get(part) != task[part]]
        if differ:
            _log.info(
                f"  recomputing {family}: {path} was computed with other {', '.join(differ)}"
            )
            return None
        _log.info(f"  reusing {family} from {path}")
        return self._stored(family, idata)


@dataclass(frozen=True)
class _FamilyJob:
    """One (group, family) job of :func:`compare_groups` (picklable).

    Called with (key, run, position, family); returns (key, the run's
    result), or, with ``catch``, (key, the exception that stopped it), so
    that one group's failure does not stop the others.
    """

    catch: bool

    def __call__(self, job: tuple[K, _FamilyRun, int, str]) -> tuple[K, _FamilyFit | Exception]:
        key, run, position, family = job
        try:
            return key, run((position, family))
        except Exception as exc:
            if not self.catch:
                raise
            return key, exc


def compare_groups(
    groups: Mapping[K, Sequence[Experiment]],
    options: FitOptions | None = None,
    *,
    families: Sequence[str] = tuple(FAMILIES),
    cross_check: bool = False,
    executor: Executor | None = None,
    reuse: Mapping[K, Mapping[str, str | Path]] | None = None,
    on_family: Callable[[K, str, Evidence, az.InferenceData], None] | None = None,
    on_failure: Callable[[K, Exception], None] | None = None,
    starts: Mapping[K, Mapping[str, np.ndarray]] | None = None,
) -> Iterator[tuple[K, Comparison]]:
    """Compare the families on several independent groups of experiments, all jobs at once.

    Every (group, family) job is submitted to ``executor`` at once; a
    group's comparison is yielded as soon as all its families are done.
    Each group's result is that of :func:`compare_families` on it alone
    with the same seed, whichever executor ran it.

    Parameters
    ----------
    groups : mapping of key to list of Experiment
        Each group is pooled into one likelihood (shared damping), e.g.
        ``{path: [experiment]}`` for one comparison per run. The keys name
        the groups in what is yielded and in the callbacks.
    options : FitOptions, optional
        The robot, likelihood options, priors, sampler settings and seed of
        every group (default: the defaults'). The seed seeds every chain and
        the bridges' proposal draws (the same for every group); without
        ``channels`` each group sees every channel measured in all its
        experiments; with progress on, each job's bar is labelled with its
        family (and, with several groups, the group's experiments).
    families : sequence of str
        Names from :data:`bayes_jackal.model.FAMILIES`.
    cross_check : bool
        Also estimate each evidence by nested sampling (slow).
    executor : Executor, optional
        Where the jobs run (:mod:`bayes_jackal.inference.executors`): local processes
        (``ProcessExecutor``), a Dask cluster (``DaskExecutor``; no progress
        bars there). Default: this process, one job after the other.
    reuse : mapping of key to mapping of str to path, optional
        Per group, where its finished families were saved (family ->
        posterior file), as in :func:`compare_families`: a family saved
        with this very task is read back, not run, and ``on_family`` is not
        called for it.
    on_family : callable, optional
        Called with (key, family, evidence, posterior) as each job
        finishes, e.g. to save it at once.
    on_failure : callable, optional
        Called with (key, exception) when a group fails (a job raises, or
        ``on_family`` does): the group is not yielded and the others go on.
        Without it the exception propagates and the jobs still pending
        are stopped.
    starts : mapping of key to mapping of str to ndarray, optional
        Per group and family, parameter values, shape (S, P) in the family's
        layout, its MAP search climbs from instead of the profile
        likelihood's (a warm start: the state estimation's refit of the
        posterior without a run starts from the pooled posterior's draws).
        Part of the family's task: a posterior saved without them is not
        reused.

    Yields
    ------
    key, Comparison
        As each group is done (groups whose families were all reused
        first). Before each, the convergence warnings of its chains are
        issued as :class:`~bayes_jackal.inference.ConvergenceWarning`
        (:meth:`Comparison.convergence_messages`).

    Raises
    ------
    InputError
        For families that are not distinct names of ``FAMILIES`` (at once,
        before any job).

    Examples
    --------
    One comparison per run, here of white noise alone (a real campaign
    compares several families) on chains kept short on purpose (20 steps):

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import FitOptions, compare_groups
    >>> from bayes_jackal.likelihood import LikelihoodOptions
    >>> robot = bj.load_profile()
    >>> runs = {
    ...     name: [bj.simulate_experiment(robot, 110.0, 30.0, rng=seed, name=name)]
    ...     for seed, name in enumerate(["v1_01", "v1_02"], start=1)
    ... }
    >>> options = FitOptions(
    ...     robot=robot, likelihood_options=LikelihoodOptions(channels=["yaw"]),
    ...     settings=bj.SamplerSettings(max_steps=20), seed=1,
    ... )
    >>> for key, comparison in compare_groups(runs, options, families=["white"]):
    ...     print(key, comparison.experiments, list(comparison.evidence))
    v1_01 ['v1_01'] ['white']
    v1_02 ['v1_02'] ['white']
    """
    unknown = [name for name in families if name not in FAMILIES]
    if unknown or not families or len(set(families)) != len(families):
        raise InputError(
            f"families must be distinct names from {list(FAMILIES)}, got {list(families)}",
            field="families",
        )
    fit = FitOptions.of(options)
    fit.settings.check_evidence_steps()
    executor = executor or SerialExecutor()
    if not executor.terminal:  # workers have no terminal
        fit = fit.with_settings(progress=False)
    runs = {
        key: _FamilyRun(
            list(group),
            fit,
            cross_check,
            label="" if len(groups) == 1 else "+".join(e.name for e in group) + " ",
            starts=(starts or {}).get(key),
        )
        for key, group in groups.items()
    }
    return _comparisons(runs, tuple(families), executor, reuse or {}, on_family, on_failure)


def _comparisons(
    runs: dict[K, _FamilyRun],
    families: tuple[str, ...],
    executor: Executor,
    reuse: Mapping[K, Mapping[str, str | Path]],
    on_family: Callable[[K, str, Evidence, az.InferenceData], None] | None,
    on_failure: Callable[[K, Exception], None] | None,
) -> Iterator[tuple[K, Comparison]]:
    """The generator of :func:`compare_groups` (its arguments checked)."""
    done: dict[K, dict[str, _FamilyFit]] = {key: {} for key in runs}
    failed: set[K] = set()

    def fail(key, exc: Exception) -> None:
        if on_failure is None:
            raise exc
        failed.add(key)
        on_failure(key, exc)

    for key, run in runs.items():
        paths = reuse.get(key, {})
        try:
            for family in families:
                reused = run.reuse(family, Path(paths[family])) if family in paths else None
                if reused is not None:
                    done[key][family] = reused
        except Exception as exc:  # e.g. a channel its data lack
            fail(key, exc)
    pending = sorted(
        (
            (key, family)
            for key in runs
            if key not in failed
            for family in families
            if family not in done[key]
        ),
        # A family not measured here (added to FAMILIES later) goes first.
        key=lambda job: _LONGEST_FIRST.index(job[1]) if job[1] in _LONGEST_FIRST else -1,
    )
    lines = executor.slots(len(pending))
    runs = {key: dataclasses.replace(run, lines=lines) for key, run in runs.items()}
    jobs = [(key, runs[key], position, family) for position, (key, family) in enumerate(pending)]
    with executor.run(_FamilyJob(catch=on_failure is not None), jobs) as finished:
        for key in runs:  # every family reused
            if key not in failed and len(done[key]) == len(families):
                yield key, _comparison(runs[key], families, done[key])
        for key, outcome in finished:  # in the order they finish
            if key in failed:
                continue
            if isinstance(outcome, Exception):
                fail(key, outcome)
                continue
            done[key][outcome.family] = outcome
            # raised in a worker, shown here
            outcome.kept.issue(f"{runs[key].label}{outcome.family}: ")
            try:
                if on_family is not None:
                    on_family(key, outcome.family, outcome.evidence, outcome.posterior)
            except Exception as exc:
                fail(key, exc)
                continue
            if len(done[key]) == len(families):
                yield key, _comparison(runs[key], families, done[key])


def _comparison(
    run: _FamilyRun, families: tuple[str, ...], results: dict[str, _FamilyFit]
) -> Comparison:
    """A group's comparison, its families in order; its chains' convergence warnings issued."""
    comparison = Comparison(
        [e.name for e in run.experiments],
        {family: results[family].evidence for family in families},
        {family: results[family].posterior for family in families},
        {
            family: results[family].nested
            for family in families
            if results[family].nested is not None
        },
    )
    for message in comparison.convergence_messages():
        warnings.warn(ConvergenceWarning(message), stacklevel=3)
    return comparison


def compare_families(
    experiments: list[Experiment],
    options: FitOptions | None = None,
    *,
    families: Sequence[str] = tuple(FAMILIES),
    cross_check: bool = False,
    executor: Executor | None = None,
    reuse: Mapping[str, str | Path] | None = None,
    on_family: Callable[[str, Evidence, az.InferenceData], None] | None = None,
) -> Comparison:
    """Sample each family's posterior and estimate its evidence by bridge sampling.

    :func:`compare_groups` on one group.

    Parameters
    ----------
    experiments : list of Experiment
        Pooled into one likelihood (shared damping).
    options : FitOptions, optional
        As in :func:`compare_groups`: the seed seeds every family's chain
        and the bridge's proposal draws, and the results do not depend on
        the executor. With progress on, each family's bar is labelled and,
        with several processes, kept on a line of its own.
    families : sequence of str
        Names from :data:`bayes_jackal.model.FAMILIES`.
    cross_check : bool
        Also estimate each evidence by
        :func:`~bayes_jackal.inference.nested_sampling` (slow).
    executor : Executor, optional
        Where the families run, one job each
        (:mod:`bayes_jackal.inference.executors`), e.g. ``ProcessExecutor(2)``
        or ``DaskExecutor("tcp://host:8786")`` for a Dask cluster (no
        progress bars there). Default: this process, one after the other.
    reuse : mapping of str to path, optional
        Where finished families were saved (family -> posterior file, e.g.
        by ``on_family`` in a run that was interrupted). A family whose
        saved task (data, robot, family, likelihood options, priors,
        sampler settings but the display, seed, cross-check) equals this
        one's is read back, not recomputed, and ``on_family`` is not
        called for it.
    on_family : callable, optional
        Called with (family, evidence, posterior) as each family finishes,
        e.g. to save it at once.

    Returns
    -------
    Comparison
        Each posterior carries in its attributes its evidence
        (``evidence``, ``evidence_nested``), its ``task`` and its
        ``convergence_messages``. Families that hit the step cap re-issue their
        :class:`~bayes_jackal.inference.ConvergenceWarning` here.

    Examples
    --------
    Two families on a chain budget kept short on purpose (20 steps, far
    from converged), so that the example is quick:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import FitOptions, compare_families
    >>> from bayes_jackal.likelihood import LikelihoodOptions
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> options = FitOptions(
    ...     likelihood_options=LikelihoodOptions(channels=["yaw"]),
    ...     settings=bj.SamplerSettings(max_steps=20), seed=1,
    ... )
    >>> comparison = compare_families([run], options, families=("white", "exponential"))
    >>> list(comparison.evidence), comparison.best
    (['white', 'exponential'], 'exponential')
    >>> comparison.verdict()[0]
    'coloured'
    """
    [(_, comparison)] = compare_groups(
        {0: experiments},
        options,
        families=families,
        cross_check=cross_check,
        executor=executor,
        reuse=None if reuse is None else {0: reuse},
        on_family=None if on_family is None else lambda _, *finished: on_family(*finished),
    )
    return comparison


def compare(
    experiments: Experiment | Sequence[Experiment],
    *,
    families: Sequence[str] | None = None,
    channels: Sequence[str] | None = None,
    noise: str = NOISE,
    sensor: str = SENSOR,
    engine: str = ENGINE,
    steady: bool = STEADY,
    damping: str = DAMPING_MODEL,
    seed: int | None = None,
    max_steps: int = MAX_STEPS,
    walkers: int = WALKERS,
    priors: Mapping[str, tuple[float, float]] | None = None,
    robot: RobotProfile | str | Path | None = None,
    nested: bool = False,
    processes: int = 1,
    executor: Executor | None = None,
    progress: bool = True,
) -> Comparison:
    """Noise-filter families ranked by evidence (``bayes-jackal compare --pooled``).

    Samples each family's posterior as :func:`sample` does and estimates
    its log evidence by bridge sampling
    (:func:`bayes_jackal.inference.compare_families`).

    Parameters
    ----------
    experiments : Experiment or sequence of them
        Several are pooled: one damping for all.
    families : sequence of str, optional
        Keys of :data:`bayes_jackal.FAMILIES`, distinct (``--families``);
        None: every registered family, in the registry's order.
    channels, noise, sensor, engine, steady, damping, seed, max_steps, walkers, priors, robot,
    progress
        As in :func:`sample`; the seed seeds every family's chain and the
        bridges' proposal draws.
    nested : bool
        Cross-check each evidence by nested sampling (slow; ``--nested``,
        ``pip install 'bayes-jackal[evidence]'``).
    processes : int
        Families sampled at once, each in its own worker process; a script
        that asks for more than 1 needs an ``if __name__ == "__main__":``
        guard. The numbers do not depend on it.
    executor : Executor, optional
        Where the families run instead (:mod:`bayes_jackal.inference.executors`),
        e.g. ``DaskExecutor("tcp://host:8786")`` (``--scheduler``).

    Returns
    -------
    Comparison
        ``best`` (the family of highest evidence), ``posteriors`` (family ->
        arviz.InferenceData, each with its evidence), ``verdict()`` and
        ``to_dict()`` (the ``compare --json`` object).

    Raises
    ------
    InputError
        For families that are not distinct known names, and as :func:`sample`.

    Examples
    --------
    Two families on a quick budget (20 steps, the fewest bridge sampling
    takes are 16; far from converged: real use takes the default step cap):

    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> comparison = bj.compare(
    ...     [run], families=("white", "exponential"), channels=["yaw"], max_steps=20, seed=1
    ... )
    >>> sorted(comparison.posteriors), comparison.best in comparison.posteriors
    (['exponential', 'white'], True)
    >>> sorted(comparison.to_dict()["families"]["white"])[:3]
    ['converged', 'log_bayes_factor_vs_best', 'log_bayes_factor_vs_white']
    """
    options = FitOptions.of_keywords(locals())  # the keywords above, as they were given
    return compare_families(
        as_experiments(experiments),
        options,
        families=tuple(FAMILIES if families is None else families),
        cross_check=nested,
        executor=executor or ProcessExecutor(processes),
    )


#: A family is called coloured when it beats white noise by more than this
#: (ln B, "strong" on Kass & Raftery's scale) after two standard errors.
COLOURED_LOG_BF = 3.0


#: ... and white noise wins when every coloured family loses by more than
#: this ("positive") after two standard errors.
WHITE_LOG_BF = 1.0


@dataclass
class Comparison:
    """Noise-filter families of one data set, each with its posterior and evidence.

    Attributes
    ----------
    experiments : list of str
        Names of the experiments (several when pooled).
    evidence : dict of str to Evidence
        Bridge-sampling evidence per family.
    posteriors : dict of str to arviz.InferenceData
    nested : dict of str to Evidence
        Nested-sampling evidence per family, when cross-checked.

    Examples
    --------
    Two families' evidence as bridge sampling would give it (the
    posteriors, which :meth:`to_dict` reads, left out here):

    >>> from bayes_jackal.inference import Comparison
    >>> from bayes_jackal.posterior import Evidence
    >>> comparison = Comparison(
    ...     ["v1_01"],
    ...     {
    ...         "white": Evidence(7778.5, 0.03, "bridge sampling"),
    ...         "gaussian": Evidence(7790.5, 0.04, "bridge sampling"),
    ...     },
    ...     posteriors={},
    ... )
    >>> comparison.best
    'gaussian'
    >>> value, error = comparison.log_bayes_factor("gaussian", "white")
    >>> round(value, 2), round(error, 2)
    (12.0, 0.05)
    >>> comparison.verdict()
    ('coloured', 'coloured: gaussian over white, ln B = 12.0 +- 0.05, very strong')
    """

    experiments: list[str]
    evidence: dict[str, Evidence]
    posteriors: dict[str, az.InferenceData]
    nested: dict[str, Evidence] = field(default_factory=dict)

    @property
    def best(self) -> str:
        """The family of highest evidence."""
        return max(self.evidence, key=lambda name: self.evidence[name].log_evidence)

    def convergence_messages(self) -> list[str]:
        """Each family's chain that hit its step cap, as ``"<family>: <message>"``.

        Read from the posteriors' ``convergence_messages`` attributes (kept
        by :func:`compare_groups`, also in a saved and reused posterior).
        """
        return [
            f"{family}: {message}"
            for family, idata in self.posteriors.items()
            for message in Posterior.of(idata).metadata.convergence_messages
        ]

    def log_bayes_factor(self, family: str, other: str) -> tuple[float, float]:
        """ln B of ``family`` over ``other`` and its standard error [nats]."""
        a, b = self.evidence[family], self.evidence[other]
        return a.log_evidence - b.log_evidence, float(np.hypot(a.error, b.error))

    def verdict(
        self,
        white_warnings: Sequence[str] | None = None,
        *,
        family_warnings: Mapping[str, Sequence[dict]] | None = None,
    ) -> tuple[str, str]:
        """Is the noise coloured? :func:`colour_verdict` of the families' evidence.

        ``white_warnings``: the kinds of the white fit's criticism warnings;
        ``family_warnings``: each family's warnings (where its width is piled
        at its floor). Both are read from the posteriors when not given.
        """
        if family_warnings is None:
            family_warnings = {
                name: summarize(idata)["warnings"] for name, idata in self.posteriors.items()
            }
        if white_warnings is None:
            white_warnings = [w["kind"] for w in family_warnings.get("white", [])]
        floors = _width_floors(self.posteriors, family_warnings)
        return colour_verdict(self.evidence, white_warnings, floors)

    def to_dict(self) -> dict:
        """The ``compare --json`` object (docs/design.md §6).

        Each family carries its model-criticism ``warnings``
        (:func:`bayes_jackal.posterior.criticise`); the top-level ``warnings``
        lists them all, each with its ``family``.
        """
        families = {}
        for name, evidence in self.evidence.items():
            entry = evidence.to_dict()
            entry["log_bayes_factor_vs_best"] = self.log_bayes_factor(name, self.best)[0]
            entry["log_bayes_factor_vs_white"] = (
                self.log_bayes_factor(name, "white")[0] if "white" in self.evidence else None
            )
            entry["width"] = _width_summary(self.posteriors[name], name)
            entry["converged"] = Posterior.of(self.posteriors[name]).metadata.convergence.converged
            entry["warnings"] = summarize(self.posteriors[name])["warnings"]
            if name in self.nested:
                entry["log_evidence_nested"] = self.nested[name].log_evidence
                entry["log_evidence_nested_err"] = self.nested[name].error
            families[name] = entry
        label, sentence = self.verdict(
            family_warnings={name: entry["warnings"] for name, entry in families.items()}
        )
        return {
            "experiments": self.experiments,
            "families": families,
            "best": self.best,
            "log_bayes_factor_vs_white": families[self.best]["log_bayes_factor_vs_white"],
            "verdict": label,
            "verdict_text": sentence,
            "warnings": [
                {"family": name} | warning
                for name, entry in families.items()
                for warning in entry["warnings"]
            ],
        }


#: A width floor below this many sample intervals hides no colour: memory
#: shorter than it has a lag-1 correlation below e^-4 = 0.018, white to the data.
HIDING_FLOOR_SAMPLES = 0.25


def width_floor(warnings: Sequence[dict], widths: Sequence[str], dt: float) -> float | None:
    """The prior bound [s] a width of ``widths`` is piled at, if it can hide colour; else None.

    ``warnings`` are a fit's criticism warnings; a width piled at its floor
    has a low-side ``prior-boundary`` one (:func:`bayes_jackal.posterior.boundary_check`).
    A floor below :data:`HIDING_FLOOR_SAMPLES` sample intervals ``dt`` [s]
    does not count: what lies below it is white.
    """
    bounds = [w["bound"] for w in warnings if w["kind"] == PRIOR_BOUNDARY
              and w.get("side") == "low" and w.get("parameter") in widths
              and w["bound"] >= HIDING_FLOOR_SAMPLES * dt]  # fmt: skip
    return min(bounds) if bounds else None


def _width_floors(
    posteriors: Mapping[str, az.InferenceData], warnings: Mapping[str, Sequence[dict]]
) -> dict[str, float]:
    """Per coloured family whose width is piled at its prior's lower bound, that bound [s]."""
    floors = {}
    for name, idata in posteriors.items():
        metadata = Posterior.of(idata).metadata
        layout = metadata.layout
        widths = () if layout.width_name is None else layout.names_of(layout.width_name)
        dt = min((record.dt for record in metadata.experiments), default=0.0)
        if (floor := width_floor(warnings.get(name, ()), widths, dt)) is not None:
            floors[name] = floor
    return floors


def colour_verdict(
    evidence: Mapping[str, Evidence],
    white_warnings: Sequence[str] = (),
    width_floors: Mapping[str, float] | None = None,
) -> tuple[str, str]:
    """Is the noise coloured? ('coloured' | 'not coloured' | 'inconclusive', sentence).

    The best coloured family is set against white noise. 'coloured' needs
    ln B - 2 se > 3 (strong), 'not coloured' needs ln B + 2 se < -1
    (white better by positive evidence); anything between is
    inconclusive, so a noisy estimate never gives a confident answer.
    White beating the families compared is not "not coloured" when the
    white fit itself misses the residuals' colour (its ``predictive-acf``
    warning): a family not compared may be coloured, and the verdict is
    inconclusive. Nor is it where a coloured family's width is piled at its
    prior's floor (``width_floors``): memory shorter than the floor was not
    tried (at 1 kHz the default floor, 1 ms, is one sample), and the verdict
    is inconclusive, saying how to lower it. A "not coloured" names the
    families that were not compared.

    Parameters
    ----------
    evidence : mapping of str to Evidence
        Each family's log evidence.
    white_warnings : sequence of str
        The kinds of the white fit's criticism warnings
        (:func:`bayes_jackal.posterior.criticise`).
    width_floors : mapping of str to float, optional
        Per coloured family whose width is piled at its prior's lower bound
        (a ``prior-boundary`` warning), that bound [s].

    Examples
    --------
    >>> from bayes_jackal.inference import colour_verdict
    >>> from bayes_jackal.posterior import Evidence
    >>> colour_verdict({"white": Evidence(-10.0, 0.1, "bridge"),
    ...                 "gaussian": Evidence(-9.5, 0.1, "bridge")})[0]
    'inconclusive'

    White far ahead, but the rival's width at its floor: shorter memory was
    not tried.

    >>> evidence = {"white": Evidence(0.0, 0.01, "bridge"),
    ...             "exponential": Evidence(-39.2, 0.01, "bridge")}
    >>> colour_verdict(evidence)[0], colour_verdict(evidence, (), {"exponential": 0.001})[0]
    ('not coloured', 'inconclusive')
    """
    coloured = [name for name in evidence if name != "white"]
    if "white" not in evidence or not coloured:
        return "inconclusive", "white noise and a coloured family must both be compared"
    rival = max(coloured, key=lambda name: evidence[name].log_evidence)
    value = evidence[rival].log_evidence - evidence["white"].log_evidence
    error = float(np.hypot(evidence[rival].error, evidence["white"].error))
    words = f"ln B = {value:.1f} +- {error:.2f}, {evidence_strength(value)}"
    if value - 2 * error > COLOURED_LOG_BF:
        return "coloured", f"coloured: {rival} over white, {words}"
    untried = [name for name in FAMILIES if name not in evidence]
    floored = {name: floor for name, floor in (width_floors or {}).items() if name != "white"}
    if value + 2 * error < -WHITE_LOG_BF and floored:
        at = ", ".join(f"{name}'s at {floor:g} s" for name, floor in floored.items())
        return "inconclusive", (
            f"inconclusive: white over {rival}, {words}, but the width is piled at its "
            f"prior's floor ({at}): colour of shorter memory was not tried; lower the "
            "floor (--prior sigma_h LOW HIGH, e.g. a quarter of the sample interval)"
        )
    if value + 2 * error < -WHITE_LOG_BF and PREDICTIVE_ACF in white_warnings:
        return "inconclusive", (
            f"inconclusive: white over {rival}, {words}, but the white fit misses the "
            "residuals' colour (predictive-acf): a family not compared may be coloured"
            + (f"; compare {', '.join(untried)} too (--families)" if untried else "")
        )
    if value + 2 * error < -WHITE_LOG_BF:
        return "not coloured", f"not coloured: white over {rival}, {words}" + (
            f" ({', '.join(untried)} not compared)" if untried else ""
        )
    return "inconclusive", f"inconclusive: {rival} against white, {words}"


def _width_summary(idata: az.InferenceData, family: str) -> dict | None:
    """Posterior mean, sd and HDI of a family's width(s) [s]; None for white noise."""
    layout = Posterior.of(idata).metadata.layout
    if layout.width_name is None:
        return None
    summary = summarize(idata)
    widths = layout.names_of(layout.width_name)
    return {name: interval(summary[name]) for name in widths} | {"hdi_prob": HDI_PROB}
