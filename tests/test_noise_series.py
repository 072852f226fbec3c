"""Reading a bare noise series: CSV, MATLAB and bag inputs, the stamps' repairs, bad input.

The series are small (80-500 samples); each read checks that the input's
bytes are unchanged. The repairs are those of the experiments
(:func:`bayes_jackal.io.uniform_clock`), so only that they happen and
what the values become is checked here: one sample per stamp, in time
order, the values kept exactly where no tick was filled.
"""

from __future__ import annotations

import dataclasses
import hashlib
import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from bayes_jackal._runtime.errors import DataError, InputError
from bayes_jackal.io.bag_reading import typestore
from bayes_jackal.io.bag_writer import BagMessage, stamped_header, write_messages
from bayes_jackal.io.bags import read_bag
from bayes_jackal.io.logs import read_log
from bayes_jackal.model.robot import load_profile
from bayes_jackal.noise.series import MIN_SERIES_SAMPLES, NoiseSeries, read_noise_series

NS = 1_000_000_000
EPOCH = 1_700_000_000 * NS


def _sha(path: Path) -> str:
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    return hashlib.sha256(b"".join(p.read_bytes() for p in files)).hexdigest()


def _read(path: Path, **options) -> NoiseSeries:
    """read_noise_series, checking that the file's bytes are the same afterwards."""
    before = _sha(path)
    try:
        return read_noise_series(path, **options)
    finally:
        assert _sha(path) == before


