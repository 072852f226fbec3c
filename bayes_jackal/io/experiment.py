"""Experiments: the uniformly sampled Experiment, its validation and the NetCDF experiment file.

An :class:`Experiment` is what every analysis consumes: time [s], the
measured yaw rate [rad/s], the wheel speeds (omega_r, omega_l) [rad/s] and,
when known, body-frame vx, vy [m/s] and the motion-capture poses they were
derived from (:class:`~bayes_jackal.io.PoseTrack`, at their own
stamps). It comes from a CSV file (docs/design.md §2), a
MATLAB ``.mat`` file (v5/v7 via scipy.io, v7.3 via h5py), the package's own
NetCDF experiment file (written by ``simulate`` and ``ingest``), or is built
in memory. The CSV and MATLAB readers, their column mapping and stamp repair,
and :func:`~bayes_jackal.io.load_experiment` live in
:mod:`bayes_jackal.io.tables`; an :class:`Experiment` itself must be uniform.

Its steady-state cornering window (:meth:`Experiment.steady`), where the
wheel speeds are held and the yaw rate has settled, is found by
:func:`detect_steady`, which :func:`bayes_jackal.io.read_bag` uses unless
one is given; :func:`steady_smoothing` is its smoothing, shared with the
steadiness check of model criticism
(:func:`bayes_jackal.posterior.steadiness`), whose tolerances
are the ``STEADY_*`` constants here.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.ndimage import uniform_filter1d

from .._runtime import CHANNELS, OPTIONAL, REQUIRED, DataError, require_file, write_hdf5
from .pose_track import POSE_FIELDS, POSITION_LIMIT, PoseTrack
from .stamps import MIN_SAMPLES, UNIFORM_TOLERANCE, longest_run

__all__ = [
    "CHANNEL_FIELDS",
    "MEASURED_PREFIX",
    "MEASUREMENTS",
    "RATE_FIELDS",
    "STEADY_INPUT_TOLERANCE",
    "STEADY_MIN_DURATION",
    "STEADY_SMOOTHING",
    "STEADY_YAW_FLOOR",
    "STEADY_YAW_TOLERANCE",
    "UNITS",
    "UNLABELLED",
    "Experiment",
    "as_experiments",
    "check_finite",
    "check_values",
    "detect_steady",
    "numeric_array",
    "read_netcdf",
    "steady_smoothing",
    "write_netcdf",
]

FORMAT = "bayes_jackal.experiment/1"
#: Variable name prefix of a field's mask of measured ticks in an experiment file.
MEASURED_PREFIX = "measured_"
UNITS = {
    "t": "s",
    "yaw_rate": "rad/s",
    "omega_r": "rad/s",
    "omega_l": "rad/s",
    "vx": "m/s",
    "vy": "m/s",
    "x": "m",
    "y": "m",
    "heading": "rad",
    "pose_t": "s",
    "cmd_v": "m/s",
    "cmd_w": "rad/s",
    "cmd_omega_r": "rad/s",
    "cmd_omega_l": "rad/s",
}
#: Largest magnitude each measured column may have [its units]. They are
#: generous bounds on what any ground robot logs, there to catch garbage
#: (a unit slip, a scale of 1e300, an overflowed counter) before it turns
#: into an MSE of nan or an sd of inf: a gyro reads at most ~35 rad/s (2000
#: deg/s), a wheel below ~1000 rad/s (10,000 rpm), a ground robot drives
#: below ~50 m/s. Time is checked against the robot's rate instead
#: (:func:`check_sample_time`).
MAGNITUDE_LIMITS = {
    "yaw_rate": 100.0,
    "omega_r": 1e4,
    "omega_l": 1e4,
    "vx": 100.0,
    "vy": 100.0,
    "x": POSITION_LIMIT,
    "y": POSITION_LIMIT,
    "cmd_v": 100.0,
    "cmd_w": 100.0,
    "cmd_omega_r": 1e4,
    "cmd_omega_l": 1e4,
}
#: Series label of experiments that carry none (grid and sigma_h tables).
UNLABELLED = "unlabelled"
#: Measured-state field of each model channel.
CHANNEL_FIELDS = {"vx": "vx", "vy": "vy", "yaw": "yaw_rate"}
#: How a channel can be recorded (:meth:`Experiment.measurement`): its state
#: by a sensor (``rate``: the IMU's yaw rate, or a velocity sensor), or
#: through the world poses of motion capture (``pose``: vx and vy).
MEASUREMENTS = ("rate", "pose")
#: The channels motion-capture poses record.
POSE_CHANNELS = ("vx", "vy")
#: The fields a sensor measures on the experiment's clock, which may miss
#: ticks (:attr:`Experiment.measured`): the yaw rate, and vx, vy measured as rates.
RATE_FIELDS = ("yaw_rate", "vx", "vy")


@dataclass(frozen=True, eq=False)
class Experiment:
    """One uniformly sampled run of the robot.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Sample times [s], strictly increasing and uniform.
    yaw_rate : ndarray, shape (N,)
        Measured yaw rate r [rad/s] (IMU).
    omega_r, omega_l : ndarray, shape (N,)
        Right and left wheel speeds [rad/s], the model input.
    vx, vy : ndarray, shape (N,), optional
        Body-frame longitudinal and lateral velocity [m/s]: measured, or
        derived from ``pose`` (then for plots; the likelihood models the
        poses).
    pose : PoseTrack, optional
        The motion-capture poses at their own stamps [s on this time axis];
        needs ``vx`` and ``vy`` (a reader derives them).
    name : str
        Short name (the file stem for files).
    series : str, optional
        Label of the input setting, e.g. ``"v1"``; grid searches average per
        series (thesis eq. 5-2).
    steady_window : (float, float), optional
        Start and end [s] of steady-state cornering.
    truth : dict, optional
        Known parameters of a simulated experiment.
    truth_arrays : dict of str to ndarray
        Known noise-free states and noise of a simulated experiment.
    measured : dict of str to ndarray of bool
        For a field of :data:`RATE_FIELDS` whose sensor missed ticks of the
        clock, shape (N,): True where it measured (the other ticks hold a
        value filled in for plots, which the likelihood does not use). A
        field without an entry was measured at every tick; a mask of all
        True is dropped.
    segments : ndarray of int, optional
        The first sample of each segment of the run (its command steps, in
        order, the first 0): where the command changes, e.g. the steps of a
        calibration drive (:mod:`bayes_jackal.io.segments`). None: one
        segment.
    provenance : dict
        Where the data came from and what was repaired.
    source : str
        File it was read from, or ``"<memory>"``.

    Examples
    --------
    A run built in memory: 10 s at 72 Hz, yaw rate only, with a steady window:

    >>> import numpy as np
    >>> from bayes_jackal.io import Experiment
    >>> t = np.arange(720) / 72
    >>> run = Experiment(
    ...     t=t,
    ...     yaw_rate=np.full_like(t, 0.4),
    ...     omega_r=np.full_like(t, 12.0),
    ...     omega_l=np.full_like(t, 8.0),
    ...     name="circle",
    ...     steady_window=(2.0, 8.0),
    ... )
    >>> print(round(run.dt, 6), run.channels, run.inputs.shape)
    0.013889 ('yaw',) (720, 2)
    >>> steady = run.steady()
    >>> print(len(steady.t), float(steady.t[0]), float(steady.t[-1]))
    433 2.0 8.0
    """

    t: np.ndarray
    yaw_rate: np.ndarray
    omega_r: np.ndarray
    omega_l: np.ndarray
    vx: np.ndarray | None = None
    vy: np.ndarray | None = None
    pose: PoseTrack | None = None
    name: str = "experiment"
    series: str | None = None
    steady_window: tuple[float, float] | None = None
    truth: dict | None = None
    truth_arrays: dict[str, np.ndarray] = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    source: str = "<memory>"
    measured: dict[str, np.ndarray] = field(default_factory=dict)
    segments: np.ndarray | None = None

    def __post_init__(self) -> None:
        columns = {key: getattr(self, key) for key in (*REQUIRED, *OPTIONAL)}
        columns = {
            key: numeric_array(value, self.source, key)
            for key, value in columns.items()
            if value is not None
        }
        check_values(columns, self.source, lambda i: f"sample {i}")
        _check_uniform(columns["t"], self.source, lambda i: f"sample {i}")
        if self.steady_window is not None:
            object.__setattr__(self, "steady_window", _window(self.steady_window, self.source))
        if self.pose is not None:
            _check_pose(self.pose, columns, self.source)
        for key, value in self.truth_arrays.items():
            if np.shape(value) != columns["t"].shape:
                raise DataError(
                    f"{np.shape(value)} values for {len(columns['t'])} samples",
                    source=self.source,
                    field=f"truth_{key}",
                )
        object.__setattr__(self, "measured", _check_measured(self.measured, columns, self.source))
        object.__setattr__(
            self, "segments", _check_segments(self.segments, len(columns["t"]), self.source)
        )
        for key, value in columns.items():
            value.setflags(write=False)
            object.__setattr__(self, key, value)

    @property
    def dt(self) -> float:
        """Sample time [s] (mean step)."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    @property
    def inputs(self) -> np.ndarray:
        """Wheel speeds (omega_r, omega_l) [rad/s], shape (N, 2)."""
        return np.column_stack([self.omega_r, self.omega_l])

    @property
    def channels(self) -> tuple[str, ...]:
        """Model channels (``vx``, ``vy``, ``yaw``) this experiment measures."""
        return tuple(c for c in CHANNELS if getattr(self, CHANNEL_FIELDS[c]) is not None)

    def measurement(self, channel: str) -> str:
        """How ``channel`` was recorded: ``"pose"`` (vx, vy with poses) or ``"rate"``.

        Examples
        --------
        >>> import bayes_jackal as bj
        >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v2", rng=1)
        >>> run.measurement("vx"), run.measurement("yaw")
        ('rate', 'rate')
        """
        self.channel(channel)  # a DataError when it is not in the experiment
        return "pose" if self.pose is not None and channel in POSE_CHANNELS else "rate"

    def observed(self, channel: str) -> np.ndarray:
        """Where a rate channel was measured: a bool mask of the samples, shape (N,).

        All True unless :attr:`measured` says otherwise (a channel recorded
        as poses has its own stamps, :attr:`pose`).

        Examples
        --------
        >>> import numpy as np
        >>> from bayes_jackal.io import Experiment
        >>> t = np.arange(6) / 10
        >>> mask = np.array([1, 1, 0, 1, 1, 1], bool)  # the IMU missed the third tick
        >>> run = Experiment(t=t, yaw_rate=0 * t, omega_r=1 + 0 * t, omega_l=1 + 0 * t,
        ...                  measured={"yaw_rate": mask})
        >>> run.observed("yaw").tolist()
        [True, True, False, True, True, True]
        """
        mask = self.measured.get(CHANNEL_FIELDS[channel])
        self.channel(channel)  # a DataError when it is not in the experiment
        return np.ones(len(self.t), bool) if mask is None else mask

    @property
    def segment_starts(self) -> np.ndarray:
        """The first sample of each segment (:attr:`segments`; ``[0]`` for one segment)."""
        return np.zeros(1, int) if self.segments is None else self.segments

    def channel(self, name: str) -> np.ndarray:
        """Measured state of one model channel (``"vx"``, ``"vy"`` or ``"yaw"``)."""
        if name not in CHANNEL_FIELDS:
            raise DataError(f"unknown channel {name!r}; use one of {CHANNELS}", field="channel")
        values = getattr(self, CHANNEL_FIELDS[name])
        if values is None:
            raise DataError(
                f"channel {name!r} is not in this experiment",
                source=self.source,
                field=CHANNEL_FIELDS[name],
            )
        return values

    def states(self) -> np.ndarray:
        """States (vx, vy, r), shape (N, 3); channels not measured are NaN."""
        missing = np.full_like(self.t, np.nan)
        return np.column_stack(
            [missing if c not in self.channels else self.channel(c) for c in CHANNELS]
        )

    def window(self, start: float, stop: float) -> Experiment:
        """The samples with ``start <= t <= stop`` [s] as a new experiment."""
        keep = (self.t >= start) & (self.t <= stop)
        if keep.sum() < MIN_SAMPLES:
            raise DataError(
                f"window [{start}, {stop}] s holds {keep.sum()} samples "
                f"(data span {self.t[0]:.3f}..{self.t[-1]:.3f} s)",
                source=self.source,
                field="window",
            )
        cut = {
            key: getattr(self, key)[keep]
            for key in (*REQUIRED, *OPTIONAL)
            if getattr(self, key) is not None
        }
        arrays = {key: value[keep] for key, value in self.truth_arrays.items()}
        measured = {key: mask[keep] for key, mask in self.measured.items()}
        # The poses around each kept sample too: the pose channels read the
        # poses within half a step of each sample (bayes_jackal.io.pose_increments).
        dt = self.dt
        pose = None if self.pose is None else self.pose.window(start - dt, stop + dt)
        return dataclasses.replace(
            self,
            **cut,
            pose=pose,
            truth_arrays=arrays,
            steady_window=None,
            measured=measured,
            segments=_window_segments(self.segments, keep),
        )

    def steady(self) -> Experiment:
        """The steady-state window, or the whole experiment when none is set."""
        return self if self.steady_window is None else self.window(*self.steady_window)


