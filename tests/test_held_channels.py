"""Tables as labs record them: sparse rows, channels held on faster rows, commands, segments.

The fixtures are written here, not by the package's simulator:

- a *union table* as pandas writes an outer join (``to_csv`` of frames
  merged on their stamps): an IMU at 100 Hz, motion capture at 120 Hz and
  wheel encoders at 50 Hz, each on its own clock, of a robot driving a
  circle of radius 2 m at 0.5 m/s (0.25 rad/s);
- the *DRIVE layout* (the calibration dataset's logger): one row per 20 Hz
  tick, the IMU's yaw rate measured at every row, lidar-ICP poses at
  4.44 Hz and wheel encoders at 3.9 Hz each written again on every row
  until the next message, and the command (cmd_v, cmd_w) in steps of 8 s,
  which the robot follows with a first-order lag of 0.2 s.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pandas as pd
import pytest
import scipy.io

from bayes_jackal._runtime.errors import DataError
from bayes_jackal.io.segments import MIN_HOLD, STEP_TOLERANCE, command_segments, label_segments
from bayes_jackal.io.tables import read_csv, read_mat
from bayes_jackal.model.physics import wheel_speeds
from bayes_jackal.model.robot import load_profile

ROBOT = load_profile()
#: The union table's circle: speed [m/s], yaw rate [rad/s], and the ROS formula's
#: wheel speeds for them (the Jackal's constants).
SPEED, TURN = 0.5, 0.25
WHEELS = tuple(float(w) for w in wheel_speeds(ROBOT, SPEED, TURN))


def _circle(t: np.ndarray) -> dict[str, np.ndarray]:
    """World pose of the circle at times t [s], the heading wrapped into (-pi, pi] (drivers)."""
    heading = TURN * t
    radius = SPEED / TURN
    return {
        "x": radius * np.sin(heading),
        "y": radius * (1 - np.cos(heading)),
        "heading": np.angle(np.exp(1j * heading)),
    }


@pytest.fixture(scope="module")
def union(tmp_path_factory):
    """The union table (module text), 30 s, and its sensors' stamps."""
    rng = np.random.default_rng(11)
    imu_t = np.arange(3000) / 100
    mocap_t = 0.0042 + np.arange(3600) / 120  # its own phase
    wheel_t = 0.007 + np.arange(1500) / 50
    imu = pd.DataFrame({"t": imu_t, "yaw_rate": TURN + 0.005 * rng.standard_normal(3000)})
    mocap = pd.DataFrame({"t": mocap_t, **_circle(mocap_t)})
    # Wheel speeds ramping linearly (exact under linear interpolation).
    wheels = pd.DataFrame(
        {
            "t": wheel_t,
            "omega_r": WHEELS[0] + 0.01 * wheel_t,
            "omega_l": WHEELS[1] + 0.01 * wheel_t,
        }
    )
    joined = imu.merge(mocap, on="t", how="outer").merge(wheels, on="t", how="outer")
    path = tmp_path_factory.mktemp("union") / "union.csv"
    joined.sort_values("t").to_csv(path, index=False)
    return path, {"imu": imu_t, "mocap": mocap_t, "wheel": wheel_t}


def test_a_sparse_table_keeps_each_sensor_at_its_own_stamps(union):
    path, stamps = union
    text = path.read_text().splitlines()
    assert text[0] == "t,yaw_rate,x,y,heading,omega_r,omega_l" and ",," in text[2]
    experiment = read_csv(path)
    # The clock is the IMU's rows (100 Hz), cut to the span the wheel speeds
    # cover (0.007 .. 29.987 s): its 2998 ticks 0.01 .. 29.98 s.
    assert experiment.provenance["time_base"]["rate"] == 100.0
    assert len(experiment.t) == 2998 and experiment.t[0] == pytest.approx(0.01)
    assert any("run cut to 0.01 .. 29.98 s" in r for r in experiment.provenance["repairs"])
    # The poses at their own stamps, those within an IMU step of the run
    # (0 .. 29.99 s), the heading unwrapped.
    mocap = stamps["mocap"]
    inside = mocap[(mocap >= 0.0) & (mocap <= 29.99)]
    np.testing.assert_array_equal(experiment.pose.t, inside)
    np.testing.assert_allclose(experiment.pose.heading, TURN * inside, atol=1e-9)
    assert experiment.measurement("vx") == "pose"
    # The wheel speeds interpolated onto the clock (linear in t: exact to
    # float rounding).
    np.testing.assert_allclose(experiment.omega_r, WHEELS[0] + 0.01 * experiment.t, atol=1e-12)
    assert experiment.provenance["streams"] == {
        "sample": {"samples": 3000, "stamps": "sample rows"},
        "pose": {"samples": 3600, "stamps": "own"},
        "wheels": {"samples": 1500, "stamps": "own"},
    }
    assert experiment.measured == {} and experiment.segments is None


