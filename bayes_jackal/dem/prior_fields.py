"""The fields of an exported prior (``prior.json``) that the filters read, with their types.

:func:`bayes_jackal.dem.export_prior` writes a prior; a lab may edit it by
hand, and the filters (:mod:`bayes_jackal.filters.kalman_filters`,
:mod:`bayes_jackal.filters.generalised`, :mod:`bayes_jackal.filters.state_estimation`)
take each value they read as it is. :func:`check_prior_fields` checks every
field they read, with its type, before any of them runs: where a prior file
is read (:func:`bayes_jackal.dem.read_prior`, the error naming the file)
and where a filter is given a prior (:func:`bayes_jackal.filters.check_prior`).
A refusal is an :class:`~bayes_jackal._runtime.errors.InputError` naming the field
(its keys joined by dots) and the value.

The fields, their types and units:

- ``format``: :data:`PRIOR_FORMAT`.
- ``robot``: an object; ``name`` and ``conversion`` text (the conversion
  one of :data:`~bayes_jackal._runtime.defaults.CONVERSIONS`), the other constants of
  :data:`~bayes_jackal.posterior.ROBOT_CONSTANTS` positive numbers
  [kg, kg m^2, m, Hz] (``source``, where the profile was read, is no constant).
- ``dt``: the sample time, a positive number [s].
- ``noise``: an object; ``channels`` a non-empty list of distinct channel
  names (vx, vy, yaw); ``family`` one of :data:`~bayes_jackal.model.FAMILIES`;
  ``sensor`` one of :data:`~bayes_jackal._runtime.defaults.SENSOR_MODELS` (default
  ``ma1``); ``shared_width`` true or false; ``pose_channels`` a list of some
  of the channels; ``parameters`` an object with one object per noise
  parameter of the layout (:func:`prior_layout`), each holding its posterior
  ``mean``, a positive number [s for a width, channel units for an sd].
- ``damping.mean``: d_lat and d_long, positive numbers [N s/m].
- ``model``: an object; ``A``, ``Ad`` (3 x 3) and ``B``, ``Bd`` (3 x 2)
  finite matrices, A and Ad diagonal with poles < 0 [1/s] and in (0, 1).
- ``draws``: an object of lists of positive numbers, one list per parameter,
  all of one length (``count`` aside, which no filter reads).
- ``generalised_coordinates.order``: a whole number >= 0.
- ``sensor_noise``: null (the noise fit has one total sd) or an object; its
  ``smoothness_seconds`` a positive number [s].

The fields that only some filter reads (``model.A``, ``model.Ad``,
``draws``, ``generalised_coordinates``, ``sensor_noise``) may be absent:
that filter then refuses the prior, naming the field; present, they must
have their types.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping

import numpy as np

from .._runtime import CHANNELS, CONVERSIONS, SENSOR, SENSOR_MODELS, DataError, InputError
from ..model import DAMPING, FAMILIES, ParameterLayout
from ..posterior import ROBOT_CONSTANTS

__all__ = ["PRIOR_FORMAT", "check_prior_fields", "prior_field", "prior_layout"]

PRIOR_FORMAT = "bayes_jackal.prior/1"
#: The model matrices a prior holds and their shapes: (states, states) and (states, inputs).
_MODEL_SHAPES = {"model.A": (3, 3), "model.B": (3, 2), "model.Ad": (3, 3), "model.Bd": (3, 2)}
#: The robot's constants that are text; ``source`` (where the profile was read) is unchecked.
_ROBOT_TEXT = ("name", "conversion")


def prior_field(prior: Mapping, path: str):
    """``prior[a][b]..`` for ``path`` = "a.b..", or an InputError naming the missing field.

    Parameters
    ----------
    prior : mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`).
    path : str
        Keys joined by dots, e.g. ``"model.Ad"``.

    Examples
    --------
    >>> from bayes_jackal.dem import prior_field
    >>> prior_field({"model": {"dt": 0.01}}, "model.dt")
    0.01
    >>> prior_field({"model": {}}, "model.Ad")
    Traceback (most recent call last):
    ...
    bayes_jackal._runtime.errors.InputError: model.Ad: the prior has no field 'model.Ad'
    """
    value = prior
    for key in path.split("."):
        if not isinstance(value, Mapping) or key not in value:
            raise InputError(f"the prior has no field {path!r}", field=path)
        value = value[key]
    return value


def prior_layout(prior: Mapping) -> ParameterLayout:
    """The prior's parameter layout: shared noise, one group per channel (and one width).

    Checks the ``noise`` fields it is made of: ``channels``, ``family``,
    ``sensor``, ``shared_width`` and ``pose_channels`` (module docstring).

    Parameters
    ----------
    prior : mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`).

    Returns
    -------
    ParameterLayout

    Raises
    ------
    InputError
        For a missing field or one of the wrong type, naming it and its value.

    Examples
    --------
    >>> from bayes_jackal.dem import prior_layout
    >>> prior_layout({"noise": {"family": "white", "channels": ["yaw"]}}).names
    ('d_lat', 'd_long', 'sigma_c', 'sigma_n')
    >>> try:
    ...     prior_layout({"noise": {"family": "white", "channels": "yaw"}})
    ... except ValueError as error:
    ...     print(error)
    noise.channels: expected a non-empty list of channel names (vx, vy, yaw), got 'yaw'
    """
    channels = prior_field(prior, "noise.channels")
    _check_channels(channels, "noise.channels")
    noise = prior_field(prior, "noise")
    family = prior_field(prior, "noise.family")
    if not isinstance(family, str) or family not in FAMILIES:
        raise InputError(
            f"unknown noise family {family!r:.80}; use one of {list(FAMILIES)}",
            field="noise.family",
        )
    sensor = noise.get("sensor", SENSOR)
    if not isinstance(sensor, str) or sensor not in SENSOR_MODELS:
        raise InputError(
            f"unknown sensor model {sensor!r:.80}; use one of {list(SENSOR_MODELS)}",
            field="noise.sensor",
        )
    shared_width = noise.get("shared_width", False)  # absent before one-width
    if not isinstance(shared_width, bool | np.bool_):
        raise InputError(f"expected true or false, got {shared_width!r:.80}",
                         field="noise.shared_width")  # fmt: skip
    poses = noise.get("pose_channels", [])  # absent before poses were modelled
    _check_channels(poses, "noise.pose_channels", empty=True)
    if not set(poses) <= set(channels):
        raise InputError(
            f"pose channels {list(poses)} are not among the channels {list(channels)}",
            field="noise.pose_channels",
        )
    return ParameterLayout(
        family, sensor, tuple(channels), ("prior",), True, bool(shared_width), tuple(poses)
    )


def check_prior_fields(prior: object, *, source: str | None = None) -> None:
    """Check every field of a prior that the filters read, with its type (module docstring).

    Parameters
    ----------
    prior : object
        A prior as read from its JSON (:func:`bayes_jackal.dem.read_prior`)
        or made by :func:`bayes_jackal.dem.export_prior`.
    source : str, optional
        The file it was read from: the error is then a DataError naming it.

    Raises
    ------
    InputError
        For a prior of another format, a missing field, or a field of the
        wrong type or out of its range, naming the field and the value
        (a DataError naming ``source`` too when given).

    Examples
    --------
    >>> from bayes_jackal.dem import check_prior_fields
    >>> prior = {"format": "bayes_jackal.prior/1", "robot": {"name": "jackal"}, "dt": "fast"}
    >>> try:
    ...     check_prior_fields(prior, source="bad.json")
    ... except ValueError as error:
    ...     print(error)
    bad.json: dt: expected a positive number of seconds, got 'fast'
    """
    try:
        form = prior.get("format") if isinstance(prior, Mapping) else None
        if form != PRIOR_FORMAT:
            raise InputError(
                f"not a prior this version reads: {form!r:.80} (expected {PRIOR_FORMAT})",
                field="format",
            )
        _check_robot(prior)
        _check_dt(prior_field(prior, "dt"))
        _check_scales(prior, prior_layout(prior))
        _check_matrices(prior)
        _check_draws(prior)
        _check_filter_fields(prior)
    except InputError as error:
        if source is None:
            raise
        named = DataError(str(error), source=source)
        named.field = error.field
        raise named from None


def _check_robot(prior: Mapping) -> None:
    """The robot's constants: text for the name and conversion, positive numbers else."""
    constants = _mapping(prior, "robot")
    for key in ROBOT_CONSTANTS:
        if key == "source" or key not in constants:
            continue
        value, path = constants[key], f"robot.{key}"
        if key not in _ROBOT_TEXT:
            _positive(value, path)
        elif not isinstance(value, str):
            raise InputError(f"expected text, got {value!r:.80}", field=path)
    conversion = constants.get("conversion", CONVERSIONS[0])
    if conversion not in CONVERSIONS:
        raise InputError(f"expected one of {list(CONVERSIONS)}, got {conversion!r}",
                         field="robot.conversion")  # fmt: skip