def numeric_array(values: object, source: str | None, field: str) -> np.ndarray:
    """``values`` as a float array; a DataError naming ``source`` and ``field`` for text, objects.

    Examples
    --------
    >>> from bayes_jackal.io import numeric_array
    >>> numeric_array([1, 2], "run.nc", "vx")
    array([1., 2.])
    >>> try:
    ...     numeric_array(["1", "x"], "run.nc", "vx")
    ... except ValueError as exc:
    ...     print(exc)
    run.nc: vx: expected numbers, got values of type <U1 (first: '1')
    """
    array = np.asarray(values)
    if array.dtype.kind not in "iuf":
        first = f" (first: {array.ravel()[:1].tolist()[0]!r})" if array.size else ""
        raise DataError(
            f"expected numbers, got values of type {array.dtype}{first}",
            source=source,
            field=field,
        )
    return array.astype(float)


def _check_pose(pose: object, columns: dict[str, np.ndarray], source: str) -> None:
    """Poses come with the velocities derived from them, and overlap the samples."""
    if not isinstance(pose, PoseTrack):
        raise DataError(
            f"expected a PoseTrack, got {type(pose).__name__}", source=source, field="pose"
        )
    missing = [key for key in POSE_CHANNELS if key not in columns]
    if missing:
        raise DataError(
            f"poses need the velocities derived from them; {missing} missing",
            source=source,
            field="pose",
        )
    t = columns["t"]
    if pose.t[0] >= t[-1] or pose.t[-1] <= t[0]:
        raise DataError(
            f"the poses ({pose.t[0]:.6g}..{pose.t[-1]:.6g} s) do not overlap the samples "
            f"({t[0]:.6g}..{t[-1]:.6g} s)",
            source=source,
            field="pose.t",
        )


