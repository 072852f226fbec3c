"""Lab logs of skid-steer robots, simulated independently of the package.

The witness for calibration tests on data the package did not generate:
logs as labs record them, with sensors on their own clocks, dropouts, poses
slower than the IMU, command steps and their transients, and damping that
may depend on the speed. Nothing here comes from bayes_jackal; the model,
kernel and ROS1 messages are tests/mocap_simulator.py's (also independent
of the package), the robots' constants models/jackal.toml's and
models/husky.toml's (tomllib).

Manoeuvres (:class:`Manoeuvre`, commands (v [m/s], w [rad/s]) of time in
segments): :func:`thesis_circle` (rest, ramp, hold, ramp down, rest),
:func:`step_sequence` (DRIVE-like: 2 s rest, steps of 6 s with (v, w) uniform
within limits, some v or w zero, changing instantly, 2 s rest),
:func:`steady_circles`, :func:`figure_eight` and :func:`spot_rotation`.
:func:`simulate` makes a run's truth; :func:`write_lab_bag` (motion-capture
ROS1 bag, with pose dropouts; :func:`truncate_bag` cuts one as a crashed
recorder does), :func:`write_sparse_csv` (IMU and pose rows at their own
stamps) and :func:`write_drive_table` (a DRIVE-like table, Baril et al.,
ICRA 2024: a row per 20 Hz logger tick, held or sparse ICP cells) write it;
:func:`write_drive_run` is a Husky DRIVE run in one call.

The truth is eq. 4-32: dx/dt = A x + B u + xi(t), x = (vx, vy, r), u =
(omega_r, omega_l) from the command by ROS diff_drive (the profile's
wheel_separation and multiplier), A = diag(-4 d_long / m, -4 d_lat / m,
-(4 / I)(b^2 d_long + a^2 d_lat)). The force xi is white noise convolved with
a Gaussian kernel of width sigma_h (autocorrelation exp(-tau^2 / (4
sigma_h^2)), cut at 5 sigma_h: 1e-12 of its energy left out). Exact:

* the integration. Force, input and damping are held over each fine step
  h = dt / fine, fine = max(20, ceil(5 dt / sigma_h)) per model step dt
  (h = 0.69 ms at 72 Hz, 2.5 ms at 20 Hz), and each fine step is the closed
  form of the diagonal model. After a burn-in from rest of 10 time constants
  (>= 3 s) the state keeps e^-20 of its variance deficit.
* the noise scale. The force's sd is set so that the model-clock residual
  w[k] = x(t_{k+1}) - Ad x(t_k) - Bd u_k has sd sigma_c at the reference
  damping (mocap_simulator.unit_residual_variance), exactly for this process.
* speed-dependent damping (:class:`SpeedLaw`): log d(v) = log d_ref +
  slope (v - v_ref) per segment, v its |v_cmd|. The poles and B change at
  the segment's edges (on model ticks), the state carries over, the force's
  sd stays the reference's: Segments.sigma_c is w[k]'s sd per segment.
* wheel speeds: the command at the fine grid's points, held (a ramp is a
  staircase of h: <= 0.015 rad/s off the line in the DRIVE circles' ramps).

Approximations, against the continuous-time model with a smooth force:
holding the force over h departs from it by O((h / sigma_h)^2), 2e-4 at
the Jackal's 72 Hz and 47 ms, 6e-4 at DRIVE's 20 Hz and 0.1 s. The pose is
the trapezoid integral of the true velocities on the fine grid, within
1e-5 m and rad of Simpson's rule over a 244 s DRIVE run (1e-6 at 72 Hz),
and sensors off the fine grid interpolate it linearly, h^2 / 8 |x''| < 1e-5
m and 3e-5 rad: a thousand times below the 2 cm and 0.01 rad of the ICP,
below 1 % of 0.1 mm motion capture at 72 Hz. The damping jumps at a
segment's edge, a ramp belonging to the segment it leads to (a modelling
choice, not the physics of a speed that changes continuously). Where the
command varies within a model step (ramps, sines) eq. 4-32's residual does
not apply: ``LabRun.held`` marks the steps where it does.

Time bases: bag header stamps count from mocap_simulator.EPOCH_NS (Nov
2023) and the first IMU stamp is time zero; the sparse CSV's t counts from
its first IMU row; the DRIVE table's ros_time is ``epoch`` + the time from
its first row, run-relative by default (an epoch of 1.7e9 keeps its
microseconds with %.6f, and bayes_jackal's read_csv reads it at 20 Hz as
it reads the run-relative table). The truth's times count from the log's
time zero; the run time of that zero is truth["origin"] (within 1 ms of
the manoeuvre's start).

DRIVE-like truth (HUSKY_DRIVE): d_lat = 306, d_long = 84 N s/m (the
Jackal's 110 / 30 times the mass ratio 2.786), sigma_h = 0.1 s and sigma_c =
(0.02, 0.01, 0.02): over a 40-step sequence the process noise moves vx by
~10 % and r by ~8 % of their spread across the steps (0.51 m/s, 0.30 rad/s).
"""

from __future__ import annotations

import csv
import functools
import itertools
import math
import os
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import scipy.signal
from mocap_simulator import (
    CMD_RATE,
    DROP_FRACTION,
    EPOCH_NS,
    IMU_JITTER,
    JOINT_JITTER,
    JOINT_RATE,
    POSE_JITTER,
    STATE,
    TOPICS,
    WHEEL_SPLIT,
    command_profile,
    free_clock,
    gaussian_kernel,
    imu_message,
    interp_columns,
    joint_message,
    model_matrices,
    pose_message,
    received,
    twist_message,
    unit_residual_variance,
    wheel_speeds,
    write_ros1,
)
from scipy.integrate import cumulative_trapezoid

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

