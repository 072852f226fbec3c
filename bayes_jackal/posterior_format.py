"""The posterior file's attributes: format versions, typed records, reading and writing.

A posterior's metadata are attributes of its ``posterior`` group: strings,
numbers and JSON texts (docs/design.md §7 lists them with their types and
the format versions). This module is the only one that writes or parses
them; :mod:`bayes_jackal.posterior`, which builds, saves and loads the
files, re-exports its public names. :func:`posterior_metadata` gives them
typed; :func:`store_comparison` and :func:`store_criticism` add the results
computed later.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from . import __version__
from .errors import DataError, InputError
from .evidence import Evidence
from .likelihood import ResidualLikelihood
from .parameters import ParameterLayout
from .priors import Prior
from .robot import RobotProfile, load_profile

if TYPE_CHECKING:  # arviz is imported by bayes_jackal.posterior
    import arviz as az

__all__ = [
    "FORMAT",
    "READABLE_FORMATS",
    "ROBOT_CONSTANTS",
    "Convergence",
    "ExperimentRecord",
    "PosteriorMetadata",
    "file_attributes",
    "posterior_layout",
    "posterior_metadata",
    "store_comparison",
    "store_criticism",
]

#: The format this version writes (docs/design.md §7).
FORMAT = "bayes_jackal.posterior/1"
#: The formats this version reads.
READABLE_FORMATS = (FORMAT,)
#: The robot's body constants, which every file stores (files written before
#: the whole profile was stored hold only these).
ROBOT_CONSTANTS = (
    "name",
    "mass",
    "yaw_inertia",
    "half_wheelbase",
    "half_track",
    "wheel_radius",
    "wheel_separation",
    "wheel_separation_multiplier",
    "conversion",
    "rate",
    "source",
)


@dataclass(frozen=True)
class ExperimentRecord:
    """What a posterior file says of one experiment (its arrays are in ``constant_data``).

    Attributes
    ----------
    name : str
    source : str or None
        The file it was read from.
    series : str or None
        Its series label (``v1``...).
    steady_window : (float, float) or None
        Start and stop of the steady window [s].
    dt : float
        Sample time [s].
    truth : dict or None
        The simulator's parameters, for simulated data.
    provenance : dict
        Time base and repairs (docs/design.md §2).
    """

    name: str
    source: str | None
    series: str | None
    steady_window: tuple[float, float] | None
    dt: float
    truth: dict | None
    provenance: dict


@dataclass(frozen=True)
class Convergence:
    """The sampler's convergence diagnostics and settings.

    Attributes
    ----------
    converged : bool
        Whether the autocorrelation criterion held.
    n_steps : int
        Steps run.
    autocorr_time : dict of str to float
        Integrated autocorrelation time per parameter [steps].
    ess_autocorr : dict of str to float
        The effective sample size it implies, per parameter.
    walkers, discard, thin : int or None
        Walkers; steps discarded as burn-in; thinning of the kept draws.
    acceptance_fraction : float or None
        Mean over walkers.
    seed : int or None
    settings : dict or None
        The :class:`~bayes_jackal.inference.SamplerSettings`, as a dict.
    """

    converged: bool
    n_steps: int
    autocorr_time: dict[str, float]
    ess_autocorr: dict[str, float]
    walkers: int | None = None
    discard: int | None = None
    thin: int | None = None
    acceptance_fraction: float | None = None
    seed: int | None = None
    settings: dict | None = None


@dataclass(frozen=True)
class PosteriorMetadata:
    """Everything a posterior file says besides its draws (:func:`posterior_metadata`).

    Attributes
    ----------
    format : str
        The file format, e.g. ``bayes_jackal.posterior/1``.
    version : str
        The bayes_jackal version that wrote it.
    layout : ParameterLayout
        Parameter names, noise groups and columns; the family, sensor term,
        channels and pooling.
    engine : str
        Likelihood engine.
    steady : bool
        Whether the likelihood used the steady windows.
    prior : Prior
        The priors sampled under.
    robot : RobotProfile
        The robot profile sampled with (for files that stored only the body
        constants, the installed default profile's other fields).
    experiments : tuple of ExperimentRecord
    convergence : Convergence
    evidence, evidence_nested : Evidence or None
        Bridge-sampling and nested-sampling evidence (:func:`store_comparison`).
    convergence_messages : tuple of str
        The sampler's convergence warnings, kept by :func:`store_comparison`.
    task : dict or None
        What defined a comparison's result (:func:`store_comparison`).
    criticism : dict or None
        :func:`bayes_jackal.criticism.criticise`'s result (:func:`store_criticism`).
    """

    format: str
    version: str
    layout: ParameterLayout
    engine: str
    steady: bool
    prior: Prior
    robot: RobotProfile
    experiments: tuple[ExperimentRecord, ...]
    convergence: Convergence
    evidence: Evidence | None = None
    evidence_nested: Evidence | None = None
    convergence_messages: tuple[str, ...] = ()
    task: dict | None = None
    criticism: dict | None = None

    @property
    def family(self) -> str:
        """The noise family."""
        return self.layout.family

    @property
    def channels(self) -> tuple[str, ...]:
        """The channels, in likelihood order."""
        return self.layout.channels

    @property
    def truth(self) -> dict | None:
        """The shared truth of simulated experiments, when every one has it."""
        truths = [e.truth for e in self.experiments]
        return truths[0] if truths and all(truths) else None


#: A prior's ``kind`` attribute by whether it is log-uniform.
_PRIOR_KINDS = {False: "uniform", True: "log-uniform"}


def file_attributes(likelihood: ResidualLikelihood, prior: Prior, diagnostics: dict) -> dict:
    """The attributes of a new file (docs/design.md §7): strings, numbers and JSON.

    ``diagnostics`` holds the :class:`Convergence` fields, JSON-ready.
    """
    experiments = [
        {
            "name": e.name,
            "source": e.source,
            "series": e.series,
            "steady_window": e.steady_window,
            "dt": e.dt,
            "truth": e.truth,
            "provenance": e.provenance,
        }
        for e in likelihood.experiments
    ]
    layout = likelihood.layout
    values = {
        "format": FORMAT,
        "bayes_jackal_version": __version__,
        "family": layout.family,
        "channels": list(layout.channels),
        "shared_noise": layout.shared_noise,
        "sensor": layout.sensor,
        "engine": likelihood.engine,
        "steady": likelihood.steady,
        "parameter_names": list(prior.names),
        "prior": {
            name: {"low": lo, "high": hi, "kind": _PRIOR_KINDS[log]}
            for name, lo, hi, log in zip(
                prior.names,
                prior.low.tolist(),
                prior.high.tolist(),
                prior.log_uniform,
                strict=True,
            )
        },
        # The whole profile: the file alone rebuilds the model.
        "robot": dataclasses.asdict(likelihood.robot),
        "experiments": experiments,
        **diagnostics,
    }
    return {key: _attribute_value(value) for key, value in values.items()}


def _attribute_value(value):
    """NetCDF attributes hold strings and numbers: dicts, lists and None as JSON, bools as 0/1."""
    if isinstance(value, (dict, list, tuple)) or value is None:
        return json.dumps(value)
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    return value


def _attribute(attrs: Mapping, key: str, default: Any = dataclasses.MISSING) -> Any:
    """One attribute: a number or a JSON text, decoded; DataError when missing or bad.

    Booleans are stored as 0/1, dicts, lists and None as JSON
    (:func:`file_attributes`); ``default`` stands for an absent attribute
    (none: the attribute is required).
    """
    if key not in attrs:
        if default is dataclasses.MISSING:
            raise DataError("missing attribute of a bayes_jackal posterior", field=key)
        return default
    value = attrs[key]
    if not isinstance(value, str):
        return value.item() if isinstance(value, np.generic) else value
    try:
        return json.loads(value)
    except ValueError:
        raise DataError(f"not a JSON text: {value[:80]!r}", field=key) from None


def _text(attrs: Mapping, key: str) -> str:
    """A plain string attribute (family, sensor, engine...); DataError when missing or not one."""
    value = attrs.get(key)
    if not isinstance(value, str):
        raise DataError(f"expected a string attribute, got {value!r}", field=key)
    return value


def _check_format(attrs: Mapping) -> str:
    """The file's format, one this version reads; DataError naming the one found."""
    found = attrs.get("format")
    if found is None or not str(found).startswith("bayes_jackal.posterior/"):
        raise DataError(
            f"not a bayes_jackal posterior (format {found!r}; posteriors are written by "
            "`bayes-jackal sample` and `compare --out`)",
            field="format",
        )
    if found not in READABLE_FORMATS:
        raise DataError(
            f"posterior format {found!r} is not one this version ({__version__}) reads: "
            f"{list(READABLE_FORMATS)}; a newer bayes_jackal wrote it",
            field="format",
        )
    return str(found)


def posterior_layout(idata: az.InferenceData) -> ParameterLayout:
    """The parameter layout of a posterior, checked against its stored parameter names.

    Raises
    ------
    DataError
        For a file that is not a posterior this version reads, or whose
        attributes disagree.
    """
    attrs = idata.posterior.attrs
    _check_format(attrs)
    family, sensor = _text(attrs, "family"), _text(attrs, "sensor")
    channels, experiments = _attribute(attrs, "channels"), _attribute(attrs, "experiments")
    shared_noise = _attribute(attrs, "shared_noise")
    try:
        names = tuple(e["name"] for e in experiments)
        layout = ParameterLayout(family, sensor, tuple(channels), names, bool(shared_noise))
    except (InputError, TypeError, KeyError) as exc:
        raise DataError(f"attributes do not describe a model ({exc})") from None
    names = _attribute(attrs, "parameter_names")
    if list(layout.names) != names:
        raise DataError(
            f"parameter names {names} do not match the model's {list(layout.names)}",
            field="parameter_names",
        )
    return layout


def _robot(stored: dict) -> RobotProfile:
    """The robot profile of a posterior, from its ``robot`` attribute.

    Files that store the whole profile rebuild it as it was. Files written
    by bayes_jackal 0.1.0 before the format had one owner stored
    :data:`ROBOT_CONSTANTS` only: their priors, topics and wheel
    joints are the installed default profile's (those do not enter the
    model; the priors the chain used are the ``prior`` attribute).
    """
    names = [f.name for f in dataclasses.fields(RobotProfile)]
    if all(name in stored for name in names):
        values = {name: stored[name] for name in names}
        values["priors"] = {key: tuple(value) for key, value in values["priors"].items()}
        return RobotProfile(**values).replace()
    return load_profile().replace(**{k: v for k, v in stored.items() if k in ROBOT_CONSTANTS})


def _prior(layout: ParameterLayout, stored: dict) -> Prior:
    rows = [stored[name] for name in layout.names]
    return Prior(
        layout.names,
        np.array([row["low"] for row in rows], float),
        np.array([row["high"] for row in rows], float),
        np.array([row["kind"] == _PRIOR_KINDS[True] for row in rows]),
    )


def _experiment_record(stored: dict) -> ExperimentRecord:
    window = stored.get("steady_window")
    return ExperimentRecord(
        name=stored["name"],
        source=stored.get("source"),
        series=stored.get("series"),
        steady_window=None if window is None else tuple(window),
        dt=float(stored["dt"]),
        truth=stored.get("truth"),
        provenance=stored.get("provenance") or {},
    )


def _convergence(attrs: Mapping) -> Convergence:
    """The :class:`Convergence` fields; those without a default are required."""
    values = {
        field.name: _attribute(attrs, field.name, field.default)
        for field in dataclasses.fields(Convergence)
    }
    return Convergence(**values | {"converged": bool(values["converged"])})


def posterior_metadata(idata: az.InferenceData) -> PosteriorMetadata:
    """Everything a posterior file says besides its draws, typed (docs/design.md §7).

    Read from the attributes each time: results stored later
    (:func:`store_comparison`, :func:`store_criticism`) show at once.

    Raises
    ------
    DataError
        For a file that is not a posterior this version reads (naming the
        format found), or a missing or malformed attribute.
    """
    attrs = idata.posterior.attrs
    layout = posterior_layout(idata)
    try:
        evidence, nested = (
            None if value is None else Evidence.from_dict(value)
            for value in (
                _attribute(attrs, "evidence", None),
                _attribute(attrs, "evidence_nested", None),
            )
        )
        return PosteriorMetadata(
            format=_check_format(attrs),
            version=_text(attrs, "bayes_jackal_version"),
            layout=layout,
            engine=_text(attrs, "engine"),
            steady=bool(_attribute(attrs, "steady")),
            prior=_prior(layout, _attribute(attrs, "prior")),
            robot=_robot(_attribute(attrs, "robot")),
            experiments=tuple(map(_experiment_record, _attribute(attrs, "experiments"))),
            convergence=_convergence(attrs),
            evidence=evidence,
            evidence_nested=nested,
            convergence_messages=tuple(_attribute(attrs, "convergence_messages", ())),
            task=_attribute(attrs, "task", None),
            criticism=_attribute(attrs, "criticism", None),
        )
    except DataError:
        raise
    except (InputError, TypeError, KeyError, ValueError) as exc:
        raise DataError(f"malformed attributes of a bayes_jackal posterior ({exc})") from None


def store_comparison(
    idata: az.InferenceData,
    *,
    evidence: Evidence,
    nested: Evidence | None,
    messages: Sequence[str],
    task: dict,
) -> None:
    """Keep a comparison's result in a posterior (read back by :func:`posterior_metadata`).

    Parameters
    ----------
    idata : arviz.InferenceData
    evidence : Evidence
        Bridge-sampling evidence.
    nested : Evidence or None
        Nested-sampling evidence, when cross-checked.
    messages : sequence of str
        The sampler's convergence warnings.
    task : dict
        JSON-ready: what defined the result (for reuse).
    """
    idata.posterior.attrs |= {
        "evidence": json.dumps(evidence.to_dict()),
        "evidence_nested": json.dumps(nested and nested.to_dict()),
        "convergence_messages": json.dumps(list(messages)),
        "task": json.dumps(task),
    }


def store_criticism(idata: az.InferenceData, criticism: dict) -> None:
    """Keep :func:`bayes_jackal.criticism.criticise`'s JSON-ready result in a posterior."""
    idata.posterior.attrs["criticism"] = json.dumps(criticism)