def _check_dt(dt: object) -> None:
    """The sample time: a positive number [s]; a negative one is said as a rate too."""
    if _is_real(dt) and math.isfinite(dt) and dt < 0:
        raise InputError(f"expected a positive number of seconds, got {dt!r} "
                         f"({1 / dt:.4g} Hz)", field="dt")  # fmt: skip
    _positive(dt, "dt", " of seconds")


def _check_channels(channels: object, path: str, *, empty: bool = False) -> None:
    """A list of distinct channel names, non-empty unless ``empty``."""
    if not (
        isinstance(channels, list | tuple)
        and (channels or empty)
        and all(isinstance(channel, str) for channel in channels)
    ):
        raise InputError(f"expected a {'' if empty else 'non-empty '}list of channel names "
                         f"({', '.join(CHANNELS)}), got {channels!r:.80}", field=path)  # fmt: skip
    unknown = [channel for channel in channels if channel not in CHANNELS]
    if unknown:
        raise InputError(f"unknown channel {unknown[0]!r}; use some of {list(CHANNELS)}",
                         field=path)  # fmt: skip
    if len(set(channels)) < len(channels):
        raise InputError(f"a channel is listed twice: {list(channels)}", field=path)


def _check_scales(prior: Mapping, layout: ParameterLayout) -> None:
    """The damping's and the noise parameters' posterior means: positive numbers."""
    damping = _numbers("damping.mean", prior_field(prior, "damping.mean"))
    if damping.shape != (len(DAMPING),):
        raise InputError(f"expected {list(DAMPING)}, got {prior_field(prior, 'damping.mean')!r}",
                         field="damping.mean")  # fmt: skip
    for value in damping.tolist():
        _positive(value, "damping.mean")
    for name, stats in _mapping(prior, "noise.parameters").items():
        path = f"noise.parameters.{name}"
        if not isinstance(stats, Mapping):
            raise InputError(f"expected an object with the mean, got {stats!r:.80}", field=path)
        if "mean" in stats:
            _positive(stats["mean"], f"{path}.mean")
    for name in layout.names[len(DAMPING) :]:
        prior_field(prior, f"noise.parameters.{name}.mean")  # each one there


