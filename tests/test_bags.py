"""ROS bags: simulated experiment -> bag -> experiment recovers the truth; bad bags fail clearly.

Tolerances of the end-to-end tests:

- yaw rate and wheel speeds: the IMU and joint-state stamps are the
  simulator's sample times, so resampling onto the IMU clock only moves each
  sample by the drift of the median step (a whole number of ns) over the run,
  < 1 us; with |dr/dt| and |d omega/dt| < 10 rad/s^2 that is < 1e-5 rad/s.
- vx, vy derived from exact poses (the fixture's bags have no pose noise):
  the Savitzky-Golay slope over 0.1 s (order 2) is a weighted average of
  the velocity over +-0.05 s with non-negative (parabolic) weights, so its
  error at a sample cannot exceed the range the true velocity spans within
  +-4 samples (+-0.056 s at 72 Hz). The slack of 5e-4 m/s covers the
  interpolation between the 1,440 Hz path, the 360 Hz poses and the IMU
  grid. The bound is checked on the simulator's steady window (the ramps
  are where the range is large anyway); the RMS error there is also below
  the simulator's vx/vy sensor noise (0.003 m/s).
- the poses kept (noisy bags): the recorded pose minus the writer's true
  path at its stamp has the writer's sd; over ~9,000 poses per axis its
  sample sd is within 3 % of the truth (its relative sd is 1 / sqrt(2 n)
  = 0.75 %: 4 sd).
- steady window: the input is constant from the end of the ramp (2.0 s)
  until the ramp down (24.0 s); the simulator's window starts a deliberate
  1 s later (SETTLE). With the 0.25 s moving average and the 5 % input
  tolerance the detected start lies in [1.9 s, 3.0 s] and the end within
  0.1 s of 24.0 s.
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from bayes_jackal._runtime.errors import DataError, InputError
from bayes_jackal.io.bag_reading import typestore
from bayes_jackal.io.bag_writer import (
    BagMessage,
    bag_messages,
    pose_path,
    write_bag,
    write_messages,
)
from bayes_jackal.io.bags import read_bag
from bayes_jackal.io.experiment import read_netcdf, write_netcdf
from bayes_jackal.io.segments import STEP_TOLERANCE
from bayes_jackal.io.simulate import simulate_experiment
from bayes_jackal.model.robot import load_profile

ROBOT = load_profile()
IMU = ROBOT.topics["imu"]
POSE = ROBOT.topics["pose"]
JOINTS = ROBOT.topics["joint_states"]
NS = 1_000_000_000
#: Resampling tolerance of yaw rate and wheel speeds [rad/s] (module text).
RESAMPLE_ATOL = 1e-5
#: Slack on the smoothing bound of vx, vy [m/s] and the RMS ceiling (module text).
VELOCITY_SLACK = 5e-4
VELOCITY_RMS = 0.003


@pytest.fixture(scope="module")
def simulated():
    return simulate_experiment(ROBOT, 110, 30, "v2", rng=np.random.default_rng(7))


@pytest.fixture(scope="module")
def bags(simulated, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bags")
    return {
        name: write_bag(simulated, folder / name, ROBOT, format, rng=3, pose_noise=(0.0, 0.0))
        for name, format in (("run.bag", "ros1"), ("run.mcap", "ros2"), ("run.db3", "ros2"))
    }


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _read_unchanged(path: Path, **kwargs):
    """read_bag, checking that the file's bytes are the same afterwards."""
    before = _sha(path)
    try:
        return read_bag(path, ROBOT, **kwargs)
    finally:
        assert _sha(path) == before


@pytest.mark.parametrize("name", ["run.bag", "run.mcap", "run.db3"])
def test_bag_round_trip_recovers_the_simulation(bags, simulated, name):
    path = bags[name]
    experiment = _read_unchanged(path)
    n = len(simulated.t)
    assert len(experiment.t) == n
    np.testing.assert_allclose(experiment.t, simulated.t, atol=1e-6)
    np.testing.assert_allclose(experiment.yaw_rate, simulated.yaw_rate, atol=RESAMPLE_ATOL)
    np.testing.assert_allclose(experiment.omega_r, simulated.omega_r, atol=RESAMPLE_ATOL)
    np.testing.assert_allclose(experiment.omega_l, simulated.omega_l, atol=RESAMPLE_ATOL)

    start, stop = simulated.steady_window
    steady = (simulated.t >= start) & (simulated.t <= stop)
    for channel in ("vx", "vy"):
        truth = simulated.truth_arrays[f"{channel}_state"]
        local_range = maximum_filter1d(truth, 9) - minimum_filter1d(truth, 9)
        error = np.abs(getattr(experiment, channel) - truth)
        assert (error[steady] <= local_range[steady] + VELOCITY_SLACK).all(), channel
        assert np.sqrt(np.mean(error[steady] ** 2)) < VELOCITY_RMS, channel

    detected = experiment.steady_window
    assert 1.9 <= detected[0] <= start
    assert abs(detected[1] - stop) <= 0.1

    provenance = experiment.provenance
    assert provenance["sha256"] == _sha(path)
    assert provenance["format"] == ("ros1" if name.endswith(".bag") else "ros2")
    assert provenance["topics"]["imu"] == {
        "topic": IMU,
        "msgtype": "sensor_msgs/msg/Imu",
        "messages": n,
    }
    assert provenance["steady_window_source"] == "detected"
    assert any(POSE in r and "duplicate stamps" in r for r in provenance["repairs"])
    assert provenance["command"]["v"] == pytest.approx(0.4)