def test_a_dense_table_reads_as_it_always_has(tmp_path):
    t = np.arange(400) / 72
    rng = np.random.default_rng(3)
    columns = {
        "t": t,
        "yaw_rate": 0.4 + 0.01 * rng.standard_normal(400),
        "omega_r": 4.0 + 0.02 * rng.standard_normal(400),
        "omega_l": 3.0 + 0.02 * rng.standard_normal(400),
        "vx": 0.3 + 0.003 * rng.standard_normal(400),
        "vy": 0.003 * rng.standard_normal(400),
    }
    path = tmp_path / "dense.csv"
    pd.DataFrame(columns).to_csv(path, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no held channel, no command: nothing to say
        experiment = read_csv(path)
    # The clock is t0 + k / 72 s (k / 72 written, to float rounding); every
    # value is the row's.
    np.testing.assert_allclose(experiment.t, t, rtol=0, atol=1e-15)
    for key in ("yaw_rate", "omega_r", "omega_l", "vx", "vy"):
        np.testing.assert_array_equal(getattr(experiment, key), columns[key], err_msg=key)
    provenance = experiment.provenance
    assert set(provenance) == {"source", "format", "columns", "time_base", "repairs", "velocities"}
    assert provenance["repairs"] == [] and provenance["time_base"]["clock"] == "uniform"
    assert experiment.measured == {} and experiment.segments is None


def test_quantised_wheel_speeds_are_no_held_channel(tmp_path):
    # An encoder of 0.5 rad/s steps at the rows' rate repeats its values at
    # random (runs of 1, 2, 3 ... rows), not in the regular runs of a slower
    # sensor.
    t = np.arange(2000) / 50
    speed = 3.0 + 0.2 * np.random.default_rng(4).standard_normal(2000)
    quantised = np.round(speed / 0.5) * 0.5
    path = tmp_path / "encoder.csv"
    table = {"t": t, "yaw_rate": 0.01 * np.sin(t), "omega_r": quantised, "omega_l": quantised}
    pd.DataFrame(table).to_csv(path, index=False)
    experiment = read_csv(path)
    assert "held" not in experiment.provenance
    np.testing.assert_array_equal(experiment.omega_r, quantised)


@pytest.mark.parametrize(
    ("row", "pattern"),
    [
        ("0.05,0.1,,,1.0,,0.3", r"y: line 3 has x, heading but not y: a row holds all"),
        ("0.05,nan,,,,,", r"yaw_rate: nan at line 3"),
        ("0.05,0.1,5.0,,,,", r"omega_l: line 3 has omega_r but not omega_l"),
    ],
    ids=["part-of-a-pose", "nan", "part-of-the-wheels"],
)
def test_a_row_with_part_of_a_group_or_a_nan_is_refused_naming_the_line(tmp_path, row, pattern):
    rows = [f"{k / 10},0.1,5.0,5.0,{k / 20},0.0,0.0" for k in range(20)]
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(["t,yaw_rate,omega_r,omega_l,x,y,heading", rows[0], row, *rows[1:]]))
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: {pattern}"):
        read_csv(path)


def test_velocities_at_rows_of_their_own_are_refused_saying_what_to_do(tmp_path):
    rows = [f"{k / 10},0.1,5.0,5.0,0.5,0.0" for k in range(20)] + ["2.05,,,,0.5,0.0"]
    path = tmp_path / "velocities.csv"
    path.write_text("\n".join(["t,yaw_rate,omega_r,omega_l,vx,vy", *rows]))
    with pytest.raises(DataError, match=r"vx: vx, vy are measured at rows of their own \(line 22"):
        read_csv(path)


