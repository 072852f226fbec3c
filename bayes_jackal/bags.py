"""Robot logs: ROS bags in, experiments out, and simulated experiments as bags.

:func:`read_bag` turns a recorded run (ROS1 ``.bag``, ROS2 ``.mcap`` or
``.db3`` storage file, or a ROS2 bag directory; read with rosbags' AnyReader,
no ROS install) into an :class:`~bayes_jackal.experiment.Experiment`
(DESIGN §2). The topics come from the robot profile (``robot.topics``):

==============  =======================================  ==========================
role            message type                             used for
==============  =======================================  ==========================
imu             sensor_msgs/Imu                          yaw rate angular_velocity.z
pose            geometry_msgs/PoseStamped or             world x, y, heading -> vx, vy
                nav_msgs/Odometry (motion capture)
joint_states    sensor_msgs/JointState                   wheel speeds, averaged per side
                                                         (joint names: ``robot.wheels``)
cmd_vel         geometry_msgs/Twist (optional)           commanded (v, w), provenance only
==============  =======================================  ==========================

Preprocessing, in order; every repair is listed in ``provenance["repairs"]``:

1. Stamps are the header stamps in nanoseconds; a header stamp of zero is
   replaced by the message's receive time (Twist has no header: receive
   time throughout).
2. Per topic: a non-finite value, or a pose orientation that is not a
   unit quaternion, is an error. A stamp more than ``max_gap``
   earlier than the one before it (in recording order) is a clock jump and an
   error; smaller backward steps are out-of-order delivery and are sorted.
   Messages repeating an earlier stamp are dropped (the first is kept).
   This rule is :func:`bayes_jackal.stamps.sort_stamps`, shared with the
   CSV and MATLAB readers.
3. The run is the time range that the IMU, pose and joint-state topics all
   cover (no overlap is an error). Time zero is the first IMU stamp.
4. A gap longer than ``max_gap`` in any of those topics splits the run; the
   longest gap-free piece is kept (shorter than :data:`MIN_DURATION`: error).
5. The pose is resampled to a uniform grid at its median rate, the heading
   unwrapped, the world position differentiated with a Savitzky-Golay filter
   (:data:`SMOOTHING_WINDOW`, :data:`SMOOTHING_ORDER`) and rotated into the
   body frame: vx = cos(psi) x' + sin(psi) y', vy = -sin(psi) x' + cos(psi) y'.
6. Everything is linearly interpolated onto the IMU clock: a uniform grid at
   the IMU's median rate through the IMU stamps.
7. The steady window is detected (:func:`detect_steady`) unless given.

:func:`write_bag` writes a simulated experiment as a realistic bag (72 Hz
IMU, 360 Hz motion capture with occasional duplicated messages, four-wheel
joint states, cmd_vel), so that the whole chain can be tested against the
known truth.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import struct
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import ReaderError as Reader2Error
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_typestore
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import CubicSpline
from scipy.ndimage import uniform_filter1d
from scipy.signal import savgol_filter

from ._files import atomic_path
from .errors import DataError, InputError
from .experiment import MIN_SAMPLES, Experiment
from .kernels import as_rng
from .progress import Progress
from .robot import RobotProfile
from .simulate import Series, command_profile
from .stamps import longest_run, sort_stamps

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    "MESSAGE_TYPES",
    "BagMessage",
    "bag_messages",
    "detect_steady",
    "read_bag",
    "steady_smoothing",
    "typestore",
    "write_bag",
    "write_messages",
]

#: Accepted message types per topic role (rosbags' normalised type names).
MESSAGE_TYPES = {
    "imu": ("sensor_msgs/msg/Imu",),
    "pose": ("geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry"),
    "joint_states": ("sensor_msgs/msg/JointState",),
    "cmd_vel": ("geometry_msgs/msg/Twist",),
}
#: Roles that must be in the bag; cmd_vel is optional.
REQUIRED_ROLES = ("imu", "pose", "joint_states")
#: Savitzky-Golay differentiating smoother of the pose: window [s] and order.
#: A local quadratic fit over 0.1 s; for deriv=1 it equals the least-squares
#: slope, which passes velocities varying slower than ~5 Hz and damps
#: motion-capture noise (0.1 mm noise -> ~0.5 mm/s at 360 Hz).
SMOOTHING_WINDOW = 0.1
SMOOTHING_ORDER = 2
#: Largest tolerated deviation of a pose quaternion's norm from 1.
QUATERNION_TOLERANCE = 0.01
#: Shortest usable run after cutting at dropouts [s].
MIN_DURATION = 1.0
#: Steady-state rule (:func:`detect_steady`): moving-average length [s],
#: relative tolerances on the wheel speeds and the yaw rate, the yaw-rate
#: tolerance floor [rad/s] and the shortest steady window [s].
STEADY_SMOOTHING = 0.25
STEADY_INPUT_TOLERANCE = 0.05
STEADY_YAW_TOLERANCE = 0.1
STEADY_YAW_FLOOR = 0.01
STEADY_MIN_DURATION = 1.0

#: :func:`write_bag`: motion-capture rate [Hz], fraction of pose messages
#: published twice, receive latency [ns], epoch of time zero [s], and the
#: difference of front and rear wheel speeds [rad/s] (averages out per side).
POSE_RATE = 360.0
DUPLICATE_FRACTION = 0.005
LATENCY_NS = 2_000_000
EPOCH = 1_700_000_000
WHEEL_SPREAD = 0.01

_FORMATS = ("ros1", "ros2")
_ROS2_PLUGINS = {".mcap": StoragePlugin.MCAP, ".db3": StoragePlugin.SQLITE3}
#: What rosbags raises on unreadable or corrupt files (its readers check some
#: record fields with ``assert``, hence AssertionError).
_READ_ERRORS = (
    AssertionError,
    ArithmeticError,
    AnyReaderError,
    Reader1Error,
    Reader2Error,
    SerdeError,
    TypesysError,
    OSError,
    ValueError,
    KeyError,
    IndexError,
    EOFError,
    struct.error,
)


@dataclass(frozen=True)
class BagMessage:
    """One message to write: topic, type, receive time and message object.

    Attributes
    ----------
    topic : str
    msgtype : str
        Normalised type name, e.g. ``"sensor_msgs/msg/Imu"``.
    time : int
        Receive (bag) time [ns since the epoch].
    message : object
        A message of the typestore of the bag format.
    """

    topic: str
    msgtype: str
    time: int
    message: object


@dataclass
class _Stream:
    """Messages of one topic as arrays: stamps [ns], receive times [ns], values."""

    topic: str
    msgtype: str
    stamp: np.ndarray
    recv: np.ndarray
    values: np.ndarray

    def take(self, index: np.ndarray) -> None:
        """Keep (and order) the messages at ``index``: an index array or a mask."""
        self.stamp, self.recv, self.values = (
            self.stamp[index],
            self.recv[index],
            self.values[index],
        )


def typestore(format: str) -> Typestore:
    """The rosbags typestore of a bag format (``"ros1"``: Noetic, ``"ros2"``: Humble)."""
    if format not in _FORMATS:
        raise InputError(f"unknown bag format {format!r}; use one of {_FORMATS}", field="format")
    return get_typestore(Stores.ROS1_NOETIC if format == "ros1" else Stores.ROS2_HUMBLE)


# --------------------------------------------------------------------------- reading


def read_bag(
    path: str | Path,
    robot: RobotProfile,
    window: tuple[float, float] | None = None,
    max_gap: float = 0.25,
    progress: bool = False,
) -> Experiment:
    """Read a recorded run from a ROS bag (see the module text for the steps).

    Parameters
    ----------
    path : str or Path
        ROS1 ``.bag``, ROS2 ``.mcap`` or ``.db3`` storage file, or ROS2 bag
        directory. Never modified.
    robot : RobotProfile
        Topic names (``robot.topics``) and wheel joint names (``robot.wheels``).
    window : (float, float), optional
        Steady window [s from the first IMU stamp]; detected when omitted.
    max_gap : float
        Longest tolerated gap between messages of one topic [s]; longer
        gaps split the run, backward stamp steps longer than this are errors.
    progress : bool
        Show a progress bar over the messages (on stderr).

    Returns
    -------
    Experiment
        On the IMU clock; ``provenance`` holds the file, its sha256, the
        topics, message counts and every repair.

    Raises
    ------
    DataError
        Naming the file, the topic and the time of the problem.
    """
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise DataError("no such file", source=source)
    if not (np.isfinite(max_gap) and max_gap > 0):
        raise InputError(f"must be positive, got {max_gap!r} s", field="max_gap")
    digest = _sha256(path)
    repairs: list[str] = []
    format_name = "ros1" if path.suffix == ".bag" else "ros2"
    try:
        with AnyReader([path], default_typestore=typestore(format_name)) as reader:
            start = reader.start_time
            streams = _collect(reader, robot, source, repairs, progress)
    except DataError:
        raise
    except _READ_ERRORS as exc:
        raise DataError(f"cannot read bag ({type(exc).__name__}: {exc})", source=source) from None

    def where(ns: float) -> str:
        return f"stamp {ns * 1e-9:.6f} s ({(ns - start) * 1e-9:.3f} s into the bag)"

    for stream in streams.values():
        _clean(stream, max_gap, source, where, repairs)
    _check_quaternions(streams["pose"], source, where)
    for role in REQUIRED_ROLES[1:]:
        _check_overlap(streams["imu"], streams[role], source, where)

    imu = streams["imu"]
    origin = int(imu.stamp[0])
    seconds = {role: (s.stamp - origin) * 1e-9 for role, s in streams.items()}
    step = float(np.median(np.diff(seconds["imu"])))
    first = max(seconds[role][0] for role in REQUIRED_ROLES)
    last = min(seconds[role][-1] for role in REQUIRED_ROLES)
    # Snap to the grid within 1e-3 steps: the median step is a whole number of
    # nanoseconds, so k * step drifts from the stamps by < 1 ns per step.
    grid = np.arange(np.ceil(first / step - 1e-3), np.floor(last / step + 1e-3) + 1) * step
    grid = _cut_dropouts(grid, seconds, streams, max_gap, source, repairs)

    yaw_rate = np.interp(grid, seconds["imu"], imu.values[:, 0])
    wheels = streams["joint_states"].values
    omega_r = np.interp(grid, seconds["joint_states"], wheels[:, 0])
    omega_l = np.interp(grid, seconds["joint_states"], wheels[:, 1])
    vx, vy, pose_rate = _body_velocity(seconds["pose"], streams["pose"].values, source)
    vx = np.interp(grid, vx[0], vx[1])
    vy = np.interp(grid, vy[0], vy[1])

    if window is None:
        steady = detect_steady(grid, yaw_rate, np.column_stack([omega_r, omega_l]))
        window_source = "detected" if steady is not None else "none found"
    else:
        steady = _check_window(window, grid, source)
        window_source = "user"

    provenance = {
        "source": source,
        "format": format_name,
        "sha256": digest,
        "robot": robot.name,
        "time_zero": origin * 1e-9,
        "rate": 1.0 / step,
        "samples": len(grid),
        "topics": {
            role: {"topic": s.topic, "msgtype": s.msgtype, "messages": len(s.stamp)}
            for role, s in streams.items()
        },
        "pose_rate": pose_rate,
        "smoother": {
            "method": "scipy.signal.savgol_filter(deriv=1)",
            "window_s": SMOOTHING_WINDOW,
            "polyorder": SMOOTHING_ORDER,
        },
        "steady_window_source": window_source,
        "repairs": repairs,
    }
    if "cmd_vel" in streams:
        provenance["command"] = _command_summary(seconds["cmd_vel"], streams["cmd_vel"], steady)
    return Experiment(
        t=grid,
        yaw_rate=yaw_rate,
        omega_r=omega_r,
        omega_l=omega_l,
        vx=vx,
        vy=vy,
        name=path.stem,
        steady_window=steady,
        provenance=provenance,
        source=source,
    )


def _sha256(path: Path) -> str:
    """sha256 of a file, or of a bag directory's files in name order."""
    digest = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for file in files:
        with open(file, "rb") as stream:
            for block in iter(lambda s=stream: s.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


def _collect(
    reader: AnyReader,
    robot: RobotProfile,
    source: str,
    repairs: list[str],
    progress: bool = False,
) -> dict[str, _Stream]:
    """Read the profile's topics into per-message rows (the only per-message loop)."""
    topics = reader.topics
    roles = {}
    for role in MESSAGE_TYPES:
        topic = robot.topics.get(role)
        if topic not in topics:
            if role in REQUIRED_ROLES:
                raise DataError(
                    f"topic {topic!r} ({role}) is not in the bag; it has {sorted(topics)}",
                    source=source,
                    field=topic,
                )
            repairs.append(f"{role}: topic {topic!r} not in the bag; not used")
            continue
        msgtype = topics[topic].msgtype
        if msgtype not in MESSAGE_TYPES[role]:
            raise DataError(
                f"unsupported message type {msgtype!r} for {role}; expected one of "
                f"{MESSAGE_TYPES[role]}",
                source=source,
                field=topic,
            )
        if topics[topic].msgcount == 0:
            raise DataError(
                f"topic {topic!r} ({role}) has no messages", source=source, field=topic
            )
        roles[topic] = role
    right, left = robot.wheels.get("right", []), robot.wheels.get("left", [])
    if not (right and left):
        raise DataError(
            "the robot profile names no wheel joints ([wheels] right and left)",
            source=robot.source,
            field="wheels",
        )
    rows: dict[str, list] = {role: [] for role in roles.values()}
    connections = [c for c in reader.connections if c.topic in roles]
    last: tuple[str, int] | None = None
    messages = Progress(
        sum(topics[topic].msgcount for topic in roles),
        Path(source).name,
        unit="msg",
        enabled=progress,
    ).wrap(reader.messages(connections=connections))
    try:
        for connection, time, raw in messages:
            role = roles[connection.topic]
            message = reader.deserialize(raw, connection.msgtype)
            stamp = 0 if role == "cmd_vel" else _stamp(message)
            rows[role].append((stamp, time, *_values(role, message, right, left, time, source)))
            last = (connection.topic, time)
    except DataError:
        raise
    except _READ_ERRORS as exc:
        after = (
            ""
            if last is None
            else f" after the last good message ({last[0]}, received at {last[1] * 1e-9:.6f} s)"
        )
        raise DataError(
            f"cannot read bag{after} ({type(exc).__name__}: {exc})", source=source
        ) from None
    streams = {}
    for topic, role in roles.items():
        table = np.array(rows[role], dtype=object)
        stamp, recv = table[:, 0].astype(np.int64), table[:, 1].astype(np.int64)
        zero = stamp == 0
        if zero.any() and role != "cmd_vel":
            repairs.append(
                f"{role}: {zero.sum()} of {len(stamp)} messages on {topic} have a zero header "
                f"stamp; used their receive time"
            )
        streams[role] = _Stream(
            topic,
            topics[topic].msgtype,
            np.where(zero, recv, stamp),
            recv,
            table[:, 2:].astype(float),
        )
    return streams


def _stamp(message: object) -> int:
    stamp = message.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _values(
    role: str, message: object, right: list[str], left: list[str], time: int, source: str
) -> tuple[float, ...]:
    """The numbers of one message used for its role."""
    if role == "imu":
        return (message.angular_velocity.z,)
    if role == "cmd_vel":
        return (message.linear.x, message.angular.z)
    if role == "pose":
        pose = message.pose.pose if hasattr(message, "twist") else message.pose
        q = pose.orientation
        return (pose.position.x, pose.position.y, q.x, q.y, q.z, q.w)
    index = {name: i for i, name in enumerate(message.name)}
    missing = [name for name in (*right, *left) if name not in index]
    if missing or len(message.velocity) != len(message.name):
        raise DataError(
            f"joint state received at {time * 1e-9:.6f} s lacks velocities of {missing or 'all'}"
            f" (names {list(message.name)}, {len(message.velocity)} velocities)",
            source=source,
            field="joint_states",
        )
    velocity = np.asarray(message.velocity, float)
    return (
        float(np.mean(velocity[[index[n] for n in right]])),
        float(np.mean(velocity[[index[n] for n in left]])),
    )


def _clean(
    stream: _Stream,
    max_gap: float,
    source: str,
    where: Callable[[float], str],
    repairs: list[str],
) -> None:
    """Reject non-finite values; sort and de-duplicate stamps (:func:`sort_stamps`)."""
    bad = np.flatnonzero(~np.isfinite(stream.values).all(axis=1))
    if bad.size:
        raise DataError(
            f"non-finite value in message {bad[0]} at {where(stream.stamp[bad[0]])} "
            f"({bad.size} such messages)",
            source=source,
            field=stream.topic,
        )
    order, sorted_repairs = sort_stamps(
        stream.stamp,
        max_backstep=max_gap * 1e9,
        where=lambda i: f"message {i}, {where(stream.stamp[i])}",
        source=source,
        field=stream.topic,
        label=stream.topic,
        unit=1e-9,
    )
    stream.take(order)
    repairs.extend(sorted_repairs)
    if len(stream.stamp) < MIN_SAMPLES:
        raise DataError(
            f"only {len(stream.stamp)} distinct stamps; at least {MIN_SAMPLES} are needed",
            source=source,
            field=stream.topic,
        )


def _check_quaternions(pose: _Stream, source: str, where: Callable[[float], str]) -> None:
    """Pose orientations must be unit quaternions (within :data:`QUATERNION_TOLERANCE`)."""
    q = np.clip(pose.values[:, 2:], -2.0, 2.0)  # no overflow on garbage values
    bad = np.flatnonzero(np.abs(np.linalg.norm(q, axis=1) - 1.0) > QUATERNION_TOLERANCE)
    if bad.size:
        raise DataError(
            f"orientation of message {bad[0]} at {where(pose.stamp[bad[0]])} is not a unit "
            f"quaternion: {pose.values[bad[0], 2:].tolist()} ({bad.size} such messages)",
            source=source,
            field=pose.topic,
        )


def _check_overlap(
    imu: _Stream, other: _Stream, source: str, where: Callable[[float], str]
) -> None:
    if other.stamp[0] >= imu.stamp[-1] or other.stamp[-1] <= imu.stamp[0]:
        raise DataError(
            f"no overlap in time with {imu.topic}: {other.topic} spans "
            f"{where(other.stamp[0])} .. {where(other.stamp[-1])}, {imu.topic} spans "
            f"{where(imu.stamp[0])} .. {where(imu.stamp[-1])}",
            source=source,
            field=other.topic,
        )


def _cut_dropouts(
    grid: np.ndarray,
    seconds: dict[str, np.ndarray],
    streams: dict[str, _Stream],
    max_gap: float,
    source: str,
    repairs: list[str],
) -> np.ndarray:
    """Keep the longest piece of ``grid`` [s] that lies in no gap > max_gap."""
    good = np.ones(len(grid), bool)
    for role in REQUIRED_ROLES:
        times = seconds[role]
        steps = np.diff(times)
        for i in np.flatnonzero(steps > max_gap):
            repairs.append(
                f"{streams[role].topic}: dropout of {steps[i]:.3f} s from {times[i]:.3f} s "
                f"to {times[i + 1]:.3f} s (after the first IMU stamp)"
            )
        after = np.clip(np.searchsorted(times, grid, side="right"), 1, len(times) - 1)
        good &= (times[after] - times[after - 1] <= max_gap) | (grid == times[after - 1])
    start, stop = longest_run(good)
    if stop - start < 1 or grid[stop - 1] - grid[start] < MIN_DURATION:
        raise DataError(
            f"no gap-free stretch of {MIN_DURATION} s: dropouts longer than max_gap "
            f"{max_gap} s ({'; '.join(repairs[-3:])})",
            source=source,
        )
    if stop - start < len(grid):
        repairs.append(
            f"run cut at dropouts to {grid[start]:.3f} .. {grid[stop - 1]:.3f} s "
            f"(the longest gap-free stretch; was {grid[0]:.3f} .. {grid[-1]:.3f} s)"
        )
    return grid[start:stop]


def _body_velocity(
    t: np.ndarray, pose: np.ndarray, source: str
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], float]:
    """Body-frame vx, vy [m/s] from world poses (x, y, quaternion) at times t [s].

    Returns (times, vx), (times, vy) on a uniform grid at the pose's median
    rate, and that rate [Hz].
    """
    x, y, qx, qy, qz, qw = pose.T
    heading = np.unwrap(np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy**2 + qz**2)))
    step = float(np.median(np.diff(t)))
    uniform = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / step + 1e-6)) + 1) * step
    length = round(SMOOTHING_WINDOW / step) // 2 * 2 + 1
    if length <= SMOOTHING_ORDER or len(uniform) < length:
        raise DataError(
            f"pose too short or too slow for the {SMOOTHING_WINDOW} s smoother "
            f"({len(uniform)} samples at {1 / step:.1f} Hz)",
            source=source,
            field="pose",
        )
    world = [
        savgol_filter(np.interp(uniform, t, c), length, SMOOTHING_ORDER, deriv=1, delta=step)
        for c in (x, y)
    ]
    psi = np.interp(uniform, t, heading)
    cos, sin = np.cos(psi), np.sin(psi)
    vx = cos * world[0] + sin * world[1]
    vy = -sin * world[0] + cos * world[1]
    return (uniform, vx), (uniform, vy), 1.0 / step


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


