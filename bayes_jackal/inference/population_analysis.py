"""A campaign's population: each group's damping, their spread and their dependence on speed.

:func:`population` runs the two stages of docs/guide/population.md. Stage 1
samples each unit with emcee and bridge-samples its evidence
(:func:`~bayes_jackal.inference.compare_groups`, one family): a unit is a
group's runs pooled with their noise shared (``noise="shared"`` or
``"one-width"``, the noise per group), or one run (``"per-experiment"``,
the noise per run). Stage 2 combines the units' damping posteriors in
:class:`~bayes_jackal.inference.Hierarchy`: pooled, hierarchical and
independent structures, each with and without a slope in the covariate,
ranked by evidence.
"""

from __future__ import annotations

import logging
import math
import re
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._runtime import (
    COVARIATE_INCOMPLETE,
    DAMPING_MODEL,
    ENGINE,
    FAMILY,
    FEW_GROUPS,
    HDI_PROB,
    MAX_STEPS,
    NOISE,
    NORMAL_SUMMARY,
    NOT_CONVERGED,
    ONE_OPERATING_POINT,
    PRIOR_BOUNDARY,
    PRIOR_SENSITIVITY,
    SENSOR,
    STEADY,
    WALKERS,
    InputError,
    as_rng,
    az,
)
from ..io import Experiment, RunGroups, as_experiments, as_run_groups, group_runs, run_group
from ..model import RobotProfile
from ..posterior import Evidence, Posterior, save_posterior
from .comparison import Comparison, compare_groups
from .evidence import evidence_strength
from .executors import Executor
from .hierarchy import (
    DAMPING_NAMES,
    STRUCTURE_PARTS,
    TAU_RANGE,
    Hierarchy,
    UnitPosterior,
    unit_posterior,
)
from .options import FitOptions
from .sampler_warnings import ConvergenceWarning

__all__ = [
    "POPULATION_DRAWS",
    "SENSITIVITY_TAU_RANGES",
    "Population",
    "UnitPlan",
    "plan_units",
    "population",
    "population_posterior",
    "unit_files",
]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)

#: The population's two spreads (:data:`~bayes_jackal.inference.TO_SCALE_RATIO`).
SPREADS = ("scale", "ratio")
#: Posterior draws of each structure's parameters.
POPULATION_DRAWS = 4000
#: Other priors of the population spread the result is checked against:
#: log-uniform over a range 10 times wider at each end, and one 10 times
#: narrower at the top (at most 10 % spread per sd).
SENSITIVITY_TAU_RANGES = {"wide": (0.001, 10.0), "narrow": (0.01, 0.1)}
#: A unit's normal summary is doubted when the share of its draws in the
#: normal's 94 % ellipse is off by more than this: 3 sd of that share over
#: the 400 effective draws a converged chain has at least.
COVERAGE_TOLERANCE = 0.036
#: A unit's normal summary is doubted when a log-damping's skewness is above this: 4 sd
#: of the skewness of 400 effective normal draws, sqrt(6 / 400) = 0.12.
SKEWNESS_TOLERANCE = 0.5
#: The population mean is called prior-sensitive when another spread prior
#: moves it by more than half its posterior sd.
SENSITIVITY_SHIFT = 0.5


def _summary(values: np.ndarray) -> dict:
    """Mean, sd and 94 % HDI of 1-d draws (the keys of :func:`bayes_jackal.summarize`)."""
    low, high = az.hdi(np.asarray(values, float), hdi_prob=HDI_PROB)
    return {
        "mean": float(np.mean(values)),
        "sd": float(np.std(values, ddof=1)),
        "hdi_3%": float(low),
        "hdi_97%": float(high),
    }


def _damping(log_values: np.ndarray) -> dict:
    """``d_lat`` and ``d_long`` summaries [N s/m] of (..., 2) log-damping draws."""
    return {name: _summary(np.exp(log_values[..., i])) for i, name in enumerate(DAMPING_NAMES)}


