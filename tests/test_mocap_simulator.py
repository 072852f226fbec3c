"""Checks of tests/mocap_simulator.py, the independent motion-capture bag simulator.

The bags are read back with rosbags alone and the truth is checked against
this file's own model: A, B from models/jackal.toml and the zero-order hold by
scipy's matrix exponential (the simulator uses closed forms per channel).
Tolerances are stated in sds of the estimator for the run's length and the
noise's correlation; every run is seeded, so the checks are deterministic,
and the sds say how unlikely a failure is under a correct simulator.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from mocap_simulator import write_mocap_bag, write_mocap_pair
from rosbags.highlevel import AnyReader

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

JACKAL = tomllib.loads((Path(__file__).parents[1] / "models" / "jackal.toml").read_text())
TOPICS = {
    "/imu/data": "sensor_msgs/msg/Imu",
    "/mocap_node/Jackal/pose": "geometry_msgs/msg/PoseStamped",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/cmd_vel": "geometry_msgs/msg/Twist",
}
#: Allowed departures of a statistic from its target, in sds of its estimator.
Z = 4.0


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A thesis v1/v2 pair with the pose at 360 Hz and a v1 run with the pose at 120 Hz."""
    folder = tmp_path_factory.mktemp("mocap")
    v1, v2 = write_mocap_pair(folder, seed=2024)
    slow = write_mocap_bag(folder / "v1_120.bag", pose_rate=120.0, rng=7)
    return {"v1-360": v1, "v2-360": v2, "v1-120": slow}


def read_topics(path: Path) -> dict[str, list]:
    """(receive time [ns], message) per topic, in the bag's order."""
    messages: dict[str, list] = {}
    with AnyReader([path]) as reader:
        for connection, time, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            messages.setdefault(connection.topic, []).append((time, message))
    return messages


def stamp_ns(message) -> int:
    return message.header.stamp.sec * 10**9 + message.header.stamp.nanosec


def model(truth: dict):
    """(A, B, Ad, Bd) of eq. 4-32 at the IMU step, from jackal.toml (not from the simulator)."""
    body = JACKAL["body"]
    m, inertia, r = body["mass"], body["yaw_inertia"], body["wheel_radius"]
    a, b, d_lat, d_long = (
        body["half_wheelbase"],
        body["half_track"],
        truth["d_lat"],
        truth["d_long"],
    )
    A = np.diag([-4 * d_long / m, -4 * d_lat / m, -4 * (b**2 * d_long + a**2 * d_lat) / inertia])
    B = 2 * d_long * r * np.array([[1 / m, 1 / m], [0, 0], [b / inertia, -b / inertia]])
    block = np.zeros((5, 5))
    block[:3, :3], block[:3, 3:] = A, B
    exponential = scipy.linalg.expm(block / truth["imu_rate"])
    return A, B, exponential[:3, :3], exponential[:3, 3:]


def held_input(truth: dict) -> np.ndarray:
    """Wheel speeds (omega_r, omega_l) [rad/s] of the held command (ROS diff_drive)."""
    drive, command = JACKAL["diff_drive"], truth["command"]
    half = command["w"] * drive["wheel_separation"] * drive["wheel_separation_multiplier"] / 2
    return np.array([command["v"] + half, command["v"] - half]) / JACKAL["body"]["wheel_radius"]


def steady_residuals(run) -> np.ndarray:
    """w[k] = x[k+1] - Ad x[k] - Bd u of the true states, steps inside the steady window."""
    # The true IMU instants are exact IMU steps (only the stamps are jittered).
    np.testing.assert_allclose(np.diff(run.imu_t), 1 / run.truth["imu_rate"], atol=1e-9)
    *_, Ad, Bd = model(run.truth)
    lo, hi = run.steady_window
    # Steps from t_k >= lo to t_{k+1} <= hi; 1 ms of slack for the stamp of time zero.
    step = 1 / run.truth["imu_rate"]
    k = np.flatnonzero((run.imu_t >= lo - 1e-3) & (run.imu_t + step <= hi + 1e-3))
    return run.states[k + 1] - run.states[k] @ Ad.T - Bd @ held_input(run.truth)