def test_missing_rows_are_marked_unmeasured_and_the_input_interpolated(tmp_path):
    # 100 rows at 10 Hz, rows 50-52 lost: a gap of 4 steps, filled (at most 5).
    t = np.arange(100) / 10
    table = pd.DataFrame({"t": t, "yaw_rate": 0.1 * t, "omega_r": t, "omega_l": 2 * t, "vx": t})
    path = tmp_path / "lost.csv"
    table.drop(index=[50, 51, 52]).to_csv(path, index=False)
    experiment = read_csv(path)
    assert np.flatnonzero(~experiment.observed("yaw")).tolist() == [50, 51, 52]
    assert np.flatnonzero(~experiment.observed("vx")).tolist() == [50, 51, 52]
    np.testing.assert_allclose(experiment.omega_l, 2 * t)  # linear: interpolated exactly
    assert experiment.provenance["input"]["interpolated"] == (
        "linearly across the clock's 3 filled ticks"
    )
    # With poses, vx, vy are modelled through them: no mask of theirs.
    with_pose = table.drop(columns="vx").assign(x=0.1 * t, y=0.0 * t, heading=0.0 * t)
    with_pose.drop(index=[50, 51, 52]).to_csv(path, index=False)
    assert list(read_csv(path).measured) == ["yaw_rate"]


# --------------------------------------------------------------------------- held channels

#: The DRIVE layout (module text): rows [Hz], the held sensors' rates [Hz].
ROW_RATE, ICP_RATE, ENCODER_RATE = 20.0, 4.44, 3.9
#: The command's steps: (start [s], cmd_v [m/s], cmd_w [rad/s]); rest before
#: the first and after the last.
STEPS = ((2.0, 0.5, 0.3), (10.0, 1.0, 0.0), (18.0, 0.5, -0.3), (26.0, 0.0, 0.0))
DURATION, LAG = 30.0, 0.2


def _drive(rng: np.random.Generator) -> tuple[pd.DataFrame, dict]:
    """A DRIVE-layout table and its truth: the messages' stamps and values."""
    fine = np.arange(round(DURATION * 1000)) / 1000  # 1 kHz truth
    command = np.zeros((len(fine), 2))
    for start, v, w in STEPS:
        command[fine >= start] = (v, w)
    gain = 1 - np.exp(-1e-3 / LAG)  # the first-order lag, exact per 1 ms step of a held command
    state = np.zeros_like(command)
    for k in range(1, len(fine)):
        state[k] = state[k - 1] + gain * (command[k - 1] - state[k - 1])
    heading = np.concatenate([[0.0], np.cumsum(state[:-1, 1]) * 1e-3])
    x = np.concatenate([[0.0], np.cumsum(state[:-1, 0] * np.cos(heading[:-1])) * 1e-3])
    y = np.concatenate([[0.0], np.cumsum(state[:-1, 0] * np.sin(heading[:-1])) * 1e-3])
    wheels = np.column_stack(wheel_speeds(ROBOT, state[:, 0], state[:, 1]))

    def last_message(rate: float, phase: float, values: np.ndarray) -> tuple:
        """Messages at rate from phase; each row holds the last one that had arrived."""
        stamps = phase + np.arange(0, DURATION - phase, 1 / rate)
        at = np.interp(stamps, fine, np.arange(len(fine))).round().astype(int)
        rows = np.arange(round(DURATION * ROW_RATE)) / ROW_RATE
        last = np.searchsorted(stamps, rows, side="right") - 1
        return stamps, values[at], values[at][np.maximum(last, 0)]

    icp_noise = 1e-3 * rng.standard_normal((len(fine), 3))  # 1 mm: the poses change at rest too
    icp_t, icp, icp_rows = last_message(
        ICP_RATE, 0.013, np.column_stack([x, y, heading]) + icp_noise
    )
    encoder_noise = 0.01 * rng.standard_normal((len(fine), 2))  # 0.01 rad/s, none at rest
    moving = np.abs(wheels).max(axis=1, keepdims=True) > 0
    enc_t, enc, enc_rows = last_message(ENCODER_RATE, 0.031, wheels + moving * encoder_noise)
    rows = np.arange(round(DURATION * ROW_RATE)) / ROW_RATE
    at = (rows * 1000).round().astype(int)
    table = pd.DataFrame(
        {
            "t": rows,
            "yaw_rate": state[at, 1] + 0.005 * rng.standard_normal(len(rows)),
            "omega_r": enc_rows[:, 0],
            "omega_l": enc_rows[:, 1],
            "x": icp_rows[:, 0],
            "y": icp_rows[:, 1],
            "heading": icp_rows[:, 2],
            "cmd_v": command[at, 0],
            "cmd_w": command[at, 1],
        }
    )
    return table, {"icp_t": icp_t, "icp": icp, "encoder_t": enc_t, "encoder": enc}


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    table, truth = _drive(np.random.default_rng(8))
    path = tmp_path_factory.mktemp("drive") / "drive.csv"
    table.to_csv(path, index=False)
    return path, table, truth


