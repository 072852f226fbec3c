"""Robot profiles: the packaged Jackal default and the validation of bad TOML files."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from bayes_jackal._runtime.errors import InputError, ProfileError
from bayes_jackal.io import PLAUSIBLE_RATES
from bayes_jackal.model import robot
from bayes_jackal.model.robot import RobotProfile, default_profile_path, load_profile

#: A valid profile as TOML sections of raw TOML values.
VALID = {
    "body": {
        "mass": "16.523",
        "yaw_inertia": "0.5485",
        "half_wheelbase": "0.131",
        "half_track": "0.2078",
        "wheel_radius": "0.098",
    },
    "diff_drive": {
        "wheel_separation": "0.37559",
        "wheel_separation_multiplier": "1.5",
        "conversion": '"ros"',
    },
    "sampling": {"rate": "72.0"},
    "priors": {
        "d_lat": "[10.0, 1000.0]",
        "d_long": "[10.0, 1000.0]",
        "sigma_h": "[0.001, 1.0]",
    },
}


def write_profile(folder: Path, changes: dict[str, str | None] | None = None) -> Path:
    """Write ``VALID`` with changes: ``"table.key": value``, ``None`` drops a key or table.

    A change named ``"table"`` (no dot) with a string value replaces the whole
    table by a top-level ``table = value`` line.
    """
    sections = {name: dict(table) for name, table in VALID.items()}
    top = {}
    for where, value in (changes or {}).items():
        table, _, key = where.partition(".")
        if not key:
            sections.pop(table, None)
            if value is not None:
                top[table] = value
        elif value is None:
            sections[table].pop(key)
        else:
            sections.setdefault(table, {})[key] = value
    lines = ['name = "test"'] + [f"{key} = {value}" for key, value in top.items()]
    for name, table in sections.items():
        lines += ["", f"[{name}]"] + [f"{key} = {value}" for key, value in table.items()]
    path = folder / "robot.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def error_pattern(path: Path, field: str, value: str) -> str:
    """Message pattern naming the file first, then the field, then the value."""
    return rf"^{re.escape(str(path))}: {re.escape(field)}: .*{re.escape(value)}"


def test_default_profile_has_thesis_constants():
    profile = load_profile()
    assert profile.name == "jackal"
    assert profile.mass == 16.523
    assert profile.yaw_inertia == 0.5485
    assert profile.half_wheelbase == 0.131
    assert profile.half_track == 0.2078
    assert profile.wheel_radius == 0.098
    assert profile.wheel_separation == 0.37559
    assert profile.wheel_separation_multiplier == 1.5
    assert profile.conversion == "ros"
    assert profile.rate == 72.0
    assert profile.dt == pytest.approx(1 / 72)
    assert profile.priors == {
        "d_lat": (10.0, 1000.0),
        "d_long": (10.0, 1000.0),
        "sigma_h": (0.001, 1.0),
        "sigma_c": (1e-5, 1.0),
        "sigma_n": (1e-4, 1.0),
        "sigma_p": (1e-6, 1e-2),
    }
    assert profile.topics == {
        "imu": "/imu/data",
        "joint_states": "/joint_states",
        "cmd_vel": "/cmd_vel",
        "pose": "/mocap_node/Jackal/pose",
    }
    assert profile.wheels["right"] == ["front_right_wheel", "rear_right_wheel"]
    assert profile.wheels["left"] == ["front_left_wheel", "rear_left_wheel"]
    assert profile.source == str(default_profile_path())


def test_default_profile_path_is_a_packaged_file():
    path = default_profile_path()
    assert path.is_file()
    assert path.name == "jackal.toml"
    assert load_profile(path).mass == load_profile().mass


def test_written_profile_loads_with_defaults_for_optional_tables(tmp_path):
    path = write_profile(tmp_path, {"sampling": None, "priors": None})
    profile = load_profile(path)
    assert profile.source == str(path)
    assert profile.name == "test"
    assert profile.rate == 72.0
    assert profile.priors["d_lat"] == (10.0, 1000.0)
    assert profile.topics["imu"] == "/imu/data"


def test_written_profile_overrides_priors_and_topics(tmp_path):
    path = write_profile(tmp_path, {"priors.d_lat": "[1.0, 5000.0]", "topics.imu": '"/imu"'})
    profile = load_profile(path)
    assert profile.priors["d_lat"] == (1.0, 5000.0)
    assert profile.priors["d_long"] == (10.0, 1000.0)
    assert profile.topics["imu"] == "/imu"
    assert profile.topics["cmd_vel"] == "/cmd_vel"


@pytest.mark.parametrize(
    ("changes", "field", "value"),
    [
        ({"body": None}, "body", "missing table [body]"),
        ({"diff_drive": None}, "diff_drive", "missing table [diff_drive]"),
        ({"body.yaw_inertia": None}, "body.yaw_inertia", "missing constant"),
        ({"diff_drive.wheel_separation": None}, "diff_drive.wheel_separation", "missing"),
        ({"body.mass": "-16.523"}, "body.mass", "-16.523"),
        ({"body.wheel_radius": "0"}, "body.wheel_radius", "got 0.0"),
        ({"body.yaw_inertia": "nan"}, "body.yaw_inertia", "got nan"),
        ({"body.half_track": "inf"}, "body.half_track", "got inf"),
        ({"body.mass": '"16.523"'}, "body.mass", "'16.523'"),
        ({"body.half_wheelbase": "true"}, "body.half_wheelbase", "True"),
        ({"body.mass": "[16.5]"}, "body.mass", "[16.5]"),
        (
            {"diff_drive.wheel_separation_multiplier": "-1.5"},
            "diff_drive.wheel_separation_multiplier",
            "-1.5",
        ),
        ({"sampling.rate": "0.0"}, "sampling.rate", "got 0.0"),
        ({"sampling.rate": '"fast"'}, "sampling.rate", "'fast'"),
        ({"diff_drive.conversion": '"ackermann"'}, "diff_drive.conversion", "'ackermann'"),
        ({"priors.d_lat": "[1000.0, 10.0]"}, "priors.d_lat", "[1000.0, 10.0]"),
        ({"priors.d_long": "[50.0, 50.0]"}, "priors.d_long", "[50.0, 50.0]"),
        ({"priors.d_lat": "[-10.0, 1000.0]"}, "priors.d_lat", "[-10.0, 1000.0]"),
        ({"priors.sigma_h": "[0.001, inf]"}, "priors.sigma_h", "inf"),
        ({"priors.sigma_h": "[0.1]"}, "priors.sigma_h", "[0.1]"),
        ({"priors.d_long": '["low", "high"]'}, "priors.d_long", "'low'"),
    ],
)
def test_bad_profile_names_file_field_and_value(tmp_path, changes, field, value):
    path = write_profile(tmp_path, changes)
    with pytest.raises(ProfileError, match=error_pattern(path, field, value)) as info:
        load_profile(path)
    assert info.value.source == str(path)
    assert info.value.field == field
    assert isinstance(info.value, InputError)


@pytest.mark.parametrize(
    ("table", "value"),
    [("sampling", "72.0"), ("priors", "[10.0, 1000.0]"), ("topics", '"/imu/data"')],
)
def test_table_given_as_a_plain_value_is_a_profile_error(tmp_path, table, value):
    path = write_profile(tmp_path, {table: value})
    with pytest.raises(ProfileError, match=rf"^{re.escape(str(path))}: .*{table}"):
        load_profile(path)


def test_missing_profile_file(tmp_path):
    path = tmp_path / "nowhere.toml"
    with pytest.raises(ProfileError, match=rf"^{re.escape(str(path))}: no such file$"):
        load_profile(path)


def test_profile_path_that_is_a_folder(tmp_path):
    with pytest.raises(
        ProfileError, match=rf"^{re.escape(str(tmp_path))}: is a folder, not a file"
    ):
        load_profile(tmp_path)


def test_invalid_toml(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[body]\nmass = = 16.5\n")
    with pytest.raises(
        ProfileError, match=rf"^{re.escape(str(path))}: not a valid TOML text file"
    ):
        load_profile(path)


def test_binary_file_as_profile_is_a_profile_error(tmp_path):
    path = tmp_path / "experiment.nc"
    path.write_bytes(b"\x89HDF\r\n\x1a\n\xff\xfe\x00\x01")
    with pytest.raises(ProfileError, match=rf"^{re.escape(str(path))}: "):
        load_profile(path)


def test_replace_returns_a_changed_copy():
    profile = load_profile()
    heavier = profile.replace(mass=20.0, conversion="thesis")
    assert heavier.mass == 20.0
    assert heavier.conversion == "thesis"
    assert heavier.yaw_inertia == profile.yaw_inertia
    assert profile.mass == 16.523
    assert profile.conversion == "ros"
    assert isinstance(heavier, RobotProfile)


@pytest.mark.parametrize(
    ("changes", "pattern"),
    [
        ({"mass": -1.0}, r"body\.mass: must be a positive finite number, got -1\.0"),
        ({"yaw_inertia": math.nan}, r"body\.yaw_inertia: .*got nan"),
        ({"rate": 0.0}, r"sampling\.rate: .*got 0\.0"),
        ({"conversion": "tank"}, r"diff_drive\.conversion: .*'tank'"),
        (
            {"priors": {"d_lat": (5.0, 1.0), "d_long": (1.0, 5.0), "sigma_h": (0.1, 1.0)}},
            r"priors\.d_lat: .*\[5\.0, 1\.0\]",
        ),
        ({"priors": {"d_lat": (10.0, 1000.0)}}, r"priors: missing prior ranges"),
    ],
)
def test_replace_validates(changes, pattern):
    profile = load_profile()
    with pytest.raises(ProfileError, match=re.escape(profile.source) + ": " + pattern):
        profile.replace(**changes)


@pytest.mark.parametrize(
    ("changes", "field", "allowed"),
    [
        ({"priors.d_latt": "[10.0, 1000.0]"}, "priors.d_latt", "'d_lat', 'd_long', 'sigma_h'"),
        ({"body.masss": "16.5"}, "body.masss", "'mass', 'yaw_inertia'"),
        ({"sampling.hz": "72.0"}, "sampling.hz", "['rate']"),
        ({"topics.lidar": '"/scan"'}, "topics.lidar", "'imu', 'joint_states'"),
        ({"wheels.middle": '["w"]'}, "wheels.middle", "['right', 'left']"),
        ({"imu": "42"}, "imu", "'name', 'description', 'body'"),
    ],
)
def test_unknown_profile_key_is_refused_listing_the_allowed_ones(
    tmp_path, changes, field, allowed
):
    path = write_profile(tmp_path, changes)
    key = field.rpartition(".")[2]
    with pytest.raises(ProfileError, match=error_pattern(path, field, f"unknown key '{key}'")):
        load_profile(path)
    with pytest.raises(ProfileError, match=re.escape(allowed)):
        load_profile(path)


@pytest.mark.parametrize(
    ("changes", "field", "value"),
    [
        ({"topics.imu": "42"}, "topics.imu", "got 42"),
        ({"topics.pose": '""'}, "topics.pose", "got ''"),
        ({"description": "42"}, "description", "got 42"),
        ({"diff_drive.conversion": "1"}, "diff_drive.conversion", "got 1"),
        ({"schema_version": "2"}, "schema_version", "got 2"),
    ],
)
def test_wrong_type_in_a_profile_is_a_profile_error(tmp_path, changes, field, value):
    path = write_profile(tmp_path, changes)
    with pytest.raises(ProfileError, match=error_pattern(path, field, value)):
        load_profile(path)


@pytest.mark.parametrize(
    ("changes", "field", "value"),
    [
        # The Jackal's a = 0.131 m: wheels of that radius touch their neighbours.
        ({"body.wheel_radius": "0.131"}, "body.wheel_radius", "0.131 m is not smaller than"),
        # A longer wheelbase passes a, and then the half track b = 0.2078 m refuses.
        (
            {"body.wheel_radius": "0.25", "body.half_wheelbase": "0.3"},
            "body.wheel_radius",
            "0.25 m is not smaller than the half track b = 0.2078 m",
        ),
        # I in kg cm^2 (x 1e4): sqrt(I/m) = 18 m on a 0.25 m footprint.
        ({"body.yaw_inertia": "5485.0"}, "body.yaw_inertia", "5485 kg m^2 at 16.523 kg"),
        # m in grams: sqrt(I/m) = 6 mm, 2 % of the footprint's half-diagonal.
        ({"body.mass": "16523.0"}, "body.yaw_inertia", "0.5485 kg m^2 at 16523 kg"),
        # Twice the track 2b = 0.4156 m and more, and half the track and less.
        ({"diff_drive.wheel_separation": "0.9"}, "diff_drive.wheel_separation", "0.9 m: 2.17 x"),
        (
            {"diff_drive.wheel_separation": "0.18779"},
            "diff_drive.wheel_separation",
            "0.18779 m: 0.452 x",
        ),
        (
            {"diff_drive.wheel_separation_multiplier": "0.5"},
            "diff_drive.wheel_separation_multiplier",
            "0.5, outside [1, 10]",
        ),
        (
            {"diff_drive.wheel_separation_multiplier": "12.0"},
            "diff_drive.wheel_separation_multiplier",
            "12, outside [1, 10]",
        ),
        # A rate in mHz or as a period, and one in kHz.
        ({"sampling.rate": "0.072"}, "sampling.rate", "0.072 Hz, outside [1, 10000]"),
        ({"sampling.rate": "72000.0"}, "sampling.rate", "72000 Hz, outside [1, 10000]"),
    ],
)
def test_impossible_constants_name_file_field_and_value(tmp_path, changes, field, value):
    path = write_profile(tmp_path, changes)
    with pytest.raises(ProfileError, match=error_pattern(path, field, value)) as info:
        load_profile(path)
    assert info.value.field == field


@pytest.mark.parametrize(
    "changes",
    [
        # The bounds are inclusive: k = 1 (ROS' default), k = 10, 1 Hz, 10 kHz.
        {"diff_drive.wheel_separation_multiplier": "1.0"},
        {"diff_drive.wheel_separation_multiplier": "10.0"},
        {"sampling.rate": "1.0"},
        {"sampling.rate": "10000.0"},
        # s = 2b exactly (the wheels' outer edges) and 2 x 2b.
        {"diff_drive.wheel_separation": "0.4156"},
        {"diff_drive.wheel_separation": "0.8312"},
    ],
)
def test_constants_at_the_bounds_are_possible(tmp_path, changes):
    load_profile(write_profile(tmp_path, changes))


def test_replace_refuses_impossible_constants():
    profile = load_profile()
    with pytest.raises(ProfileError, match=r"body\.wheel_radius: 0\.2 m is not smaller"):
        profile.replace(wheel_radius=0.2)
    with pytest.raises(ProfileError, match=r"sampling\.rate: 1e\+06 Hz, outside"):
        profile.replace(rate=1e6)


def test_profile_rates_are_those_of_sensor_logs():
    # The model cannot import the io layer's bound; the two must not drift apart.
    assert robot._RATES == PLAUSIBLE_RATES