def _check_measured(
    measured: object, columns: dict[str, np.ndarray], source: str
) -> dict[str, np.ndarray]:
    """The masks of measured ticks, validated; masks of all True dropped."""
    if not isinstance(measured, dict):
        raise DataError(
            f"expected a dict of masks, got {type(measured).__name__}",
            source=source,
            field="measured",
        )
    masks = {}
    for key, mask in measured.items():
        if key not in RATE_FIELDS or key not in columns:
            raise DataError(
                f"a mask of measured ticks is for a field among {RATE_FIELDS} that the "
                f"experiment has, not {key!r}",
                source=source,
                field="measured",
            )
        values = np.asarray(mask)
        if values.shape != columns["t"].shape or values.dtype.kind not in "biu":
            raise DataError(
                f"expected {len(columns['t'])} booleans, got {values.dtype} of shape "
                f"{values.shape}",
                source=source,
                field=f"measured.{key}",
            )
        values = values.astype(bool)
        if values.sum() < MIN_SAMPLES:
            raise DataError(
                f"{int(values.sum())} of {len(values)} samples measured; at least "
                f"{MIN_SAMPLES} are needed",
                source=source,
                field=key,
            )
        if not values.all():
            values.setflags(write=False)
            masks[key] = values
    return masks


def _check_segments(segments: object, samples: int, source: str) -> np.ndarray | None:
    """Segment starts as a read-only int array: increasing, from 0, within the samples."""
    if segments is None:
        return None
    starts = np.asarray(segments)
    if starts.ndim != 1 or starts.size == 0 or starts.dtype.kind not in "iu":
        raise DataError(
            f"expected the first sample of each segment (integers), got {starts.dtype} of "
            f"shape {starts.shape}",
            source=source,
            field="segments",
        )
    starts = starts.astype(int)
    if starts[0] != 0 or (np.diff(starts) <= 0).any() or starts[-1] >= samples:
        raise DataError(
            f"segment starts must increase from 0 and lie within the {samples} samples, got "
            f"{starts[:6].tolist()}{' ...' if len(starts) > 6 else ''}",
            source=source,
            field="segments",
        )
    if len(starts) == 1:
        return None
    starts.setflags(write=False)
    return starts