@dataclass
class Population:
    """The result of :func:`population`: each structure's evidence, the population's draws.

    Attributes
    ----------
    family : str
        The noise family of every unit.
    covariate : str or None
        The covariate of the state dependence (e.g. ``speed``), when given.
    hierarchy : Hierarchy
        The units' normal summaries and the structures.
    evidence : dict of str to Evidence
        Log evidence of each structure.
    replicas : dict of str to ndarray
        Each structure's :meth:`Hierarchy.log_integral_replicas`, for the
        errors of Bayes factors.
    draws : dict of str to dict
        :meth:`Hierarchy.draws` of each structure.
    posteriors : dict of str to Posterior
        Stage 1's posterior of each unit.
    sensitivity : dict
        The population under the other spread priors
        (:data:`SENSITIVITY_TAU_RANGES`).
    warnings : list of dict
        ``kind``, ``message`` and, where one is concerned, ``unit``.

    Examples
    --------
    Two floors of two runs each, whose d_long differ by a third; chains of
    white noise on the yaw rate, which pins the ratio d_lat / d_long:

    >>> import bayes_jackal as bj
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, d_long, rng=seed, name=f"run{seed}")
    ...     for seed, d_long in enumerate([30.0, 30.0, 40.0, 40.0])
    ... ]
    >>> floors = {"run0": "tiles", "run1": "tiles", "run2": "carpet", "run3": "carpet"}
    >>> result = bj.population(
    ...     runs, groups=floors, family="white", channels=["yaw"], seed=1,
    ...     max_steps=400, progress=False,
    ... )
    >>> result.best, result.model, list(result.hierarchy.groups)
    ('hierarchical', 'hierarchical', ['tiles', 'carpet'])
    >>> value, error = result.log_bayes_factor("hierarchical", "pooled")
    >>> value > 3
    True
    >>> sorted(result.population_summary()["d_lat"])
    ['mean', 'new_group', 'sd']
    """

    family: str
    covariate: str | None
    hierarchy: Hierarchy
    evidence: dict[str, Evidence]
    replicas: dict[str, np.ndarray]
    draws: dict[str, dict]
    posteriors: dict[str, Posterior]
    sensitivity: dict = field(default_factory=dict)
    warnings: list[dict] = field(default_factory=list)

    @property
    def best(self) -> str:
        """The structure of highest evidence."""
        return self._highest(self.evidence)

    @property
    def model(self) -> str:
        """The hierarchical structure reported: with the slope when its evidence is higher."""
        return self._highest(name for name in self.evidence if name.startswith("hierarchical"))

    def _highest(self, structures: Iterable[str]) -> str:
        """The one of ``structures`` of highest evidence."""
        return max(structures, key=lambda name: self.evidence[name].log_evidence)

    def log_bayes_factor(self, structure: str, other: str) -> tuple[float, float]:
        """ln B of ``structure`` over ``other`` and its error [nats]."""
        value = self.evidence[structure].log_evidence - self.evidence[other].log_evidence
        difference = self.replicas[structure] - self.replicas[other]
        return value, float(np.std(difference, ddof=1)) if len(difference) > 1 else math.nan

    def group_summaries(self, structure: str | None = None) -> dict[str, dict]:
        """Each group's ``d_lat`` and ``d_long`` [N s/m] under ``structure`` (the model's)."""
        levels = self.draws[structure or self.model]["groups"]
        return {g: _damping(levels[:, i]) for i, g in enumerate(self.hierarchy.groups)}

    def population_summary(self) -> dict:
        """The population of the model: its mean and sd, on the log scale and in N s/m.

        Per damping, ``mean.log`` is mu and ``sd.log`` the sd of log d
        across groups, sqrt(tau_scale^2 + tau_ratio^2 / 4); in N s/m the
        log-normal's mean exp(mu + sd^2 / 2) and sd; ``new_group`` is the
        damping [N s/m] a new group would have, what to expect of a new
        floor. ``spread`` holds the two spreads, of the scale and of the
        ratio (:data:`~bayes_jackal.inference.TO_SCALE_RATIO`).
        """
        draws = self.draws[self.model]
        mu, tau, new_group = draws["mu"], draws["tau"], draws["new_group"]
        sd = np.sqrt(tau[:, 0] ** 2 + tau[:, 1] ** 2 / 4)
        result = {}
        for i, name in enumerate(DAMPING_NAMES):
            mean = np.exp(mu[:, i] + sd**2 / 2)
            result[name] = {
                "mean": {"log": _summary(mu[:, i]), "N s/m": _summary(mean)},
                "sd": {"log": _summary(sd), "N s/m": _summary(mean * np.sqrt(np.expm1(sd**2)))},
                "new_group": _summary(np.exp(new_group[:, i])),
            }
        result["spread"] = {name: _summary(tau[:, i]) for i, name in enumerate(SPREADS)}
        return result

    def speed_dependence(self) -> dict | None:
        """The slope of log d in the covariate and ln B of a slope over none; None without one."""
        if self.covariate is None:
            return None
        confounded = self.covariate_confounded()
        if confounded:  # the slope, or the groups' difference: against one damping for all
            sloped, constant = "pooled + slope", "pooled"
        else:
            sloped = self._highest(name for name in self.evidence if STRUCTURE_PARTS[name][1])
            constant = self._highest(
                name for name in self.evidence if not STRUCTURE_PARTS[name][1]
            )
        slope = self.draws[sloped]["slope"]
        span = self.hierarchy.covariate_span
        value, error = self.log_bayes_factor(sloped, constant)
        slopes = {}
        excludes_zero = False
        for i, name in enumerate(DAMPING_NAMES):
            per_unit = _summary(slope[:, i] / span)
            excludes_zero |= not per_unit["hdi_3%"] <= 0 <= per_unit["hdi_97%"]
            slopes[name] = {
                "log_per_unit": per_unit,
                "ratio_across_range": _summary(np.exp(slope[:, i])),
            }
        values = [unit.covariate for unit in self.hierarchy.units]
        detected = excludes_zero and value > 3
        if confounded:
            claim = (
                f"each group has one {self.covariate}, a difference only the groups carry: a "
                f"dependence on {self.covariate} and a difference between the groups are one "
                f"model here, which the data cannot tell apart. The damping "
                + (
                    f"depends on {self.covariate} or differs between the groups"
                    if detected
                    else f"neither depends on {self.covariate} nor differs between the groups"
                )
            )
        else:
            shown = "depends" if detected else "is not shown to depend"
            claim = f"the damping {shown} on {self.covariate}"
        verdict = (
            f"{claim}: {sloped} over {constant}, ln B = {value:.1f} +- {error:.2f}, "
            f"{evidence_strength(value)}"
        )
        return {
            "covariate": self.covariate,
            "range": [min(values), max(values)],
            # mu and a new group's damping are at this covariate value
            "reference": self.hierarchy.covariate_centre,
            "structure": sloped,
            "against": constant,
            "slope": slopes,
            "log_bayes_factor": value,
            "error": error,
            "detected": bool(detected),
            "confounded": confounded,
            "verdict": verdict,
        }

    def covariate_confounded(self) -> bool:
        """Whether the covariate only tells the groups apart: several groups, one value each.

        Then a slope in the covariate and the groups' own dampings are the same
        model, and :meth:`speed_dependence` weighs the slope against one
        damping for every group.
        """
        values: dict[str, set] = {}
        for unit in self.hierarchy.units:
            values.setdefault(unit.group, set()).add(unit.covariate)
        return len(values) > 1 and all(len(group) == 1 for group in values.values())

    def verdict(self) -> str:
        """The best structure, in words."""
        best = self.best
        kind = STRUCTURE_PARTS[best][0]
        others = [name for name in self.evidence if STRUCTURE_PARTS[name][0] != kind]
        runner_up = self._highest(others)
        value, error = self.log_bayes_factor(best, runner_up)
        meaning = {
            "pooled": "one damping fits every group",
            "hierarchical": "the groups' dampings differ, drawn from one population",
            "independent": "the groups' dampings differ, each its own",
        }[kind]
        doubted = {w["kind"] for w in self.warnings} & {NORMAL_SUMMARY, PRIOR_BOUNDARY}
        return (
            f"{meaning}: {best} over {runner_up}, ln B = {value:.1f} +- {error:.2f}, "
            f"{evidence_strength(value)}"
            + (
                " (approximate: a unit's damping posterior is not normal or reaches its "
                "prior's bound; see the warnings)"
                if doubted
                else ""
            )
        )

    def unit_summaries(self) -> dict[str, dict]:
        """Each unit alone (stage 1): group, runs, covariate, damping [N s/m], evidence."""
        result = {}
        for unit in self.hierarchy.units:
            posterior = self.posteriors[unit.name].posterior
            result[unit.name] = {
                "group": unit.group,
                "runs": list(unit.runs),
                "covariate": unit.covariate,
                **{name: _summary(posterior[name].values.ravel()) for name in DAMPING_NAMES},
                "log_evidence": unit.log_evidence,
                "error": unit.evidence_error,
                "normal_coverage": unit.coverage,
                "skewness": unit.skewness,
            }
        return result

    def to_dict(self) -> dict:
        """The ``population --json`` object (docs/guide/population.md)."""
        independent = self.group_summaries("independent")
        groups = {
            label: summary | {"independent": independent[label]}
            for label, summary in self.group_summaries().items()
        }
        return {
            "family": self.family,
            "model": self.model,
            "groups": groups,
            "population": self.population_summary(),
            "speed_dependence": self.speed_dependence(),
            "evidence": {
                name: evidence.to_dict()
                | {"log_bayes_factor_vs_best": self.log_bayes_factor(name, self.best)[0]}
                for name, evidence in self.evidence.items()
            },
            "best": self.best,
            "verdict": self.verdict(),
            "units": self.unit_summaries(),
            "sensitivity": self.sensitivity,
            "warnings": self.warnings,
        }