#: The robot profiles (models/<name>.toml), read as plain dicts.
ROBOTS = {
    name: tomllib.loads((Path(__file__).parents[1] / "models" / f"{name}.toml").read_text())
    for name in ("jackal", "husky")
}
#: A time within EDGE [s] before a segment's edge belongs to the next segment,
#: so the fine grid's rounding (~1e-13 s) puts no sample on the wrong side.
EDGE = 1e-9
#: Pose sensors of the bags and sparse tables: rate [Hz], position sd [m], heading sd [rad].
POSE_PRESETS = {
    "mocap": {"pose_rate": 360.0, "pose_sd": 5e-4, "heading_sd": 2e-3},
    "slow": {"pose_rate": 10.0, "pose_sd": 0.02, "heading_sd": 0.01},
}
#: Columns of the sparse-row table (write_sparse_csv) and the role each holds.
SPARSE_ROLES = {
    "t": "t",
    "yaw_rate": "gyro_z",
    "omega_r": "wheel_right",
    "omega_l": "wheel_left",
    "x": "pos_x",
    "y": "pos_y",
    "heading": "yaw",
}
#: Columns of the DRIVE-like table (write_drive_table), in file order.
DRIVE_COLUMNS = (
    "ros_time",
    "imu_wz",
    "cmd_left_vel",
    "cmd_right_vel",
    "meas_left_vel",
    "meas_right_vel",
    "icp_x",
    "icp_y",
    "icp_yaw",
    "calib_step",
)
#: The roles of the DRIVE-like table's columns (the encoders as the wheel speeds).
DRIVE_ROLES = {
    "t": "ros_time",
    "yaw_rate": "imu_wz",
    "omega_r": "meas_right_vel",
    "omega_l": "meas_left_vel",
    "x": "icp_x",
    "y": "icp_y",
    "heading": "icp_yaw",
}
#: Every column's role as a user maps them: with the commanded wheel speeds and
#: the step label, which give the runs' segments.
DRIVE_ALL_ROLES = {
    **DRIVE_ROLES,
    "cmd_omega_r": "cmd_right_vel",
    "cmd_omega_l": "cmd_left_vel",
    "segment": "calib_step",
}
#: The DRIVE-like truth of the Husky: the Jackal's thesis damping (110, 30 N s/m)
#: scaled by the mass ratio 46.034 / 16.523 = 2.786, a smooth force, and process
#: noise of ~10 % of the spread of vx and r over a step sequence (module docstring).
HUSKY_DRIVE = {"d_lat": 306.0, "d_long": 84.0, "sigma_h": 0.1, "sigma_c": (0.02, 0.01, 0.02)}
#: DRIVE-like logger: rate [Hz] (the model clock), encoder and ICP rates [Hz], stamp jitter [s].
DRIVE_RATE, ENCODER_RATE, ICP_RATE, DRIVE_JITTER = 20.0, 4.0, 5.0, 1e-3
#: Limits of the step commands |v| [m/s], |w| [rad/s] (the Husky's top speed is 1 m/s).
DRIVE_LIMITS = {"v_max": 1.0, "w_max": 1.0}
#: Steady circles (v [m/s], w [rad/s]) of DRIVE-like runs, spanning the step commands' range.
DRIVE_CIRCLES = ((0.25, 0.5), (0.5, -0.8), (0.75, 0.3), (1.0, -0.6))


# Manoeuvres ------------------------------------------------------------------


@dataclass(frozen=True)
class Manoeuvre:
    """A command (v [m/s], w [rad/s]) of time, in segments of constant damping.

    A segment begins where the command starts moving to its level (a ramp
    belongs to the segment it leads to); every manoeuvre starts and ends at rest.

    Attributes
    ----------
    name : str
        What it is ("step sequence", ...).
    edges : np.ndarray
        Segment edges [s], 0 to the duration, shape (S + 1,).
    levels : np.ndarray
        Held (v, w) of each segment, zero at rest, shape (S, 2); the
        figure-8's is (v, w0), its w the amplitude of a sine.
    step : np.ndarray
        Step (circle, turn) index of each segment, -1 at rest, shape (S,).
    shape : callable
        Times [s], shape (N,), to commands (v, w), shape (N, 2).
    """

    name: str
    edges: np.ndarray
    levels: np.ndarray
    step: np.ndarray
    shape: Callable[[np.ndarray], np.ndarray]

    @property
    def duration(self) -> float:
        return float(self.edges[-1])

    @property
    def speed(self) -> np.ndarray:
        """|v| [m/s] of each segment's level, the speed of the damping's law."""
        return np.abs(self.levels[:, 0])

    def segment(self, t: np.ndarray) -> np.ndarray:
        """Segment index at times t [s]: the first before the start, the last after the end."""
        return _segment_of(self.edges, t)

    def command(self, t: np.ndarray) -> np.ndarray:
        """(v [m/s], w [rad/s]) at times t [s], shape (N, 2); zero before and after the run."""
        return self.shape(np.atleast_1d(np.asarray(t, float)))


def _segment_of(edges: np.ndarray, t: np.ndarray) -> np.ndarray:
    index = np.searchsorted(edges, np.asarray(t, float) + EDGE, side="right") - 1
    return np.clip(index, 0, len(edges) - 2)


def _held_shape(t: np.ndarray, edges: np.ndarray, levels: np.ndarray) -> np.ndarray:
    return levels[_segment_of(edges, t)]


def _ramped_shape(t: np.ndarray, knots: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, knots, column) for column in values.T])


def _figure_shape(t, v, w0, period, start, knots) -> np.ndarray:
    level = np.interp(t, knots, [0.0, 0.0, 1.0, 1.0, 0.0, 0.0])
    return level[:, None] * np.column_stack(
        [np.full_like(t, v), w0 * np.sin(2 * np.pi * (t - start) / period)]
    )


def thesis_circle(v: float = 0.3, w: float = 0.3927, duration: float = 38.0) -> Manoeuvre:
    """Manoeuvre 1, mocap_simulator.command_profile: 1 s rest, 1 s ramp, hold, ramp down, rest."""
    return Manoeuvre(
        "thesis circle",
        edges=np.array([0.0, 1.0, duration - 2.0, duration]),
        levels=np.array([[0.0, 0.0], [v, w], [0.0, 0.0]]),
        step=np.array([-1, 0, -1]),
        shape=functools.partial(command_profile, v=v, w=w, duration=duration),
    )


def step_sequence(
    rng: np.random.Generator | int,
    n_steps: int = 40,
    *,
    step_duration: float = 6.0,
    rest: float = 2.0,
    v_max: float = 1.0,
    w_max: float = 1.0,
    p_zero: float = 0.1,
) -> Manoeuvre:
    """Manoeuvre 2, DRIVE-like: rest, ``n_steps`` held commands changing instantly, rest.

    Each step's v and w are uniform in [-v_max, v_max] and [-w_max, w_max];
    each is then set to zero with probability ``p_zero`` (independently).
    """
    rng = np.random.default_rng(rng)
    draws = rng.uniform(-1.0, 1.0, (n_steps, 2)) * [v_max, w_max]
    draws[rng.random((n_steps, 2)) < p_zero] = 0.0
    edges = np.r_[
        0.0, rest + step_duration * np.arange(n_steps + 1), 2 * rest + step_duration * n_steps
    ]
    levels = np.vstack([np.zeros(2), draws, np.zeros(2)])
    return Manoeuvre(
        "step sequence",
        edges=edges,
        levels=levels,
        step=np.r_[-1, np.arange(n_steps), -1],
        shape=functools.partial(_held_shape, edges=edges, levels=levels),
    )