def _window_segments(segments: np.ndarray | None, keep: np.ndarray) -> np.ndarray | None:
    """The segment starts within a window of the samples (``keep``, a contiguous mask)."""
    if segments is None:
        return None
    first, count = int(np.argmax(keep)), int(keep.sum())
    inside = segments[(segments > first) & (segments < first + count)] - first
    return np.concatenate([[0], inside]).astype(int)


def _window(window: object, source: str) -> tuple[float, float]:
    """A steady window as (start, stop) [s]: two finite numbers, start < stop."""
    values = np.ravel(np.asarray(window, dtype=object))
    try:
        start, stop = (float(v) for v in values)
    except (TypeError, ValueError):
        start = stop = math.nan
    if not (math.isfinite(start) and math.isfinite(stop) and start < stop):
        raise DataError(
            f"expected [start, stop] with start < stop [s], got {np.asarray(window).tolist()!r}",
            source=source,
            field="steady_window",
        )
    return start, stop


def check_finite(
    values: np.ndarray, source: str | None, field: str, row_name: Callable[[int], str]
) -> None:
    """Refuse a column with a NaN or an infinity, naming the first and where it is.

    ``row_name(i)`` says where sample i is in the file (a line, an index).
    Raises :class:`~bayes_jackal._runtime.errors.DataError` naming ``source`` and ``field``.
    """
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise DataError(
            f"{values[bad[0]]} at {row_name(int(bad[0]))} ({bad.size} non-finite values)",
            source=source,
            field=field,
        )