def unit_files(folder: str | Path, names: Sequence[str], family: str) -> dict[str, Path]:
    """Where :func:`population` keeps each unit's posterior under ``folder`` (``units/``).

    Examples
    --------
    >>> from bayes_jackal.inference import unit_files
    >>> unit_files("campaign", ["floor A", "v1_01"], "gaussian")["floor A"].as_posix()
    'campaign/units/floor_A.gaussian.nc'
    """
    return {
        name: Path(folder) / "units" / f"{stem}.{family}.nc"
        for name, stem in _file_stems(names).items()
    }


def _file_stems(names: Sequence[str]) -> dict[str, str]:
    """Each unit's file stem, its name made safe; two names of one stem are refused."""
    stems = {name: re.sub(r"[^A-Za-z0-9_.-]+", "_", name) for name in names}
    taken: dict[str, str] = {}
    for name, stem in stems.items():
        other = taken.setdefault(stem.lower(), name)  # one file on a case-blind file system
        if other != name:
            raise InputError(
                f"units {other!r} and {name!r} would share the file {stem}.*: rename one",
                field="group",
            )
    return stems


def _covariate_name(
    experiments: Sequence[Experiment], table: RunGroups | None, covariate: str | None
) -> str | None:
    """The covariate to use: as named, else ``speed`` when every run has one."""
    name = covariate or "speed"
    given = [name in run_group(experiment, table)[1] for experiment in experiments]
    if all(given):
        return name
    if covariate is None:
        return None
    if table is not None and covariate in table.text_columns:
        raise InputError(
            f"the column {covariate!r} holds text, not numbers: a covariate must be a number "
            "(a group's label goes in the group column)",
            source=table.source,
            field=covariate,
        )
    missing = experiments[given.index(False)]
    raise InputError(
        f"run {missing.name!r} has no {covariate!r}",
        source=getattr(table, "source", None) or missing.source,
        field=covariate,
    )


