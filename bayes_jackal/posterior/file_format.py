"""The posterior file's attributes: format versions, reading and writing.

A posterior's metadata are attributes of its ``posterior`` group: strings,
numbers and JSON texts (docs/design.md §7 lists them with their types and
the format versions). This module is the only one that writes or parses
them, and the only one that names the arrays of the ``constant_data``
(:func:`experiment_data`, :func:`experiment_arrays`) and ``observed_data``
groups (:func:`observed_data`, :func:`observed_residuals`);
:mod:`bayes_jackal.posterior.posterior`, which builds, saves and loads the files,
reads them through :func:`posterior_metadata` into
:attr:`~bayes_jackal.posterior.Posterior.metadata` (the records of
:mod:`bayes_jackal.posterior.records`);
:func:`store_comparison` and :func:`store_criticism` add the results
computed later, :func:`store_reweighting` the record of a posterior made by
reweighting another's draws.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import __version__
from .._runtime import CHANNELS, OPTIONAL, REQUIRED, DataError, InputError
from ..io import CHANNEL_FIELDS, MEASURED_PREFIX, POSE_FIELDS, RATE_FIELDS, Experiment, PoseTrack
from ..likelihood import Prior, ResidualLikelihood, channel_residuals
from ..model import ParameterLayout, RobotProfile, load_profile
from .records import Convergence, Evidence, ExperimentRecord, PosteriorMetadata

if TYPE_CHECKING:  # arviz is imported by bayes_jackal.posterior.posterior
    import arviz as az

__all__ = [
    "FORMAT",
    "READABLE_FORMATS",
    "ROBOT_CONSTANTS",
    "experiment_arrays",
    "experiment_data",
    "file_attributes",
    "observed_data",
    "observed_residuals",
    "posterior_layout",
    "store_comparison",
    "store_criticism",
    "store_reweighting",
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


#: A prior's ``kind`` attribute by whether it is log-uniform.
_PRIOR_KINDS = {False: "uniform", True: "log-uniform"}


def file_attributes(likelihood: ResidualLikelihood, prior: Prior, diagnostics: dict) -> dict:
    """The attributes of a new file (docs/design.md §7): strings, numbers and JSON.

    ``diagnostics`` holds the :class:`Convergence` fields, JSON-ready.

    Examples
    --------
    The attributes of a new file, for a likelihood and its priors (the sampler
    adds its diagnostics):

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.posterior import file_attributes
    >>> from bayes_jackal.likelihood import Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="white", channels=("yaw",))
    >>> prior = Prior.for_likelihood(likelihood, robot)
    >>> attrs = file_attributes(likelihood, prior, {"converged": False, "n_steps": 0})
    >>> attrs["format"], attrs["family"], attrs["channels"], attrs["steady"]
    ('bayes_jackal.posterior/1', 'white', '["yaw"]', 0)
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
            "pose_samples": likelihood.pose_samples.get(e.name, 1),
            "pose_clock": likelihood.pose_clocks.get(e.name),
            "segments": None if e.segments is None else e.segments.tolist(),
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
        "shared_width": layout.shared_width,
        "pose_channels": list(layout.pose_channels),
        "sensor": layout.sensor,
        "engine": likelihood.engine,
        "steady": likelihood.steady,
        "damping": layout.damping,
        "speed_range": None if likelihood.speed_range is None else list(likelihood.speed_range),
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
    except (ValueError, RecursionError):  # RecursionError: nested deeper than Python parses
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

    Examples
    --------
    The parameter layout of a posterior. The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import posterior_layout
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> layout = posterior_layout(posterior)
    >>> layout.family, layout.channels, layout.names
    ('white', ('yaw',), ('d_lat', 'd_long', 'sigma_c', 'sigma_n'))
    """
    attrs = idata.posterior.attrs
    _check_format(attrs)
    family, sensor = _text(attrs, "family"), _text(attrs, "sensor")
    channels, experiments = _attribute(attrs, "channels"), _attribute(attrs, "experiments")
    shared_noise = _attribute(attrs, "shared_noise")
    # Files written before one width could be shared have one per group.
    shared_width = _attribute(attrs, "shared_width", False)
    # Files written before poses were modelled have none, before the speed model
    # one damping.
    poses = _attribute(attrs, "pose_channels", [])
    damping = _text(attrs, "damping") if "damping" in attrs else "constant"
    try:
        names = tuple(e["name"] for e in experiments)
        layout = ParameterLayout(
            family,
            sensor,
            tuple(channels),
            names,
            bool(shared_noise),
            bool(shared_width),
            tuple(poses),
            damping,
        )
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


def _array_key(field: str, index: int) -> str:
    """The ``constant_data`` name of an experiment's array: ``yaw_rate_0``."""
    return f"{field}_{index}"


