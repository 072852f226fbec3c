"""Motion-capture lab logs as ROS1 bags, simulated independently of the package.

``write_mocap_bag`` writes a run the way the Jackal's lab records one (thesis
"The Noisy Jackal", ch. 7-3): a gyro on ``/imu/data``, the motion-capture
pose on ``/mocap_node/Jackal/pose``, wheel speeds on ``/joint_states`` and the
command on ``/cmd_vel``, each sensor on its own clock. Nothing here comes from
bayes_jackal (not its simulator, bag writer, kernels or model code); only the
robot's constants are read from models/jackal.toml. Tests that read these
bags with the package therefore check it against data it did not generate.

The truth is the linear model of eq. 4-32, dx/dt = A x + B u + xi(t) with
x = (vx, vy, r), u = (omega_r, omega_l), driven by a continuous-time force xi
that is white noise coloured by a Gaussian kernel of width sigma_h, so its
autocorrelation is exp(-tau^2 / (4 sigma_h^2)). The force's scale is set so
the one-step residual at the IMU rate, w[k] = x(t_{k+1}) - Ad x(t_k) - Bd u_k,
has the requested sd sigma_c per channel (:func:`unit_residual_variance`).
Everything is integrated on a fine grid of ``fine`` steps per IMU step and
the sensors sample that truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.linalg
import scipy.signal
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore
from scipy.integrate import cumulative_trapezoid

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

#: The Jackal's constants (thesis ch. 3), read from the robot profile rather than the package.
JACKAL = tomllib.loads((Path(__file__).parents[1] / "models" / "jackal.toml").read_text())
#: Channels in the order of the model's state (vx, vy, yaw rate).
STATE = ("vx", "vy", "yaw")
#: Header stamps count from this epoch [ns] (November 2023, as a real log's would).
EPOCH_NS = 1_700_000_000 * 10**9
#: Thesis commands (v [m/s], w [rad/s], duration [s]) of the v1 and v2 runs (ch. 7-3-1).
THESIS_COMMANDS = {
    "v1": (0.3, float(np.deg2rad(22.5)), 38.0),
    "v2": (0.4, float(np.deg2rad(30.0)), 26.0),
}
#: Wheel joints in the order the Jackal's driver publishes them.
WHEELS = ("front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel")
#: Topic and message type per role (models/jackal.toml [topics]).
TOPICS = {
    "imu": ("/imu/data", "sensor_msgs/msg/Imu"),
    "pose": ("/mocap_node/Jackal/pose", "geometry_msgs/msg/PoseStamped"),
    "joint_states": ("/joint_states", "sensor_msgs/msg/JointState"),
    "cmd_vel": ("/cmd_vel", "geometry_msgs/msg/Twist"),
}
#: Rates [Hz] of the wheel encoders and of the teleoperation command.
JOINT_RATE, CMD_RATE = 50.0, 20.0
#: Header-stamp jitter [s] of the IMU, motion capture and wheel driver.
IMU_JITTER, POSE_JITTER, JOINT_JITTER = 1e-4, 5e-5, 1e-4
#: Transport latency [s], header stamp to receive time: uniform in this range.
LATENCY = (1e-3, 3e-3)
#: Fractions of motion-capture messages published twice or dropped.
DUPLICATE_FRACTION, DROP_FRACTION = 0.005, 0.002
#: Front and rear wheel of a side differ by up to this much [rad/s] (averaging out per side).
WHEEL_SPLIT = 0.01


@dataclass(frozen=True)
class MocapRun:
    """One simulated run and its truth; times in s from the first IMU header stamp.

    Attributes
    ----------
    path : Path
        The bag written.
    truth : dict
        d_lat, d_long [N s/m]; sigma_h [s]; sigma_c and sigma_c_realised (dicts
        vx, vy [m/s], yaw [rad/s]); force_sd, the sd of xi per channel [m/s^2,
        rad/s^2]; pose_sd [m], heading_sd [rad], gyro_sd [rad/s]; imu_rate,
        pose_rate [Hz]; command (v [m/s], w [rad/s], duration [s]); fine, the
        fine steps per IMU step; pose_duplicates and pose_dropped (counts).
    imu_t : np.ndarray
        True sample instants of the IMU messages [s], shape (N,).
    states : np.ndarray
        True (vx [m/s], vy [m/s], r [rad/s]) at ``imu_t``, shape (N, 3).
    steady_window : tuple of float
        (3.0, duration - 2.0) [s]: the command is held and transients have decayed.
    pose_t : np.ndarray
        True sample instants of the distinct motion-capture messages in the bag [s], shape (P,).
    poses : np.ndarray
        True (X [m], Y [m], psi [rad], unwrapped) at ``pose_t``, shape (P, 3).
    """

    path: Path
    truth: dict
    imu_t: np.ndarray
    states: np.ndarray
    steady_window: tuple[float, float]
    pose_t: np.ndarray
    poses: np.ndarray


def model_matrices(
    d_lat: float, d_long: float, robot: dict = JACKAL
) -> tuple[np.ndarray, np.ndarray]:
    """Diagonal of A [1/s] and B of eq. 4-32 (state vx, vy, r; input omega_r, omega_l).

    A is diagonal, so its poles are all it takes; B maps wheel speeds [rad/s]
    to accelerations [m/s^2, m/s^2, rad/s^2]. ``robot`` is a profile read from
    models/*.toml (the Jackal's by default).
    """
    body = robot["body"]
    m, inertia, r_w = body["mass"], body["yaw_inertia"], body["wheel_radius"]
    a, b = body["half_wheelbase"], body["half_track"]
    poles = np.array(
        [-4 * d_long / m, -4 * d_lat / m, -4 * (b**2 * d_long + a**2 * d_lat) / inertia]
    )
    gain = 2 * d_long * r_w
    B = np.array([[gain / m, gain / m], [0.0, 0.0], [b * gain / inertia, -b * gain / inertia]])
    return poles, B


def wheel_speeds(v: np.ndarray, w: np.ndarray, robot: dict = JACKAL) -> np.ndarray:
    """(omega_r, omega_l) [rad/s] of a command (v [m/s], w [rad/s]): ROS diff_drive_controller.

    With the profile's wheel_separation s and multiplier k: (v +- w s k / 2) / r_w.
    """
    drive, r_w = robot["diff_drive"], robot["body"]["wheel_radius"]
    half = np.asarray(w) * drive["wheel_separation"] * drive["wheel_separation_multiplier"] / 2
    return np.stack([(v + half) / r_w, (v - half) / r_w], axis=-1)


def command_profile(t: np.ndarray, v: float, w: float, duration: float) -> np.ndarray:
    """Command (v, w) at times t [s]: 1 s rest, 1 s ramp, hold, 1 s ramp down, 1 s rest."""
    level = np.interp(t, [0.0, 1.0, 2.0, duration - 2.0, duration - 1.0], [0, 0, 1, 1, 0])
    return level[:, None] * np.array([v, w])


def gaussian_kernel(sigma_h: float, h: float) -> np.ndarray:
    """exp(-t^2 / (2 sigma_h^2)) on a grid of step h, |t| <= 5 sigma_h, scaled to unit energy.

    White unit noise convolved with it has unit variance and autocorrelation
    sum_j g_j g_{j+m}, the Riemann sum of exp(-tau^2 / (4 sigma_h^2)). Cutting
    at 5 sigma_h leaves out a fraction 1e-12 of the energy.
    """
    t = h * np.arange(-math.floor(5 * sigma_h / h), math.floor(5 * sigma_h / h) + 1)
    g = np.exp(-(t**2) / (2 * sigma_h**2))
    return g / np.sqrt(np.sum(g**2))


def unit_residual_variance(poles: np.ndarray, g: np.ndarray, h: float, fine: int) -> np.ndarray:
    """Var of the IMU-step residual w[k] per channel for a force xi of unit sd.

    With the force held over each fine step, one fine step adds
    c xi[n] (c = (exp(a h) - 1) / a), so over an IMU step (``fine`` fine steps)
    w[k] = sum_i f_i xi[n + i] with f_i = exp(a h (fine - 1 - i)) c: exactly, for
    the simulated process, and the Riemann sum of the integral of
    exp(a (dt - tau)) xi(tau) over the step. Its variance is f' R f with R the
    Toeplitz matrix of xi's autocovariance on the fine grid, sum_j g_j g_{j+m}.
    """
    rho = np.correlate(g, g, "full")[len(g) - 1 :][:fine]
    rho = np.pad(rho, (0, fine - len(rho)))  # a kernel shorter than an IMU step
    R = scipy.linalg.toeplitz(rho)
    i = np.arange(fine)
    f = np.exp(poles[:, None] * h * (fine - 1 - i)) * (np.expm1(poles * h) / poles)[:, None]
    return np.einsum("ci,ij,cj->c", f, R, f)


def interp_columns(t: np.ndarray, grid: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Columns of values (on grid) linearly interpolated at times t."""
    return np.stack([np.interp(t, grid, column) for column in values.T], axis=-1)


def free_clock(rng: np.random.Generator, rate: float, duration: float) -> np.ndarray:
    """True sample instants [s] of a free-running clock, from a random phase in [0, 1/rate)."""
    return rng.uniform(0, 1 / rate) + np.arange(math.floor(duration * rate)) / rate


def _truth(rng, d_lat, d_long, sigma_h, sigma_c, command, imu_rate) -> dict:
    """The fine-grid truth: t [s], inputs u, states x, pose (X, Y, psi), wheel speeds, angles.

    Also the fine steps per IMU step, the burn-in length [fine samples], the
    force sd per channel and the realised sd of w[k] in the steady window.
    """
    poles, B = model_matrices(d_lat, d_long)
    v, w, duration = command
    dt = 1.0 / imu_rate
    # 20 fine steps per IMU step (h = 0.69 ms at 72 Hz), more for a narrow kernel:
    # with >= 5 steps per sigma_h the sampled, truncated autocorrelation is
    # within 1e-6 of the Gaussian's, and a force held over each fine step
    # departs from a smooth one by O((h / sigma_h)^2), 2e-4 at the default.
    # The force's scale below is exact for the held force whatever h is.
    fine = max(20, math.ceil(5 * dt / sigma_h))
    h = dt / fine
    # Burn-in of 10 time constants of the slowest channel (>= 3 s): the state,
    # started at rest, keeps e^-20 of its variance deficit. A whole number of
    # IMU steps, so IMU instant k dt is exactly fine sample burn + k fine.
    burn = fine * math.ceil(max(3.0, 10 / np.min(-poles)) / dt)
    n = burn + fine * (math.ceil(duration / dt) + 2)
    t = h * (np.arange(n) - burn)
    u = wheel_speeds(*command_profile(t, v, w, duration).T)

    # Force: white noise convolved with the kernel ('valid': no edge effects).
    g = gaussian_kernel(sigma_h, h)
    force_sd = np.asarray(sigma_c, float) / np.sqrt(unit_residual_variance(poles, g, h, fine))
    white = rng.standard_normal((n + len(g) - 1, 3))
    xi = force_sd * scipy.signal.fftconvolve(white, g[:, None], mode="valid", axes=0)
    # Exact step of the diagonal model with u and xi held over [t_n, t_n + h]:
    # x[n+1] = e^{a h} x[n] + (e^{a h} - 1) / a (B u[n] + xi[n]), x = 0 at the start.
    drive = np.expm1(poles * h) / poles * (u @ B.T + xi)
    x = np.column_stack(
        [
            scipy.signal.lfilter([0.0, 1.0], [1.0, -np.exp(a * h)], drive[:, c])
            for c, a in enumerate(poles)
        ]
    )

    # World pose by the trapezoid rule, local error h^3 / 12 |X'''|: against
    # Simpson's rule on the same grid it differs by < 1e-7 m and rad over a
    # 38 s run, 5000 times below pose_sd.
    start = rng.uniform([-1.0, -1.0, -np.pi], [1.0, 1.0, np.pi])  # the pose at t = 0
    psi = cumulative_trapezoid(x[:, 2], t, initial=0.0)
    psi += start[2] - psi[burn]
    cos, sin = np.cos(psi), np.sin(psi)
    world = np.column_stack([x[:, 0] * cos - x[:, 1] * sin, x[:, 0] * sin + x[:, 1] * cos])
    position = cumulative_trapezoid(world, t, axis=0, initial=0.0)
    position += start[:2] - position[burn]
    # Front and rear wheels of a side differ by slow sinusoids (as two
    # controllers fighting the skid would) that cancel in the side's mean.
    split = WHEEL_SPLIT * np.sin(2 * np.pi * 0.4 * t[:, None] + rng.uniform(0, 2 * np.pi, 2))
    right, left = u[:, :1] + [1, -1] * split[:, :1], u[:, 1:] + [1, -1] * split[:, 1:]
    wheels = np.column_stack([left[:, 0], right[:, 0], left[:, 1], right[:, 1]])  # WHEELS order
    angles = cumulative_trapezoid(wheels, t, axis=0, initial=0.0) + rng.uniform(-np.pi, np.pi, 4)

    # w[k] realised at exact IMU steps in the steady window, where u is held.
    k = np.arange(burn, n, fine)
    inside = k[(t[k] >= 3.0 - 1e-9) & (t[k] + dt <= duration - 2.0 + 1e-9)]
    Ad, Bd = np.exp(poles * dt), (np.expm1(poles * dt) / poles)[:, None] * B
    residual = x[inside + fine] - Ad * x[inside] - u[inside] @ Bd.T
    return {
        "t": t,
        "u": u,
        "x": x,
        "pose": np.column_stack([position, psi]),
        "wheels": wheels,
        "angles": angles,
        "fine": fine,
        "burn": burn,
        "force_sd": force_sd,
        "realised": residual.std(axis=0),
    }


#: The message definitions of ROS1 Noetic, in which the bags are written.
STORE = get_typestore(Stores.ROS1_NOETIC)


def _header(seq: int, stamp_ns: int, frame: str):
    """std_msgs/Header of a message numbered ``seq`` stamped ``stamp_ns`` [ns]."""
    sec, nanosec = divmod(int(stamp_ns), 10**9)
    time = STORE.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
    return STORE.types["std_msgs/msg/Header"](seq=int(seq), stamp=time, frame_id=frame)


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0):
    return STORE.types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


def _heading(psi: float):
    """The unit quaternion of a rotation by psi [rad] about z."""
    quaternion = STORE.types["geometry_msgs/msg/Quaternion"]
    return quaternion(x=0.0, y=0.0, z=math.sin(psi / 2), w=math.cos(psi / 2))


def imu_message(seq: int, stamp_ns: int, psi: float, gyro_z: float):
    """sensor_msgs/Imu: heading psi [rad], yaw rate gyro_z [rad/s], gravity, no covariances."""
    zeros = np.zeros(9)
    return STORE.types["sensor_msgs/msg/Imu"](
        header=_header(seq, stamp_ns, "imu_link"),
        orientation=_heading(psi),
        orientation_covariance=zeros,
        angular_velocity=_vector(z=gyro_z),
        angular_velocity_covariance=zeros,
        linear_acceleration=_vector(z=9.81),
        linear_acceleration_covariance=zeros,
    )


def pose_message(seq: int, stamp_ns: int, x: float, y: float, psi: float):
    """geometry_msgs/PoseStamped in the world frame: position (x, y, 0) [m], heading psi [rad]."""
    T = STORE.types
    point = T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0)
    return T["geometry_msgs/msg/PoseStamped"](
        header=_header(seq, stamp_ns, "world"),
        pose=T["geometry_msgs/msg/Pose"](position=point, orientation=_heading(psi)),
    )


def joint_message(seq: int, stamp_ns: int, angles: np.ndarray, speeds: np.ndarray):
    """sensor_msgs/JointState of the four wheels, WHEELS order: angles [rad], speeds [rad/s]."""
    return STORE.types["sensor_msgs/msg/JointState"](
        header=_header(seq, stamp_ns, ""),
        name=list(WHEELS),
        position=angles,
        velocity=speeds,
        effort=np.zeros(4),
    )


def twist_message(v: float, w: float):
    """geometry_msgs/Twist of a command: v [m/s] along x, w [rad/s] about z."""
    return STORE.types["geometry_msgs/msg/Twist"](linear=_vector(x=v), angular=_vector(z=w))


def received(rng: np.random.Generator, streams: dict) -> tuple[list, int]:
    """(receive time [ns], role, message) of every message in receive-time order; duplicates.

    ``streams`` maps a role of TOPICS to (header stamps [ns], messages). Receive
    time = stamp + a latency uniform in LATENCY. A fraction DUPLICATE_FRACTION
    of the poses is published twice, the copy's latency between the original's
    and 3 ms: before the next pose.
    """
    twice = np.flatnonzero(rng.random(len(streams["pose"][1])) < DUPLICATE_FRACTION)
    lag = {role: rng.uniform(*LATENCY, len(messages)) for role, (_, messages) in streams.items()}
    again = rng.uniform(lag["pose"][twice], LATENCY[1])
    rows = []
    for role, (stamps, messages) in streams.items():
        rows.extend(zip(stamps, lag[role], [role] * len(messages), messages, strict=True))
        if role == "pose":
            copies = [messages[i] for i in twice]
            rows.extend(zip(stamps[twice], again, [role] * len(twice), copies, strict=True))
    rows = [(int(s) + round(delay * 1e9), role, message) for s, delay, role, message in rows]
    rows.sort(key=lambda row: row[0])
    return rows, len(twice)


def write_ros1(path: Path, rows: list, topics: dict = TOPICS) -> None:
    """Write (receive time [ns], role, message) rows to a ROS1 bag, a connection per role."""
    with Writer(path) as writer:
        connections = {
            role: writer.add_connection(topic, msgtype, typestore=STORE)
            for role, (topic, msgtype) in topics.items()
        }
        for recv, role, message in rows:
            writer.write(connections[role], recv, STORE.serialize_ros1(message, topics[role][1]))


def write_mocap_bag(
    path: str | Path,
    *,
    d_lat: float = 110.0,
    d_long: float = 30.0,
    sigma_h: float = 0.047,
    sigma_c: tuple[float, float, float] = (0.005, 0.005, 0.01),
    v: float = 0.3,
    w: float = 0.3927,
    duration: float = 38.0,
    imu_rate: float = 72.0,
    pose_rate: float = 360.0,
    pose_sd: float = 0.5e-3,
    heading_sd: float = 0.002,
    gyro_sd: float = 0.005,
    pose_gaps: tuple[tuple[float, float], ...] = (),
    with_pose: bool = True,
    imu_lost: tuple[int, ...] = (),
    rng: np.random.Generator | int,
) -> MocapRun:
    """Simulate one run on a fine grid and write it as a ROS1 bag of four topics.

    Parameters
    ----------
    path : str or Path
        The bag to write; it must not exist (rosbags does not overwrite).
    d_lat, d_long : float
        Lateral and longitudinal damping [N s/m].
    sigma_h : float
        Width of the Gaussian noise kernel [s].
    sigma_c : tuple of float
        Target sd of the IMU-step residual w[k] for (vx [m/s], vy [m/s], yaw [rad/s]).
    v, w : float
        Commanded speed [m/s] and turn rate [rad/s] while held.
    duration : float
        Length of the run [s], rests and ramps included.
    imu_rate, pose_rate : float
        IMU and motion-capture rates [Hz].
    pose_sd, heading_sd, gyro_sd : float
        White sensor noise: position per axis [m], heading [rad], gyro [rad/s].
    pose_gaps : tuple of (float, float)
        Spans [start, stop) of true time [s] in which the motion capture lost
        the robot: no pose messages there (dropouts).
    with_pose : bool
        Whether the bag has the motion-capture topic at all (False: a lab
        without one; the run's truth still holds the poses).
    imu_lost : tuple of int
        IMU messages (by index, not the first) that never reached the bag;
        ``imu_t`` and ``states`` still hold their instants and truth.
    rng : numpy.random.Generator or int
        Source of all randomness (an int seeds a new Generator).

    Returns
    -------
    MocapRun
        The bag's path, the true parameters, states and poses.
    """
    rng = np.random.default_rng(rng)
    path = Path(path)
    sim = _truth(rng, d_lat, d_long, sigma_h, sigma_c, (v, w, duration), imu_rate)
    t, fine, burn = sim["t"], sim["fine"], sim["burn"]
    # Each sensor samples the truth at the true instants of its own clock; the
    # header stamps report them with jitter. The IMU's instants k dt lie on the
    # fine grid; the others' truth is interpolated linearly, erring by h^2/8 |x''|:
    # < 1e-7 m and rad for the pose, < 1e-6 rad for wheel angles. Wheel speeds
    # are exact but within h of a ramp's corner (<= h/4 * 4.2 rad/s^2 there).
    imu_index = burn + fine * np.arange(round(duration * imu_rate) + 1)
    imu_true = t[imu_index]
    pose_true = free_clock(rng, pose_rate, duration)
    pose_seq = np.flatnonzero(rng.random(len(pose_true)) >= DROP_FRACTION)  # seq gaps: drops
    for start, stop in pose_gaps:  # tracking lost: no messages
        pose_seq = pose_seq[(pose_true[pose_seq] < start) | (pose_true[pose_seq] >= stop)]
    dropped = len(pose_true) - len(pose_seq)
    pose_true = pose_true[pose_seq]
    joint_true = free_clock(rng, JOINT_RATE, duration)
    cmd_true = free_clock(rng, CMD_RATE, duration)

    def stamp(instants: np.ndarray, jitter: float) -> np.ndarray:
        noisy = instants + jitter * rng.standard_normal(len(instants))
        return EPOCH_NS + np.round(noisy * 1e9).astype(np.int64)

    imu_stamp, pose_stamp = stamp(imu_true, IMU_JITTER), stamp(pose_true, POSE_JITTER)
    joint_stamp, cmd_stamp = stamp(joint_true, JOINT_JITTER), stamp(cmd_true, 0.0)
    gyro = sim["x"][imu_index, 2] + gyro_sd * rng.standard_normal(len(imu_index))
    pose_at = interp_columns(pose_true, t, sim["pose"])
    measured = pose_at + [pose_sd, pose_sd, heading_sd] * rng.standard_normal(pose_at.shape)
    speeds = interp_columns(joint_true, t, sim["wheels"])
    angles = interp_columns(joint_true, t, sim["angles"])
    command = command_profile(cmd_true, v, w, duration)

    imu = [
        imu_message(k, imu_stamp[k], sim["pose"][i, 2], gyro[k]) for k, i in enumerate(imu_index)
    ]
    imu_kept = np.setdiff1d(np.arange(len(imu)), imu_lost)
    pose = [
        pose_message(seq, s, px, py, psi)
        for seq, s, (px, py, psi) in zip(pose_seq, pose_stamp, measured, strict=True)
    ]
    joints = [
        joint_message(k, joint_stamp[k], angles[k], speeds[k]) for k in range(len(joint_true))
    ]
    cmd = [twist_message(cv, cw) for cv, cw in command]
    streams = {
        "imu": (imu_stamp[imu_kept], [imu[k] for k in imu_kept]),
        "pose": (pose_stamp, pose),
        "joint_states": (joint_stamp, joints),
        "cmd_vel": (cmd_stamp, cmd),
    }
    rows, duplicates = received(rng, streams)
    if not with_pose:  # a lab without motion capture: no such topic
        rows = [row for row in rows if row[1] != "pose"]
    topics = {role: topic for role, topic in TOPICS.items() if with_pose or role != "pose"}
    write_ros1(path, rows, topics)

    origin = (int(imu_stamp[0]) - EPOCH_NS) * 1e-9  # the first IMU stamp is time zero

    def channels(values):
        return {c: float(value) for c, value in zip(STATE, values, strict=True)}

    truth = dict(d_lat=d_lat, d_long=d_long, sigma_h=sigma_h, sigma_c=channels(sigma_c))
    truth.update(sigma_c_realised=channels(sim["realised"]), force_sd=channels(sim["force_sd"]))
    truth.update(pose_sd=pose_sd, heading_sd=heading_sd, gyro_sd=gyro_sd)
    truth.update(imu_rate=imu_rate, pose_rate=pose_rate, fine=fine)
    truth.update(command={"v": v, "w": w, "duration": duration})
    truth.update(pose_duplicates=duplicates, pose_dropped=dropped)
    return MocapRun(
        path=path,
        truth=truth,
        imu_t=imu_true - origin,
        states=sim["x"][imu_index],
        steady_window=(3.0, duration - 2.0),
        pose_t=pose_true - origin,
        poses=pose_at,
    )


def write_mocap_pair(folder: str | Path, *, seed: int | list[int], **options) -> list[MocapRun]:
    """A thesis v1 and v2 run, ``folder``/v1.bag and v2.bag, with independent noise.

    Parameters
    ----------
    folder : str or Path
        Existing folder to write into.
    seed : int or list of int
        Seed of a numpy SeedSequence; each run gets one of its two spawned children.
    **options
        Keyword options of :func:`write_mocap_bag` other than v, w, duration and rng.

    Returns
    -------
    list of MocapRun
        The v1 run, then the v2 run.
    """
    children = np.random.SeedSequence(seed).spawn(len(THESIS_COMMANDS))
    return [
        write_mocap_bag(
            Path(folder) / f"{name}.bag",
            v=v,
            w=w,
            duration=duration,
            rng=np.random.default_rng(child),
            **options,
        )
        for (name, (v, w, duration)), child in zip(THESIS_COMMANDS.items(), children, strict=True)
    ]
