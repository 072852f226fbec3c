"""The parameter layout: names, noise groups, columns and prior keys (docs/design.md §4).

A parameter vector is (d_lat, d_long, then each noise group's noise
parameters). A noise group is one channel's noise, shared by every
experiment (``shared_noise``, group key :data:`SHARED_GROUP`) or one per
experiment and channel. Each group has the family's width (none for white
noise), ``sigma_c`` and its sensor's noise: ``sigma_n`` for a channel a
sensor measures (none for white noise with the diagonal sensor term, where
``sigma_c`` is the total sd), ``sigma_p`` for a channel recorded as
motion-capture poses (``pose_channels``, the pose's position noise [m],
:mod:`bayes_jackal.likelihood.measurements`); with ``shared_width`` the
width is one parameter, after the damping, that every group shares (the one
smoothness of SPM's ``spm_DEM_R`` and dempy). :class:`ParameterLayout`
is the one place that knows this: the likelihood, the priors, the posterior
file and everything that reads one ask it for names, groups and columns
instead of building or splitting names. :func:`prior_overrides` validates
the prior ranges a user gives, for the library and the command line alike.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .._runtime import DAMPING_MODELS, InputError
from .kernels import FAMILIES, Family, get_family
from .robot import DEFAULT_PRIORS

__all__ = [
    "DAMPING",
    "POSE_SENSOR",
    "PRIOR_KEYS",
    "RATE_SENSOR",
    "SHARED_GROUP",
    "SPEED_RATIO",
    "SPEED_RATIOS",
    "SPEED_RATIO_PRIOR",
    "WIDTH_ALIAS",
    "WIDTH_PRIOR",
    "ParameterLayout",
    "prior_overrides",
    "prior_range",
    "width_keys",
]

#: The damping parameters, first in every parameter vector [N s/m].
DAMPING = ("d_lat", "d_long")
#: The speed model's parameters after the damping: each damping at the top
#: speed over the damping at the bottom one [-] (d_lat, d_long then at the
#: middle of the speed range).
SPEED_RATIOS = ("speed_ratio_lat", "speed_ratio_long")
#: Their prior key and range: log-uniform, a tenfold change across the
#: speed range either way.
SPEED_RATIO = "speed_ratio"
SPEED_RATIO_PRIOR = (0.1, 10.0)
#: Experiment key of a noise group shared by every experiment.
SHARED_GROUP = "all"
#: The prior keys of a robot profile and of prior overrides.
PRIOR_KEYS = tuple(DEFAULT_PRIORS)
#: The prior key of every family's width (the thesis' Gaussian sigma_h).
WIDTH_PRIOR = "sigma_h"
#: Accepted for :data:`WIDTH_PRIOR` in prior overrides: the width's name in
#: every family but the Gaussian.
WIDTH_ALIAS = "width"
#: The sensor parameter of a channel recorded as poses: the motion-capture
#: position noise sd per recorded pose [m].
POSE_SENSOR = "sigma_p"
#: The sensor parameter of a channel a sensor measures [channel unit].
RATE_SENSOR = "sigma_n"


@dataclass(frozen=True)
class ParameterLayout:
    """Names, noise groups and columns of a model's parameter vector.

    Parameters
    ----------
    family : str
        Noise family name (:data:`bayes_jackal.model.FAMILIES`).
    sensor : {"ma1", "diagonal"}
        Sensor-noise term.
    channels : tuple of str
        The channels, in likelihood order.
    experiments : tuple of str
        Experiment names, in order.
    shared_noise : bool
        One noise group per channel (True) or per experiment and channel.
    shared_width : bool
        One width parameter for every group (True; column 2, named without
        a group), or one per group (False, the default). Families without a
        width (white) have the same layout either way.
    pose_channels : tuple of str
        The channels recorded as motion-capture poses: their groups' sensor
        parameter is :data:`POSE_SENSOR` instead of ``sigma_n``.
    damping : {"constant", "speed"}
        :data:`DAMPING_MODELS`: with ``speed`` the damping's speed ratios
        (:data:`SPEED_RATIOS`) follow it.

    Notes
    -----
    The derived names and groups are computed once per layout.

    Examples
    --------
    >>> from bayes_jackal.model import ParameterLayout
    >>> layout = ParameterLayout("gaussian", "ma1", ("yaw", "vx"), ("v1",), True)
    >>> layout.names[:5]
    ('d_lat', 'd_long', 'sigma_h[yaw]', 'sigma_c[yaw]', 'sigma_n[yaw]')
    >>> layout.column("sigma_c", layout.group("vx", "v1"))
    6

    One width shared by both channels: one column, read by every group.

    >>> one = ParameterLayout("gaussian", "ma1", ("yaw", "vx"), ("v1",), True, shared_width=True)
    >>> one.names
    ('d_lat', 'd_long', 'sigma_h', 'sigma_c[yaw]', 'sigma_n[yaw]', 'sigma_c[vx]', 'sigma_n[vx]')
    >>> one.noise_columns(1)
    [2, 5, 6]

    vx recorded as motion-capture poses: its sensor parameter is the pose noise.

    >>> pose = ParameterLayout("white", "ma1", ("yaw", "vx"), ("v1",), True, pose_channels=("vx",))
    >>> pose.names
    ('d_lat', 'd_long', 'sigma_c[yaw]', 'sigma_n[yaw]', 'sigma_c[vx]', 'sigma_p[vx]')
    >>> pose.noise_bases
    ('sigma_c', 'sigma_n', 'sigma_p')
    """

    family: str
    sensor: str
    channels: tuple[str, ...]
    experiments: tuple[str, ...]
    shared_noise: bool
    shared_width: bool = False
    pose_channels: tuple[str, ...] = ()
    damping: str = "constant"

    def __post_init__(self) -> None:
        if self.damping not in DAMPING_MODELS:
            raise InputError(
                f"unknown damping {self.damping!r}; use one of {DAMPING_MODELS}", field="damping"
            )
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "experiments", tuple(self.experiments))
        object.__setattr__(self, "pose_channels", tuple(self.pose_channels))
        get_family(self.family)  # an InputError naming the known families
        unknown = [c for c in self.pose_channels if c not in self.channels]
        if unknown:
            raise InputError(
                f"pose channels {unknown} are not among the channels {list(self.channels)}",
                field="pose_channels",
            )

    @property
    def _family(self) -> Family:
        return get_family(self.family)

    @property
    def width_name(self) -> str | None:
        """The family's width parameter (``sigma_h`` or ``width``); None for white noise."""
        return self._family.width_name

    @cached_property
    def groups(self) -> tuple[tuple[str, str], ...]:
        """Noise groups as (channel, experiment name or :data:`SHARED_GROUP`), in order."""
        keys = (
            (channel, SHARED_GROUP if self.shared_noise else experiment)
            for experiment in self.experiments
            for channel in self.channels
        )
        return tuple(dict.fromkeys(keys))

    def group(self, channel: str, experiment: str) -> int:
        """Index of the noise group of ``channel`` in the experiment named ``experiment``."""
        key = (channel, SHARED_GROUP if self.shared_noise else experiment)
        if key not in self.groups:
            raise InputError(f"no noise group {key}; the groups are {list(self.groups)}")
        return self.groups.index(key)

    def noise_bases_of(self, group: int) -> tuple[str, ...]:
        """Base names of one group's noise parameters: (width,) sigma_c(, sensor).

        The sensor's is ``sigma_p`` for a channel recorded as poses, else
        ``sigma_n``, except for white noise with the diagonal sensor term:
        its covariance (sigma_c^2 + sigma_n^2) I has one variance, which two
        parameters would split along a flat ridge that the data cannot
        inform, so that model has one sd, ``sigma_c``: the residual's total.
        """
        family = self._family
        width = (family.width_name,) if family.has_width else ()
        channel, _ = self.groups[group]
        if channel in self.pose_channels:
            sensor: tuple[str, ...] = (POSE_SENSOR,)
        else:
            one_sd = not family.has_width and self.sensor == "diagonal"
            sensor = () if one_sd else (RATE_SENSOR,)
        return (*width, "sigma_c", *sensor)

    @cached_property
    def noise_bases(self) -> tuple[str, ...]:
        """Every group's noise parameter bases, each once, in group order."""
        bases = (self.noise_bases_of(g) for g in range(len(self.groups)))
        return tuple(dict.fromkeys(base for group in bases for base in group))

    @cached_property
    def shared_bases(self) -> tuple[str, ...]:
        """Parameters every group shares, one column each: the width with ``shared_width``."""
        width = self.width_name
        return (width,) if self.shared_width and width is not None else ()

    def group_bases_of(self, group: int) -> tuple[str, ...]:
        """A group's noise parameters with a column of its own: the others are shared."""
        return tuple(b for b in self.noise_bases_of(group) if b not in self.shared_bases)

    def sensor_parameter(self, group: int) -> str | None:
        """The group's sensor parameter (``sigma_n`` or ``sigma_p``); None where it has none."""
        sensors = [b for b in self.noise_bases_of(group) if b in (RATE_SENSOR, POSE_SENSOR)]
        return sensors[0] if sensors else None

    def label(self, group: int) -> str:
        """Coordinate label of a noise group: its channel, experiment, or both."""
        channel, experiment = self.groups[group]
        if self.shared_noise or len(self.groups) == 1:
            return channel
        return f"{experiment}, {channel}" if len(self.channels) > 1 else experiment

    @cached_property
    def labels(self) -> tuple[str, ...]:
        """The groups' coordinate labels (``noise_group`` of the posterior file)."""
        return tuple(self.label(g) for g in range(len(self.groups)))

    @cached_property
    def damping_bases(self) -> tuple[str, ...]:
        """The damping's parameters: :data:`DAMPING`, then the speed ratios with ``speed``."""
        return DAMPING + (SPEED_RATIOS if self.damping == "speed" else ())

    @cached_property
    def names(self) -> tuple[str, ...]:
        """Names in vector order: ``sigma_h[yaw]`` (no suffix for one group or a shared one)."""
        single = len(self.groups) == 1
        return (
            self.damping_bases
            + self.shared_bases
            + tuple(
                base if single else f"{base}[{self.label(g)}]"
                for g in range(len(self.groups))
                for base in self.group_bases_of(g)
            )
        )

    @cached_property
    def bases(self) -> tuple[str, ...]:
        """Base name of each column (``sigma_h`` for ``sigma_h[yaw]``)."""
        per_group = (self.group_bases_of(g) for g in range(len(self.groups)))
        return (
            self.damping_bases + self.shared_bases + tuple(b for bases in per_group for b in bases)
        )

    def names_of(self, base: str) -> tuple[str, ...]:
        """The names of parameter ``base`` in every group (``sigma_h[yaw]``, ``sigma_h[vx]``)."""
        return tuple(n for n, b in zip(self.names, self.bases, strict=True) if b == base)

    def groups_of(self, base: str) -> tuple[int, ...]:
        """The noise groups that have parameter ``base`` (every group for a shared one)."""
        return tuple(g for g in range(len(self.groups)) if base in self.noise_bases_of(g))

    @cached_property
    def column_groups(self) -> tuple[int | None, ...]:
        """Noise group of each column; None for the damping and the shared parameters."""
        return (None,) * (len(self.damping_bases) + len(self.shared_bases)) + tuple(
            g for g in range(len(self.groups)) for _ in self.group_bases_of(g)
        )

    def column(self, base: str, group: int | None = None) -> int:
        """Column of parameter ``base`` (of noise group ``group``) in the vector.

        The damping and the shared parameters (:attr:`shared_bases`) have one
        column, whatever the group.
        """
        shared = self.damping_bases + self.shared_bases
        if base in shared:
            return shared.index(base)
        if (
            group is None
            or not 0 <= group < len(self.groups)
            or base not in self.group_bases_of(group)
        ):
            raise InputError(
                f"no parameter {base!r} of group {group}; this model has {list(self.names)}"
            )
        return self.column_groups.index(group) + self.group_bases_of(group).index(base)

    def noise_columns(self, group: int) -> list[int]:
        """Columns of a group's noise parameters (shared ones too), in ``noise_bases_of`` order."""
        return [self.column(base, group) for base in self.noise_bases_of(group)]

    @cached_property
    def _noise_indices(self) -> tuple[tuple[int | None, int, int | None], ...]:
        """Per group, the columns of (width, sigma_c, sensor sd); None where there is none."""
        indices = []
        for group in range(len(self.groups)):
            columns = dict(zip(self.noise_bases_of(group), self.noise_columns(group), strict=True))
            sensor = self.sensor_parameter(group)
            indices.append(
                (
                    columns.get(self.width_name),
                    columns["sigma_c"],
                    None if sensor is None else columns[sensor],
                )
            )
        return tuple(indices)

    def noise_parameters(self, theta: np.ndarray, group: int) -> tuple[np.ndarray, ...]:
        """(width [s], sigma_c, sensor sd) of one noise group, each shape (B,).

        The sensor sd is ``sigma_n`` [channel unit] or, for a channel
        recorded as poses, ``sigma_p`` [m]. White noise has unit width
        (ignored); where the group has no sensor parameter (white noise with
        the diagonal term) it is zero, and sigma_c is the total sd.

        Parameters
        ----------
        theta : ndarray, shape (B, P)
            Parameter vectors in natural units, in :attr:`names` order.
        group : int
        """
        width, sigma_c, sensor = self._noise_indices[group]
        return (
            np.ones(len(theta)) if width is None else theta[:, width],
            theta[:, sigma_c],
            np.zeros(len(theta)) if sensor is None else theta[:, sensor],
        )

    def prior_key(self, base: str) -> str:
        """The prior range a parameter takes: its base, :data:`WIDTH_PRIOR` for a width,
        :data:`SPEED_RATIO` for a speed ratio."""
        if base in SPEED_RATIOS:
            return SPEED_RATIO
        return WIDTH_PRIOR if base == self.width_name else base