def _check_matrices(prior: Mapping) -> None:
    """The model's matrices a prior holds (the Kalman filters take Ad, Bd; the generalised A, B).

    Finite, of :data:`_MODEL_SHAPES`, and A, Ad diagonal (eq. 4-32, 6-6)
    with continuous poles < 0 and discrete ones in (0, 1).
    """
    given = _mapping(prior, "model")
    matrices = {path: _numbers(path, given[path.removeprefix("model.")])
                for path in _MODEL_SHAPES if path.removeprefix("model.") in given}  # fmt: skip
    for path, values in matrices.items():
        if values.shape != _MODEL_SHAPES[path] or not np.all(np.isfinite(values)):
            raise InputError(
                f"expected a finite {' x '.join(map(str, _MODEL_SHAPES[path]))} matrix, got "
                f"shape {values.shape} with {int(np.sum(~np.isfinite(values)))} non-finite",
                field=path,
            )
    for path, low, high in (("model.A", -np.inf, 0.0), ("model.Ad", 0.0, 1.0)):
        if path not in matrices:
            continue
        values = matrices[path]
        poles = np.diag(values)
        if np.any(values != np.diag(poles)) or not np.all((poles > low) & (poles < high)):
            raise InputError(
                f"expected a diagonal matrix with poles in ({low:g}, {high:g}) (eq. 4-32, "
                f"6-6), got {values.tolist()}",
                field=path,
            )


