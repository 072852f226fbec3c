"""The poses on the experiment's clock, and the body-frame increments between them.

The pose channels (vx, vy recorded by motion capture) enter the likelihood
through the poses, not through a derivative of them (docs/design.md §2.2).
Two steps bring the poses to the IMU's clock t_k = t_0 + k dt without
smoothing them:

1. **A pose per sample** (:func:`tick_poses`). Each sample k owns the poses
   within half a step of it. Every sample takes the n poses nearest to it,
   n the most that (nearly) every sample owns (5 at 360 Hz against a
   72 Hz IMU, 3 at 240 Hz, 1 at 120 Hz): their mean, each moved to t_k by
   its offset tau times the smoothed rate of change halfway between its
   stamp and t_k (:meth:`~bayes_jackal.io.PoseTrack.smoothed_rates`;
   exact but for tau^3 times the rate's curvature). The moved poses are
   the recorded ones plus a correction of at most half a pose step times
   the velocity's smoothing error (~1e-6 m), so a sample's pose noise is
   the mean of n independent recordings: white, of sd sigma_p / sqrt(n)
   per axis, where sigma_p is the motion-capture system's. A sample that
   owns fewer than n poses (a dropout) borrows its neighbours' nearest;
   :attr:`TickPoses.borrowed` counts them.
2. **Body-frame increments** (:func:`body_increments`): the world
   displacement over each step, rotated into the body frame by the mean of
   the step's two headings,

       M_k = R(-(psi_k + psi_{k+1}) / 2) (p_{k+1} - p_k),

   which is the integral of the body velocity over the step up to
   r^2 dt^3 v / 24 (< 1e-7 m at 0.5 rad/s, 72 Hz), and whose noise is the
   difference of two samples' pose noise. The heading's noise moves the
   lateral increment by v dt sigma_psi / sqrt(2 n), v dt sigma_psi / (2
   sigma_p) of the position noise's sd: 4 % at 0.3 m/s, 0.002 rad and
   0.1 mm (0.2 % of the variance), 14 % at 1 m/s; it is left out, and grows
   with the speed.

Poses slower than the samples (lidar ICP at 4-10 Hz, motion capture at 50
Hz beside a 72 Hz IMU), or dropping out, do not give every sample a pose of
its own. :func:`pose_observations` says how the likelihood observes an
experiment's poses: a pose per sample where (nearly) every sample owns
one, as above, with the samples no pose lies within one step of left out
(a dropout: the pose channels' residuals split there); otherwise each pose
at its own stamp, unmoved, for the exact likelihood of
:mod:`bayes_jackal.likelihood.irregular`.

:mod:`bayes_jackal.likelihood.measurements` relates M_k to the model's state.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from .._runtime import DataError
from .experiment import POSE_CHANNELS, Experiment
from .pose_track import PoseTrack

__all__ = [
    "BORROW_FRACTION",
    "STRIDE_TOLERANCE",
    "PoseObservations",
    "TickPoses",
    "body_displacement",
    "body_increments",
    "pose_observations",
    "pose_samples",
    "tick_poses",
]

#: Samples per pose at the most that may own fewer than the n poses each
#: sample takes (they borrow): n is the largest count that all but this
#: fraction of the samples own.
BORROW_FRACTION = 0.01
#: Largest offset [samples] of a pose from its tick on a strided clock of its
#: own that the pose is moved across (by the offset times the smoothed rate:
#: at 20 Hz, 12.5 ms x a rate error of 7 cm/s = 0.9 mm against 2 cm of ICP noise).
STRIDE_TOLERANCE = 0.25


@dataclass(frozen=True)
class TickPoses:
    """The poses at an experiment's samples (:func:`tick_poses`).

    Attributes
    ----------
    x, y : ndarray, shape (N,)
        World position at each sample [m].
    heading : ndarray, shape (N,)
        Heading at each sample [rad].
    samples : int
        n, the recorded poses averaged into each: the pose noise at a
        sample has sd sigma_p / sqrt(n) per axis.
    borrowed : int
        Samples that own fewer than n poses and took their neighbours'.

    Examples
    --------
    :func:`tick_poses` makes them; by hand, two samples at heading 0:

    >>> import numpy as np
    >>> from bayes_jackal.io import TickPoses
    >>> ticks = TickPoses(np.array([0.0, 0.01]), np.zeros(2), np.zeros(2), samples=5, borrowed=0)
    >>> ticks.samples
    5
    """

    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    samples: int
    borrowed: int


@dataclass(frozen=True)
class PoseObservations:
    """An experiment's poses as the likelihood observes them (:func:`pose_observations`).

    Attributes
    ----------
    regime : {"tick", "stride", "stamp"}
        ``tick``: a pose per sample, the mean of the n nearest moved to it
        (:func:`tick_poses`); ``stride``: poses slower than the samples on
        a clock of their own, a pose every m samples at one phase, each moved
        to its tick of that clock; ``stamp``: each recorded pose at its own
        stamp, unmoved (poses slower than the samples and irregular).
    ticks : ndarray of int, shape (M,)
        The sample each observation is at (``tick``) or falls after.
    phases : ndarray, shape (M,)
        Its time after that sample [s]: 0 for ``tick``, one phase for
        ``stride``, in [0, dt) for ``stamp``.
    x, y, heading : ndarray, shape (M,)
        The world pose observed [m, m, rad].
    samples : int
        Recorded poses averaged into each observation (1 for ``stamp``).
    borrowed : int
        ``tick``: samples that own fewer than n poses and took their neighbours'.
    rate : float
        The poses' median rate [Hz].
    stride : int
        m, the samples between poses: 1 for ``tick``, 0 for ``stamp``.
    dropped : int
        ``stride``: poses off their clock by more than
        :data:`STRIDE_TOLERANCE` (at most :data:`BORROW_FRACTION` of them),
        or a second pose of one tick, left out.

    Examples
    --------
    Poses at 10 Hz beside a 50 Hz clock: a pose every 5 samples, a fifth of a
    step past its sample:

    >>> import numpy as np
    >>> from bayes_jackal.io import Experiment, PoseTrack, pose_observations
    >>> t, s = np.arange(500) / 50, np.arange(100) / 10 + 0.004
    >>> run = Experiment(t=t, yaw_rate=0 * t, omega_r=3 + 0 * t, omega_l=3 + 0 * t,
    ...                  vx=0.3 + 0 * t, vy=0 * t, pose=PoseTrack(s, 0.3 * s, 0 * s, 0 * s))
    >>> poses = pose_observations(run)
    >>> poses.regime, poses.ticks[:3].tolist(), poses.phases[:3].round(6).tolist()
    ('stride', [0, 5, 10], [0.004, 0.004, 0.004])
    """

    regime: str
    ticks: np.ndarray
    phases: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    samples: int
    borrowed: int
    rate: float
    stride: int = 1
    dropped: int = 0

    @property
    def clock(self) -> tuple[int, float]:
        """(m, phase [s]) of the poses' clock on the samples' (``tick``: (1, 0))."""
        return (self.stride, float(self.phases[0]) if self.stride > 1 else 0.0)

    def increments(self, channel: str) -> np.ndarray:
        """D_j, the body-frame travel between consecutive observations along an axis [m].

        The world displacement rotated by the mean of the two headings
        (:func:`body_increments`), shape (M - 1,).
        """
        return body_increments(self, channel)


def pose_observations(experiment: Experiment) -> PoseObservations:
    """How the likelihood observes an experiment's poses: a pose per sample, or at their stamps.

    A pose per sample (``tick``, as :func:`tick_poses`) where all but
    :data:`BORROW_FRACTION` of the samples that have a pose within one
    step own one; the samples without a pose within one step (a dropout,
    or before the poses begin) are left out. Otherwise the poses are
    slower than the samples. Where all but :data:`BORROW_FRACTION` of them
    lie within :data:`STRIDE_TOLERANCE` steps of a clock of theirs that
    ticks every m >= 2 samples at one phase (a lidar at 5 Hz beside a 20 Hz
    IMU, motion capture at 100 Hz beside 200 Hz; a dropout is a tick
    without a pose), each is moved to its tick by its offset times the
    smoothed rate (``stride``): their residuals are then a stationary series
    the Toeplitz engines evaluate at a cost flat in the run's length.
    Otherwise each pose within the samples' span is observed at its own
    stamp (``stamp``), for the irregular engine.

    Raises
    ------
    DataError
        Naming the file: no poses, or fewer than three within the samples.

    Examples
    --------
    Motion capture at 360 Hz beside a 72 Hz IMU with a 0.2 s dropout: the
    13 samples without a pose within one step are left out:

    >>> import numpy as np
    >>> from bayes_jackal.io import Experiment, PoseTrack, pose_observations
    >>> t, s = np.arange(720) / 72, np.arange(-2, 3602) / 360 + 0.0011
    >>> s = s[(s < 4.0) | (s > 4.2)]
    >>> run = Experiment(t=t, yaw_rate=0 * t, omega_r=3 + 0 * t, omega_l=3 + 0 * t,
    ...                  vx=0.3 + 0 * t, vy=0 * t, pose=PoseTrack(s, 0.3 * s, 0 * s, 0 * s))
    >>> poses = pose_observations(run)
    >>> poses.regime, poses.samples, len(t) - len(poses.ticks)
    ('tick', 5, 13)
    """
    track, t = _track(experiment), experiment.t
    near = _near_samples(track.t, t, experiment.dt)
    owners = _owned_counts(track.t, t, experiment.dt)
    covered = owners[near]
    if covered.size and np.mean(covered > 0) >= 1 - BORROW_FRACTION:
        ticks = np.flatnonzero(near)
        samples = int(np.quantile(covered[covered > 0], BORROW_FRACTION, method="lower"))
        x, y, heading = _moved_means(track, t[ticks], samples)
        return PoseObservations("tick", ticks, np.zeros(len(ticks)), x, y, heading, samples,
                                int(np.sum(covered < samples)), track.rate)  # fmt: skip
    inside = (track.t >= t[0]) & (track.t < t[-1])
    if inside.sum() < 3:
        raise DataError(
            f"{int(inside.sum())} poses lie within the samples' span "
            f"({t[0]:.6g}..{t[-1]:.6g} s); at least 3 are needed",
            source=experiment.source,
            field="pose",
        )
    strided = _strided(track, inside, t, experiment.dt)
    if strided is not None:
        return strided
    stamps = track.t[inside]
    ticks = np.minimum(np.floor((stamps - t[0]) / experiment.dt + 1e-9).astype(int), len(t) - 2)
    phases = np.clip(stamps - t[ticks], 0.0, experiment.dt * (1 - 1e-12))
    return PoseObservations("stamp", ticks, phases, track.x[inside], track.y[inside],
                            track.heading[inside], 1, 0, track.rate, stride=0)  # fmt: skip


def _strided(
    track: PoseTrack, inside: np.ndarray, t: np.ndarray, dt: float
) -> PoseObservations | None:
    """The ``stride`` observations of poses on a clock of their own, or None where none fits."""
    position = (track.t[inside] - t[0]) / dt  # [samples]
    stride = round(float(np.median(np.diff(position))))
    if stride < 2:
        return None
    index = np.rint((position - position[0]) / stride).astype(int)  # on the poses' clock
    deviation = position - position[0] - index * stride
    origin = position[0] + float(np.median(deviation))
    offset = position - (origin + index * stride)  # [samples]
    near = np.abs(offset) <= STRIDE_TOLERANCE
    near &= np.concatenate([[True], np.diff(index) > 0])  # one pose per tick of theirs
    if near.mean() < 1 - BORROW_FRACTION:
        return None
    first = int(np.floor(origin))
    if first < 0:  # the clock's first tick before the samples': start one tick of theirs on
        index, near = index - 1, near & (index >= 1)
        first += stride
    ticks = first + index[near] * stride
    keep = near.copy()
    keep[near] = ticks <= len(t) - 2
    ticks = ticks[ticks <= len(t) - 2]
    phase = (origin - np.floor(origin)) * dt
    stamps = track.t[inside][keep]
    x, y, heading = _moved(track, stamps, t[ticks] + phase)
    return PoseObservations("stride", ticks, np.full(len(ticks), phase), x, y, heading, 1, 0,
                            track.rate, stride=stride,
                            dropped=int(inside.sum() - keep.sum()))  # fmt: skip


def _moved(
    track: PoseTrack, stamps: np.ndarray, targets: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The poses at ``stamps`` moved to ``targets`` by the offset times the smoothed rate."""
    grid, rates = track.smoothed_rates()
    offset = stamps - targets
    halfway = stamps - offset / 2
    row = np.searchsorted(track.t, stamps)
    return tuple(
        values[row] - offset * np.interp(halfway, grid, rate)
        for values, rate in zip((track.x, track.y, track.heading), rates.T, strict=True)
    )


