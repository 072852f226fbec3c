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

:mod:`bayes_jackal.likelihood.measurements` relates M_k to the model's state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._runtime.errors import DataError
from .experiment import POSE_CHANNELS, Experiment

__all__ = [
    "BORROW_FRACTION",
    "TickPoses",
    "body_displacement",
    "body_increments",
    "pose_samples",
    "tick_poses",
]

#: Samples per pose at the most that may own fewer than the n poses each
#: sample takes (they borrow): n is the largest count that all but this
#: fraction of the samples own.
BORROW_FRACTION = 0.01


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
    track, t = experiment.pose, experiment.t
    samples, borrowed = pose_samples(experiment)
    index = _nearest_poses(track.t, t, samples)
    grid, rates = track.smoothed_rates()
    offset = track.t[index] - t[:, None]
    # Each pose moved by its offset times the rate halfway between its stamp
    # and the sample: exact to the offset^3 times the rate's curvature.
    halfway = track.t[index] - offset / 2
    moved = [
        np.mean(values[index] - offset * np.interp(halfway, grid, rate), axis=1)
        for values, rate in zip((track.x, track.y, track.heading), rates.T, strict=True)
    ]
    return TickPoses(*moved, samples=samples, borrowed=borrowed)


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
    Hz) are slower than the samples (72 Hz) or drop out too often, and the pose channels need
    a pose of each sample's own (--channels yaw leaves them out)
    """
    track = experiment.pose
    if track is None:
        raise DataError("the experiment holds no poses", source=experiment.source, field="pose")
    t, dt = experiment.t, experiment.dt
    nearest = _nearest_poses(track.t, t, 1)[:, 0]
    far = np.flatnonzero(np.abs(track.t[nearest] - t) > dt)
    if far.size:
        raise DataError(
            f"no pose within one step ({dt:.4g} s) of the sample at {t[far[0]]:.6g} s "
            f"({far.size} such samples; the poses span {track.t[0]:.6g}..{track.t[-1]:.6g} s)",
            source=experiment.source,
            field="pose",
        )
    owners = np.rint((track.t - t[0]) / dt).astype(int)
    counts = np.bincount(owners[(owners >= 0) & (owners < len(t))], minlength=len(t))
    samples = int(np.quantile(counts, BORROW_FRACTION, method="lower"))
    if samples == 0:
        alone = int(np.sum(counts == 0))
        raise DataError(
            f"{alone} of {len(t)} samples ({100 * alone / len(t):.0f} %) own no pose within "
            f"half a step: the poses ({track.rate:.4g} Hz) are slower than the samples "
            f"({1 / dt:.4g} Hz) or drop out too often, and the pose channels need a pose of "
            "each sample's own (--channels yaw leaves them out)",
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