def prior_range(key: str, value: Sequence[float]) -> tuple[float, float]:
    """A prior range (low, high), validated: numbers with 0 < low < high, finite.

    Raises
    ------
    InputError
        Naming ``priors.<key>`` and the values.

    Examples
    --------
    >>> from bayes_jackal.model import prior_range
    >>> prior_range("d_lat", [50, 500])
    (50.0, 500.0)
    >>> try:
    ...     prior_range("sigma_n", (0.0, 1.0))
    ... except ValueError as error:
    ...     print(error)
    priors.sigma_n: prior range must satisfy 0 < low < high, got [0.0, 1.0]:
    it excludes every value
    """
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(
            f"low and high must be numbers, got {value!r}", field=f"priors.{key}"
        ) from None
    if not (math.isfinite(low) and math.isfinite(high)):  # 1e400 reads as inf
        raise InputError(
            f"low and high must be finite numbers, got {[str(v) for v in value]}: read as "
            f"[{low}, {high}] (a float holds at most 1.8e308)",
            field=f"priors.{key}",
        )
    if not 0 < low < high:
        raise InputError(
            f"prior range must satisfy 0 < low < high, got [{low}, {high}]: it excludes "
            "every value",
            field=f"priors.{key}",
        )
    return low, high


def width_keys() -> tuple[str, ...]:
    """The names of the one width prior, :data:`WIDTH_PRIOR` first.

    Then :data:`WIDTH_ALIAS` and each registered family's width name, read
    from ``FAMILIES`` at each call so that a family registered later
    (docs/families.md) adds its own. The robot's prior overrides
    (:func:`prior_overrides`) and a noise series'
    (:func:`bayes_jackal.noise.series_prior_overrides`)
    accept each of them for :data:`WIDTH_PRIOR`.

    Returns
    -------
    tuple of str
        Without repeats.

    Examples
    --------
    >>> from bayes_jackal.model import width_keys
    >>> width_keys()
    ('sigma_h', 'width')
    """
    names = (WIDTH_PRIOR, WIDTH_ALIAS, *(f.width_name for f in FAMILIES.values() if f.has_width))
    return tuple(dict.fromkeys(names))