def _partial_speed(experiments: Sequence[Experiment], table: RunGroups | None) -> list[dict]:
    """A note where some runs have a ``speed`` and others not: no slope is then fitted."""
    given = {run.name for run in experiments if "speed" in run_group(run, table)[1]}
    if not given:
        return []
    missing = [run.name for run in experiments if run.name not in given]
    return [{
        "kind": COVARIATE_INCOMPLETE,
        "message": f"{len(given)} of {len(experiments)} runs have a speed ({missing[0]!r} has "
                   "none): no state dependence is fitted; give every run's speed, or "
                   "--covariate speed to refuse such a table",
    }]  # fmt: skip


def _units(
    grouped: Mapping[str, list[Experiment]],
    table: RunGroups | None,
    covariate: str | None,
    per_run: bool,
) -> dict[str, tuple[str, list[Experiment], float | None]]:
    """Unit name -> (group, experiments, covariate): one per run, or one per group."""
    units = {}
    for label, runs in grouped.items():
        for members in [[run] for run in runs] if per_run else [runs]:
            name = members[0].name if per_run else label
            if name in units:
                raise InputError(f"two runs are named {name!r}", field="run")
            values = sorted({run_group(run, table)[1][covariate] for run in members if covariate})
            if len(values) > 1:
                raise InputError(
                    f"group {label!r} pools runs at {covariate} {values} with the noise shared: "
                    "give each operating point its own group, or fit each run alone "
                    "(noise='per-experiment'; on the command line --noise per-experiment)",
                    field=covariate,
                )
            units[name] = (label, members, values[0] if values else None)
    return units


