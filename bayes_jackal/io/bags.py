"""Robot logs: ROS bags in, experiments out.

:func:`read_bag` turns a recorded run (ROS1 ``.bag``, ROS2 ``.mcap`` or
``.db3`` storage file, or a ROS2 bag directory; read with rosbags' AnyReader,
no ROS install) into an :class:`~bayes_jackal.io.Experiment`
(docs/design.md §2). The topics come from the robot profile (``robot.topics``):

==============  =======================================  ==========================
role            message type                             used for
==============  =======================================  ==========================
imu             sensor_msgs/Imu                          yaw rate angular_velocity.z
pose            geometry_msgs/PoseStamped or             world x, y, heading -> vx, vy
                nav_msgs/Odometry (motion capture)
joint_states    sensor_msgs/JointState                   wheel speeds, averaged per side
                                                         (joint names: ``robot.wheels``)
cmd_vel         geometry_msgs/Twist (optional)           commanded (v, w): segments
==============  =======================================  ==========================

The pose is optional too: a bag without it (no motion capture) is a
yaw-rate-only experiment, vx and vy absent, and a warning says so.

Preprocessing, in order; every repair is listed in ``provenance["repairs"]``:

1. Stamps are the header stamps in nanoseconds; a header stamp of zero is
   replaced by the message's receive time (Twist has no header: receive
   time throughout).
2. Per topic: a non-finite value, or a pose orientation that is not a
   unit quaternion, is an error. A stamp more than ``max_gap``
   earlier than the one before it (in recording order) is a clock jump and an
   error; smaller backward steps are out-of-order delivery and are sorted.
   Messages repeating an earlier stamp are dropped (the first is kept).
   This rule is :func:`bayes_jackal.io.sort_stamps`, shared with the
   CSV and MATLAB readers.
3. The run is the time range that the IMU, joint-state and (where the bag
   has it) pose topics all cover (no overlap is an error). Time zero is the
   first IMU stamp.
4. A gap longer than ``max_gap`` in the IMU or the joint states splits the
   run; the longest gap-free piece is kept (shorter than
   :data:`MIN_DURATION`: error). A pose dropout (motion capture lost for a
   second) does not: the poses are kept with their gap, which the repairs
   list.
5. The poses are kept as recorded (:class:`~bayes_jackal.io.PoseTrack`:
   world x, y and the heading, unwrapped, at their own stamps): the
   likelihood and the filters model them (:mod:`bayes_jackal.io.pose_increments`).
   For plots, body-frame vx, vy are also derived: the pose resampled to a
   uniform grid at its median rate, the world position differentiated with
   a Savitzky-Golay filter (:data:`SMOOTHING_WINDOW`, :data:`SMOOTHING_ORDER`)
   and rotated into the body frame: vx = cos(psi) x' + sin(psi) y',
   vy = -sin(psi) x' + cos(psi) y'.
6. The IMU's clock is the uniform clock of its stamps
   (:func:`bayes_jackal.io.uniform_clock`: the rate and origin fitted by
   least squares, a whole number of Hz where the stamps allow it;
   docs/design.md §2.1). Each IMU sample keeps its value on its tick; a
   tick it missed within ``max_gap`` is interpolated, for plots, and marked
   unmeasured (:attr:`~bayes_jackal.io.Experiment.measured`). The wheel
   speeds (the model's input) and the derived vx, vy are linearly
   interpolated onto the clock, across such ticks too. (A clock at
   the stamps' median step drifts by its error, ~3 us a step at 0.1 ms of
   jitter, 8 ms over a 38 s run, and interpolating onto it smoothed the
   gyro's white noise by up to 30 %.)
7. The steady window is detected (:func:`bayes_jackal.io.detect_steady`)
   unless given.
8. The segments (:attr:`~bayes_jackal.io.Experiment.segments`) are the
   steps of the command (:func:`bayes_jackal.io.command_segments`), held
   from each cmd_vel message to the next and turned into wheel speeds by
   the profile's diff-drive formula, where the bag has cmd_vel.

The writer of simulated experiments as bags is :mod:`bayes_jackal.io.bag_writer`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

from .._runtime import MAX_GAP, DataError, InputError, Progress, file_sha256, require_file
from ..model import RobotProfile, wheel_speeds
from .bag_reading import READ_ERRORS, bag_format, header_stamp, open_bag, receive_time_for_zero
from .experiment import Experiment, detect_steady
from .pose_track import SMOOTHING_ORDER, SMOOTHING_WINDOW, PoseTrack, body_velocities
from .segments import MIN_HOLD, STEP_TOLERANCE, command_segments
from .stamps import MIN_SAMPLES, hold_values, longest_run, sort_stamps, uniform_clock

__all__ = ["MESSAGE_TYPES", "read_bag"]

#: Accepted message types per topic role (rosbags' normalised type names).
MESSAGE_TYPES = {
    "imu": ("sensor_msgs/msg/Imu",),
    "pose": ("geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry"),
    "joint_states": ("sensor_msgs/msg/JointState",),
    "cmd_vel": ("geometry_msgs/msg/Twist",),
}
#: Roles that must be in the bag, and whose dropouts cut the run; the pose
#: (motion capture, not in every lab) and cmd_vel are optional.
REQUIRED_ROLES = ("imu", "joint_states")
#: Largest tolerated deviation of a pose quaternion's norm from 1.
QUATERNION_TOLERANCE = 0.01
#: Shortest usable run after cutting at dropouts [s].
MIN_DURATION = 1.0


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


# --------------------------------------------------------------------------- reading


def read_bag(
    path: str | Path,
    robot: RobotProfile,
    window: tuple[float, float] | None = None,
    max_gap: float = MAX_GAP,
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

    Examples
    --------
    A bag written from a short simulated run (8 s, :func:`~bayes_jackal.io.write_bag`):
    the IMU clock, the velocities derived from the motion-capture pose, the
    detected steady window, and the repairs (duplicated poses):

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.io import write_bag
    >>> from bayes_jackal.io import read_bag
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import Series, simulate_experiment
    >>> robot = load_profile()
    >>> run = simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=1, name="short")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     bag = write_bag(run, Path(folder) / "short.bag", robot, "ros1", rng=1)
    ...     experiment = read_bag(bag, robot)
    >>> print(experiment.name, len(experiment.t), round(1 / experiment.dt, 3), experiment.channels)
    short 577 72.0 ('vx', 'vy', 'yaw')
    >>> print("steady window {:.2f}-{:.2f} s".format(*experiment.steady_window))
    steady window 1.99-6.03 s
    >>> print(experiment.provenance["repairs"][0])
    /mocap_node/Jackal/pose: 11 duplicate stamps (first at message 324, stamp ...);
    kept the first message of each
    """
    path = Path(path)
    source = str(path)
    require_file(path, source, folder=True)
    if not (np.isfinite(max_gap) and max_gap > 0):
        raise InputError(f"must be positive, got {max_gap!r} s", field="max_gap")
    digest = file_sha256(path)
    repairs: list[str] = []
    format_name = bag_format(path)
    with open_bag(path, source) as reader:
        start = reader.start_time
        streams = _collect(reader, robot, source, repairs, progress)

    def where(ns: float) -> str:
        return f"stamp {ns * 1e-9:.6f} s ({(ns - start) * 1e-9:.3f} s into the bag)"

    for stream in streams.values():
        _clean(stream, max_gap, source, where, repairs)
    if "pose" in streams:
        _check_quaternions(streams["pose"], source, where)
    recorded = [role for role in ("joint_states", "pose") if role in streams]
    for role in recorded:
        _check_overlap(streams["imu"], streams[role], source, where)

    imu = streams["imu"]
    origin = int(imu.stamp[0])
    seconds = {role: (s.stamp - origin) * 1e-9 for role, s in streams.items()}
    clock = uniform_clock(
        seconds["imu"],
        max_gap=max_gap,
        source=source,
        row_name=lambda i: f"message {i}, {where(imu.stamp[i])}",
        field=imu.topic,
    )
    repairs.extend(clock.repairs)
    step = 1.0 / clock.provenance["rate"]
    first = max(seconds[role][0] for role in ("imu", *recorded))
    last = min(seconds[role][-1] for role in ("imu", *recorded))
    within = (clock.t >= first - 1e-3 * step) & (clock.t <= last + 1e-3 * step)
    kept = _cut_dropouts(clock.t[within], seconds, streams, max_gap, source, repairs)
    grid = clock.t[within][kept]
    # The IMU's own samples, one per tick of its clock: a sample keeps its
    # value (interpolating onto a clock that drifts from the samples would
    # smooth the gyro's noise); a tick it missed within max_gap is filled,
    # and marked unmeasured.
    yaw_rate = clock.resample(imu.values[:, 0])[within][kept]
    wheels = streams["joint_states"].values
    omega_r = np.interp(grid, seconds["joint_states"], wheels[:, 0])
    omega_l = np.interp(grid, seconds["joint_states"], wheels[:, 1])
    pose = vx = vy = None
    if "pose" in streams:
        pose = _pose_track(seconds["pose"], streams["pose"].values, grid, step, source)
        vx, vy = body_velocities(pose, grid)

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
        "imu_clock": clock.provenance,
        "samples": len(grid),
        "topics": {
            role: {"topic": s.topic, "msgtype": s.msgtype, "messages": len(s.stamp)}
            for role, s in streams.items()
        },
        "pose_rate": None if pose is None else pose.rate,
        "input": {
            "from": streams["joint_states"].topic,
            "interpolated": "linearly onto the IMU clock, across the ticks it missed too",
        },
        "steady_window_source": window_source,
        "repairs": repairs,
    }
    if pose is not None:
        provenance["smoother"] = {
            "method": "scipy.signal.savgol_filter(deriv=1)",
            "window_s": SMOOTHING_WINDOW,
            "polyorder": SMOOTHING_ORDER,
        }
    segments = None
    if "cmd_vel" in streams:
        provenance["command"] = _command_summary(seconds["cmd_vel"], streams["cmd_vel"], steady)
        segments = _command_segments(seconds["cmd_vel"], streams["cmd_vel"], grid, robot)
        provenance["segments"] = {
            "from": streams["cmd_vel"].topic,
            "step_tolerance": STEP_TOLERANCE,
            "min_hold": MIN_HOLD,
            "count": 1 if segments is None else len(segments),
        }
    return Experiment(
        t=grid,
        yaw_rate=yaw_rate,
        omega_r=omega_r,
        omega_l=omega_l,
        vx=vx,
        vy=vy,
        pose=pose,
        name=path.stem,
        steady_window=steady,
        provenance=provenance,
        source=source,
        measured={"yaw_rate": clock.measured[within][kept]},
        segments=segments,
    )


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
            if role == "pose":
                note = (
                    f"pose: topic {topic!r} not in the bag (it has {sorted(topics)}): read as "
                    "a yaw-rate-only experiment, vx and vy absent (--topic pose NAME names "
                    "the motion capture's topic)"
                )
                warnings.warn(f"{source}: {note}", UserWarning, stacklevel=3)
            else:
                note = f"{role}: topic {topic!r} not in the bag; not used"
            repairs.append(note)
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
            stamp = 0 if role == "cmd_vel" else header_stamp(message)
            rows[role].append((stamp, time, *_values(role, message, right, left, time, source)))
            last = (connection.topic, time)
    except DataError:
        raise
    except READ_ERRORS as exc:
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
        recv = table[:, 1].astype(np.int64)
        stamp, repaired = receive_time_for_zero(
            table[:, 0].astype(np.int64), recv, f"{role} ({topic})"
        )
        repairs += [] if role == "cmd_vel" else repaired
        values = table[:, 2:].astype(float)
        streams[role] = _Stream(topic, topics[topic].msgtype, stamp, recv, values)
    return streams


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
) -> slice:
    """The longest piece of ``grid`` [s] that lies in no gap > max_gap, as a slice of it.

    Gaps of the required topics cut; the poses' are listed, and kept.
    """
    good = np.ones(len(grid), bool)
    for role in (*REQUIRED_ROLES, "pose"):
        if role not in streams:
            continue
        times = seconds[role]
        steps = np.diff(times)
        kept = "; the poses are kept with their gap" if role == "pose" else ""
        for i in np.flatnonzero(steps > max_gap):
            repairs.append(
                f"{streams[role].topic}: dropout of {steps[i]:.3f} s from {times[i]:.3f} s "
                f"to {times[i + 1]:.3f} s (after the first IMU stamp){kept}"
            )
        if role == "pose":
            continue
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
    return slice(start, stop)


def _pose_track(
    t: np.ndarray, pose: np.ndarray, grid: np.ndarray, step: float, source: str
) -> PoseTrack:
    """The poses (x, y, quaternion) at times t [s] as a track over the run's grid [s].

    The heading is the quaternion's yaw, unwrapped; the poses kept reach one
    IMU ``step`` beyond the grid's ends, so that every sample has the poses
    around it (:mod:`bayes_jackal.io.pose_increments`).
    """
    x, y, qx, qy, qz, qw = pose.T
    heading = np.unwrap(np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy**2 + qz**2)))
    keep = (t >= grid[0] - step) & (t <= grid[-1] + step)
    return PoseTrack(t[keep], x[keep], y[keep], heading[keep], source=source)


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


def _command_segments(
    t: np.ndarray, stream: _Stream, grid: np.ndarray, robot: RobotProfile
) -> np.ndarray | None:
    """The command's steps on the grid: cmd_vel (v, w) at receive times t [s], held."""
    held, _ = hold_values(t, stream.values, grid)
    return command_segments(grid, np.column_stack(wheel_speeds(robot, *held.T)))