def _check_draws(prior: Mapping) -> None:
    """The posterior draws, when the prior has them: lists of positive numbers of one length."""
    if prior.get("draws") is None:
        return
    lengths = {}
    for name, values in _mapping(prior, "draws").items():
        if name == "count":  # how many, which no filter reads
            continue
        path = f"draws.{name}"
        draws = _numbers(path, values)
        if draws.ndim != 1 or not draws.size:
            raise InputError(f"expected a list of numbers, got {values!r:.80}", field=path)
        bad = np.flatnonzero(~(np.isfinite(draws) & (draws > 0)))
        if bad.size:
            raise InputError(f"expected positive numbers, got {float(draws[bad[0]])!r} (draw "
                             f"{bad[0]})", field=path)  # fmt: skip
        lengths[name] = draws.size
    if len(set(lengths.values())) > 1:
        raise InputError(f"the parameters have different numbers of draws: {lengths}",
                         field="draws")  # fmt: skip


def _check_filter_fields(prior: Mapping) -> None:
    """What the generalised filter alone reads: the embedding order and the sensor's smoothness."""
    if prior.get("generalised_coordinates") is not None:
        order = _mapping(prior, "generalised_coordinates").get("order", 0)
        if not (_is_real(order) and math.isfinite(order) and order >= 0 and order == int(order)):
            raise InputError(f"expected a whole number >= 0, got {order!r:.80}",
                             field="generalised_coordinates.order")  # fmt: skip
    if prior.get("sensor_noise") is not None:
        sensor = _mapping(prior, "sensor_noise")
        if "smoothness_seconds" in sensor:
            _positive(sensor["smoothness_seconds"], "sensor_noise.smoothness_seconds",
                      " of seconds")  # fmt: skip


def _mapping(prior: Mapping, path: str) -> Mapping:
    """The field at ``path``: an object (a JSON object, a dict), or an InputError naming it."""
    value = prior_field(prior, path)
    if not isinstance(value, Mapping):
        raise InputError(f"expected an object of named fields, got {value!r:.80}", field=path)
    return value


def _is_real(value: object) -> bool:
    """Whether ``value`` is a real number: a bool is none (true is no 1.0)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _positive(value: object, path: str, unit: str = "") -> None:
    """Refuse (InputError naming ``path``) a value that is not a finite number > 0."""
    if not (_is_real(value) and math.isfinite(value) and value > 0):
        raise InputError(f"expected a positive number{unit}, got {value!r:.80}", field=path)


def _numbers(path: str, value: object) -> np.ndarray:
    """``value`` (numbers, in nested lists) as an array of floats, or an InputError naming it."""
    try:
        values = np.asarray(value)
    except ValueError:  # lists of different lengths
        values = np.array(None)
    if values.dtype.kind not in "iuf":
        raise InputError(f"expected numbers, got {value!r:.80}", field=path)
    return values.astype(float)