def check_values(
    columns: dict[str, np.ndarray],
    source: str,
    row_name: Callable[[int], str],
    *,
    min_samples: int = MIN_SAMPLES,
) -> None:
    """Refuse an experiment's columns of unequal lengths, too short, non-finite or too large.

    The check of :class:`Experiment` and of the log readers
    (:mod:`bayes_jackal.io.tables`), before any stamp is repaired.

    Parameters
    ----------
    columns : dict of str to ndarray, shape (n,)
        By role: ``t`` [s] and the measured columns (:data:`UNITS`).
    source : str
        The file named in errors.
    row_name : callable
        ``row_name(i)`` says where sample i is in the file (a line, an index).
    min_samples : int
        Fewest samples: :data:`bayes_jackal.io.MIN_SAMPLES` (one-step
        residuals need them), 1 for a command held from its first value.

    Raises
    ------
    DataError
        Naming ``source``, the column and the first bad value: columns of
        different lengths or not 1-D, fewer than ``min_samples`` samples, a
        NaN or infinity, or
        a magnitude at or above ``MAGNITUDE_LIMITS``
        (wrong units or a corrupt file).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.io import check_values
    >>> t = np.arange(100) / 72
    >>> try:
    ...     check_values({"t": t, "yaw_rate": np.full(100, 1e3)}, "run.csv", "line {}".format)
    ... except ValueError as exc:
    ...     print(exc)
    run.csv: yaw_rate: 1000 rad/s at line 0 (100 values): magnitudes must be below 100
    rad/s, beyond any ground robot (wrong units or a corrupt file?)
    """
    for key, value in columns.items():
        if value.ndim != 1:
            raise DataError(f"shape {value.shape}: a column must be 1-D", source=source, field=key)
        if len(value) != len(columns["t"]):
            raise DataError(
                f"{len(value)} values for {len(columns['t'])} time stamps; columns must "
                "have one length",
                source=source,
                field=key,
            )
    if len(columns["t"]) < min_samples:
        raise DataError(
            f"only {len(columns['t'])} samples; at least {min_samples} are needed", source=source
        )
    for key, values in columns.items():
        check_finite(values, source, key, row_name)
        limit = MAGNITUDE_LIMITS.get(key, math.inf)
        bad = np.flatnonzero(np.abs(values) >= limit)
        if bad.size:
            raise DataError(
                f"{values[bad[0]]:.6g} {UNITS[key]} at {row_name(bad[0])} ({bad.size} values): "
                f"magnitudes must be below {limit:g} {UNITS[key]}, beyond any ground robot "
                "(wrong units or a corrupt file?)",
                source=source,
                field=key,
            )


