"""Motion-capture poses as recorded: world position and heading at the pose system's own stamps.

A lab's motion capture (OptiTrack, Vicon; 100-360 Hz, sub-millimetre noise)
records the robot's world position (x, y) [m] and heading [rad]. The
body-frame velocities vx and vy are not measured: a reader can derive them
(:func:`bayes_jackal.io.read_bag` does, with a Savitzky-Golay derivative,
for plots), but the likelihood models the poses themselves
(:mod:`bayes_jackal.io.pose_increments`, docs/design.md §2.2). So an
:class:`~bayes_jackal.io.Experiment` keeps its :class:`PoseTrack`
beside the derived velocities, at the stamps the poses had, after the
repairs of the reader (sorted, repeated stamps dropped), on the experiment's
time axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from .._runtime import DataError

__all__ = [
    "POSE_FIELDS",
    "POSITION_LIMIT",
    "SMOOTHING_MIN_POSES",
    "SMOOTHING_ORDER",
    "SMOOTHING_WINDOW",
    "PoseTrack",
    "body_velocities",
]

#: The arrays of a pose track, in order, and their units.
POSE_FIELDS = {"t": "s", "x": "m", "y": "m", "heading": "rad"}
#: Largest world coordinate a pose may have [m]: a motion-capture volume is
#: tens of metres across; a larger value is a unit slip (mm) or garbage.
POSITION_LIMIT = 1e4
#: Fewest poses a track must hold.
MIN_POSES = 3
#: Savitzky-Golay differentiating smoother of the poses
#: (:meth:`PoseTrack.smoothed_rates`): window [s] and order. A local
#: quadratic fit over 0.1 s; for deriv=1 it equals the least-squares slope,
#: which passes velocities varying slower than ~5 Hz and damps
#: motion-capture noise (0.1 mm noise -> ~0.5 mm/s at 360 Hz).
SMOOTHING_WINDOW = 0.1
SMOOTHING_ORDER = 2
#: Fewest poses the smoother spans, odd and more than its order: poses slower
#: than 15 Hz (lidar ICP at 4 Hz) give fewer in 0.1 s, and are differentiated
#: over 3 (for order 2: the central difference).
SMOOTHING_MIN_POSES = SMOOTHING_ORDER + 1 + SMOOTHING_ORDER % 2


@dataclass(frozen=True, eq=False)
class PoseTrack:
    """World poses at their own stamps, as the motion-capture system recorded them.

    Attributes
    ----------
    t : ndarray, shape (M,)
        Stamps [s] on the experiment's time axis, strictly increasing (not
        necessarily uniform: jitter and dropouts are as recorded).
    x, y : ndarray, shape (M,)
        World position [m].
    heading : ndarray, shape (M,)
        Heading [rad], unwrapped (continuous through +-pi).
    source : str
        The file named in errors.

    Examples
    --------
    A straight line at 0.3 m/s recorded at 100 Hz:

    >>> import numpy as np
    >>> from bayes_jackal.io import PoseTrack
    >>> t = np.arange(300) / 100
    >>> track = PoseTrack(t, 0.3 * t, np.zeros(300), np.zeros(300))
    >>> print(len(track.t), round(track.rate, 6), track.window(1.0, 2.0).t[[0, -1]])
    300 100.0 [1. 2.]
    >>> try:
    ...     PoseTrack(t[::-1], 0.3 * t, np.zeros(300), np.zeros(300), source="run.bag")
    ... except ValueError as error:
    ...     print(error)
    run.bag: pose.t: pose stamps must increase; 2.99 s is followed by 2.98 s at pose 1
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    source: str = "<memory>"

    def __post_init__(self) -> None:
        arrays = {}
        for name in POSE_FIELDS:
            values = np.asarray(getattr(self, name))
            if values.dtype.kind not in "iuf" or values.ndim != 1:
                raise DataError(
                    f"expected a 1-D array of numbers, got {values.dtype} of shape {values.shape}",
                    source=self.source,
                    field=f"pose.{name}",
                )
            arrays[name] = values.astype(float)
        lengths = {name: len(values) for name, values in arrays.items()}
        if len(set(lengths.values())) != 1 or lengths["t"] < MIN_POSES:
            raise DataError(
                f"pose arrays must have one length of at least {MIN_POSES}, got {lengths}",
                source=self.source,
                field="pose",
            )
        for name, values in arrays.items():
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise DataError(
                    f"{values[bad[0]]} at pose {bad[0]} ({bad.size} non-finite values)",
                    source=self.source,
                    field=f"pose.{name}",
                )
        for name in ("x", "y"):
            bad = np.flatnonzero(np.abs(arrays[name]) >= POSITION_LIMIT)
            if bad.size:
                raise DataError(
                    f"{arrays[name][bad[0]]:.6g} m at pose {bad[0]}: positions must be within "
                    f"{POSITION_LIMIT:g} m (millimetres given as metres?)",
                    source=self.source,
                    field=f"pose.{name}",
                )
        back = np.flatnonzero(np.diff(arrays["t"]) <= 0)
        if back.size:
            i = int(back[0])
            raise DataError(
                f"pose stamps must increase; {arrays['t'][i]:.6g} s is followed by "
                f"{arrays['t'][i + 1]:.6g} s at pose {i + 1}",
                source=self.source,
                field="pose.t",
            )
        for name, values in arrays.items():
            values.setflags(write=False)
            object.__setattr__(self, name, values)

    @property
    def rate(self) -> float:
        """The median pose rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.t)))

    def window(self, start: float, stop: float) -> PoseTrack:
        """The poses with ``start <= t <= stop`` [s]."""
        keep = (self.t >= start) & (self.t <= stop)
        if keep.sum() < MIN_POSES:
            raise DataError(
                f"the window [{start:.6g}, {stop:.6g}] s holds {keep.sum()} poses (poses span "
                f"{self.t[0]:.6g}..{self.t[-1]:.6g} s)",
                source=self.source,
                field="pose",
            )
        return PoseTrack(*(getattr(self, name)[keep] for name in POSE_FIELDS), source=self.source)

    def smoothed_rates(self) -> tuple[np.ndarray, np.ndarray]:
        """Rates of change of x, y and heading, smoothed: the derived velocities' source.

        The poses are interpolated onto a uniform grid at their median rate
        and differentiated with a Savitzky-Golay filter
        (:data:`SMOOTHING_WINDOW`, :data:`SMOOTHING_ORDER`, at least
        :data:`SMOOTHING_MIN_POSES` poses). What it gives
        is not a measurement: a smoothing differentiator widens the process
        noise's kernel and colours the pose noise, so the likelihood models
        the poses instead (docs/design.md §2.2). It serves the derived vx,
        vy of plots and the small shift of a pose to its sample's time
        (:func:`bayes_jackal.io.tick_poses`).

        Returns
        -------
        t : ndarray, shape (U,)
            The uniform grid [s].
        rates : ndarray, shape (U, 3)
            dx/dt, dy/dt [m/s] (world frame) and dheading/dt [rad/s].

        Raises
        ------
        DataError
            When the poses are too few for the smoother.

        Examples
        --------
        A circle of radius 2 m at 0.5 rad/s, recorded at 120 Hz: the world
        velocity has the speed 1 m/s (to 3e-4: the quadratic fit's bias on
        the curve, largest at the ends), the heading turns at 0.5 rad/s:

        >>> import numpy as np
        >>> from bayes_jackal.io import PoseTrack
        >>> t = np.arange(600) / 120
        >>> track = PoseTrack(t, 2 * np.sin(0.5 * t), 2 - 2 * np.cos(0.5 * t), 0.5 * t)
        >>> grid, rates = track.smoothed_rates()
        >>> bool(np.allclose(np.hypot(rates[:, 0], rates[:, 1]), 1.0, atol=3e-4))
        True
        >>> bool(np.allclose(rates[:, 2], 0.5))
        True
        """
        t = self.t
        step = float(np.median(np.diff(t)))
        uniform = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / step + 1e-6)) + 1) * step
        length = max(round(SMOOTHING_WINDOW / step) // 2 * 2 + 1, SMOOTHING_MIN_POSES)
        if len(uniform) < length:
            raise DataError(
                f"pose too short for the {SMOOTHING_WINDOW} s smoother ({len(uniform)} "
                f"samples at {1 / step:.1f} Hz)",
                source=self.source,
                field="pose",
            )
        rates = [
            savgol_filter(
                np.interp(uniform, t, values), length, SMOOTHING_ORDER, deriv=1, delta=step
            )
            for values in (self.x, self.y, self.heading)
        ]
        return uniform, np.column_stack(rates)


def body_velocities(track: PoseTrack, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame vx, vy [m/s] derived from the poses, at times ``t`` [s], for plots.

    The smoothed world velocity (:meth:`PoseTrack.smoothed_rates`) rotated
    into the body frame by the heading, vx = cos(psi) x' + sin(psi) y',
    vy = -sin(psi) x' + cos(psi) y', then interpolated to ``t``. Not a
    measurement (docs/design.md §2.2): the likelihood models the poses.

    Examples
    --------
    A circle of radius 2 m at 0.5 rad/s: 1 m/s forward (less the quadratic
    fit's bias on the curve, 1e-4), nothing sideways:

    >>> import numpy as np
    >>> from bayes_jackal.io import PoseTrack
    >>> from bayes_jackal.io import body_velocities
    >>> s = np.arange(600) / 120
    >>> track = PoseTrack(s, 2 * np.sin(0.5 * s), 2 - 2 * np.cos(0.5 * s), 0.5 * s)
    >>> vx, vy = body_velocities(track, np.array([1.0, 2.0]))
    >>> vx.round(3).tolist(), vy.round(4).tolist()
    ([1.0, 1.0], [0.0, 0.0])
    """
    grid, rates = track.smoothed_rates()
    psi = np.interp(grid, track.t, track.heading)
    cos, sin = np.cos(psi), np.sin(psi)
    vx = cos * rates[:, 0] + sin * rates[:, 1]
    vy = -sin * rates[:, 0] + cos * rates[:, 1]
    return np.interp(t, grid, vx), np.interp(t, grid, vy)