def test_the_poses_are_kept_as_recorded_with_the_writers_noise(simulated, tmp_path):
    noise = (5e-4, 0.002)
    path = write_bag(simulated, tmp_path / "noisy.bag", ROBOT, "ros1", rng=3, pose_noise=noise)
    experiment = _read_unchanged(path)
    pose = experiment.pose
    assert experiment.measurement("vx") == "pose" and experiment.measurement("yaw") == "rate"
    fine_t, path_true = pose_path(simulated, ROBOT)
    # The bag's time zero is its first IMU stamp, the simulator's first sample.
    truth = np.column_stack([np.interp(pose.t, fine_t, column) for column in path_true.T])
    errors = np.column_stack([pose.x, pose.y, pose.heading]) - truth
    np.testing.assert_allclose(errors.std(axis=0), [noise[0], noise[0], noise[1]], rtol=0.03)
    assert np.all(np.diff(pose.t) > 0)  # the duplicates dropped, sorted
    # They cover the run (its grid is the IMU's within a ns drift per step).
    assert pose.t[0] <= experiment.t[0] + 1e-6 and pose.t[-1] >= experiment.t[-1] - 1e-6
    again = read_netcdf(write_netcdf(experiment, tmp_path / "noisy.nc"))
    for field in ("t", "x", "y", "heading"):
        np.testing.assert_array_equal(getattr(again.pose, field), getattr(pose, field))


def test_window_override_and_netcdf(bags, tmp_path):
    experiment = read_bag(bags["run.mcap"], ROBOT, window=(5.0, 20.0))
    assert experiment.steady_window == (5.0, 20.0)
    assert experiment.provenance["steady_window_source"] == "user"
    again = read_netcdf(write_netcdf(experiment, tmp_path / "run.nc"))
    assert again.provenance == experiment.provenance
    np.testing.assert_array_equal(again.vx, experiment.vx)
    with pytest.raises(DataError, match="window"):
        read_bag(bags["run.mcap"], ROBOT, window=(40.0, 50.0))


def test_write_bag_is_atomic_and_checks_the_suffix(simulated, tmp_path):
    with pytest.raises(InputError, match="must end in"):
        write_bag(simulated, tmp_path / "run.bag", ROBOT, "ros2")
    with pytest.raises(InputError, match="simulated"):
        plain = dataclasses.replace(simulated, truth_arrays={})
        write_bag(plain, tmp_path / "run.bag", ROBOT, "ros1")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- repairs


@pytest.fixture(scope="module")
def messages(simulated):
    """Fresh ROS2 messages per use (tests modify them)."""
    return lambda: bag_messages(simulated, ROBOT, "ros2", rng=3)


def _stamp_seconds(message: BagMessage) -> float:
    stamp = message.message.header.stamp
    return stamp.sec - 1_700_000_000 + stamp.nanosec * 1e-9