def _track(experiment: Experiment) -> PoseTrack:
    """The experiment's pose track; a DataError naming its file when it has none."""
    if experiment.pose is None:
        raise DataError("the experiment holds no poses", source=experiment.source, field="pose")
    return experiment.pose


def _near_samples(stamps: np.ndarray, t: np.ndarray, dt: float) -> np.ndarray:
    """Which samples have a pose within one step, shape (N,)."""
    nearest = _nearest_poses(stamps, t, 1)[:, 0]
    return np.abs(stamps[nearest] - t) <= dt


def _owned_counts(stamps: np.ndarray, t: np.ndarray, dt: float) -> np.ndarray:
    """The poses each sample owns (within half a step of it), shape (N,)."""
    owners = np.rint((stamps - t[0]) / dt).astype(int)
    return np.bincount(owners[(owners >= 0) & (owners < len(t))], minlength=len(t))


def _moved_means(
    track: PoseTrack, t: np.ndarray, samples: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, heading at times t: the mean of the ``samples`` nearest poses, each moved to it.

    Each pose moves by its offset times the smoothed rate halfway between
    its stamp and the time: exact to the offset^3 times the rate's curvature.
    """
    index = _nearest_poses(track.t, t, samples)
    grid, rates = track.smoothed_rates()
    offset = track.t[index] - t[:, None]
    halfway = track.t[index] - offset / 2
    return tuple(
        np.mean(values[index] - offset * np.interp(halfway, grid, rate), axis=1)
        for values, rate in zip((track.x, track.y, track.heading), rates.T, strict=True)
    )


def tick_poses(experiment: Experiment) -> TickPoses:
    """The poses of an experiment at its samples: the mean of the n nearest, moved to each.

    Parameters
    ----------
    experiment : Experiment
        With poses (:attr:`~bayes_jackal.io.Experiment.pose`).

    Returns
    -------
    TickPoses

    Raises
    ------
    DataError
        As :func:`pose_samples`: no poses, or too few of them.

    Examples
    --------
    Poses at 360 Hz, starting at a phase of their own, of a straight run at
    0.3 m/s sampled at 72 Hz: each sample averages the 5 poses it owns, and
    their offsets are undone exactly on a straight line:

    >>> import numpy as np
    >>> from bayes_jackal.io import Experiment
    >>> from bayes_jackal.io import tick_poses
    >>> from bayes_jackal.io import PoseTrack
    >>> t = np.arange(720) / 72
    >>> s = np.arange(-2, 3602) / 360 + 0.0011
    >>> pose = PoseTrack(s, 0.3 * s, np.zeros_like(s), np.zeros_like(s))
    >>> run = Experiment(t=t, yaw_rate=0 * t, omega_r=3 + 0 * t, omega_l=3 + 0 * t,
    ...                  vx=0.3 + 0 * t, vy=0 * t, pose=pose)
    >>> ticks = tick_poses(run)
    >>> ticks.samples, ticks.borrowed, bool(np.allclose(ticks.x, 0.3 * t))
    (5, 0, True)
    """
    ticks = _TICKS.get(experiment)
    if ticks is None:
        samples, borrowed = pose_samples(experiment)
        x, y, heading = _moved_means(experiment.pose, experiment.t, samples)
        for values in (x, y, heading):
            values.flags.writeable = False  # shared by every caller: read-only
        ticks = _TICKS[experiment] = TickPoses(x, y, heading, samples=samples, borrowed=borrowed)
    return ticks


#: Each experiment's :func:`tick_poses`, while it lives: the state estimation's
#: filters take them once per prior draw (128 times a run on the demo's, 40 %
#: of the filters' time when each call moved the poses anew). An experiment
#: is immutable and hashed by identity.
_TICKS: weakref.WeakKeyDictionary[Experiment, TickPoses] = weakref.WeakKeyDictionary()


def pose_samples(experiment: Experiment) -> tuple[int, int]:
    """n, the recorded poses each sample averages, and how many samples borrow (own fewer).

    n is the most that all but :data:`BORROW_FRACTION` of the samples own
    (the poses within half a step of them).

    Raises
    ------
    DataError
        Naming the file: the experiment has no poses; a sample has no pose
        within one step (the poses do not cover the samples); or more than
        :data:`BORROW_FRACTION` of the samples own no pose (poses slower than
        the samples, or dropping out often): their noise would be shared
        with a neighbour's, which the model's white pose noise is not.

    Examples
    --------
    Poses at 50 Hz are too slow for a 72 Hz IMU:

    >>> import numpy as np
    >>> from bayes_jackal.io import Experiment
    >>> from bayes_jackal.io import pose_samples
    >>> from bayes_jackal.io import PoseTrack
    >>> t, s = np.arange(720) / 72, np.arange(-1, 502) / 50
    >>> pose = PoseTrack(s, 0.3 * s, 0 * s, 0 * s)
    >>> run = Experiment(t=t, yaw_rate=0 * t, omega_r=3 + 0 * t, omega_l=3 + 0 * t,
    ...                  vx=0.3 + 0 * t, vy=0 * t, pose=pose, source="run.bag")
    >>> try:
    ...     pose_samples(run)
    ... except ValueError as error:
    ...     print(error)
    run.bag: pose: 220 of 720 samples (31 %) own no pose within half a step: the poses (50
    Hz) are slower than the samples (72 Hz), and the state-estimation filters need a pose of
    each sample's own (the likelihood takes the poses at their own stamps; the filters take
    --channels yaw)
    """
    track, t, dt = _track(experiment), experiment.t, experiment.dt
    far = np.flatnonzero(~_near_samples(track.t, t, dt))
    if far.size:
        raise DataError(
            f"no pose within one step ({dt:.4g} s) of the sample at {t[far[0]]:.6g} s "
            f"({far.size} such samples; the poses span {track.t[0]:.6g}..{track.t[-1]:.6g} s)",
            source=experiment.source,
            field="pose",
        )
    counts = _owned_counts(track.t, t, dt)
    samples = int(np.quantile(counts, BORROW_FRACTION, method="lower"))
    if samples == 0:
        alone = int(np.sum(counts == 0))
        why = (
            f"the poses ({track.rate:.4g} Hz) are slower than the samples ({1 / dt:.4g} Hz)"
            if track.rate < (1 - BORROW_FRACTION) / dt
            else f"the poses ({track.rate:.4g} Hz) drop out or jitter off the samples' ticks"
        )
        raise DataError(
            f"{alone} of {len(t)} samples ({100 * alone / len(t):.0f} %) own no pose within "
            f"half a step: {why}, and the state-estimation filters need a pose of each "
            "sample's own (the likelihood takes the poses at their own stamps; the filters "
            "take --channels yaw)",
            source=experiment.source,
            field="pose",
        )
    return samples, int(np.sum(counts < samples))


def _nearest_poses(stamps: np.ndarray, t: np.ndarray, n: int) -> np.ndarray:
    """Indices of the n stamps nearest each time t, shape (len(t), n) (n <= len(stamps)).

    In sorted stamps the n nearest are contiguous, among the n on each side
    of t's insertion point.
    """
    insertion = np.searchsorted(stamps, t)
    start = np.clip(insertion - n, 0, len(stamps) - 2 * n if len(stamps) >= 2 * n else 0)
    window = start[:, None] + np.arange(min(2 * n, len(stamps)))
    distance = np.abs(stamps[window] - t[:, None])
    chosen = np.argsort(distance, axis=1, kind="stable")[:, :n]
    return np.sort(np.take_along_axis(window, chosen, axis=1), axis=1)


def body_increments(ticks: TickPoses, channel: str) -> np.ndarray:
    """M_k: the displacement over each step along a body axis [m], shape (N - 1,).

    Parameters
    ----------
    ticks : TickPoses
        The poses at the samples (:func:`tick_poses`).
    channel : {"vx", "vy"}
        The body axis: longitudinal (vx) or lateral (vy).

    Examples
    --------
    Driving sideways (at heading pi/2, along world y) is longitudinal motion:

    >>> import numpy as np
    >>> from bayes_jackal.io import TickPoses, body_increments
    >>> ticks = TickPoses(np.zeros(4), 0.01 * np.arange(4), np.full(4, np.pi / 2), 1, 0)
    >>> body_increments(ticks, "vx").round(6).tolist(), body_increments(ticks, "vy").round(6)
    ([0.01, 0.01, 0.01], array([0., 0., 0.]))
    """
    if channel not in POSE_CHANNELS:
        raise DataError(f"poses record {POSE_CHANNELS}, not {channel!r}", field="channel")
    heading = 0.5 * (ticks.heading[1:] + ticks.heading[:-1])
    dx, dy = np.diff(ticks.x), np.diff(ticks.y)
    if channel == "vx":
        return np.cos(heading) * dx + np.sin(heading) * dy
    return -np.sin(heading) * dx + np.cos(heading) * dy


def body_displacement(ticks: TickPoses, channel: str) -> np.ndarray:
    """Q_k = M_0 + .. + M_(k-1): the body-frame travel along one axis since the first sample [m].

    The measurement the filters take for a pose channel: Q_k = q_k + e_k -
    e_0, the true travel q_k plus the pose noise of sample k (and of the
    first sample, a constant), so a state q' = q - e_0 is measured with white
    noise (:mod:`bayes_jackal.filters.state_space`).

    Parameters
    ----------
    ticks : TickPoses
    channel : {"vx", "vy"}

    Returns
    -------
    ndarray, shape (N,)

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.io import TickPoses, body_displacement
    >>> ticks = TickPoses(0.01 * np.arange(4), np.zeros(4), np.zeros(4), 1, 0)
    >>> body_displacement(ticks, "vx").round(6).tolist()
    [0.0, 0.01, 0.02, 0.03]
    """
    return np.concatenate([[0.0], np.cumsum(body_increments(ticks, channel))])