@dataclass(frozen=True)
class UnitPlan:
    """What :func:`population` will sample: its units, their covariate and the notes on it.

    Attributes
    ----------
    units : dict of str to (str, list of Experiment, float or None)
        Unit name -> (group label, its runs, its covariate).
    covariate : str or None
        The covariate of the slope, None without one.
    notes : list of dict
        Warnings to keep (``one-operating-point``, ``covariate-incomplete``).

    Examples
    --------
    Two floors of two runs each, every run at one speed: no slope, and a note
    that says why.

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import plan_units
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=s, name=f"r{s}") for s in range(4)]
    >>> floors = {"r0": "A", "r1": "A", "r2": "B", "r3": "B"}
    >>> table = bj.io.RunGroups(floors, {run: {"speed": 0.3} for run in floors})
    >>> plan = plan_units(runs, table)
    >>> {name: [run.name for run in unit[1]] for name, unit in plan.units.items()}
    {'A': ['r0', 'r1'], 'B': ['r2', 'r3']}
    >>> plan.covariate, [note["kind"] for note in plan.notes]
    (None, ['one-operating-point'])
    """

    units: dict[str, tuple[str, list[Experiment], float | None]]
    covariate: str | None
    notes: list[dict]


def plan_units(
    experiments: Sequence[Experiment],
    groups: RunGroups | Mapping[str, str] | str | Path | None,
    *,
    covariate: str | None = None,
    noise: str = NOISE,
) -> UnitPlan:
    """The units of a population, checked before any sampling (``analyse --groups`` first).

    Raises
    ------
    InputError
        For a groups file that cannot be read, a run without a group or
        covariate, fewer than two groups, a group pooling runs at
        different operating points with the noise shared, or two units
        named alike.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import plan_units
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=s, name=f"r{s}") for s in range(4)]
    >>> speeds = {"r0": 0.3, "r1": 0.5, "r2": 0.3, "r3": 0.5}
    >>> table = bj.io.RunGroups(
    ...     {"r0": "A", "r1": "A", "r2": "B", "r3": "B"},
    ...     {run: {"speed": speed} for run, speed in speeds.items()},
    ... )
    >>> plan = plan_units(runs, table, noise="per-experiment")
    >>> list(plan.units), plan.covariate
    (['r0', 'r1', 'r2', 'r3'], 'speed')
    """
    table = as_run_groups(groups)
    grouped = group_runs(experiments, table)
    if len(grouped) < 2:
        raise InputError(
            f"a population needs two groups at least, got {list(grouped)}; for one group, "
            "sample its runs pooled (bayes-jackal sample --pooled)",
            source=getattr(table, "source", None),
            field="group",
        )
    name = _covariate_name(experiments, table, covariate and covariate.strip().lower())
    units = _units(grouped, table, name, per_run=noise == "per-experiment")
    _file_stems(list(units))  # two unit names that would share a file are refused
    if name is None:
        return UnitPlan(units, None, _partial_speed(experiments, table))
    if len({value for _, _, value in units.values()}) > 1:
        return UnitPlan(units, name, [])
    note = {
        "kind": ONE_OPERATING_POINT,
        "message": f"every unit has the same {name}: no state dependence is fitted",
    }
    units = {key: (label, members, None) for key, (label, members, _) in units.items()}
    return UnitPlan(units, None, [note])