def _check_window(
    window: tuple[float, float], grid: np.ndarray, source: str
) -> tuple[float, float]:
    start, stop = (float(w) for w in window)
    if not (np.isfinite(start) and np.isfinite(stop) and start < stop):
        raise DataError(
            f"window must satisfy start < stop, got {window}", source=source, field="window"
        )
    inside = (grid >= start) & (grid <= stop)
    if inside.sum() < MIN_SAMPLES:
        raise DataError(
            f"window [{start}, {stop}] s holds {inside.sum()} samples "
            f"(data span {grid[0]:.3f}..{grid[-1]:.3f} s)",
            source=source,
            field="window",
        )
    return start, stop


def _command_summary(
    t: np.ndarray, stream: _Stream, steady: tuple[float, float] | None
) -> dict[str, float | int | None]:
    """Median commanded v [m/s], w [rad/s] in the steady window (or the whole run)."""
    inside = np.ones(len(t), bool) if steady is None else (t >= steady[0]) & (t <= steady[1])
    if not inside.any():
        return {"v": None, "w": None, "messages": 0}
    v, w = np.median(stream.values[inside], axis=0)
    return {"v": float(v), "w": float(w), "messages": int(inside.sum())}


# --------------------------------------------------------------------------- writing


def bag_messages(
    experiment: Experiment,
    robot: RobotProfile,
    format: str = "ros2",
    rng: np.random.Generator | int | None = None,
) -> list[BagMessage]:
    """The messages of a simulated experiment as they would be recorded.

    IMU at the experiment's clock with the measured yaw rate; joint states of
    four wheels on the same stamps (front and rear differ by
    ±:data:`WHEEL_SPREAD`, averaging to the experiment's wheel speeds);
    cmd_vel from the series' command profile at a quarter of the rate; and a
    motion-capture pose at :data:`POSE_RATE` from integrating the noise-free
    states (``truth_arrays`` ``vx_state``, ``vy_state``, ``yaw_state``):
    heading and world position by the trapezoid rule on the experiment's
    clock, then a cubic spline to the pose stamps. About
    :data:`DUPLICATE_FRACTION` of the pose messages are published twice with
    the same stamp. Stamps start at :data:`EPOCH`; receive times lag by
    :data:`LATENCY_NS`.

    Parameters
    ----------
    experiment : Experiment
        A simulated experiment (:func:`bayes_jackal.simulate.simulate_experiment`).
    robot : RobotProfile
        Topic and wheel joint names.
    format : {"ros1", "ros2"}
        Typestore of the messages.
    rng : numpy.random.Generator, int or None
        Chooses the duplicated pose messages.

    Returns
    -------
    list of BagMessage
        Sorted by receive time.
    """
    missing = [
        k for k in ("vx_state", "vy_state", "yaw_state") if k not in experiment.truth_arrays
    ]
    command = (experiment.truth or {}).get("command", {})
    if missing or not {"v", "w", "duration"} <= set(command):
        raise InputError(
            f"needs a simulated experiment (truth arrays {missing} missing or no command "
            f"in its truth: {command})",
            source=experiment.source,
        )
    right, left = robot.wheels.get("right", []), robot.wheels.get("left", [])
    if not (right and left):
        raise InputError("the robot profile names no wheel joints", field="wheels")
    store = typestore(format)
    rng = as_rng(rng)
    t = experiment.t
    stamps = EPOCH * 1_000_000_000 + np.round(t * 1e9).astype(np.int64)
    heading = cumulative_trapezoid(experiment.truth_arrays["yaw_state"], t, initial=0.0)
    vx, vy = experiment.truth_arrays["vx_state"], experiment.truth_arrays["vy_state"]
    world_x = cumulative_trapezoid(np.cos(heading) * vx - np.sin(heading) * vy, t, initial=0.0)
    world_y = cumulative_trapezoid(np.sin(heading) * vx + np.cos(heading) * vy, t, initial=0.0)
    pose_t = np.arange(int(np.floor(t[-1] * POSE_RATE)) + 1) / POSE_RATE
    x, y, psi = CubicSpline(t, np.column_stack([world_x, world_y, heading]))(pose_t).T
    pose_stamps = EPOCH * 1_000_000_000 + np.round(pose_t * 1e9).astype(np.int64)
    repeat = 1 + (rng.random(len(pose_t)) < DUPLICATE_FRACTION)

    types = store.types
    messages = []
    for k, stamp in enumerate(stamps):
        header = _header(store, stamp, "imu_link", k)
        messages.append(
            BagMessage(
                robot.topics["imu"],
                "sensor_msgs/msg/Imu",
                int(stamp) + LATENCY_NS,
                types["sensor_msgs/msg/Imu"](
                    header=header,
                    orientation=_quaternion(store, heading[k]),
                    orientation_covariance=np.zeros(9),
                    angular_velocity=_vector(store, 0.0, 0.0, experiment.yaw_rate[k]),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=_vector(store, 0.0, 0.0, 9.81),
                    linear_acceleration_covariance=np.zeros(9),
                ),
            )
        )
    names = [*left, *right]
    spread = np.linspace(WHEEL_SPREAD, -WHEEL_SPREAD, len(right))
    spread_l = np.linspace(WHEEL_SPREAD, -WHEEL_SPREAD, len(left))
    velocity = np.column_stack(
        [
            experiment.omega_l[:, None] + spread_l[None, :],
            experiment.omega_r[:, None] + spread[None, :],
        ]
    )
    position = cumulative_trapezoid(velocity, t, axis=0, initial=0.0)
    for k, stamp in enumerate(stamps):
        messages.append(
            BagMessage(
                robot.topics["joint_states"],
                "sensor_msgs/msg/JointState",
                int(stamp) + LATENCY_NS,
                types["sensor_msgs/msg/JointState"](
                    header=_header(store, stamp, "base_link", k),
                    name=names,
                    position=position[k],
                    velocity=velocity[k],
                    effort=np.zeros(len(names)),
                ),
            )
        )
    _, v, w = command_profile(Series(**command), experiment.dt)
    for k in range(0, min(len(v), len(stamps)), 4):
        messages.append(
            BagMessage(
                robot.topics["cmd_vel"],
                "geometry_msgs/msg/Twist",
                int(stamps[k]),
                types["geometry_msgs/msg/Twist"](
                    linear=_vector(store, v[k], 0.0, 0.0),
                    angular=_vector(store, 0.0, 0.0, w[k]),
                ),
            )
        )
    for k, stamp in enumerate(pose_stamps):
        message = types["geometry_msgs/msg/PoseStamped"](
            header=_header(store, stamp, "world", k),
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=x[k], y=y[k], z=0.0),
                orientation=_quaternion(store, psi[k]),
            ),
        )
        messages.extend(
            BagMessage(
                robot.topics["pose"],
                "geometry_msgs/msg/PoseStamped",
                int(stamp) + LATENCY_NS + j * 100_000,
                message,
            )
            for j in range(repeat[k])
        )
    messages.sort(key=lambda m: m.time)
    return messages