def _check_uniform(t: np.ndarray, source: str, row_name: Callable[[int], str]) -> None:
    """An experiment's own time must increase uniformly (the readers make it so)."""
    steps = np.diff(t)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise DataError(
            f"time does not increase at {row_name(i)}: {t[i - 1]:.10g} -> {t[i]:.10g} s "
            "(bayes_jackal.io.uniform_clock repairs stamps)",
            source=source,
            field="t",
        )
    median = float(np.median(steps))
    off = np.flatnonzero(np.abs(steps - median) > UNIFORM_TOLERANCE * median)
    if off.size:
        i = int(off[0]) + 1
        raise DataError(
            f"time is not uniformly sampled at {row_name(i)}: step {steps[i - 1]:.6g} s, "
            f"median step {median:.6g} s (tolerance {UNIFORM_TOLERANCE:.0%}); resample first "
            "(bayes_jackal.io.uniform_clock repairs stamps)",
            source=source,
            field="t",
        )


#: Steady-state rule (:func:`detect_steady`): moving-average length [s],
#: relative tolerances on the wheel speeds and the yaw rate, the yaw-rate
#: tolerance floor [rad/s] and the shortest steady window [s].
STEADY_SMOOTHING = 0.25
STEADY_INPUT_TOLERANCE = 0.05
STEADY_YAW_TOLERANCE = 0.1
STEADY_YAW_FLOOR = 0.01
STEADY_MIN_DURATION = 1.0