def _csv(path: Path, header: list[str], *columns) -> Path:
    lines = [",".join(header)]
    lines += [",".join(str(v) for v in row) for row in zip(*columns, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _noise(n: int, seed: int = 1) -> np.ndarray:
    return 0.01 * np.random.default_rng(seed).standard_normal(n)


def test_jittered_stamps_go_onto_the_uniform_clock(tmp_path):
    t = (np.arange(500) + np.random.default_rng(2).uniform(-0.2, 0.2, 500)) / 100
    gyro = _noise(500)
    series = _read(_csv(tmp_path / "still.csv", ["t", "gyro"], t, gyro))
    assert series.dt == 0.01
    assert series.field == "gyro" and series.name == "still"
    np.testing.assert_array_equal(series.values, gyro)
    assert series.provenance["time_base"]["rate"] == 100.0
    assert any("jittered" in repair for repair in series.provenance["repairs"])


def test_duplicated_and_late_stamps_are_sorted_and_dropped(tmp_path):
    t, gyro = np.arange(200) / 100, _noise(200)
    order = np.r_[0:50, 51, 50, 52:200]  # sample 50 delivered after 51
    t_file = np.insert(t[order], 101, t[order][100])  # line 103 repeats line 102's stamp
    gyro_file = np.insert(gyro[order], 101, 99.0)  # and is dropped: the first is kept
    series = _read(_csv(tmp_path / "late.csv", ["time", "gyro"], t_file, gyro_file))
    np.testing.assert_array_equal(series.values, gyro)
    repairs = " ".join(series.provenance["repairs"])
    assert "1 out-of-order stamps; sorted" in repairs
    assert "1 duplicate stamps" in repairs


def test_odd_column_names_and_unread_text_columns(tmp_path):
    t, gyro = np.arange(100) / 50, _noise(100)
    frame = ["imu_link"] * 100
    header = ["Time (s)", "gyro z [rad/s]", "frame id", "accel x"]
    path = _csv(tmp_path / "odd.csv", header, t, gyro, frame, gyro + 1)
    series = _read(path, column="gyro z [rad/s]", time_column="Time (s)")
    assert series.field == "gyro z [rad/s]" and series.dt == 0.02
    np.testing.assert_array_equal(series.values, gyro)
    assert series.provenance["column"] == "gyro z [rad/s]"
    assert series.provenance["time_column"] == "Time (s)"


def test_a_rate_stands_for_the_stamps(tmp_path):
    roll = _noise(720)
    series = _read(_csv(tmp_path / "roll.csv", ["roll"], roll), rate=120)
    assert series.dt == 1 / 120
    np.testing.assert_array_equal(series.values, roll)
    assert series.provenance["time_column"] is None
    assert series.provenance["repairs"] == []
    assert series.provenance["time_base"]["rate_source"] == "declared"


def test_a_declared_rate_checks_the_stamps(tmp_path):
    path = _csv(tmp_path / "still.csv", ["t", "gyro"], np.arange(100) / 100, _noise(100))
    assert _read(path, rate=100).dt == 0.01
    with pytest.raises(DataError, match=r"still\.csv: t: "):
        _read(path, rate=50)


def test_stamps_in_milliseconds_are_refused_not_read_as_a_slow_series(tmp_path):
    # 100 Hz stamped in ms reads as a 0.1 Hz series: outside 1-10,000 Hz.
    path = _csv(tmp_path / "gyro.csv", ["t", "gyro"], np.arange(400) * 10.0, _noise(400))
    with pytest.raises(DataError, match=r"gyro\.csv: t: the stamps give 0\.1 Hz .* milliseconds"):
        _read(path)


def test_matlab_struct_fields(tmp_path):
    t, gyro = np.arange(300) / 200, _noise(300)
    path = tmp_path / "log.mat"
    scipy.io.savemat(path, {"log": {"t": t, "gyro_z": gyro}, "fs": 200.0})
    with pytest.raises(DataError, match=r"2 data columns \['fs', 'log.gyro_z'\]"):
        _read(path)
    series = _read(path, column="log.gyro_z")
    assert series.field == "log.gyro_z" and series.dt == 0.005
    assert series.provenance["time_column"] == "log.t"
    np.testing.assert_array_equal(series.values, gyro)
    with pytest.raises(DataError, match=r"log\.mat: fs: variable 'fs' has shape"):
        _read(path, column="fs", rate=200)


def test_a_matlab_text_field_is_said_to_hold_text_not_to_be_missing(tmp_path):
    # It read "column 'gyro_z' is not in the file; it has ['t']" (issue 37, item 13).
    path = tmp_path / "log.mat"
    scipy.io.savemat(path, {"t": np.arange(300) / 200, "gyro_z": np.array(["n/a"] * 300)})
    with pytest.raises(DataError, match=r"log\.mat: gyro_z: variable 'gyro_z' holds text"):
        _read(path, column="gyro_z")
    with pytest.raises(DataError, match=r"0 data columns \[\] \('gyro_z': text, not numbers\)"):
        _read(path)


def _imu(store, stamp: int, seq: int, z: float):
    types = store.types
    vector = types["geometry_msgs/msg/Vector3"]
    return types["sensor_msgs/msg/Imu"](
        header=stamped_header(store, stamp, "imu_link", seq),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=vector(x=0.0, y=0.0, z=float(z)),
        angular_velocity_covariance=np.arange(9.0),
        linear_acceleration=vector(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )


@pytest.fixture(scope="module", params=[("still.bag", "ros1"), ("still.mcap", "ros2")])
def bag(request, tmp_path_factory):
    """A ROS1 or ROS2 bag: 80 IMU messages at 100 Hz (one published twice) and a
    50 Hz Float64 topic without header stamps, received up to 0.5 ms late."""
    name, format = request.param
    store = typestore(format)
    z, level = _noise(80, seed=3), _noise(40, seed=4)
    stamps = EPOCH + np.arange(80) * NS // 100
    messages = [
        BagMessage("/imu/data", "sensor_msgs/msg/Imu", int(s) + 2_000_000, _imu(store, s, k, z[k]))
        for k, s in enumerate(stamps)
    ]
    messages.insert(31, dataclasses.replace(messages[30], time=messages[30].time + 1))
    late = np.random.default_rng(5).integers(0, 500_000, 40)
    messages += [
        BagMessage(
            "/level",
            "std_msgs/msg/Float64",
            int(EPOCH + k * NS // 50 + late[k]),
            store.types["std_msgs/msg/Float64"](data=float(level[k])),
        )
        for k in range(40)
    ]
    messages.sort(key=lambda m: m.time)
    path = write_messages(messages, tmp_path_factory.mktemp("bag") / name, format)
    return path, z, level


def bag_format(path: Path) -> str:
    return "ros1" if path.suffix == ".bag" else "ros2"


def test_a_topic_field_of_a_bag(bag):
    path, z, _ = bag
    series = _read(path, topic="/imu/data", field="angular_velocity.z")
    assert series.field == "/imu/data.angular_velocity.z" and series.dt == 0.01
    np.testing.assert_array_equal(series.values, z)
    provenance = series.provenance
    assert provenance["format"] == bag_format(path) and provenance["messages"] == 81
    assert provenance["sha256"] == _sha(path)
    assert provenance["stamps"] == "header"
    assert any("1 duplicate stamps" in repair for repair in provenance["repairs"])


def test_a_headerless_topic_takes_the_receive_times(bag):
    path, _, level = bag
    series = _read(path, topic="/level", field="data")
    assert series.dt == 0.02 and series.provenance["stamps"] == "receive time"
    np.testing.assert_array_equal(series.values, level)
    assert any("jittered" in repair for repair in series.provenance["repairs"])


def test_a_number_in_the_field_path_indexes_an_array(bag):
    path, _, _ = bag
    with pytest.raises(DataError, match="constant"):  # orientation_covariance is all zeros
        _read(path, topic="/imu/data", field="orientation_covariance.4")
    with pytest.raises(DataError, match=r"index 9 is out of range: .* has 9 values"):
        _read(path, topic="/imu/data", field="angular_velocity_covariance.9")


@pytest.mark.parametrize(
    ("topic", "field", "match"),
    [
        (
            "/imu",
            "angular_velocity.z",
            r"still\.(bag|mcap): /imu: topic '/imu' is not in the bag.*'/imu/data': 81",
        ),
        (
            "/imu/data",
            "angular_velocity.w",
            r"/imu/data.angular_velocity.w: .* has no field 'w'.*'z'",
        ),
        ("/imu/data", "header.frame_id", r"field 'header.frame_id' is str, not a number"),
    ],
)
def test_bad_topics_and_fields(bag, topic, field, match):
    with pytest.raises(DataError, match=match):
        _read(bag[0], topic=topic, field=field)


def test_options_must_fit_the_file_type(bag, tmp_path):
    path = _csv(tmp_path / "still.csv", ["t", "gyro"], np.arange(100) / 100, _noise(100))
    with pytest.raises(InputError, match="topic: topic does not apply to CSV"):
        _read(path, topic="/imu/data")
    with pytest.raises(InputError, match="column: column does not apply to a bag"):
        _read(bag[0], column="gyro")
    with pytest.raises(InputError, match="field: a bag needs a topic and a field"):
        _read(bag[0], topic="/imu/data")


def _bad_csv(tmp_path: Path, name: str, header: list[str], *columns, **options) -> str:
    with pytest.raises(DataError) as error:
        _read(_csv(tmp_path / name, header, *columns), **options)
    return str(error.value)


def test_bad_tables(tmp_path):
    t, gyro = np.arange(100) / 100, _noise(100)
    nan = np.where(np.arange(100) == 7, np.nan, gyro)
    text = np.where(np.arange(100) == 9, "n/a", gyro.astype(str))
    short = MIN_SERIES_SAMPLES - 1
    cases = [
        ("nan.csv", ["t", "gyro"], (t, nan), {}, "gyro: nan at line 9 (1 non-finite"),
        ("text.csv", ["t", "gyro"], (t, text), {}, "gyro: non-numeric value 'n/a' at line 11"),
        ("flat.csv", ["t", "gyro"], (t, t * 0 + 0.2), {}, "gyro: the series is constant (every "),
        ("short.csv", ["t", "gyro"], (t[:short], gyro[:short]), {}, f"gyro: only {short} samples"),
        ("two.csv", ["t", "a", "b"], (t, gyro, gyro), {}, "column: 2 data columns ['a', 'b']"),
        (
            "unknown.csv",
            ["t", "gyro"],
            (t, gyro),
            {"column": "gyro_z"},
            "gyro_z: column 'gyro_z' ",
        ),
        ("nostamps.csv", ["gyro"], (gyro,), {}, "t: no stamps: no column named t or time in "),
        (
            "nantime.csv",
            ["t", "gyro"],
            (np.where(t == 0.03, np.nan, t), gyro),
            {},
            "t: nan at line 5",
        ),
    ]
    for name, header, columns, options, message in cases:
        error = _bad_csv(tmp_path, name, header, *columns, **options)
        assert error.startswith(f"{tmp_path / name}: {message}"), error


def test_too_few_samples_after_cutting_at_a_gap(tmp_path):
    t = np.r_[np.arange(30), np.arange(60, 90)] / 100  # a gap of 31 steps: the pieces are cut
    message = _bad_csv(tmp_path, "gap.csv", ["t", "gyro"], t, _noise(60))
    assert message.endswith(
        "only 30 samples on the uniform clock; a noise series needs at least 32"
    )


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(DataError, match=r"nothing\.csv: no such file"):
        read_noise_series(tmp_path / "nothing.csv")
    (tmp_path / "still.txt").write_text("t,gyro\n")
    with pytest.raises(DataError, match=r"unknown series file type '\.txt'"):
        _read(tmp_path / "still.txt")


def test_a_series_built_in_memory_is_checked():
    with pytest.raises(DataError, match="<memory>: values: a series is 1-D"):
        NoiseSeries(values=np.zeros((40, 2)), dt=0.01)
    with pytest.raises(DataError, match="expected numbers"):
        NoiseSeries(values=np.array(["a"] * 40), dt=0.01)
    with pytest.raises(InputError, match="dt: must be a positive number of s"):
        NoiseSeries(values=_noise(40), dt=0.0)
    series = NoiseSeries(values=list(_noise(40)), dt=0.01)
    assert not series.values.flags.writeable


def test_a_named_time_column_gives_the_stamps(tmp_path):
    t = np.arange(200) / 50
    path = _csv(tmp_path / "mocap.csv", ["stamp_s", "roll"], t, _noise(200))
    with pytest.raises(DataError, match="column: 2 data columns"):  # no column named t or time
        _read(path)
    series = _read(path, time_column="stamp_s")
    assert series.dt == 0.02 and series.field == "roll"
    assert series.provenance["time_column"] == "stamp_s"


def test_a_bag_suffix_in_capitals_is_one_rule_for_every_reader(bag, tmp_path):
    # bag_reading.bag_format says what is a bag, its suffix in any case, for the
    # noise series and the robot's logs alike; rosbags tells the formats apart
    # by the suffix as written (RUN.BAG went to its ROS2 reader), so it is
    # refused with the fix named.
    shouting = tmp_path / bag[0].name.upper()
    shutil.copyfile(bag[0], shouting)
    fix = rf"{shouting.stem}\{shouting.suffix.lower()}"
    for read in (
        lambda: _read(shouting, topic="/imu/data", field="angular_velocity.z"),
        lambda: read_log(shouting, load_profile()),
    ):
        with pytest.raises(DataError, match=rf"suffix in lower case: .* as {fix}$"):
            read()
    table = _csv(tmp_path / "still.csv", ["t", "gyro"], np.arange(40) / 100, _noise(40))
    with pytest.raises(DataError, match=r"still\.csv: not a bag: expected a \.bag, \.mcap"):
        read_bag(table, load_profile())


def test_a_folder_of_csv_files_is_not_taken_for_a_bag(tmp_path):
    # A folder is a ROS2 bag only with its metadata.yaml (rosbags reads the bag from it).
    folder = tmp_path / "runs"
    folder.mkdir()
    for name in ("a.csv", "b.csv"):
        _csv(folder / name, ["t", "gyro"], np.arange(100) / 100, _noise(100))
    with pytest.raises(DataError) as error:
        _read(folder, column="gyro")
    message = str(error.value)
    assert message.startswith(f"{folder}: a folder is read only as a ROS2 bag")
    assert "metadata.yaml" in message and "['a.csv', 'b.csv']" in message


def test_the_series_checks_are_those_of_the_likelihood():
    # One check serves NoiseSeries and SeriesLikelihood: the same words, each
    # with its own minimum length.
    from bayes_jackal.likelihood.series_likelihood import (
        MIN_LIKELIHOOD_SAMPLES,
        SeriesLikelihood,
    )

    for values, dt in [(np.full(40, 0.5), 0.01), (np.r_[_noise(39), np.inf], 0.01),
                       (_noise(40), -1.0)]:  # fmt: skip
        with pytest.raises(ValueError) as from_series:
            NoiseSeries(values=values, dt=dt)
        with pytest.raises(ValueError) as from_likelihood:
            SeriesLikelihood(values=values, dt=dt)
        assert type(from_series.value) is type(from_likelihood.value)
        assert str(from_series.value).removeprefix("<memory>: ") == str(from_likelihood.value)
    assert (
        len(SeriesLikelihood(values=_noise(MIN_LIKELIHOOD_SAMPLES), dt=0.01).values)
        == MIN_LIKELIHOOD_SAMPLES
    )
    with pytest.raises(DataError, match=f"only {MIN_LIKELIHOOD_SAMPLES} samples; .* at least 32"):
        NoiseSeries(values=_noise(MIN_LIKELIHOOD_SAMPLES), dt=0.01)


def test_zero_header_stamps_take_the_receive_time(tmp_path):
    store = typestore("ros2")
    stamps = EPOCH + np.arange(60) * NS // 100
    z = _noise(60, seed=6)
    messages = [
        BagMessage(
            "/imu/data",
            "sensor_msgs/msg/Imu",
            int(s) + 1_000_000,
            _imu(store, 0 if k in (10, 11) else s, k, z[k]),
        )
        for k, s in enumerate(stamps)
    ]
    series = _read(write_messages(messages, tmp_path / "zero.mcap", "ros2"),
                   topic="/imu/data", field="angular_velocity.z")  # fmt: skip
    np.testing.assert_array_equal(series.values, z)  # 1 ms late: on the same ticks
    assert series.provenance["stamps"] == "header"
    assert (
        "/imu/data: 2 of 60 messages have a zero header stamp; used their receive time"
        in series.provenance["repairs"]
    )