def experiment_data(experiments: Sequence[Experiment]) -> tuple[dict, dict]:
    """The ``constant_data`` group of a new file: the experiments' measured arrays.

    Parameters
    ----------
    experiments : sequence of Experiment
        In the likelihood's order: experiment i's arrays are named
        ``<field>_<i>`` along the dimension ``time_<i>``.

    Returns
    -------
    arrays : dict of str to ndarray
        Every measured field (``t``, ``yaw_rate``, ``omega_r``, ``omega_l``,
        and ``vx``, ``vy`` when measured) of every experiment [its unit],
        and its poses where it has them (``pose_t``, ``pose_x``, ``pose_y``,
        ``pose_heading`` along ``pose_time_<i>``).
    dims : dict of str to list of str
        Each array's dimension.

    Examples
    --------
    The arrays of a simulated run, as a new posterior file stores them:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import experiment_data
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> arrays, dims = experiment_data([run])
    >>> sorted(arrays)
    ['omega_l_0', 'omega_r_0', 't_0', 'vx_0', 'vy_0', 'yaw_rate_0']
    >>> arrays["yaw_rate_0"].shape, dims["yaw_rate_0"]
    ((2737,), ['time_0'])
    """
    arrays, dims = {}, {}
    for i, experiment in enumerate(experiments):
        for field in (*REQUIRED, *OPTIONAL):
            values = getattr(experiment, field)
            if values is not None:
                arrays[_array_key(field, i)] = np.asarray(values)
                dims[_array_key(field, i)] = [f"time_{i}"]
        for field, mask in experiment.measured.items():
            arrays[_array_key(f"{MEASURED_PREFIX}{field}", i)] = mask.astype(np.uint8)
            dims[_array_key(f"{MEASURED_PREFIX}{field}", i)] = [f"time_{i}"]
        if experiment.pose is not None:
            for field in POSE_FIELDS:
                key = _array_key(f"pose_{field}", i)
                arrays[key] = np.asarray(getattr(experiment.pose, field))
                dims[key] = [f"pose_time_{i}"]
    return arrays, dims


def experiment_arrays(idata: az.InferenceData, index: int) -> dict[str, np.ndarray]:
    """The measured arrays of experiment ``index`` that a posterior stores, by field name.

    The fields of :class:`~bayes_jackal.io.Experiment`: ``t`` [s],
    ``yaw_rate``, ``omega_r``, ``omega_l`` [rad/s], ``vx``, ``vy`` [m/s]
    when measured, and ``pose`` (a
    :class:`~bayes_jackal.io.PoseTrack`) where the experiment had
    poses (written by :func:`experiment_data`).

    Examples
    --------
    The measured arrays stored in a posterior, read back. The 20-step chain is
    short on purpose:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import experiment_arrays
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> arrays = experiment_arrays(posterior, 0)
    >>> sorted(arrays)
    ['omega_l', 'omega_r', 't', 'vx', 'vy', 'yaw_rate']
    >>> np.array_equal(arrays["yaw_rate"], run.yaw_rate)
    True
    """
    data = idata.constant_data
    arrays = {
        field: data[_array_key(field, index)].values
        for field in (*REQUIRED, *OPTIONAL)
        if _array_key(field, index) in data
    }
    measured = {
        field: data[_array_key(f"{MEASURED_PREFIX}{field}", index)].values
        for field in RATE_FIELDS
        if _array_key(f"{MEASURED_PREFIX}{field}", index) in data
    }
    if measured:
        arrays["measured"] = measured
    if _array_key("pose_t", index) in data:
        values = [data[_array_key(f"pose_{field}", index)].values for field in POSE_FIELDS]
        arrays["pose"] = PoseTrack(*values)
    return arrays