def population(
    experiments: Experiment | Sequence[Experiment],
    *,
    groups: RunGroups | Mapping[str, str] | str | Path | None = None,
    covariate: str | None = None,
    family: str = FAMILY,
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
    executor: Executor | None = None,
    out: str | Path | None = None,
    progress: bool = True,
    tau_range: tuple[float, float] = TAU_RANGE,
) -> Population:
    """The damping of a campaign's groups of runs, their population and its speed dependence.

    Parameters
    ----------
    experiments : Experiment or sequence of them
        Every run of the campaign.
    groups : RunGroups, mapping, str or Path, optional
        Each run's group: a groups CSV (:func:`bayes_jackal.io.read_groups`),
        a table read from one, or a mapping run -> label. Default: each
        experiment's ``provenance["group"]``.
    covariate : str, optional
        The covariate of the state dependence log d = a + b (x - x0); by
        default ``speed`` when every run has one, else none.
    family, channels, noise, sensor, engine, steady, damping
        The likelihood, as in :func:`bayes_jackal.sample`. ``noise``
        decides the units: ``"shared"`` or ``"one-width"`` pool each
        group's runs, their noise shared; ``"per-experiment"`` samples each
        run alone, its own noise.
    seed : int, optional
        Seeds every unit's chain and the stage 2 draws: same seed, same result.
    max_steps, walkers, priors, robot
        As in :func:`bayes_jackal.sample`.
    executor : Executor, optional
        Where the units' chains run (e.g. ``ProcessExecutor(2)``); default:
        this process, one after the other.
    out : str or Path, optional
        Folder where each unit's posterior is saved as it finishes
        (``units/<unit>.<family>.nc``) and read back on a rerun with the
        same task.
    progress : bool
        Show each chain's progress.
    tau_range : (float, float)
        Log-uniform prior range of the population spread [log d].

    Returns
    -------
    Population
        A unit's chain that hit its step cap raises no
        :class:`~bayes_jackal.inference.ConvergenceWarning`: it is a
        ``not-converged`` entry of its ``warnings``, with the unit's name.

    Raises
    ------
    InputError
        For a run without a group or covariate, a group pooling runs at
        different operating points with the noise shared, two runs of one
        name, or a bad option.

    Examples
    --------
    Two floors of two runs each, whose d_long differ by a third; chains of
    white noise on the yaw rate, which pins the ratio d_lat / d_long:

    >>> import bayes_jackal as bj
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, d_long, rng=seed, name=f"run{seed}")
    ...     for seed, d_long in enumerate([30.0, 30.0, 40.0, 40.0])
    ... ]
    >>> floors = {"run0": "tiles", "run1": "tiles", "run2": "carpet", "run3": "carpet"}
    >>> result = bj.population(
    ...     runs, groups=floors, family="white", channels=["yaw"], seed=1,
    ...     max_steps=400, progress=False,
    ... )
    >>> result.best, sorted(result.to_dict()["groups"])
    ('hierarchical', ['carpet', 'tiles'])
    """
    options = FitOptions.of_keywords(locals())  # the keywords above, as they were given
    return population_posterior(
        as_experiments(experiments),
        options,
        groups=groups,
        covariate=covariate,
        family=family,
        executor=executor,
        out=out,
        tau_range=tau_range,
    )