def test_held_icp_and_encoders_are_read_as_the_slower_sensors_and_the_command_used(drive):
    path, table, truth = drive
    with pytest.warns(UserWarning) as caught:
        experiment = read_csv(path)
    said = " ".join(str(w.message) for w in caught)
    assert "x, y, heading: held on the 20 Hz rows" in said
    assert "the command (cmd_v, cmd_w) is the model's input" in said
    held = experiment.provenance["held"]
    # The ICP's rate: its clock fitted through the change rows' midpoints.
    assert held["x, y, heading"]["rate"] == pytest.approx(ICP_RATE, rel=1e-3)
    assert held["x, y, heading"]["placement"] == "sensor clock"
    # The encoders' (not on a clock of their own: 3.9 Hz on 20 Hz rows has
    # runs of 5 and 6): rows' rate / mean run, within a run over ~100 runs.
    assert held["omega_r, omega_l"]["rate"] == pytest.approx(ENCODER_RATE, rel=0.02)
    assert held["omega_r, omega_l"]["run_length"] == {"median": 5.0, "min": 5, "max": 6}
    # The pose track is the ICP's messages, all but the first (its arrival is
    # unknown) and those after the last row, each within half a row step
    # (0.025 s) of its stamp; the sensor clock averages the midpoints' errors.
    pose = experiment.pose
    stamps = truth["icp_t"][1 : 1 + len(pose.t)]
    assert len(pose.t) == int(np.sum(truth["icp_t"] <= table["t"].iloc[-1])) - 1
    error = pose.t - stamps
    assert np.abs(error).max() <= 0.5 / ROW_RATE and error.std() < 0.005
    np.testing.assert_array_equal(pose.x, truth["icp"][1 : 1 + len(pose.t), 0])
    # The command is the input: cmd_v, cmd_w through the ROS formula, row by row.
    expected = wheel_speeds(ROBOT, table["cmd_v"].to_numpy(), table["cmd_w"].to_numpy())
    np.testing.assert_allclose(experiment.omega_r, expected[0], atol=1e-12)
    assert experiment.provenance["input"]["from"] == "command"
    # Segments: each step of the command, at its row (the steps are jumps).
    starts = [0, *(round(start * ROW_RATE) for start, *_ in STEPS)]
    assert experiment.segments.tolist() == starts
    assert experiment.provenance["segments"]["from"] == "command"


def test_held_encoders_without_a_command_are_deheld(drive, tmp_path):
    _, table, truth = drive
    bare = tmp_path / "bare.csv"
    table.drop(columns=["cmd_v", "cmd_w"]).to_csv(bare, index=False)
    with pytest.warns(UserWarning) as caught:
        experiment = read_csv(bare)
    assert "transients shorter than the sensor's step" in str(caught[-1].message)
    assert experiment.provenance["input"]["from"] == "wheel speeds, de-held"
    assert len(experiment.t) == len(table)  # the first and last rows' values close the span
    # Between the encoder's own samples the input is their linear
    # interpolation: at each message's placed time, its value (the placed
    # time within half a row step of the stamp, over which the wheel speed
    # changes by at most its largest rate, ~30 rad/s^2 x 0.025 s = 0.75 rad/s).
    # Its samples: the messages that change the rows' value (not the zeros
    # repeated at rest, nor the first: its arrival is unknown).
    held = experiment.provenance["held"]["omega_r, omega_l"]
    assert held["samples"] == (np.diff(truth["encoder"], axis=0) != 0).any(axis=1).sum()
    inside = (truth["encoder_t"] > 1.0) & (truth["encoder_t"] < DURATION - 1.0)
    at = np.interp(truth["encoder_t"][inside], experiment.t, experiment.omega_r)
    assert np.abs(at - truth["encoder"][inside, 0]).max() < 0.75
    assert experiment.segments is None


def test_a_held_yaw_rate_is_measured_where_it_changes(tmp_path):
    # A gyro at 10 Hz written on 50 Hz rows: each value on 5 rows.
    t = np.arange(1000) / 50
    gyro = 0.3 + 0.01 * np.random.default_rng(6).standard_normal(200)
    path = tmp_path / "gyro.csv"
    table = {"t": t, "yaw_rate": np.repeat(gyro, 5), "omega_r": 4 + 0.1 * t, "omega_l": 3 + 0 * t}
    pd.DataFrame(table).to_csv(path, index=False)
    with pytest.warns(UserWarning, match="yaw_rate: held on the 50 Hz rows in runs of 5 rows"):
        experiment = read_csv(path)
    # Measured at the first row of each value but the first (its start unknown).
    assert np.flatnonzero(experiment.observed("yaw")).tolist() == list(range(5, 1000, 5))
    assert experiment.provenance["held"]["yaw_rate"]["rate"] == pytest.approx(10.0)