def _residual_key(index: int, channel: str) -> str:
    """The ``observed_data`` name of experiment ``index``'s residuals: ``residual_yaw_0``."""
    return f"residual_{channel}_{index}"


def observed_residuals(idata: az.InferenceData, index: int, channel: str) -> np.ndarray:
    """The stored one-step residuals of experiment ``index`` in ``channel``.

    At the posterior median of the damping, on the steady window when the
    likelihood used it [channel unit].

    Examples
    --------
    The stored yaw-rate residuals of the first experiment, at the posterior
    median. The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import observed_residuals
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> residuals = observed_residuals(posterior, 0, "yaw")
    >>> residuals.shape, f"{residuals.std():.4f} rad/s"
    ((2736,), '0.0091 rad/s')
    """
    return idata.observed_data[_residual_key(index, channel)].values


def observed_data(
    likelihood: ResidualLikelihood, d_lat: float, d_long: float
) -> tuple[dict, dict]:
    """The ``observed_data`` group of a new file: the one-step residuals at (d_lat, d_long).

    Parameters
    ----------
    likelihood : ResidualLikelihood
    d_lat, d_long : float
        The damping [N s/m]: the posterior median.

    Returns
    -------
    residuals : dict of str to ndarray
        Experiment i's residuals in each channel of the likelihood, on the
        steady window when the likelihood uses it [channel unit], named
        ``residual_<channel>_<i>``.
    dims : dict of str to list of str
        Each one's dimension, ``step_<i>`` (``pose_step_<i>`` for a channel
        recorded as poses, whose residuals are one fewer).

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.posterior import observed_data
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="white", channels=("yaw", "vx"))
    >>> residuals, dims = observed_data(likelihood, 110.0, 30.0)
    >>> sorted(residuals), dims["residual_yaw_0"], residuals["residual_yaw_0"].shape
    (['residual_vx_0', 'residual_yaw_0'], ['step_0'], (2736,))
    """
    residuals, dims = {}, {}
    poses = likelihood.layout.pose_channels
    for i, experiment in enumerate(likelihood.experiments):
        for channel in likelihood.channels:
            key = _residual_key(i, channel)
            residuals[key] = channel_residuals(
                experiment, likelihood.robot, d_lat, d_long, channel, likelihood.steady
            )
            # A pose channel's residuals are one shorter (two increments each).
            dims[key] = [f"pose_step_{i}" if channel in poses else f"step_{i}"]
    return residuals, dims


def _experiment_record(stored: dict, data: Mapping, index: int) -> ExperimentRecord:
    """Experiment ``index``'s record: its attribute ``stored``, its arrays' names in ``data``."""
    window = stored.get("steady_window")
    return ExperimentRecord(
        name=stored["name"],
        source=stored.get("source"),
        series=stored.get("series"),
        steady_window=None if window is None else tuple(window),
        dt=float(stored["dt"]),
        truth=stored.get("truth"),
        provenance=stored.get("provenance") or {},
        channels=tuple(c for c in CHANNELS if _array_key(CHANNEL_FIELDS[c], index) in data),
        pose_samples=int(stored.get("pose_samples", 1)),
        pose_clock=_pose_clock(stored),
        segments=None if stored.get("segments") is None else tuple(stored["segments"]),
    )


def _pose_clock(stored: dict) -> tuple[int, float] | None:
    """An experiment record's pose clock: (m, phase [s]); files written before: (1, 0)."""
    if "pose_clock" not in stored:
        return (1, 0.0)
    clock = stored["pose_clock"]
    return None if clock is None else (int(clock[0]), float(clock[1]))