def _header(store: Typestore, stamp: int, frame: str, seq: int) -> object:
    fields = {f.name for f in dataclasses.fields(store.types["std_msgs/msg/Header"])}
    time = store.types["builtin_interfaces/msg/Time"](
        sec=int(stamp) // 1_000_000_000, nanosec=int(stamp) % 1_000_000_000
    )
    extra = {"seq": seq} if "seq" in fields else {}
    return store.types["std_msgs/msg/Header"](stamp=time, frame_id=frame, **extra)


def _vector(store: Typestore, x: float, y: float, z: float) -> object:
    return store.types["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))


def _quaternion(store: Typestore, heading: float) -> object:
    return store.types["geometry_msgs/msg/Quaternion"](
        x=0.0, y=0.0, z=float(np.sin(heading / 2)), w=float(np.cos(heading / 2))
    )


#: Chunk compressions of ROS1 bags (rosbags' writer).
ROS1_COMPRESSIONS = {"bz2": Writer1.CompressionFormat.BZ2, "lz4": Writer1.CompressionFormat.LZ4}


def write_messages(
    messages: list[BagMessage],
    path: str | Path,
    format: str = "ros2",
    compression: str | None = None,
) -> Path:
    """Write messages as a bag, atomically (a temporary file moved into place).

    Parameters
    ----------
    messages : list of BagMessage
        Written in the given order; topics get a connection each in order of
        first appearance (so a topic can be declared with no messages by
        passing ``message=None``, which is not written).
    path : str or Path
        ``.bag`` for ``"ros1"``; ``.mcap`` or ``.db3`` for ``"ros2"`` (a
        single storage file, which rosbags reads without the bag directory).
    format : {"ros1", "ros2"}
    compression : {"bz2", "lz4"}, optional
        Chunk compression of a ROS1 bag (bz2 shrinks a simulated run ~4x).

    Returns
    -------
    Path
    """
    path = Path(path)
    store = typestore(format)
    if compression is not None and (format != "ros1" or compression not in ROS1_COMPRESSIONS):
        raise InputError(
            f"compression {compression!r} needs format ros1 and one of "
            f"{sorted(ROS1_COMPRESSIONS)}",
            field="compression",
        )
    if format == "ros1" and path.suffix != ".bag":
        raise InputError(f"a ROS1 bag must end in .bag, got {path.name!r}", field="path")
    if format == "ros2" and path.suffix not in _ROS2_PLUGINS:
        raise InputError(
            f"a ROS2 bag must end in {sorted(_ROS2_PLUGINS)}, got {path.name!r}", field="path"
        )
    with atomic_path(path) as temporary:
        if format == "ros1":
            temporary.unlink()
            writer = Writer1(temporary)
            if compression is not None:
                writer.set_compression(ROS1_COMPRESSIONS[compression])
            with writer:
                _write_all(writer, messages, store, store.serialize_ros1)
        else:
            with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}.") as folder:
                bag = Path(folder) / "bag"
                with Writer2(
                    bag, version=Writer2.VERSION_LATEST, storage_plugin=_ROS2_PLUGINS[path.suffix]
                ) as writer:
                    _write_all(writer, messages, store, store.serialize_cdr)
                os.replace(bag / f"bag{path.suffix}", temporary)
    return path