# --------------------------------------------------------------------------- commands, segments


def test_a_command_without_wheel_speeds_is_the_input(tmp_path):
    t = np.arange(300) / 50
    table = {"t": t, "yaw_rate": 0.2 + 0 * t, "cmd_v": 0.4 + 0 * t, "cmd_w": 0.2 + 0 * t}
    path = tmp_path / "commanded.csv"
    pd.DataFrame(table).to_csv(path, index=False)
    with pytest.warns(UserWarning, match=r"no wheel speeds: the command \(cmd_v, cmd_w\) is the"):
        experiment = read_csv(path)
    # ROS diff_drive_controller's formula with the Jackal's constants.
    np.testing.assert_allclose(experiment.omega_r, wheel_speeds(ROBOT, 0.4, 0.2)[0])
    assert experiment.provenance["robot"] == "jackal"
    pd.DataFrame({"t": t, "yaw_rate": 0.2 + 0 * t}).to_csv(path, index=False)
    with pytest.raises(DataError, match=r"missing column\(s\) \['omega_r', 'omega_l'\]"):
        read_csv(path)


def test_segments_from_a_segment_column_held_over_sparse_rows(tmp_path):
    # Labels written only where they change (rows 0, 40, 100 of 150 at 10 Hz).
    lines = ["t,yaw_rate,omega_r,omega_l,segment"]
    labels = {0: "rest", 40: "step 1", 100: "step 2"}
    lines += [f"{k / 10},0.1,3.0,3.0,{labels.get(k, '')}" for k in range(150)]
    path = tmp_path / "labelled.csv"
    path.write_text("\n".join(lines))
    experiment = read_csv(path)
    assert experiment.segments.tolist() == [0, 40, 100]
    assert experiment.provenance["segments"] == {"from": "segment column", "count": 3}
    # A label on one row holds throughout: one segment.
    path.write_text("\n".join(lines).replace("step 1", "").replace("step 2", ""))
    assert read_csv(path).segments is None


def test_segments_from_a_step_command_and_a_ramp_is_one():
    # At 50 Hz: rest 2 s, a jump to 3 rad/s held 3 s, a 1 s ramp to 5 rad/s
    # held 3 s. The jump starts a segment at 2.0 s; the ramp one, where it has
    # left its hold by STEP_TOLERANCE (2 rad/s per s: after 0.05 s, the 3rd
    # sample of the ramp), not one per tick.
    assert (STEP_TOLERANCE, MIN_HOLD) == (0.1, 0.5)
    t = np.arange(450) / 50
    wheel = np.interp(t, [0, 1.999, 2, 5, 6, 9], [0, 0, 3, 3, 5, 5])
    assert command_segments(t, np.column_stack([wheel, wheel])).tolist() == [0, 100, 253]
    # A command that keeps moving (0.5 rad/s per s: 0.25 rad/s over MIN_HOLD)
    # has one segment.
    assert command_segments(t, 0.5 * t) is None
    assert label_segments([1, 1, 2, 2, 1]).tolist() == [0, 2, 4]


def test_a_segment_column_in_a_mat_file_and_poses_of_their_own(tmp_path):
    t = np.arange(300) / 100
    s = 0.003 + np.arange(330) / 110
    path = tmp_path / "run.mat"
    log = {"t": t, "gz": 0.1 + 0 * t, "wr": 3 + 0 * t, "wl": 3 + 0 * t}
    log["step"] = np.repeat([1.0, 2.0, 3.0], 100)
    pose = {"t": s, "x": 0.3 * s, "y": 0 * s, "heading": 0 * s}
    scipy.io.savemat(path, {"log": log, "pose": pose})
    columns = {"t": "log.t", "yaw_rate": "log.gz", "omega_r": "log.wr", "omega_l": "log.wl"}
    columns |= {"segment": "log.step", "pose_t": "pose.t", "x": "pose.x", "y": "pose.y"}
    columns |= {"heading": "pose.heading"}
    experiment = read_mat(path, columns=columns)
    assert experiment.segments.tolist() == [0, 100, 200]
    np.testing.assert_array_equal(experiment.pose.t, s[s <= 2.99 + 0.01])
    pose["x"] = pose["x"][:-1]
    scipy.io.savemat(path, {"log": log, "pose": pose})
    with pytest.raises(DataError, match=r"pose.x: 329 values for the 330 of 'pose.t'"):
        read_mat(path, columns=columns)