def population_posterior(
    experiments: Sequence[Experiment],
    options: FitOptions | None = None,
    *,
    groups: RunGroups | Mapping[str, str] | str | Path | None = None,
    covariate: str | None = None,
    family: str = FAMILY,
    executor: Executor | None = None,
    out: str | Path | None = None,
    tau_range: tuple[float, float] = TAU_RANGE,
) -> Population:
    """:func:`population` with its options as an object, as ``analyse --groups`` runs it.

    Parameters
    ----------
    experiments : sequence of Experiment
    options : FitOptions, optional
        Every unit's robot, likelihood options (whose ``noise`` decides the
        units), priors, sampler settings and seed.
    groups, covariate, family, executor, out, tau_range
        As in :func:`population`.

    Returns
    -------
    Population

    Examples
    --------
    The call :func:`population`'s example makes:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import FitOptions, population_posterior
    >>> from bayes_jackal.likelihood import LikelihoodOptions
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, d_long, rng=seed, name=f"run{seed}")
    ...     for seed, d_long in enumerate([30.0, 30.0, 40.0, 40.0])
    ... ]
    >>> floors = {"run0": "tiles", "run1": "tiles", "run2": "carpet", "run3": "carpet"}
    >>> options = FitOptions(
    ...     likelihood_options=LikelihoodOptions(channels=["yaw"]),
    ...     settings=bj.SamplerSettings(max_steps=400), seed=1,
    ... )
    >>> population_posterior(runs, options, groups=floors, family="white").best
    'hierarchical'
    """
    fit = FitOptions.of(options)
    plan = plan_units(experiments, groups, covariate=covariate, noise=fit.likelihood_options.noise)
    units, name = plan.units, plan.covariate
    files = unit_files(out, list(units), family) if out is not None else {}

    def finished(key: str, _family: str, evidence: Evidence, idata) -> None:
        _log.info(f"  {key}: log Z = {evidence.log_evidence:.2f} +- {evidence.error:.3f}")
        if key in files:
            files[key].parent.mkdir(parents=True, exist_ok=True)
            save_posterior(idata, files[key])

    with warnings.catch_warnings():
        # A chain that hit its cap is in the result's warnings (kind "not-converged").
        warnings.simplefilter("ignore", ConvergenceWarning)
        units_sampled = compare_groups(
            {key: members for key, (_, members, _) in units.items()},
            fit,
            families=[family],
            executor=executor,
            reuse={key: {family: path} for key, path in files.items()},
            on_family=finished,
        )
        comparisons = dict(units_sampled)  # the jobs run as this consumes them
    return combine_units(
        {key: comparisons[key] for key in units},
        {key: (label, value) for key, (label, _, value) in units.items()},
        family=family,
        covariate=name,
        tau_range=tau_range,
        seed=fit.seed,
        notes=plan.notes,
    )


def combine_units(
    comparisons: Mapping[str, Comparison],
    labels: Mapping[str, tuple[str, float | None]],
    *,
    family: str,
    covariate: str | None,
    tau_range: tuple[float, float],
    seed: int | None,
    notes: Sequence[dict] = (),
) -> Population:
    """Stage 2: the units' posteriors (stage 1's comparisons) combined in every structure.

    ``labels`` gives each unit's (group, covariate); ``notes`` are warnings
    to keep.
    """
    summaries, warnings = [], list(notes)
    posteriors = {}
    for key, comparison in comparisons.items():
        label, value = labels[key]
        posterior = Posterior.of(comparison.posteriors[family])
        posteriors[key] = posterior
        metadata = posterior.metadata
        columns = [metadata.prior.names.index(name) for name in DAMPING_NAMES]
        bounds = np.stack([metadata.prior.low[columns], metadata.prior.high[columns]], axis=1)
        evidence = comparison.evidence[family]
        draws = np.stack([posterior.posterior[n].values.ravel() for n in DAMPING_NAMES], axis=1)
        ess = min(metadata.convergence.ess_autocorr.get(n, math.inf) for n in DAMPING_NAMES)
        unit = unit_posterior(
            key,
            label,
            draws,
            bounds,
            runs=list(comparison.experiments),
            covariate=value,
            log_evidence=evidence.log_evidence,
            evidence_error=evidence.error,
            ess=ess,
        )
        summaries.append(unit)
        warnings += _unit_warnings(unit, comparison.convergence_messages())
    return combine_summaries(
        summaries, bounds, family=family, covariate=covariate, tau_range=tau_range, seed=seed,
        posteriors=posteriors, notes=warnings,
    )  # fmt: skip