def steady_circles(
    levels: Sequence[tuple[float, float]] = DRIVE_CIRCLES,
    duration: float = 244.0,
    *,
    rest: float = 2.0,
    ramp: float = 1.0,
) -> Manoeuvre:
    """Circles at ``levels`` (v, w) sharing ``duration`` less two rests, each entered by a ramp.

    The first ramp starts from rest, the others from the previous circle; the
    ramp down to rest is the final rest's first ``ramp`` seconds.
    """
    hold = (duration - 2 * rest) / len(levels)
    starts = rest + hold * np.arange(len(levels) + 1)
    values = np.asarray(levels, float)
    knots = np.r_[0.0, np.column_stack([starts, starts + ramp]).ravel(), duration]
    knot_values = np.vstack([np.zeros((2, 2)), np.repeat(values, 2, axis=0), np.zeros((2, 2))])
    return Manoeuvre(
        "steady circles",
        edges=np.r_[0.0, starts, duration],
        levels=np.vstack([np.zeros(2), values, np.zeros(2)]),
        step=np.r_[-1, np.arange(len(levels)), -1],
        shape=functools.partial(_ramped_shape, knots=knots, values=knot_values),
    )


def figure_eight(
    v: float = 0.3,
    w0: float = 0.6,
    *,
    period: float = 20.0,
    hold: float = 40.0,
    ramp: float = 1.0,
    rest: float = 1.0,
) -> Manoeuvre:
    """Manoeuvre 3: v held for ``hold`` s after a ramp, w = w0 sin(2 pi (t - rest) / period).

    Both v and w are scaled by the same ramps (1 s up after a rest, 1 s down
    before one), so w starts and ends at zero.
    """
    knots = np.cumsum([0.0, rest, ramp, hold, ramp, rest])
    return Manoeuvre(
        "figure-8",
        edges=knots[[0, 1, 3, 5]],
        levels=np.array([[0.0, 0.0], [v, w0], [0.0, 0.0]]),
        step=np.array([-1, 0, -1]),
        shape=functools.partial(_figure_shape, v=v, w0=w0, period=period, start=rest, knots=knots),
    )


def spot_rotation(
    w0: float = 0.8,
    *,
    turn: float = 5.0,
    repeats: int = 2,
    ramp: float = 0.5,
    rest: float = 1.0,
) -> Manoeuvre:
    """Manoeuvre 4: v = 0 and w = +w0 for ``turn`` s, then -w0, ``repeats`` times.

    Each turn ramps up and down in ``ramp`` s and is followed by ``rest`` s at rest.
    """
    signs = np.tile([1.0, -1.0], repeats)
    period = 2 * ramp + turn + rest
    starts = rest + period * np.arange(len(signs))
    corners = starts[:, None] + np.array([0.0, ramp, ramp + turn, 2 * ramp + turn])
    knots = np.r_[0.0, corners.ravel(), starts[-1] + period]
    w = np.r_[0.0, (signs[:, None] * w0 * np.array([0.0, 1.0, 1.0, 0.0])).ravel(), 0.0]
    edges = np.r_[0.0, np.column_stack([starts, starts + ramp + turn]).ravel(), knots[-1]]
    levels = np.zeros((len(edges) - 1, 2))
    levels[1::2, 1] = signs * w0
    step = np.full(len(levels), -1)
    step[1::2] = np.arange(len(signs))
    return Manoeuvre(
        "spot rotation",
        edges=edges,
        levels=levels,
        step=step,
        shape=functools.partial(_ramped_shape, knots=knots, values=np.column_stack([0 * w, w])),
    )


# The truth ---------------------------------------------------------------------


@dataclass(frozen=True)
class SpeedLaw:
    """log d(v) = log d_ref + slope (v - v_ref) for d_lat and d_long; v a segment's |v| [m/s].

    d_ref are the damping given to :func:`simulate` (d_lat, d_long) and slope [s/m].
    """

    v_ref: float
    slope_lat: float
    slope_long: float

    @classmethod
    def from_ratio(
        cls, ratio: float = 1.5, v_min: float = 0.0, v_max: float = 1.0, v_ref: float | None = None
    ) -> SpeedLaw:
        """Both dampings ``ratio`` times higher at v_max than at v_min; v_ref by default midway."""
        slope = math.log(ratio) / (v_max - v_min)
        return cls((v_min + v_max) / 2 if v_ref is None else v_ref, slope, slope)

    def damping(self, d_lat: float, d_long: float, speed: np.ndarray) -> np.ndarray:
        """(d_lat, d_long) [N s/m] at speeds |v| [m/s], shape (S, 2)."""
        offset = np.abs(np.asarray(speed, float))[:, None] - self.v_ref
        return np.array([d_lat, d_long]) * np.exp(offset * [self.slope_lat, self.slope_long])


@dataclass(frozen=True)
class Segments:
    """The manoeuvre's segments of constant damping and held command, with their truth.

    Attributes
    ----------
    start, end : np.ndarray
        Edges [s] of each segment, shape (S,), in the log's time (run time before a writer).
    step : np.ndarray
        Step (circle, turn) index, -1 at rest, shape (S,).
    v, w : np.ndarray
        The held command [m/s, rad/s] (the figure-8's w: the sine's amplitude).
    speed : np.ndarray
        |v| [m/s], at which the damping's speed law is taken.
    d_lat, d_long : np.ndarray
        Damping [N s/m] of each segment.
    sigma_c : np.ndarray
        Sd of the model-clock residual w[k] at the segment's damping, shape (S, 3):
        the force's sd is the same in all, so these differ where the damping does.
    """

    start: np.ndarray
    end: np.ndarray
    step: np.ndarray
    v: np.ndarray
    w: np.ndarray
    speed: np.ndarray
    d_lat: np.ndarray
    d_long: np.ndarray
    sigma_c: np.ndarray