def gaussian_acf(lag: np.ndarray, truth: dict) -> np.ndarray:
    """exp(-tau^2 / (4 sigma_h^2)) at tau = lag / imu_rate."""
    return np.exp(-((lag / truth["imu_rate"]) ** 2) / (4 * truth["sigma_h"] ** 2))


@pytest.mark.parametrize("name", ["v1-360", "v2-360", "v1-120"])
def test_bag_topics_counts_and_stamps(runs, name):
    run = runs[name]
    truth, duration = run.truth, run.truth["command"]["duration"]
    topics = read_topics(run.path)
    with AnyReader([run.path]) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == TOPICS
    # Every clock starts within its first step, so the counts are exact.
    assert len(topics["/imu/data"]) == round(duration * truth["imu_rate"]) + 1
    assert len(topics["/joint_states"]) == round(duration * 50)
    assert len(topics["/cmd_vel"]) == round(duration * 20)
    # Pose: about 0.2 % dropped and 0.5 % published twice, binomial counts
    # within Z sds of their means.
    nominal = round(duration * truth["pose_rate"])
    stamps = [stamp_ns(m) for _, m in topics["/mocap_node/Jackal/pose"]]
    distinct = len(set(stamps))
    dropped, duplicates = nominal - distinct, len(stamps) - distinct
    for count, p, n in [(dropped, 0.002, nominal), (duplicates, 0.005, distinct)]:
        assert abs(count - n * p) <= Z * np.sqrt(n * p * (1 - p)), (count, n * p)
    assert (dropped, duplicates) == (truth["pose_dropped"], truth["pose_duplicates"])
    # A drop leaves a gap in seq; a duplicate repeats its message.
    seqs = {m.header.seq for _, m in topics["/mocap_node/Jackal/pose"]}
    assert max(seqs) + 1 - len(seqs) == dropped
    # Receive time = header stamp + 1-3 ms (1 ns of rounding).
    for topic in ("/imu/data", "/mocap_node/Jackal/pose", "/joint_states"):
        latency = np.array([t - stamp_ns(m) for t, m in topics[topic]])
        assert latency.min() >= 1e6 - 1 and latency.max() <= 3e6 + 1
        assert np.all(np.diff(np.array([stamp_ns(m) for _, m in topics[topic]])) >= 0)
    joint = topics["/joint_states"][len(topics["/joint_states"]) // 2][1]
    assert list(joint.name) == [
        "front_left_wheel",
        "front_right_wheel",
        "rear_left_wheel",
        "rear_right_wheel",
    ]
    # Front and rear of a side differ by at most 0.01 rad/s each way.
    assert np.all(np.abs(joint.velocity[:2] - joint.velocity[2:]) <= 0.02 + 1e-12)


def test_process_noise_scale(runs):
    z = []
    for run in runs.values():
        residual = steady_residuals(run)
        realised = residual.std(axis=0)
        np.testing.assert_allclose(realised, list(run.truth["sigma_c_realised"].values()))
        # Var of a sample variance of a correlated Gaussian series: 2 s^4 / N *
        # sum_m rho(m)^2, so sd(s_hat) / s = sqrt(sum rho^2 / (2 N)). For
        # sigma_h = 47 ms at 72 Hz, sum rho^2 = 8.5 and N = 2375 give 4.2 %.
        lags = np.arange(-200, 201)
        spread = np.sqrt(np.sum(gaussian_acf(lags, run.truth) ** 2) / (2 * len(residual)))
        z.extend((realised / list(run.truth["sigma_c"].values()) - 1) / spread)
        # The force is nearly constant over a step (its correlation time 66 ms
        # >> 13.9 ms), so w ~ xi (e^{a dt} - 1) / a: the scale agrees with
        # sigma_c to O((dt / sigma_h)^2 / 24) ~ 0.4 % (1 % allowed).
        A, *_ = model(run.truth)
        gain = np.abs(np.expm1(np.diag(A) / run.truth["imu_rate"]) / np.diag(A))
        force = np.array(list(run.truth["force_sd"].values()))
        np.testing.assert_allclose(force * gain, list(run.truth["sigma_c"].values()), rtol=0.01)
    z = np.array(z)
    # Each channel of each run within Z sds (4.2 % each for v1), and the mean
    # of the 9 independent z-scores within Z / 3.
    assert np.all(np.abs(z) < Z), z
    assert abs(z.mean()) < Z / np.sqrt(len(z)), z


def test_yaw_residual_autocorrelation(runs):
    lags = np.array([1, 2])
    differences, variances = [], []
    for run in runs.values():
        w = steady_residuals(run)[:, 2]
        n = len(w)
        acf = np.array([np.mean(w[:-m] * w[m:]) for m in lags]) / np.mean(w**2)
        rho = gaussian_acf(np.arange(-300, 301), run.truth)
        # Bartlett's variance of a sample autocorrelation at lag k:
        # (1/N) sum_m [rho(m+k)^2 + rho(m-k) rho(m+k) - 4 rho(k) rho(m) rho(m+k)
        # + 2 rho(k)^2 rho(m)^2]; ~0.0016 (lag 1) and 0.0061 (lag 2) at N = 2375.
        variance = []
        for k in lags:
            rk, plus, minus = gaussian_acf(k, run.truth), np.roll(rho, -k), np.roll(rho, k)
            terms = plus**2 + minus * plus - 4 * rk * rho * plus + 2 * rk**2 * rho**2
            variance.append(np.sum(terms) / n)
        differences.append(acf - gaussian_acf(lags, run.truth))
        variances.append(variance)
    differences, sds = np.array(differences), np.sqrt(np.array(variances))
    # Besides chance: w integrates xi over a step, which raises its ACF above
    # xi's by 1.5e-4 (lag 1) and 5.8e-4 (lag 2) (computed on the fine grid),
    # and the ratio estimator is biased low by O(sum rho^2 / N) ~ 5e-4: 2e-3 allowed.
    allowance = 2e-3
    assert np.all(np.abs(differences) < Z * sds + allowance), (differences, sds)
    # The mean over the three independent runs: lag 2 then pins sigma_h to ~15 %.
    pooled = np.sqrt(np.sum(sds**2, axis=0)) / len(sds)
    assert np.all(np.abs(differences.mean(axis=0)) < Z * pooled + allowance)


@pytest.mark.parametrize("name", ["v1-360", "v2-360", "v1-120"])
def test_pose_noise(runs, name):
    run, truth = runs[name], runs[name].truth
    topics = read_topics(run.path)
    origin = stamp_ns(topics["/imu/data"][0][1])
    first: dict[int, object] = {}
    for _, message in topics["/mocap_node/Jackal/pose"]:
        first.setdefault(stamp_ns(message), message.pose)
    stamps = np.array(sorted(first))
    poses = [first[s] for s in stamps]
    assert len(poses) == len(run.pose_t)
    # Stamps are the true instants plus 0.05 ms of jitter, and time zero is
    # the first IMU stamp (its own 0.1 ms jitter): within 0.5 ms is > 4 sds.
    assert np.max(np.abs((stamps - origin) * 1e-9 - run.pose_t)) < 5e-4
    position = np.array([(p.position.x, p.position.y) for p in poses])
    quaternion = np.array([(p.orientation.z, p.orientation.w) for p in poses])
    np.testing.assert_allclose(np.hypot(*quaternion.T), 1.0, atol=1e-12)
    heading = 2 * np.arctan2(quaternion[:, 0], quaternion[:, 1])
    errors = {
        "pose_sd": (position - run.poses[:, :2]).ravel(),
        "heading_sd": np.angle(np.exp(1j * (heading - run.poses[:, 2]))),
    }
    for key, error in errors.items():
        # White noise: sd(s_hat) / s = 1 / sqrt(2 n), 0.4 % for 2 x 13600
        # samples, 1.3 % for 4500; the mean within Z sd / sqrt(n).
        n, sd = len(error), truth[key]
        assert abs(error.std() / sd - 1) < Z / np.sqrt(2 * n), (key, error.std())
        assert abs(error.mean()) < Z * sd / np.sqrt(n), (key, error.mean())


def test_steady_yaw_rate_matches_model(runs):
    for run in runs.values():
        truth = run.truth
        A, B, *_ = model(truth)
        steady = -np.linalg.solve(A, B @ held_input(truth))
        # Sanity of the model: vx settles at v exactly; yaw well below the command.
        assert steady[0] == pytest.approx(truth["command"]["v"], rel=1e-12)
        topics = read_topics(run.path)
        imu = topics["/imu/data"]
        t = np.array([stamp_ns(m) - stamp_ns(imu[0][1]) for _, m in imu]) * 1e-9
        gyro = np.array([m.angular_velocity.z for _, m in imu])
        lo, hi = run.steady_window
        inside = (t >= lo) & (t <= hi)
        # The mean of r's noise over T: the force's spectrum at zero,
        # force_sd^2 * 2 sqrt(pi) sigma_h, divided by a^2 and T. For v1 that is
        # 0.0026 rad/s (1.2 % of 0.217), plus the gyro's 0.005 / sqrt(N).
        a = A[2, 2]
        span = hi - lo
        force = truth["force_sd"]["yaw"]
        sd = np.hypot(
            force / abs(a) * np.sqrt(2 * np.sqrt(np.pi) * truth["sigma_h"] / span),
            truth["gyro_sd"] / np.sqrt(inside.sum()),
        )
        assert abs(gyro[inside].mean() - steady[2]) < Z * sd, (gyro[inside].mean(), steady[2])
        assert steady[2] < 0.6 * truth["command"]["w"]


def test_true_pose_moves_with_the_true_velocities(runs):
    """Central differences of the true pose, in the body frame, match the true states."""
    run = runs["v1-360"]
    t, (x, y, psi) = run.pose_t, run.poses.T
    inside = np.flatnonzero((t > run.steady_window[0]) & (t < run.steady_window[1]))
    gap = t[inside + 1] - t[inside - 1]
    dx, dy = (x[inside + 1] - x[inside - 1]) / gap, (y[inside + 1] - y[inside - 1]) / gap
    c, s = np.cos(psi[inside]), np.sin(psi[inside])
    body = np.column_stack(
        [c * dx + s * dy, -s * dx + c * dy, (psi[inside + 1] - psi[inside - 1]) / gap]
    )
    truth = np.column_stack([np.interp(t[inside], run.imu_t, run.states[:, i]) for i in range(3)])
    # Errors: central difference over <= 5.6 ms (a drop doubles it), h^2/6 |x'''|,
    # and linear interpolation of the states at 72 Hz, dt^2/8 |x''| ~ 1e-3 at
    # worst; the rms is smaller. A sign error in vy or a missing rotation
    # would leave errors of the size of the states' noise (~0.01).
    rms = np.sqrt(np.mean((body - truth) ** 2, axis=0))
    assert np.all(rms < [1e-3, 1e-3, 2e-3]), rms
    assert np.all(np.std(truth, axis=0) > 5e-3)


def test_pair_is_reproducible_and_independent(runs, tmp_path):
    v1, v2 = runs["v1-360"], runs["v2-360"]
    assert (v1.path.name, v2.path.name) == ("v1.bag", "v2.bag")
    assert v1.truth["command"]["duration"] == 38.0 and v2.truth["command"]["duration"] == 26.0
    assert v2.truth["command"]["w"] == pytest.approx(np.deg2rad(30.0))
    again = write_mocap_pair(tmp_path, seed=2024, pose_rate=120.0)
    # The truth is drawn before the sensors: the same seed gives the same states.
    np.testing.assert_array_equal(again[0].states, v1.states)
    np.testing.assert_array_equal(again[1].states, v2.states)
    n = len(v2.imu_t)
    assert not np.allclose(v1.states[:n, 2], v2.states[:, 2], atol=1e-3)
    with pytest.raises(Exception, match="exists"):
        write_mocap_bag(v1.path, rng=0)