def _set_stamp(message: BagMessage, ns: int) -> None:
    Time = typestore("ros2").types["builtin_interfaces/msg/Time"]
    message.message.header.stamp = Time(sec=ns // NS, nanosec=ns % NS)


def _stamp_ns(message: BagMessage) -> int:
    stamp = message.message.header.stamp
    return stamp.sec * NS + stamp.nanosec


def test_zero_header_stamps_use_receive_time(messages, simulated, tmp_path):
    batch = messages()
    zeroed = [m for m in batch if m.topic == JOINTS and 10 < _stamp_seconds(m) < 11]
    for m in zeroed:
        _set_stamp(m, 0)
    experiment = _read_unchanged(write_messages(batch, tmp_path / "zero.mcap"))
    repairs = experiment.provenance["repairs"]
    assert any(f"{len(zeroed)} of" in r and "zero header" in r for r in repairs)
    # Constant input there: the 2 ms receive latency does not matter.
    np.testing.assert_allclose(experiment.omega_r, simulated.omega_r, atol=RESAMPLE_ATOL)


def test_out_of_order_stamps_are_sorted(messages, simulated, tmp_path):
    batch = messages()
    imu = [m for m in batch if m.topic == IMU]
    first, second = imu[500], imu[501]
    batch[batch.index(first)] = BagMessage(IMU, first.msgtype, second.time + 1, first.message)
    batch.sort(key=lambda m: m.time)
    experiment = _read_unchanged(write_messages(batch, tmp_path / "order.mcap"))
    assert any("1 out-of-order" in r for r in experiment.provenance["repairs"])
    np.testing.assert_allclose(experiment.yaw_rate, simulated.yaw_rate, atol=RESAMPLE_ATOL)


def test_a_joint_state_dropout_splits_the_run(messages, tmp_path):
    batch = [m for m in messages() if not (m.topic == JOINTS and 8.0 < _stamp_seconds(m) < 8.5)]
    path = write_messages(batch, tmp_path / "gap.mcap")
    experiment = _read_unchanged(path)
    assert 8.5 <= experiment.t[0] < 8.52
    repairs = " ".join(experiment.provenance["repairs"])
    assert "dropout" in repairs and "cut at dropouts" in repairs
    # Shorter than the IMU's step: every step is a gap of its clock.
    with pytest.raises(DataError, match="/imu/data: no stretch of 3 samples without a gap"):
        _read_unchanged(path, max_gap=0.001)


# Bags simulated independently of the package (tests/mocap_simulator.py): an
# 8 s run (1 s rest, 1 s ramp, 4 s hold, 1 s ramp down, 1 s rest; the IMU at
# 72 Hz, motion capture at 120 Hz, the command at 20 Hz).
MOCAP = {"duration": 8.0, "pose_rate": 120.0}


@pytest.mark.parametrize("lost", [1.0, 2.0])
def test_a_pose_dropout_keeps_the_whole_run_and_its_gap(tmp_path, lost):
    from mocap_simulator import write_mocap_bag

    gap = (3.0, 3.0 + lost)
    run = write_mocap_bag(tmp_path / "lost.bag", pose_gaps=(gap,), rng=5, **MOCAP)
    experiment = _read_unchanged(run.path)
    # The whole run: the span all topics cover, the joint states' (50 Hz, from a
    # random phase) within a step of its ends, on the IMU's next tick (1/72 s).
    assert experiment.t[0] <= 1 / 50 + 1 / 72
    assert experiment.t[-1] >= MOCAP["duration"] - 1 / 50 - 1 / 72
    assert experiment.measurement("vx") == "pose"
    # The poses keep their gap: lost plus up to a pose step at each end.
    assert lost <= np.diff(experiment.pose.t).max() <= lost + 2 / MOCAP["pose_rate"]
    repairs = experiment.provenance["repairs"]
    assert [r for r in repairs if "dropout" in r] == [
        r for r in repairs if r.startswith(POSE) and "the poses are kept with their gap" in r
    ]
    assert len([r for r in repairs if "dropout" in r]) == 1
    assert not any("cut at dropouts" in r for r in repairs)


def test_a_bag_without_poses_is_a_yaw_rate_experiment_with_a_note(tmp_path):
    from mocap_simulator import write_mocap_bag

    run = write_mocap_bag(tmp_path / "imu_only.bag", with_pose=False, rng=5, **MOCAP)
    with pytest.warns(UserWarning, match=r"pose: topic '/mocap_node/Jackal/pose' not in the"):
        experiment = _read_unchanged(run.path)
    assert experiment.channels == ("yaw",)
    assert experiment.vx is None and experiment.pose is None
    assert experiment.provenance["pose_rate"] is None
    assert any("yaw-rate-only experiment" in r for r in experiment.provenance["repairs"])
    # Its yaw rate is the gyro's (sd 0.005 rad/s about the truth; 5 sd).
    error = experiment.yaw_rate - np.interp(experiment.t, run.imu_t, run.states[:, 2])
    assert np.abs(error).max() < 5 * run.truth["gyro_sd"]


def test_the_ticks_the_imu_missed_are_marked_unmeasured(tmp_path):
    from mocap_simulator import write_mocap_bag

    lost = (300, 301, 302)  # 3 messages: a gap of 4 steps, filled (max_gap 0.25 s = 18 steps)
    run = write_mocap_bag(tmp_path / "lost_imu.bag", imu_lost=lost, rng=5, **MOCAP)
    experiment = _read_unchanged(run.path)
    # The unmeasured ticks are those of the lost messages (within the IMU's
    # stamp jitter, 0.1 ms, and its clock's fit; a tick is 14 ms).
    mask = experiment.observed("yaw")
    assert (~mask).sum() == len(lost)
    np.testing.assert_allclose(experiment.t[~mask], run.imu_t[list(lost)], atol=1e-3)
    assert experiment.provenance["imu_clock"]["interpolated"] == len(lost)
    assert "across the ticks it missed" in experiment.provenance["input"]["interpolated"]


def test_the_segments_of_a_bag_are_the_steps_of_its_cmd_vel(tmp_path):
    from mocap_simulator import wheel_speeds, write_mocap_bag

    run = write_mocap_bag(tmp_path / "steps.bag", rng=5, **MOCAP)
    experiment = _read_unchanged(run.path)
    # The command ramps (1 s) from rest at 1.0 s and from its hold at 6.0 s
    # (duration - 2) and has moved by the tolerance once the faster wheel's
    # command has: STEP_TOLERANCE / its held speed into the ramp. The reader
    # sees the first 20 Hz message after that, received 1-3 ms after its
    # stamp, on the next 72 Hz tick: within 0.05 + 0.003 + 1/72 s more.
    command = run.truth["command"]
    leave = STEP_TOLERANCE / wheel_speeds(command["v"], command["w"]).max()
    assert experiment.segments[0] == 0 and len(experiment.segments) == 3
    starts = experiment.t[experiment.segments[1:]] - [1.0, 6.0]
    assert ((starts >= leave) & (starts <= leave + 0.05 + 0.003 + 1 / 72)).all()
    assert experiment.provenance["segments"]["from"] == "/cmd_vel"


def test_odometry_pose_is_accepted(messages, simulated, tmp_path):
    types = typestore("ros2").types
    batch = []
    for m in messages():
        if m.topic == POSE:
            odometry = types["nav_msgs/msg/Odometry"](
                header=m.message.header,
                child_frame_id="base_link",
                pose=types["geometry_msgs/msg/PoseWithCovariance"](
                    pose=m.message.pose, covariance=np.zeros(36)
                ),
                twist=types["geometry_msgs/msg/TwistWithCovariance"](
                    twist=types["geometry_msgs/msg/Twist"](
                        linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                        angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                    ),
                    covariance=np.zeros(36),
                ),
            )
            m = BagMessage(POSE, "nav_msgs/msg/Odometry", m.time, odometry)
        batch.append(m)
    experiment = _read_unchanged(write_messages(batch, tmp_path / "odometry.mcap"))
    assert experiment.provenance["topics"]["pose"]["msgtype"] == "nav_msgs/msg/Odometry"
    reference = read_bag(write_messages(messages(), tmp_path / "pose.mcap"), ROBOT)
    np.testing.assert_array_equal(experiment.vx, reference.vx)


# --------------------------------------------------------------------------- bad input


def test_truncated_and_corrupt_bags(bags, tmp_path):
    for name in ("run.bag", "run.mcap"):
        truncated = tmp_path / f"truncated_{name}"
        truncated.write_bytes(bags[name].read_bytes()[: bags[name].stat().st_size // 2])
        with pytest.raises(DataError, match="cannot read bag") as info:
            _read_unchanged(truncated)
        assert str(truncated) in str(info.value)
        garbage = tmp_path / f"garbage_{name}"
        garbage.write_bytes(np.random.default_rng(0).bytes(5000))
        with pytest.raises(DataError, match="cannot read bag"):
            _read_unchanged(garbage)
        damaged = bytearray(bags[name].read_bytes())
        middle = len(damaged) // 2
        damaged[middle : middle + 2000] = bytes(2000)
        corrupt = tmp_path / f"corrupt_{name}"
        corrupt.write_bytes(bytes(damaged))
        with pytest.raises(DataError, match=r"cannot read bag after the last good message \(/"):
            _read_unchanged(corrupt)
    with pytest.raises(DataError, match="no such file"):
        read_bag(tmp_path / "absent.bag", ROBOT)


def test_missing_topic(bags):
    robot = ROBOT.replace(topics={**ROBOT.topics, "imu": "/imu/missing"})
    with pytest.raises(DataError, match=r"'/imu/missing' \(imu\) is not in the bag") as info:
        read_bag(bags["run.bag"], robot)
    assert str(bags["run.bag"]) in str(info.value)


def _write_bad(batch: list[BagMessage], path: Path, match: str, topic: str) -> DataError:
    write_messages(batch, path)
    with pytest.raises(DataError, match=match) as info:
        _read_unchanged(path)
    message = str(info.value)
    assert str(path) in message and topic in message
    return info.value


def test_empty_topic(messages, tmp_path):
    batch = [m for m in messages() if m.topic != POSE]
    batch.append(BagMessage(POSE, "geometry_msgs/msg/PoseStamped", 0, None))
    _write_bad(batch, tmp_path / "empty.mcap", "no messages", POSE)


def test_unknown_message_type(messages, tmp_path):
    Float64 = typestore("ros2").types["std_msgs/msg/Float64"]
    batch = [m for m in messages() if m.topic != IMU]
    batch.append(BagMessage(IMU, "std_msgs/msg/Float64", batch[0].time, Float64(data=1.0)))
    match = "unsupported message type 'std_msgs/msg/Float64'"
    _write_bad(batch, tmp_path / "type.mcap", match, IMU)


def test_timestamps_going_backwards(messages, tmp_path):
    batch = messages()
    for m in [m for m in batch if m.topic == IMU][1000:]:
        _set_stamp(m, _stamp_ns(m) - 5 * NS)
    # The jump is 5 s less the one 72 Hz step between the two messages.
    error = _write_bad(batch, tmp_path / "back.mcap", "backwards by 4.986 s", IMU)
    assert "into the bag" in str(error)


def test_nan_in_a_message(messages, tmp_path):
    batch = messages()
    [m for m in batch if m.topic == IMU][700].message.angular_velocity.z = np.nan
    error = _write_bad(batch, tmp_path / "nan.mcap", "non-finite value in message 700", IMU)
    assert "9.7" in str(error)  # 700 / 72 Hz = 9.72 s into the run


def test_no_overlap_between_imu_and_pose(messages, tmp_path):
    batch = messages()
    shifted = set()  # duplicated pose messages share one message object
    for i, m in enumerate(batch):
        if m.topic == POSE:
            if id(m.message) not in shifted:
                _set_stamp(m, _stamp_ns(m) + 100 * NS)
                shifted.add(id(m.message))
            batch[i] = BagMessage(m.topic, m.msgtype, m.time + 100 * NS, m.message)
    batch.sort(key=lambda m: m.time)
    _write_bad(batch, tmp_path / "overlap.mcap", "no overlap", POSE)


def test_a_bz2_compressed_ros1_bag_reads_back_the_same_run(simulated, bags, tmp_path):
    compressed = write_bag(
        simulated, tmp_path / "run.bag", ROBOT, "ros1", rng=3, compression="bz2", pose_noise=(0, 0)
    )
    assert compressed.stat().st_size < bags["run.bag"].stat().st_size / 2
    plain, packed = read_bag(bags["run.bag"], ROBOT), _read_unchanged(compressed)
    for key in ("t", "yaw_rate", "omega_r", "omega_l", "vx", "vy"):
        np.testing.assert_array_equal(getattr(packed, key), getattr(plain, key))
    with pytest.raises(InputError, match="compression 'zip'"):
        write_bag(simulated, tmp_path / "x.bag", ROBOT, "ros1", compression="zip")
    with pytest.raises(InputError, match="needs format ros1"):
        write_bag(simulated, tmp_path / "x.mcap", ROBOT, "ros2", compression="bz2")


def test_a_jittered_imu_keeps_its_samples_on_its_fitted_clock(tmp_path):
    # Header stamps jittered by 0.1 ms around a 72 Hz clock: a clock at the
    # stamps' median step drifted from the samples by 8 ms over a run, and
    # interpolating the gyro onto it smoothed its white noise (measured: sd
    # 0.0040 against 0.005, lag-1 correlation 0.29). On the fitted clock each
    # sample keeps its value: over ~1,870 samples the noise's sd is within
    # 5 % (3 sd of its sampling error, 1 / sqrt(2 N) = 1.6 %) and its lag-1
    # correlation within 4 / sqrt(N) = 0.09 of 0.
    from mocap_simulator import write_mocap_bag

    run = write_mocap_bag(tmp_path / "run.bag", v=0.4, w=0.52, duration=26.0, rng=3)
    experiment = read_bag(run.path, ROBOT)
    assert experiment.provenance["imu_clock"]["rate"] == 72.0
    error = experiment.yaw_rate - np.interp(experiment.t, run.imu_t, run.states[:, 2])
    assert error.std() == pytest.approx(run.truth["gyro_sd"], rel=0.05)
    assert abs(np.corrcoef(error[1:], error[:-1])[0, 1]) < 0.09