def _convergence(attrs: Mapping) -> Convergence:
    """The :class:`Convergence` fields; those without a default are required."""
    values = {
        field.name: _attribute(attrs, field.name, field.default)
        for field in dataclasses.fields(Convergence)
    }
    return Convergence(**values | {"converged": bool(values["converged"])})


def posterior_metadata(idata: az.InferenceData) -> PosteriorMetadata:
    """Everything a posterior file says besides its draws, typed (docs/design.md §7).

    The reader behind :attr:`bayes_jackal.posterior.Posterior.metadata`, its
    one caller, which reads again when the attributes change (results
    stored later by :func:`store_comparison`, :func:`store_criticism`,
    :func:`store_reweighting`).

    Raises
    ------
    DataError
        For a file that is not a posterior this version reads (naming the
        format found), a missing or malformed attribute, or no
        ``constant_data`` group.
    """
    attrs = idata.posterior.attrs
    layout = posterior_layout(idata)
    data = getattr(idata, "constant_data", None)
    if data is None:
        raise DataError("no constant_data group (the measured experiments) in the posterior")
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
            experiments=tuple(
                _experiment_record(stored, data, i)
                for i, stored in enumerate(_attribute(attrs, "experiments"))
            ),
            convergence=_convergence(attrs),
            evidence=evidence,
            evidence_nested=nested,
            convergence_messages=tuple(_attribute(attrs, "convergence_messages", ())),
            task=_attribute(attrs, "task", None),
            criticism=_attribute(attrs, "criticism", None),
            reweighting=_attribute(attrs, "reweighting", None),
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
    """Keep a comparison's result in a posterior (read back by :attr:`Posterior.metadata`).

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

    Examples
    --------
    An evidence kept in a posterior, and read back. The 20-step chain is short
    on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.posterior import store_comparison
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> evidence = Evidence(-12.5, 0.03, "bridge sampling")
    >>> store_comparison(
    ...     posterior, evidence=evidence, nested=None, messages=[], task={"family": "white"}
    ... )
    >>> posterior.metadata.evidence == evidence
    True
    """
    idata.posterior.attrs |= {
        "evidence": json.dumps(evidence.to_dict()),
        "evidence_nested": json.dumps(nested and nested.to_dict()),
        "convergence_messages": json.dumps(list(messages)),
        "task": json.dumps(task),
    }


def store_criticism(idata: az.InferenceData, criticism: dict) -> None:
    """Keep :func:`bayes_jackal.posterior.criticise`'s JSON-ready result in a posterior.

    Examples
    --------
    A criticism kept in a posterior; :func:`~bayes_jackal.posterior.summarize`
    then reports it instead of computing it. The 20-step chain is short on
    purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import store_criticism
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> store_criticism(posterior, {"warnings": [], "criticism": {}})
    >>> posterior.metadata.criticism
    {'warnings': [], 'criticism': {}}
    >>> bj.summarize(posterior)["warnings"]
    []
    """
    idata.posterior.attrs["criticism"] = json.dumps(criticism)


def store_reweighting(idata: az.InferenceData, record: dict) -> None:
    """Mark a posterior as a reweighting of another's draws (read back as ``reweighting``).

    Parameters
    ----------
    idata : arviz.InferenceData
        The reweighted posterior (:mod:`bayes_jackal.filters.left_out` writes
        one per run left out).
    record : dict
        JSON-ready: ``method``, ``of``, ``experiments``, ``left_out``,
        ``pareto_k``, ``weights_ess``, ``draws``, ``relative_efficiency``,
        ``task`` (:attr:`PosteriorMetadata.reweighting`).

    Examples
    --------
    A record kept in a posterior, and read back. The 20-step chain is short on
    purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import store_reweighting
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> posterior.metadata.reweighting is None  # sampled
    True
    >>> store_reweighting(posterior, {"method": "psis", "pareto_k": 0.21})
    >>> posterior.metadata.reweighting
    {'method': 'psis', 'pareto_k': 0.21}
    """
    idata.posterior.attrs["reweighting"] = json.dumps(record)