@dataclass(frozen=True)
class Simulation:
    """One run's truth on the fine grid and at the model clock, in run time [s].

    Attributes
    ----------
    robot : dict
        The profile (models/<name>.toml).
    manoeuvre : Manoeuvre
        The command.
    truth : dict
        Parameters (see :class:`LabRun`).
    segments : Segments
        Per-segment damping, commands and residual sds.
    t : np.ndarray
        The fine grid [s], shape (n,), burn-in (t < 0) included.
    u : np.ndarray
        True wheel speeds (omega_r, omega_l) [rad/s] held over each fine step, shape (n, 2).
    x : np.ndarray
        True states (vx, vy, r), shape (n, 3).
    pose : np.ndarray
        True (X [m], Y [m], psi [rad], unwrapped), shape (n, 3).
    wheels, angles : np.ndarray
        Speeds [rad/s] (held) and angles [rad] of the four wheels in WHEELS order, shape (n, 4).
    ticks : np.ndarray
        Fine index of each model-clock sample k / rate, k = 0..K, shape (K + 1,).
    held : np.ndarray
        Whether the input and damping are constant over model step k, shape (K,).
    """

    robot: dict
    manoeuvre: Manoeuvre
    truth: dict
    segments: Segments
    t: np.ndarray
    u: np.ndarray
    x: np.ndarray
    pose: np.ndarray
    wheels: np.ndarray
    angles: np.ndarray
    ticks: np.ndarray
    held: np.ndarray

    def at(self, t: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Columns of fine-grid ``values`` linearly interpolated at times t [s]."""
        return interp_columns(t, self.t, values)

    def held_at(self, t: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Rows of fine-grid ``values`` held over each fine step, at times t [s]."""
        return values[np.searchsorted(self.t, np.asarray(t) + EDGE, side="right") - 1]


def _profile(robot: str | dict) -> dict:
    return ROBOTS[robot] if isinstance(robot, str) else robot


def _check_on_clock(manoeuvre: Manoeuvre, rate: float) -> None:
    ticks = manoeuvre.edges * rate
    if np.any(np.abs(ticks - np.round(ticks)) > 1e-6):
        raise ValueError(f"segment edges {manoeuvre.edges} are not on the {rate} Hz model clock")


def _matrices(robot: dict, damping: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poles (S, 3) and B (S, 3, 2) of each segment's (d_lat, d_long)."""
    pairs = [model_matrices(d_lat, d_long, robot) for d_lat, d_long in damping]
    return np.array([p for p, _ in pairs]), np.array([b for _, b in pairs])


def _propagate(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """x[0] = 0 and x[n+1] = p[n] x[n] + q[n] per column, p constant over runs of rows."""
    x = np.zeros_like(q)
    changes = np.flatnonzero(np.any(p[1:] != p[:-1], axis=1)) + 1
    edges = np.unique(np.r_[0, changes, len(q) - 1])
    for lo, hi in itertools.pairwise(edges):
        for c in range(q.shape[1]):
            zi = [p[lo, c] * x[lo, c]]  # lfilter's y[0] = q[lo] + zi = x[lo + 1]
            x[lo + 1 : hi + 1, c] = scipy.signal.lfilter(
                [1.0], [1.0, -p[lo, c]], q[lo:hi, c], zi=zi
            )[0]
    return x


def _fine_grid(rate: float, sigma_h: float, slowest: float, duration: float):
    """(t, fine, burn, K): the fine grid, fine steps per model step, burn-in, model steps."""
    dt = 1.0 / rate
    # As mocap_simulator: >= 20 fine steps per model step and >= 5 per sigma_h.
    fine = max(20, math.ceil(5 * dt / sigma_h))
    # Burn-in of 10 time constants of the first segment's slowest channel
    # (>= 3 s), a whole number of model steps: tick k is fine sample burn + k fine.
    burn = fine * math.ceil(max(3.0, 10 / slowest) / dt)
    steps = round(duration * rate)
    t = dt / fine * (np.arange(burn + fine * (steps + 2)) - burn)
    return t, fine, burn, steps


def _force(rng, shape, g: np.ndarray, force_sd: np.ndarray) -> np.ndarray:
    """White noise convolved with the kernel g ('valid': no edge effects), scaled per channel."""
    white = rng.standard_normal((shape[0] + len(g) - 1, shape[1]))
    return force_sd * scipy.signal.fftconvolve(white, g[:, None], mode="valid", axes=0)


def _world(rng, t: np.ndarray, x: np.ndarray, burn: int) -> np.ndarray:
    """(X, Y, psi) by the trapezoid rule from a random pose at t = 0 (as mocap_simulator)."""
    start = rng.uniform([-1.0, -1.0, -np.pi], [1.0, 1.0, np.pi])
    psi = cumulative_trapezoid(x[:, 2], t, initial=0.0)
    psi += start[2] - psi[burn]
    cos, sin = np.cos(psi), np.sin(psi)
    world = np.column_stack([x[:, 0] * cos - x[:, 1] * sin, x[:, 0] * sin + x[:, 1] * cos])
    position = cumulative_trapezoid(world, t, axis=0, initial=0.0)
    return np.column_stack([position + start[:2] - position[burn], psi])


def _four_wheels(rng, t: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speeds and angles of the four wheels (WHEELS order), front and rear split as mocap's.

    The speeds are held over each fine step, so the angles' sums are exact.
    """
    split = WHEEL_SPLIT * np.sin(2 * np.pi * 0.4 * t[:, None] + rng.uniform(0, 2 * np.pi, 2))
    right, left = u[:, :1] + [1, -1] * split[:, :1], u[:, 1:] + [1, -1] * split[:, 1:]
    wheels = np.column_stack([left[:, 0], right[:, 0], left[:, 1], right[:, 1]])
    h = t[1] - t[0]
    angles = h * (np.cumsum(wheels, axis=0) - wheels) + rng.uniform(-np.pi, np.pi, 4)
    return wheels, angles


def _held_steps(u: np.ndarray, segment: np.ndarray, ticks: np.ndarray, fine: int) -> np.ndarray:
    """Model steps over which the input and the segment (the damping) do not change."""
    inputs = u[ticks[:-1, None] + np.arange(fine)]
    same = np.all(inputs == inputs[:, :1], axis=(1, 2))
    return same & (segment[ticks[:-1]] == segment[ticks[:-1] + fine - 1])


def _residuals(x, u, poles, B, ticks, dt) -> np.ndarray:
    """w[k] = x(t_{k+1}) - Ad x(t_k) - Bd u_k of all K steps, poles and B those at t_k."""
    Ad, gain = np.exp(poles * dt), np.expm1(poles * dt) / poles
    drive = gain * np.einsum("kij,kj->ki", B, u[ticks[:-1]])
    return x[ticks[1:]] - Ad * x[ticks[:-1]] - drive


def _segments(manoeuvre: Manoeuvre, damping: np.ndarray, sigma_c: np.ndarray) -> Segments:
    return Segments(
        start=manoeuvre.edges[:-1],
        end=manoeuvre.edges[1:],
        step=manoeuvre.step,
        v=manoeuvre.levels[:, 0],
        w=manoeuvre.levels[:, 1],
        speed=manoeuvre.speed,
        d_lat=damping[:, 0],
        d_long=damping[:, 1],
        sigma_c=sigma_c,
    )


def _law_truth(law: SpeedLaw | None) -> dict:
    if law is None:
        return {"v_ref": None, "slope": {"d_lat": 0.0, "d_long": 0.0}}
    return {"v_ref": law.v_ref, "slope": {"d_lat": law.slope_lat, "d_long": law.slope_long}}


def _channels(values) -> dict[str, float]:
    return {c: float(value) for c, value in zip(STATE, values, strict=True)}


def simulate(
    manoeuvre: Manoeuvre,
    *,
    robot: str | dict = "jackal",
    d_lat: float = 110.0,
    d_long: float = 30.0,
    sigma_h: float = 0.047,
    sigma_c: Sequence[float] = (0.005, 0.005, 0.01),
    rate: float | None = None,
    speed_law: SpeedLaw | None = None,
    rng: np.random.Generator | int,
) -> Simulation:
    """Simulate the model's truth for a manoeuvre on a fine grid.

    Parameters
    ----------
    manoeuvre : Manoeuvre
        The command; its segment edges must lie on the model clock.
    robot : str or dict
        "jackal", "husky" or a profile dict.
    d_lat, d_long : float
        Damping [N s/m]; with a speed law, at its v_ref.
    sigma_h : float
        Width of the Gaussian kernel [s].
    sigma_c : sequence of float
        Sd of the model-clock residual (vx [m/s], vy [m/s], yaw [rad/s]) at (d_lat, d_long).
    rate : float, optional
        Model clock [Hz] (the IMU's, or a table logger's); the profile's [sampling] rate if None.
    speed_law : SpeedLaw, optional
        Speed-dependent damping per segment; constant damping if None.
    rng : numpy.random.Generator or int
        Source of the force, the initial pose and the wheels' split.

    Returns
    -------
    Simulation
        The fine-grid truth; truth["sigma_c_realised"] is the sd of w[k] over
        the held model steps, each step's rescaled to the reference damping
        by sigma_c / Segments.sigma_c (no rescaling without a speed law).
    """
    rng, robot = np.random.default_rng(rng), _profile(robot)
    rate = float(robot["sampling"]["rate"] if rate is None else rate)
    _check_on_clock(manoeuvre, rate)
    damping = np.tile([d_lat, d_long], (len(manoeuvre.step), 1))
    if speed_law is not None:
        damping = speed_law.damping(d_lat, d_long, manoeuvre.speed)
    poles, B = _matrices(robot, damping)
    t, fine, burn, steps = _fine_grid(rate, sigma_h, np.min(-poles[0]), manoeuvre.duration)
    h, segment, ticks = t[1] - t[0], manoeuvre.segment(t), burn + fine * np.arange(steps + 1)
    g = gaussian_kernel(sigma_h, h)
    reference = model_matrices(d_lat, d_long, robot)[0]
    force_sd = np.asarray(sigma_c, float) / np.sqrt(unit_residual_variance(reference, g, h, fine))
    segment_sd = force_sd * np.sqrt([unit_residual_variance(p, g, h, fine) for p in poles])
    # Exact step of the diagonal model with u, xi and the damping held over
    # [t_n, t_n + h]: x[n+1] = e^{a h} x[n] + (e^{a h} - 1) / a (B u[n] + xi[n]).
    u = wheel_speeds(*manoeuvre.command(t).T, robot)
    xi = _force(rng, (len(t), 3), g, force_sd)
    a, Bu = poles[segment], np.einsum("nij,nj->ni", B[segment], u)
    x = _propagate(np.exp(a * h), np.expm1(a * h) / a * (Bu + xi))
    held, at = _held_steps(u, segment, ticks, fine), segment[ticks[:-1]]
    # The realised sd of w[k] over the held steps, each rescaled to the reference damping.
    residual = _residuals(x, u, poles[at], B[at], ticks, 1 / rate)[held]
    realised = np.std(residual / segment_sd[at[held]], axis=0) * sigma_c
    pose = _world(rng, t, x, burn)
    wheels, angles = _four_wheels(rng, t, u)
    truth = {"robot": robot["name"], "manoeuvre": manoeuvre.name, "duration": manoeuvre.duration}
    truth.update(d_lat=d_lat, d_long=d_long, **_law_truth(speed_law), sigma_h=sigma_h)
    truth.update(sigma_c=_channels(sigma_c), sigma_c_realised=_channels(realised))
    truth.update(force_sd=_channels(force_sd), rate=rate, fine=fine)
    segments = _segments(manoeuvre, damping, segment_sd)
    return Simulation(
        robot, manoeuvre, truth, segments, t, u, x, pose, wheels, angles, ticks, held
    )


# Logs --------------------------------------------------------------------------


@dataclass(frozen=True)
class LabRun:
    """A written log and its truth; times [s] count from the log's time zero.

    Attributes
    ----------
    path : Path
        The file written.
    truth : dict
        The simulation's: robot, manoeuvre, duration [s]; d_lat, d_long [N s/m]
        (at v_ref with a speed law); v_ref [m/s] (None without one); slope,
        {"d_lat", "d_long"} [s/m] (0 without); sigma_h [s]; sigma_c,
        sigma_c_realised and force_sd (dicts vx, vy [m/s, m/s^2], yaw [rad/s,
        rad/s^2]); rate, the model clock [Hz]; fine, fine steps per model step.
        Then origin, the run time [s] of the log's time zero, and the writer's
        rates, noise sds and counts (see each writer).
    t : np.ndarray
        True instants of the model clock (IMU or logger ticks, missing rows
        included), shape (K + 1,).
    states : np.ndarray
        True (vx [m/s], vy [m/s], r [rad/s]) at ``t``, shape (K + 1, 3).
    inputs : np.ndarray
        True wheel speeds (omega_r, omega_l) [rad/s] at ``t``, held over each
        fine step, shape (K + 1, 2).
    commands : np.ndarray
        Commanded (v [m/s], w [rad/s]) at ``t``, shape (K + 1, 2).
    segment : np.ndarray
        Index into ``segments`` of each sample, shape (K + 1,).
    held : np.ndarray
        Whether the input and the damping are constant over the step from
        t[k] to t[k + 1] (then w[k] is the residual of eq. 4-32), shape (K,).
    segments : Segments
        Per segment: edges, step index, command, damping and residual sd.
    pose_t, poses : np.ndarray
        True instants (P,) of the distinct poses in the log and the true
        (X [m], Y [m], psi [rad], unwrapped) there, shape (P, 3).
    wheel_t, wheels : np.ndarray
        True instants (M,) of the wheel-speed samples in the log and the true
        (omega_r, omega_l) [rad/s] there (the side's mean), shape (M, 2).
    """

    path: Path
    truth: dict
    t: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    commands: np.ndarray
    segment: np.ndarray
    held: np.ndarray
    segments: Segments
    pose_t: np.ndarray
    poses: np.ndarray
    wheel_t: np.ndarray
    wheels: np.ndarray


def _lab_run(path, sim: Simulation, origin: float, pose, wheel, **written) -> LabRun:
    """The LabRun of a log written from ``sim``: (instants, values) of its poses and wheels."""
    t = sim.t[sim.ticks]
    start, end = sim.segments.start - origin, sim.segments.end - origin
    return LabRun(
        path=Path(path),
        truth={**sim.truth, "origin": float(origin), **written},
        t=t - origin,
        states=sim.x[sim.ticks],
        inputs=sim.u[sim.ticks],
        commands=sim.manoeuvre.command(t),
        segment=sim.manoeuvre.segment(t),
        held=sim.held,
        segments=replace(sim.segments, start=start, end=end),
        pose_t=pose[0] - origin,
        poses=pose[1],
        wheel_t=wheel[0] - origin,
        wheels=wheel[1],
    )


def _pose_clock(rng, rate: float, duration: float, dropouts, drop: float = DROP_FRACTION):
    """(seq, true instants) of the poses published and received, and what was lost.

    None inside a dropout window (start [s], length [s]) in run time: the
    tracking is lost and nothing is published, so seq runs on. A fraction
    ``drop`` is lost in transport, which leaves gaps in seq.
    """
    instants = free_clock(rng, rate, duration)
    lost = np.zeros(len(instants), bool)
    for start, length in dropouts:
        lost |= (instants >= start) & (instants < start + length)
    instants = instants[~lost]
    seq = np.flatnonzero(rng.random(len(instants)) >= drop)
    counts = {"pose_in_dropouts": int(lost.sum()), "pose_dropped": len(instants) - len(seq)}
    return seq, instants[seq], counts


def _stamp_ns(rng, instants: np.ndarray, jitter: float) -> np.ndarray:
    """Header stamps [ns from EPOCH_NS's epoch] of true instants [s], with Gaussian jitter [s]."""
    noisy = instants + jitter * rng.standard_normal(len(instants))
    return EPOCH_NS + np.round(noisy * 1e9).astype(np.int64)


def _noisy_pose(rng, poses: np.ndarray, sd: float, heading_sd: float) -> np.ndarray:
    """Measured (X, Y, psi): white noise added, the heading wrapped to [-pi, pi)."""
    measured = poses + [sd, sd, heading_sd] * rng.standard_normal(poses.shape)
    measured[:, 2] = (measured[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return measured


def _topics(robot: dict) -> dict:
    """TOPICS with the robot's topic names (models/<name>.toml [topics])."""
    return {role: (robot["topics"][role], msgtype) for role, (_, msgtype) in TOPICS.items()}


def _bag_streams(rng, sim: Simulation, pose_rate: float, sds: dict, dropouts) -> tuple:
    """The bag's (stamps, messages) per role; the instants and truth of its poses and wheels."""
    duration = sim.manoeuvre.duration
    pose_seq, pose_true, counts = _pose_clock(rng, pose_rate, duration, dropouts)
    joint_true, cmd_true = (
        free_clock(rng, JOINT_RATE, duration),
        free_clock(rng, CMD_RATE, duration),
    )
    imu_stamp = _stamp_ns(rng, sim.t[sim.ticks], IMU_JITTER)
    pose_stamp = _stamp_ns(rng, pose_true, POSE_JITTER)
    joint_stamp = _stamp_ns(rng, joint_true, JOINT_JITTER)
    cmd_stamp = _stamp_ns(rng, cmd_true, 0.0)
    gyro = sim.x[sim.ticks, 2] + sds["gyro_sd"] * rng.standard_normal(len(imu_stamp))
    poses = sim.at(pose_true, sim.pose)
    measured = _noisy_pose(rng, poses, sds["pose_sd"], sds["heading_sd"])
    imu = zip(imu_stamp, sim.pose[sim.ticks, 2], gyro, strict=True)
    pose = zip(pose_seq, pose_stamp, measured, strict=True)
    angles, speeds = sim.at(joint_true, sim.angles), sim.held_at(joint_true, sim.wheels)
    joint = zip(joint_stamp, angles, speeds, strict=True)
    streams = {
        "imu": (imu_stamp, [imu_message(k, *row) for k, row in enumerate(imu)]),
        "pose": (pose_stamp, [pose_message(q, s, *xyz) for q, s, xyz in pose]),
        "joint_states": (joint_stamp, [joint_message(k, *row) for k, row in enumerate(joint)]),
        "cmd_vel": (cmd_stamp, [twist_message(v, w) for v, w in sim.manoeuvre.command(cmd_true)]),
    }
    origin = (int(imu_stamp[0]) - EPOCH_NS) * 1e-9  # the first IMU stamp is time zero
    sampled = (pose_true, poses), (joint_true, sim.held_at(joint_true, sim.u))
    return streams, origin, sampled, counts


def write_lab_bag(
    path: str | Path,
    sim: Simulation,
    *,
    pose_rate: float = 360.0,
    pose_sd: float = 5e-4,
    heading_sd: float = 2e-3,
    gyro_sd: float = 5e-3,
    pose_dropouts: Sequence[tuple[float, float]] = (),
    rng: np.random.Generator | int,
) -> LabRun:
    """Write a simulated run as a motion-capture ROS1 bag (A), as mocap_simulator does.

    The IMU (/imu/data) samples the model clock; the pose (the profile's
    topic), the wheels (/joint_states, 50 Hz) and the command (/cmd_vel,
    20 Hz) run on free clocks. Stamps are jittered (IMU 0.1 ms, pose 0.05 ms,
    wheels 0.1 ms) and received 1-3 ms late; 0.2 % of the poses are lost in
    transport and 0.5 % published twice. No pose is published inside the
    ``pose_dropouts`` windows (start, length) [s of run time]; the other
    topics go on. Time zero is the first IMU stamp.

    Parameters
    ----------
    path : str or Path
        The bag; it must not exist.
    sim : Simulation
        The truth (:func:`simulate`), its rate the IMU's.
    pose_rate, pose_sd, heading_sd : float
        Pose rate [Hz] and noise [m per axis, rad] (POSE_PRESETS: motion
        capture at 120-360 Hz and 0.1-1 mm, or 10 Hz, 2 cm and 0.01 rad).
    gyro_sd : float
        Gyro noise [rad/s].
    pose_dropouts : sequence of (float, float)
        Windows without poses.
    rng : numpy.random.Generator or int
        Source of the sensors' clocks, noise and losses.

    Returns
    -------
    LabRun
        truth also holds imu_rate, pose_rate, joint_rate, cmd_rate [Hz],
        pose_sd, heading_sd, gyro_sd, pose_dropouts, and the counts
        pose_in_dropouts, pose_dropped and pose_duplicates.
    """
    rng = np.random.default_rng(rng)
    sds = {"pose_sd": pose_sd, "heading_sd": heading_sd, "gyro_sd": gyro_sd}
    streams, origin, (pose, wheel), counts = _bag_streams(rng, sim, pose_rate, sds, pose_dropouts)
    rows, duplicates = received(rng, streams)
    write_ros1(Path(path), rows, _topics(sim.robot))
    rates = {"imu_rate": sim.truth["rate"], "pose_rate": pose_rate}
    rates.update(joint_rate=JOINT_RATE, cmd_rate=CMD_RATE)
    return _lab_run(
        path,
        sim,
        origin,
        pose,
        wheel,
        **rates,
        **sds,
        pose_dropouts=[tuple(map(float, window)) for window in pose_dropouts],
        **counts,
        pose_duplicates=duplicates,
    )


def truncate_bag(
    path: str | Path, fraction: float = 0.6, *, out: str | Path | None = None
) -> Path:
    """Cut a bag to ``fraction`` of its bytes, as a recorder that crashed leaves one.

    A ROS1 bag keeps its index at the end, so the cut bag has none and its
    last record stops mid-way. With ``out``, the bag is copied there first
    and the original kept. Returns the cut file.
    """
    size = Path(path).stat().st_size
    target = Path(path) if out is None else Path(shutil.copyfile(path, out))
    os.truncate(target, int(fraction * size))
    return target


# Tables ------------------------------------------------------------------------


def _kept_ticks(rng, n: int, missing: int) -> np.ndarray:
    """Indices of the n ticks written: all but ``missing`` single ticks, none at an end.

    One tick is drawn from the inside of each of ``missing`` equal blocks, so
    no two missing ticks are neighbours.
    """
    blocks = np.array_split(np.arange(1, n - 1), missing) if missing else []
    return np.setdiff1d(np.arange(n), [rng.choice(block[1:-1]) for block in blocks])


def _numbers(values) -> list[str]:
    """Cells of numbers: 9 significant digits, so a held value repeats exactly."""
    return [f"{value:.9g}" for value in values]


def _write_table(path: Path, header: Sequence[str], rows: list[list[str]]) -> None:
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        writer.writerows(rows)


def write_sparse_csv(
    path: str | Path,
    sim: Simulation,
    *,
    pose_rate: float = 120.0,
    pose_sd: float = 5e-4,
    heading_sd: float = 2e-3,
    gyro_sd: float = 5e-3,
    wheel_sd: float = 0.0,
    missing: int = 2,
    pose_dropouts: Sequence[tuple[float, float]] = (),
    rng: np.random.Generator | int,
) -> LabRun:
    """Write a simulated run as one CSV of IMU rows and pose rows at their own stamps (B).

    Columns (SPARSE_ROLES): t, gyro_z, wheel_right, wheel_left, pos_x, pos_y,
    yaw. An IMU row (a model-clock tick, stamp jittered by 0.1 ms) fills t,
    gyro_z [rad/s] and the wheel speeds [rad/s] (the truth at the tick, as
    the bag's joint states, plus white noise of sd ``wheel_sd``: what it
    does to the damping is tests/test_input_noise.py's) and leaves the pose
    cells empty; a pose row (its own clock, 0.05 ms of jitter) fills t,
    pos_x, pos_y [m] and yaw [rad, wrapped] and leaves the others empty.
    Rows in time order, t [s, 6 decimals] from the first IMU row's stamp;
    ``missing`` single IMU ticks are not written.

    Returns
    -------
    LabRun
        truth also holds imu_rate, pose_rate [Hz], pose_sd, heading_sd,
        gyro_sd, wheel_sd, pose_dropouts, pose_in_dropouts and missing_ticks
        (indices into ``t``).
    """
    rng = np.random.default_rng(rng)
    kept = _kept_ticks(rng, len(sim.ticks), missing)
    ticks = sim.ticks[kept]
    imu_stamp = sim.t[ticks] + IMU_JITTER * rng.standard_normal(len(ticks))
    duration = sim.manoeuvre.duration
    _, pose_true, counts = _pose_clock(rng, pose_rate, duration, pose_dropouts, drop=0.0)
    pose_stamp = pose_true + POSE_JITTER * rng.standard_normal(len(pose_true))
    gyro = sim.x[ticks, 2] + gyro_sd * rng.standard_normal(len(ticks))
    wheels = sim.u[ticks] + wheel_sd * rng.standard_normal((len(ticks), 2))
    poses = sim.at(pose_true, sim.pose)
    measured = _noisy_pose(rng, poses, pose_sd, heading_sd)
    origin = imu_stamp[0]
    rows = [
        (s, [*_numbers([g, *w]), "", "", ""])
        for s, g, w in zip(imu_stamp, gyro, wheels, strict=True)
    ]
    rows += [
        (s, ["", "", "", *_numbers(xyz)]) for s, xyz in zip(pose_stamp, measured, strict=True)
    ]
    rows.sort(key=lambda row: row[0])
    table = [[f"{s - origin:.6f}", *cells] for s, cells in rows]
    _write_table(Path(path), list(SPARSE_ROLES.values()), table)
    return _lab_run(
        path,
        sim,
        origin,
        (pose_true, poses),
        (sim.t[ticks], sim.u[ticks]),
        imu_rate=sim.truth["rate"],
        pose_rate=pose_rate,
        pose_sd=pose_sd,
        heading_sd=heading_sd,
        gyro_sd=gyro_sd,
        wheel_sd=wheel_sd,
        pose_dropouts=[tuple(map(float, window)) for window in pose_dropouts],
        pose_in_dropouts=counts["pose_in_dropouts"],
        missing_ticks=sorted(set(range(len(sim.ticks))) - set(kept.tolist())),
    )


def _lead_clock(rng, rate: float, duration: float, jitter: float):
    """True instants and stamps [s] of a driver started before the logger.

    Its first message comes 10 ms to a period + 10 ms before the logger's
    first tick (so a held cell always has a value), then one per period
    to the run's end; stamps carry Gaussian jitter.
    """
    first = -0.01 - rng.uniform(0, 1 / rate)
    instants = first + np.arange(math.floor((duration - first) * rate) + 1) / rate
    return instants, instants + jitter * rng.standard_normal(len(instants))


def _latest(stamps: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Index of the last of ``stamps`` at or before each of ``at`` (a held value)."""
    return np.searchsorted(stamps, at, side="right") - 1


def _drive_rows(layout: str, stamp, cells, step, icp_stamp, icp) -> tuple[list, np.ndarray]:
    """(stamp, cells but the time) of a DRIVE-like table's rows in time order; the ICP used.

    ``cells`` are the logger rows' imu and wheel columns, ``step`` their
    calib_step; the ICP cells are held from the last message (``"held"``) or
    get rows of their own (``"sparse"``, messages inside the logger's span).
    """
    if layout == "held":
        seen = _latest(icp_stamp, stamp)
        values = np.column_stack([cells, icp[seen]])
        rows = [(s, [*_numbers(v), str(k)]) for s, v, k in zip(stamp, values, step, strict=True)]
        return rows, seen
    seen = np.flatnonzero((icp_stamp >= stamp[0]) & (icp_stamp <= stamp[-1]))
    logger = [
        (s, [*_numbers(c), "", "", "", str(k)]) for s, c, k in zip(stamp, cells, step, strict=True)
    ]
    poses = [(icp_stamp[i], [""] * 5 + _numbers(icp[i]) + [""]) for i in seen]
    return sorted(logger + poses, key=lambda row: row[0]), seen


def write_drive_table(
    path: str | Path,
    sim: Simulation,
    *,
    icp_layout: str = "held",
    encoder_rate: float = ENCODER_RATE,
    icp_rate: float = ICP_RATE,
    jitter: float = DRIVE_JITTER,
    gyro_sd: float = 0.01,
    wheel_sd: float = 0.05,
    icp_sd: float = 0.02,
    icp_heading_sd: float = 0.01,
    missing: int = 2,
    epoch: float = 0.0,
    rng: np.random.Generator | int,
) -> LabRun:
    """Write a simulated run as a DRIVE-like calibration table (C): a row per logger tick.

    The logger ticks are the model clock (``sim``'s rate, 20 Hz in DRIVE), their
    stamps jittered by ``jitter``; ``missing`` single ticks are not written.
    Columns (DRIVE_COLUMNS): ros_time [s, 6 decimals, ``epoch`` + time from the
    first row's stamp]; imu_wz, the true yaw rate at the tick + ``gyro_sd``;
    cmd_left_vel, cmd_right_vel, the commanded (= true) wheel speeds [rad/s];
    meas_left_vel, meas_right_vel, encoders on their own clock
    (``encoder_rate``, jittered stamps): the true speed at the encoder's
    instant + ``wheel_sd``, held until the next encoder message; icp_x, icp_y
    [m], icp_yaw [rad, wrapped], ICP poses on their own clock (``icp_rate``)
    with noise ``icp_sd`` per axis and ``icp_heading_sd``; calib_step, the
    step index (-1 at rest). ``icp_layout="held"`` holds the ICP cells like the
    encoders'; ``"sparse"`` leaves them empty in the logger rows and adds a row
    per ICP message (inside the logger's span) with only ros_time and the ICP cells.

    Returns
    -------
    LabRun
        truth also holds logger_rate, encoder_rate, icp_rate [Hz], jitter [s],
        gyro_sd, wheel_sd, icp_sd, icp_heading_sd, icp_layout, epoch and
        missing_ticks (indices into ``t``).
    """
    if icp_layout not in ("held", "sparse"):
        raise ValueError(f"icp_layout is 'held' or 'sparse', not {icp_layout!r}")
    rng = np.random.default_rng(rng)
    kept = _kept_ticks(rng, len(sim.ticks), missing)
    ticks = sim.ticks[kept]
    stamp = sim.t[ticks] + jitter * rng.standard_normal(len(ticks))
    duration = sim.manoeuvre.duration
    encoder_t, encoder_stamp = _lead_clock(rng, encoder_rate, duration, jitter)
    encoders = sim.held_at(encoder_t, sim.u) + wheel_sd * rng.standard_normal((len(encoder_t), 2))
    icp_t, icp_stamp = _lead_clock(rng, icp_rate, duration, jitter)
    icp_true = sim.at(icp_t, sim.pose)
    icp = _noisy_pose(rng, icp_true, icp_sd, icp_heading_sd)
    gyro = sim.x[ticks, 2] + gyro_sd * rng.standard_normal(len(ticks))
    heard = _latest(encoder_stamp, stamp)
    step = sim.manoeuvre.step[sim.manoeuvre.segment(sim.t[ticks])]
    cells = np.column_stack([gyro, sim.u[ticks][:, ::-1], encoders[heard][:, ::-1]])
    origin = stamp[0]
    table, seen = _drive_rows(icp_layout, stamp, cells, step, icp_stamp, icp)
    rows = [[f"{epoch + (s - origin):.6f}", *row] for s, row in table]
    _write_table(Path(path), DRIVE_COLUMNS, rows)
    used_icp, used_encoders = np.unique(seen), np.unique(heard)
    return _lab_run(
        path,
        sim,
        origin,
        (icp_t[used_icp], icp_true[used_icp]),
        (encoder_t[used_encoders], sim.held_at(encoder_t[used_encoders], sim.u)),
        logger_rate=sim.truth["rate"],
        encoder_rate=encoder_rate,
        icp_rate=icp_rate,
        jitter=jitter,
        gyro_sd=gyro_sd,
        wheel_sd=wheel_sd,
        icp_sd=icp_sd,
        icp_heading_sd=icp_heading_sd,
        icp_layout=icp_layout,
        epoch=epoch,
        missing_ticks=sorted(set(range(len(sim.ticks))) - set(kept.tolist())),
    )


def drive_manoeuvre(
    kind: str = "steps",
    rng: np.random.Generator | int | None = None,
    *,
    n_steps: int = 40,
    step_duration: float = 6.0,
) -> Manoeuvre:
    """A DRIVE-like step sequence within DRIVE_LIMITS, or steady circles of its duration.

    ``kind`` is "steps" (:func:`step_sequence`, drawn from ``rng``) or
    "circles" (:func:`steady_circles` at DRIVE_CIRCLES over the same
    4 + n_steps * step_duration seconds).
    """
    if kind == "steps":
        return step_sequence(rng, n_steps, step_duration=step_duration, **DRIVE_LIMITS)
    if kind == "circles":
        return steady_circles(DRIVE_CIRCLES, 4.0 + n_steps * step_duration)
    raise ValueError(f"kind is 'steps' or 'circles', not {kind!r}")


def write_drive_run(
    path: str | Path,
    *,
    kind: str = "steps",
    icp_layout: str = "held",
    speed_dependent: bool = False,
    n_steps: int = 40,
    truth: dict | None = None,
    rng: np.random.Generator | int,
    **table,
) -> LabRun:
    """A DRIVE-like Husky run at 20 Hz, HUSKY_DRIVE updated by ``truth``: write_drive_table's.

    With ``speed_dependent`` both dampings follow SpeedLaw.from_ratio(1.5, 0,
    v_max): 50 % higher at the top speed 1 m/s than at rest, HUSKY_DRIVE's at
    0.5 m/s. ``rng`` is split into the manoeuvre's, the truth's and the
    table's; ``table`` holds other options of :func:`write_drive_table`.
    """
    manoeuvre_rng, truth_rng, table_rng = np.random.default_rng(rng).spawn(3)
    manoeuvre = drive_manoeuvre(kind, manoeuvre_rng, n_steps=n_steps)
    law = SpeedLaw.from_ratio(1.5, 0.0, DRIVE_LIMITS["v_max"]) if speed_dependent else None
    parameters = {**HUSKY_DRIVE, **(truth or {})}
    sim = simulate(
        manoeuvre, robot="husky", rate=DRIVE_RATE, speed_law=law, rng=truth_rng, **parameters
    )
    return write_drive_table(path, sim, icp_layout=icp_layout, rng=table_rng, **table)