def prior_overrides(
    overrides: Mapping[str, Sequence[float]] | None, *, field: str = "prior_overrides"
) -> dict[str, tuple[float, float]]:
    """Prior ranges that replace a profile's, validated and keyed on :data:`PRIOR_KEYS`.

    Keys: ``d_lat``, ``d_long`` [N s/m], ``sigma_h`` [s] (every family's
    width), ``sigma_c``, ``sigma_n`` [channel units], ``sigma_p`` [m],
    ``speed_ratio`` [-] (:data:`SPEED_RATIOS`). Every name of the width
    (``width``, and each registered family's own width name, such as a
    ``tau``) is accepted for ``sigma_h``; one width
    prior serves every family, so give it under one name. A range for a
    parameter a model lacks (white noise has no width) is valid and unused,
    so that one set of overrides serves every family compared.

    Parameters
    ----------
    overrides : mapping of str to (low, high), optional
    field : str
        Names the option in an error about a key (``--prior`` on the
        command line).

    Returns
    -------
    dict of str to (float, float)

    Raises
    ------
    InputError
        For an unknown key (naming it and the keys allowed), two names of the
        width (``width`` and ``sigma_h``), or a range that is not numbers with
        0 < low < high.

    Examples
    --------
    Every family's width takes the ``sigma_h`` range, whatever it is called:

    >>> from bayes_jackal.model import prior_overrides
    >>> prior_overrides({"width": (0.01, 0.5), "d_lat": [50, 500]})
    {'d_lat': (50.0, 500.0), 'sigma_h': (0.01, 0.5)}
    >>> try:
    ...     prior_overrides({"d_latt": (50, 500)})
    ... except ValueError as error:
    ...     print(error)
    prior_overrides: unknown prior 'd_latt'; use one of
    ['d_lat', 'd_long', 'sigma_h', 'sigma_c', 'sigma_n', 'sigma_p', 'speed_ratio', 'width']
    (width is sigma_h: every family's width)
    """
    widths = width_keys()
    aliases = widths[1:]
    allowed = list(dict.fromkeys([*PRIOR_KEYS, SPEED_RATIO, *aliases]))
    given = dict(overrides or {})
    for key in given:
        if key not in allowed:
            raise InputError(
                f"unknown prior {key!r}; use one of {allowed} ({' and '.join(aliases)} "
                f"{'is' if len(aliases) == 1 else 'are'} {WIDTH_PRIOR}: every family's width)",
                field=field,
            )
    named = [key for key in given if key in widths]
    if len(named) > 1:
        raise InputError(
            f"{' and '.join(named)} are the same prior (every family's width): give one",
            field=field,
        )
    if named:
        given[WIDTH_PRIOR] = given.pop(named[0])
    return {key: prior_range(key, value) for key, value in given.items()}