def _write_all(
    writer: Writer1 | Writer2,
    messages: list[BagMessage],
    store: Typestore,
    serialize: Callable[[object, str], memoryview],
) -> None:
    connections = {}
    for m in messages:
        if m.topic not in connections:
            connections[m.topic] = writer.add_connection(m.topic, m.msgtype, typestore=store)
        if m.message is not None:
            writer.write(connections[m.topic], m.time, serialize(m.message, m.msgtype))


def write_bag(
    experiment: Experiment,
    path: str | Path,
    robot: RobotProfile,
    format: str = "ros2",
    rng: np.random.Generator | int | None = None,
    compression: str | None = None,
) -> Path:
    """Write a simulated experiment as a realistic bag (:func:`bag_messages`).

    Parameters
    ----------
    experiment : Experiment
        A simulated experiment.
    path : str or Path
        ``.bag`` for ``"ros1"``; ``.mcap`` (or ``.db3``) for ``"ros2"``.
    robot : RobotProfile
        Topic and wheel joint names.
    format : {"ros1", "ros2"}
    rng : numpy.random.Generator, int or None
        Chooses the duplicated pose messages.
    compression : {"bz2", "lz4"}, optional
        Chunk compression of a ROS1 bag.

    Returns
    -------
    Path
    """
    messages = bag_messages(experiment, robot, format, rng)
    return write_messages(messages, path, format, compression)