def steady_smoothing(
    t: np.ndarray, yaw_rate: np.ndarray, inputs: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Wheel speeds and yaw rate smoothed as by the steady rule (:data:`STEADY_SMOOTHING`).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times [s].
    yaw_rate : ndarray, shape (N,)
        Yaw rate [rad/s].
    inputs : ndarray, shape (N, 2)
        Wheel speeds [rad/s].

    Returns
    -------
    inputs, yaw_rate : ndarray, shapes (N, 2) and (N,)
        Smoothed, same units (edges padded with the end values).

    Examples
    --------
    A moving average of 0.25 s (18 samples at 72 Hz) removes an alternating
    ripple, except near the edges:

    >>> import numpy as np
    >>> from bayes_jackal.io import steady_smoothing
    >>> t = np.arange(144) / 72
    >>> yaw_rate = 0.4 + 0.1 * (-1.0) ** np.arange(144)
    >>> wheels = np.column_stack([np.full(144, 12.0), np.full(144, 8.0)])
    >>> smooth_wheels, smooth_yaw = steady_smoothing(t, yaw_rate, wheels)
    >>> np.allclose(smooth_yaw[9:-9], 0.4), np.allclose(smooth_wheels, wheels)
    (True, True)
    """
    size = max(1, round(STEADY_SMOOTHING / (t[1] - t[0])))
    u = uniform_filter1d(np.asarray(inputs, float), size, axis=0, mode="nearest")
    r = uniform_filter1d(np.asarray(yaw_rate, float), size, mode="nearest")
    return u, r


def detect_steady(
    t: np.ndarray, yaw_rate: np.ndarray, inputs: np.ndarray
) -> tuple[float, float] | None:
    """Steady-state cornering window: wheel speeds constant and yaw rate settled.

    Rule (all signals first smoothed by a :data:`STEADY_SMOOTHING` moving
    average): the held input level is the median of the wheel speeds where
    the robot moves (largest wheel speed at least half its maximum); the
    input is constant where both wheel speeds are within
    :data:`STEADY_INPUT_TOLERANCE` times the largest held level of it, and
    the window is the longest such stretch. Its start is moved to where the
    yaw rate has settled: the first sample of the stretch at which the yaw
    rate is within :data:`STEADY_YAW_TOLERANCE` (relative, at least
    :data:`STEADY_YAW_FLOOR`) of its median over the stretch. Process noise
    makes the yaw rate wander by ~10 % in steady state, so "first within",
    not "stays within", is the test. The end is the input's: the yaw rate
    lags the input. Windows shorter than :data:`STEADY_MIN_DURATION` count
    as none.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times [s].
    yaw_rate : ndarray, shape (N,)
        Yaw rate [rad/s].
    inputs : ndarray, shape (N, 2)
        Wheel speeds (omega_r, omega_l) [rad/s].

    Returns
    -------
    (float, float) or None
        Start and end [s], or None when the run has no steady stretch.

    Examples
    --------
    A simulated v2 run, whose command is held from 2 s to 24 s (the simulator
    counts the steady part from 3 s, after its settling time):

    >>> from bayes_jackal.io import detect_steady
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> run = simulate_experiment(load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> start, stop = detect_steady(run.t, run.yaw_rate, run.inputs)
    >>> print(f"{start:.2f}-{stop:.2f} s; simulated: {run.steady_window}")
    1.99-24.03 s; simulated: (3.0, 24.0)
    """
    u, r = steady_smoothing(t, yaw_rate, inputs)
    speed = np.abs(u).max(axis=1)
    if not speed.max() > 0:
        return None
    level = np.median(u[speed >= 0.5 * speed.max()], axis=0)
    constant = (np.abs(u - level) <= STEADY_INPUT_TOLERANCE * np.abs(level).max()).all(axis=1)
    start, stop = longest_run(constant)
    if stop - start < 2:
        return None
    settled = np.median(r[start:stop])
    tolerance = max(STEADY_YAW_TOLERANCE * abs(settled), STEADY_YAW_FLOOR)
    start += int(np.argmax(np.abs(r[start:stop] - settled) <= tolerance))
    if t[stop - 1] - t[start] < STEADY_MIN_DURATION:
        return None
    return float(t[start]), float(t[stop - 1])


def write_netcdf(experiment: Experiment, path: str | Path) -> Path:
    """Write an experiment, with its truth and provenance, as NetCDF (atomically).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.io import read_netcdf, write_netcdf
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> run = simulate_experiment(load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = write_netcdf(run, Path(folder) / "v2.nc")
    ...     back = read_netcdf(path)
    >>> print(path.name, back.steady_window, back.truth["d_lat"])
    v2.nc (3.0, 24.0) 110.0
    """
    path = Path(path)
    data = {
        key: ("time", getattr(experiment, key), {"units": UNITS[key]})
        for key in (*REQUIRED[1:], *OPTIONAL)
        if getattr(experiment, key) is not None
    }
    data |= {f"truth_{key}": ("time", value) for key, value in experiment.truth_arrays.items()}
    data |= {
        f"{MEASURED_PREFIX}{key}": ("time", mask.astype(np.uint8))
        for key, mask in experiment.measured.items()
    }
    coords = {"time": ("time", experiment.t, {"units": "s"})}
    if experiment.pose is not None:
        coords["pose_time"] = ("pose_time", experiment.pose.t, {"units": "s"})
        data |= {
            f"pose_{key}": ("pose_time", getattr(experiment.pose, key), {"units": unit})
            for key, unit in POSE_FIELDS.items()
            if key != "t"
        }
    attrs = {
        "format": FORMAT,
        "name": experiment.name,
        "series": experiment.series or "",
        "truth": json.dumps(experiment.truth),
        "provenance": json.dumps(experiment.provenance),
    }
    if experiment.steady_window is not None:
        attrs["steady_window"] = list(experiment.steady_window)
    if experiment.segments is not None:
        attrs["segments"] = json.dumps(experiment.segments.tolist())
    dataset = xr.Dataset(data, coords=coords, attrs=attrs)
    return write_hdf5(dataset, path)


def read_netcdf(path: str | Path) -> Experiment:
    """Read an experiment file written by :func:`write_netcdf`.

    Raises
    ------
    DataError
        When the file is missing, not NetCDF, not an experiment file, or
        lacks a required variable.

    Examples
    --------
    The round trip keeps the data, the truth and the steady window:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from bayes_jackal.io import read_netcdf, write_netcdf
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> run = simulate_experiment(load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     back = read_netcdf(write_netcdf(run, Path(folder) / "v2.nc"))
    >>> print(back.name, back.series, back.channels, np.array_equal(back.yaw_rate, run.yaw_rate))
    v2 v2 ('vx', 'vy', 'yaw') True
    """
    path = Path(path)
    source = str(path)
    require_file(path, source)
    try:
        # phony_dims: an HDF5 variable without dimension scales (a file from h5py)
        # is read, and refused as not 1-D by name, without h5netcdf's warning.
        with xr.open_dataset(path, engine="h5netcdf", phony_dims="access") as dataset:
            dataset = dataset.load()
    except (OSError, ValueError) as exc:
        raise DataError(f"not a readable NetCDF file ({exc})", source=source) from None
    if dataset.attrs.get("format") != FORMAT:
        raise DataError(
            f"not a bayes_jackal experiment file (format {dataset.attrs.get('format')!r})",
            source=source,
            field="format",
        )
    missing = [key for key in REQUIRED[1:] if key not in dataset]
    if missing:
        raise DataError(f"missing variable(s) {missing}", source=source, field=missing[0])
    return Experiment(
        t=dataset["time"].values,
        **{key: dataset[key].values for key in (*REQUIRED[1:], *OPTIONAL) if key in dataset},
        pose=_pose(dataset, source),
        name=str(dataset.attrs.get("name") or path.stem),
        series=str(dataset.attrs.get("series", "")) or None,
        steady_window=dataset.attrs.get("steady_window"),
        truth=_json_attribute(dataset.attrs, "truth", source, null=True),
        truth_arrays={
            key.removeprefix("truth_"): numeric_array(dataset[key].values, source, key)
            for key in dataset.data_vars
            if key.startswith("truth_")
        },
        provenance=_json_attribute(dataset.attrs, "provenance", source),
        source=source,
        measured={
            key.removeprefix(MEASURED_PREFIX): dataset[key].values
            for key in dataset.data_vars
            if key.startswith(MEASURED_PREFIX)
        },
        segments=_segments_attribute(dataset.attrs, source),
    )


def _segments_attribute(attrs: dict, source: str) -> np.ndarray | None:
    """The segment starts of an experiment file (absent in older files: one segment)."""
    if "segments" not in attrs:
        return None
    try:
        return np.asarray(json.loads(attrs["segments"]), dtype=int)
    except (TypeError, ValueError, RecursionError):
        raise DataError(
            f"expected a JSON list of sample indices, got {str(attrs['segments'])[:80]!r}",
            source=source,
            field="segments",
        ) from None


def _pose(dataset: xr.Dataset, source: str) -> PoseTrack | None:
    """The pose track of an experiment file; None for a file without poses (older ones)."""
    if "pose_time" not in dataset.coords:
        return None
    keys = [f"pose_{key}" for key in POSE_FIELDS if key != "t"]
    missing = [key for key in keys if key not in dataset]
    if missing:
        raise DataError(f"missing variable(s) {missing}", source=source, field=missing[0])
    arrays = [numeric_array(dataset[key].values, source, key) for key in keys]
    return PoseTrack(dataset["pose_time"].values, *arrays, source=source)


def _json_attribute(attrs: dict, key: str, source: str, *, null: bool = False) -> dict | None:
    """A JSON-object attribute of an experiment file, decoded (absent: null or {})."""
    text = attrs.get(key, "null" if null else "{}")
    try:
        value = json.loads(text)
    except (TypeError, ValueError, RecursionError):  # json recurses per level of nesting
        value = text  # not JSON text, or nested deeper than Python parses: refused below
    if not (isinstance(value, dict) or (null and value is None)):
        raise DataError(
            f"expected a JSON object{' or null' if null else ''}, got {str(text)[:80]!r}",
            source=source,
            field=key,
        )
    return value


def as_experiments(experiments: Experiment | Sequence[Experiment]) -> list[Experiment]:
    """One experiment, or several, as a list.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.io import as_experiments
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> len(as_experiments(run)), len(as_experiments((run, run)))
    (1, 2)
    """
    return [experiments] if isinstance(experiments, Experiment) else list(experiments)