def combine_summaries(
    units: Sequence[UnitPosterior],
    bounds: np.ndarray,
    *,
    family: str,
    covariate: str | None,
    tau_range: tuple[float, float] = TAU_RANGE,
    seed: int | None = None,
    posteriors: Mapping[str, Posterior] | None = None,
    notes: Sequence[dict] = (),
) -> Population:
    """Stage 2 on the units' normal summaries: every structure's evidence and draws.

    Parameters
    ----------
    units : sequence of UnitPosterior
    bounds : ndarray, shape (2, 2)
        The units' prior range (low, high) of d_lat and d_long [N s/m].
    family, covariate : str
        The units' noise family, and the covariate's name (None: none).
    tau_range : (float, float)
        As in :func:`population`.
    seed : int, optional
        The draws' and the evidence replicas' seed.
    posteriors : mapping, optional
        Each unit's posterior by name (:meth:`Population.unit_summaries`).
    notes : sequence of dict
        Warnings to keep.

    Returns
    -------
    Population
    """
    hierarchy = Hierarchy(units, bounds, tau_range=tau_range)
    rng = as_rng(seed)
    evidence = {}
    for structure in hierarchy.structures:
        value, error = hierarchy.log_evidence(structure)
        evidence[structure] = Evidence(value, error, "population (normal summaries)")
    replicas = hierarchy.log_integral_replicas(rng=rng)
    draws = {
        name: hierarchy.draws(name, POPULATION_DRAWS, rng=rng) for name in hierarchy.structures
    }
    result = Population(
        family, covariate, hierarchy, evidence, replicas, draws, dict(posteriors or {})
    )
    result.sensitivity = _sensitivity(result, rng)
    result.warnings = list(notes) + _population_warnings(result)
    return result


def _unit_warnings(unit: UnitPosterior, convergence: list[str]) -> list[dict]:
    warnings = [
        {"kind": NOT_CONVERGED, "unit": unit.name, "message": f"{unit.name}: {message}"}
        for message in convergence
    ]
    if abs(unit.coverage - HDI_PROB) > COVERAGE_TOLERANCE or unit.skewness > SKEWNESS_TOLERANCE:
        warnings.append(
            {
                "kind": NORMAL_SUMMARY,
                "unit": unit.name,
                "message": (
                    f"{unit.name}: its damping posterior is not normal on the log scale "
                    f"({unit.coverage:.1%} of the draws in the 94 % ellipse, skewness "
                    f"{unit.skewness:.2f}): the population's combination is approximate"
                ),
            }
        )
    for name in unit.at_bound:
        warnings.append(
            {
                "kind": PRIOR_BOUNDARY,
                "unit": unit.name,
                "message": (
                    f"{unit.name}: {name}'s posterior reaches its prior's bound; widen the "
                    f"range (--prior {name} LOW HIGH)"
                ),
            }
        )
    return warnings


def _sensitivity(result: Population, rng: np.random.Generator) -> dict:
    """The population mean and spread under each of :data:`SENSITIVITY_TAU_RANGES`."""
    hierarchy = result.hierarchy
    checked = {"default": hierarchy.tau_range} | SENSITIVITY_TAU_RANGES
    sensitivity = {}
    for label, tau_range in checked.items():
        if label == "default":
            other, draws = hierarchy, result.draws[result.model]
        else:
            other = Hierarchy(hierarchy.units, hierarchy.bounds, tau_range=tau_range)
            draws = other.draws(result.model, POPULATION_DRAWS, rng=rng)
        sensitivity[label] = {
            "tau_range": list(tau_range),
            "log_bayes_factor_vs_pooled": other.log_integral(result.model)
            - other.log_integral(result.model.replace("hierarchical", "pooled")),
            **{name: _summary(draws["mu"][:, i]) for i, name in enumerate(DAMPING_NAMES)},
            **{f"tau_{name}": _summary(draws["tau"][:, i]) for i, name in enumerate(SPREADS)},
        }
    return sensitivity


def _population_warnings(result: Population) -> list[dict]:
    warnings = []
    groups = len(result.hierarchy.groups)
    if groups < 3:
        warnings.append(
            {
                "kind": FEW_GROUPS,
                "message": (
                    f"{groups} groups: the population's spread is barely determined; its "
                    "mean's interval is wide by right"
                ),
            }
        )
    default = result.sensitivity["default"]
    for label, other in result.sensitivity.items():
        for name in DAMPING_NAMES:
            shift = abs(other[name]["mean"] - default[name]["mean"])
            if shift > SENSITIVITY_SHIFT * default[name]["sd"]:
                warnings.append(
                    {
                        "kind": PRIOR_SENSITIVITY,
                        "message": (
                            f"the population mean of log {name} moves by {shift:.3f} "
                            f"({shift / default[name]['sd']:.1f} sd) under the {label} "
                            f"spread prior {other['tau_range']}"
                        ),
                    }
                )
    return warnings
