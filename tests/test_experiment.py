"""Experiments: CSV and NetCDF reading and writing, their errors, windows and atomic writes."""

from __future__ import annotations

import dataclasses
import os
import re
import stat
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import xarray as xr

from bayes_jackal._runtime.errors import DataError, InputError
from bayes_jackal.cli import main
from bayes_jackal.io.experiment import Experiment, read_netcdf, write_netcdf
from bayes_jackal.io.logs import load_experiments
from bayes_jackal.io.tables import load_experiment, read_csv, read_mat, write_csv

DT = 0.1
N = 40
CHANNEL_KEYS = ("yaw_rate", "omega_r", "omega_l", "vx", "vy")


def make_experiment(velocities: bool = True, **extra: object) -> Experiment:
    """An in-memory experiment with N uniform samples and distinct columns."""
    t = DT * np.arange(N)
    columns = {
        "t": t,
        "yaw_rate": 0.5 * np.sin(t),
        "omega_r": 10.0 + 0.1 * t,
        "omega_l": 5.0 - 0.2 * t,
    }
    if velocities:
        columns |= {"vx": 0.8 + 0.01 * t, "vy": -0.05 * np.cos(t)}
    return Experiment(**columns, **extra)


def full_experiment() -> Experiment:
    """An experiment with every optional attribute set, as ``simulate`` writes it."""
    t = DT * np.arange(N)
    return make_experiment(
        name="v1_07",
        series="v1",
        steady_window=(0.95, 3.05),
        truth={"d_lat": 110.0, "d_long": 30.0, "sigma_h": 0.05},
        truth_arrays={"yaw_state": 0.4 * np.sin(t), "yaw_process_noise": 0.01 * np.cos(t)},
        provenance={"generator": "test", "repairs": ["none"]},
    )


def csv_text(header: str, rows: list[str]) -> str:
    return "\n".join([header, *rows]) + "\n"


def good_rows(n: int = 6) -> list[str]:
    """Rows of t, yaw_rate, omega_r, omega_l with t = 0, 0.1, ..."""
    return [f"{DT * i:.1f},{0.01 * i},{10 + i},{5 - i}" for i in range(n)]


def snapshot(path: Path) -> tuple[bytes, int]:
    return path.read_bytes(), path.stat().st_mtime_ns


# --- CSV reading -------------------------------------------------------------


def test_read_csv_any_column_order_and_extra_columns(tmp_path):
    path = tmp_path / "run_3.csv"
    rows = [f"{i},{5 - i},{0.02 * i},{DT * i:.1f},{10 + i},{0.3 * i}" for i in range(5)]
    path.write_text(csv_text("note, omega_l ,vy,t,omega_r,yaw_rate", rows))
    experiment = read_csv(path)
    # The reader returns the uniform clock t0 + k dt (bayes_jackal.io.stamps).
    np.testing.assert_array_equal(experiment.t, DT * np.arange(5))
    np.testing.assert_array_equal(experiment.omega_l, 5.0 - np.arange(5))
    np.testing.assert_array_equal(experiment.omega_r, 10.0 + np.arange(5))
    np.testing.assert_allclose(experiment.yaw_rate, 0.3 * np.arange(5))
    np.testing.assert_allclose(experiment.vy, 0.02 * np.arange(5))
    assert experiment.vx is None
    assert experiment.channels == ("vy", "yaw")
    assert experiment.name == "run_3"
    assert experiment.series is None
    assert experiment.source == str(path)
    assert experiment.provenance["format"] == "csv"
    assert experiment.dt == pytest.approx(DT)


def test_read_csv_name_and_series_arguments(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text(csv_text("t,yaw_rate,omega_r,omega_l", good_rows()))
    experiment = read_csv(path, name="left_turn", series="v2")
    assert experiment.name == "left_turn"
    assert experiment.series == "v2"


@pytest.mark.parametrize("velocities", [True, False])
def test_csv_round_trip(tmp_path, velocities):
    original = make_experiment(velocities=velocities, name="ignored")
    path = write_csv(original, tmp_path / "sub" / "round.csv")
    assert path == tmp_path / "sub" / "round.csv"
    assert path.read_text().splitlines()[0] == (
        "t,yaw_rate,omega_r,omega_l,vx,vy" if velocities else "t,yaw_rate,omega_r,omega_l"
    )
    back = read_csv(path)
    assert back.name == "round"
    for key in ("t", "yaw_rate", "omega_r", "omega_l", "vx", "vy"):
        if velocities or key not in ("vx", "vy"):
            np.testing.assert_allclose(getattr(back, key), getattr(original, key), rtol=1e-9)
        else:
            assert getattr(back, key) is None
    assert [p.name for p in path.parent.iterdir()] == ["round.csv"]


def test_netcdf_round_trip_keeps_everything(tmp_path):
    original = full_experiment()
    path = write_netcdf(original, tmp_path / "v1_07.nc")
    back = read_netcdf(path)
    for key in ("t", "yaw_rate", "omega_r", "omega_l", "vx", "vy"):
        np.testing.assert_array_equal(getattr(back, key), getattr(original, key))
    assert back.name == "v1_07"
    assert back.series == "v1"
    assert back.steady_window == (0.95, 3.05)
    assert back.truth == {"d_lat": 110.0, "d_long": 30.0, "sigma_h": 0.05}
    assert back.provenance == {"generator": "test", "repairs": ["none"]}
    assert set(back.truth_arrays) == {"yaw_state", "yaw_process_noise"}
    for key, value in original.truth_arrays.items():
        np.testing.assert_array_equal(back.truth_arrays[key], value)
    assert back.source == str(path)
    assert [p.name for p in tmp_path.iterdir()] == ["v1_07.nc"]


def test_netcdf_round_trip_of_a_bare_experiment(tmp_path):
    original = make_experiment(velocities=False, name="bare")
    back = read_netcdf(write_netcdf(original, tmp_path / "bare.nc"))
    np.testing.assert_array_equal(back.yaw_rate, original.yaw_rate)
    assert back.vx is None
    assert back.vy is None
    assert back.series is None
    assert back.steady_window is None
    assert back.truth is None
    assert back.truth_arrays == {}
    assert back.channels == ("yaw",)


def test_load_experiment_dispatches_on_suffix(tmp_path):
    write_csv(make_experiment(), tmp_path / "A.CSV")
    write_netcdf(full_experiment(), tmp_path / "b.nc")
    assert load_experiment(tmp_path / "A.CSV").provenance["format"] == "csv"
    assert load_experiment(tmp_path / "b.nc").truth["d_lat"] == 110.0


# --- CSV errors --------------------------------------------------------------

HEADER = "t,yaw_rate,omega_r,omega_l"


def replace_cell(rows: list[str], row: int, column: int, value: str) -> list[str]:
    rows = list(rows)
    cells = rows[row].split(",")
    cells[column] = value
    rows[row] = ",".join(cells)
    return rows


@pytest.mark.parametrize(
    ("text", "field", "pattern"),
    [
        (csv_text("t,yaw_rate,omega_r", ["0,0,0"] * 4), "omega_l", r"missing column.*omega_l"),
        (csv_text("t,omega_r,omega_l", ["0,0,0"] * 4), "yaw_rate", r"missing column.*yaw_rate"),
        (
            csv_text(HEADER, replace_cell(good_rows(), 2, 1, "abc")),
            "yaw_rate",
            r"non-numeric value 'abc' at line 4$",
        ),
        (
            csv_text(HEADER, replace_cell(good_rows(), 0, 3, "")),
            "omega_l",
            r"line 2 has omega_r but not omega_l: a row holds all of omega_r, omega_l or none",
        ),
        (csv_text(HEADER, replace_cell(good_rows(), 3, 2, "nan")), "omega_r", r"nan at line 5 "),
        (csv_text(HEADER, replace_cell(good_rows(), 1, 1, "inf")), "yaw_rate", r"inf at line 3 "),
        (
            csv_text(
                HEADER + ",vx", [row + ",0.5" for row in good_rows()[:5]] + ["0.5,0,0,0,-inf"]
            ),
            "vx",
            r"-inf at line 7 ",
        ),
        (
            csv_text(HEADER, replace_cell(good_rows(), 2, 0, "0.02")),
            "t",
            r"not uniformly sampled at line 4: t = 0\.02 s follows 0 s by 0\.02 s, less than "
            r"half the 0\.1 s step; no uniform clock fits.*declare it \(--rate HZ",
        ),
    ],
    ids=[
        "missing-omega_l",
        "missing-yaw_rate",
        "text",
        "empty-cell",
        "nan",
        "inf",
        "minus-inf",
        "irregular-time",
    ],
)
def test_bad_csv_names_file_column_and_line(tmp_path, text, field, pattern):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    before = snapshot(path)
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: {field}: .*{pattern}") as info:
        read_csv(path)
    assert info.value.source == str(path)
    assert info.value.field == field
    assert snapshot(path) == before


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("", r"file is empty"),
        (csv_text(HEADER, []), r"only 0 samples; at least 3"),
        (csv_text(HEADER, good_rows(2)), r"only 2 samples; at least 3"),
        (csv_text(HEADER, [*good_rows(3), "0.3,0,0", *good_rows(6)[4:]]), r"line 5 has 3 fields"),
        (csv_text(HEADER, [*good_rows(3), "0.3,0,0,0,7"]), r"line 5 has 5 fields"),
    ],
    ids=["empty", "header-only", "two-rows", "short-row", "long-row"],
)
def test_bad_csv_shape_names_file(tmp_path, text, pattern):
    path = tmp_path / "shape.csv"
    path.write_text(text)
    before = snapshot(path)
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: {pattern}"):
        read_csv(path)
    assert snapshot(path) == before


def test_missing_csv_file(tmp_path):
    path = tmp_path / "absent.csv"
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: no such file$"):
        read_csv(path)
    assert not path.exists()


def test_channel_not_in_csv(tmp_path):
    path = tmp_path / "yaw_only.csv"
    path.write_text(csv_text(HEADER, good_rows()))
    experiment = read_csv(path)
    np.testing.assert_array_equal(experiment.channel("yaw"), experiment.yaw_rate)
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: vx: channel 'vx' is not in"):
        experiment.channel("vx")
    with pytest.raises(DataError, match=r"unknown channel 'heading'"):
        experiment.channel("heading")


# --- NetCDF errors -----------------------------------------------------------


def test_missing_netcdf_file(tmp_path):
    path = tmp_path / "absent.nc"
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: no such file"):
        read_netcdf(path)


def test_file_that_is_not_netcdf(tmp_path):
    path = tmp_path / "text.nc"
    path.write_text(csv_text(HEADER, good_rows()))
    before = snapshot(path)
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: not a readable NetCDF file"):
        read_netcdf(path)
    assert snapshot(path) == before


def test_netcdf_that_is_not_an_experiment(tmp_path):
    path = tmp_path / "other.nc"
    xr.Dataset({"x": ("n", [1.0, 2.0, 3.0])}, attrs={"format": "other/1"}).to_netcdf(
        path, engine="h5netcdf"
    )
    before = snapshot(path)
    with pytest.raises(
        DataError, match=rf"^{re.escape(str(path))}: format: not a bayes_jackal .*'other/1'"
    ):
        read_netcdf(path)
    assert snapshot(path) == before


def test_experiment_netcdf_missing_a_variable(tmp_path):
    path = tmp_path / "partial.nc"
    write_netcdf(make_experiment(), path)
    with xr.open_dataset(path, engine="h5netcdf") as dataset:
        partial = dataset.load().drop_vars("omega_l")
    path.unlink()
    partial.to_netcdf(path, engine="h5netcdf")
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: omega_l: missing variable"):
        read_netcdf(path)


@pytest.mark.parametrize("name", ["run.txt", "run.bag", "run"])
def test_load_experiment_unknown_suffix(tmp_path, name):
    path = tmp_path / name
    path.write_text(csv_text(HEADER, good_rows()))
    suffix = Path(name).suffix
    with pytest.raises(
        DataError, match=rf"^{re.escape(str(path))}: unknown experiment file type '{suffix}'"
    ):
        load_experiment(path)


def test_load_experiments_rejects_duplicate_names(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    write_csv(make_experiment(), tmp_path / "a" / "run.csv")
    write_netcdf(make_experiment(name="run"), tmp_path / "b" / "run.nc")
    with pytest.raises(
        DataError,
        match=r"name: experiment names are not unique: \{'run': \[.*a/run\.csv', .*b/run\.nc'\]\}",
    ):
        load_experiments([tmp_path / "a" / "run.csv", tmp_path / "b" / "run.nc"], rate=1 / DT)


def test_load_experiments_keeps_order(tmp_path):
    paths = [
        write_netcdf(make_experiment(name="second"), tmp_path / "second.nc"),
        write_csv(make_experiment(), tmp_path / "first.csv"),
    ]
    assert [e.name for e in load_experiments(paths, rate=1 / DT)] == ["second", "first"]


# --- windows -----------------------------------------------------------------


def test_window_cuts_every_array():
    experiment = full_experiment()
    cut = experiment.window(1.0, 2.0)
    keep = (experiment.t >= 1.0) & (experiment.t <= 2.0)
    assert keep.sum() == 11
    for key in ("t", "yaw_rate", "omega_r", "omega_l", "vx", "vy"):
        np.testing.assert_array_equal(getattr(cut, key), getattr(experiment, key)[keep])
    for key, value in experiment.truth_arrays.items():
        np.testing.assert_array_equal(cut.truth_arrays[key], value[keep])
    assert cut.steady_window is None
    assert cut.name == experiment.name
    assert cut.series == "v1"
    assert cut.truth == experiment.truth
    assert len(experiment.t) == N


def test_window_with_too_few_samples():
    with pytest.raises(DataError, match=r"window: window \[1\.0, 1\.15\] s holds 2 samples"):
        make_experiment().window(1.0, 1.15)


def test_steady_uses_the_steady_window():
    experiment = full_experiment()
    steady = experiment.steady()
    assert steady.t[0] == pytest.approx(1.0)
    assert steady.t[-1] == pytest.approx(3.0)
    assert len(steady.t) == 21
    np.testing.assert_array_equal(steady.yaw_rate, experiment.window(0.95, 3.05).yaw_rate)


def test_steady_without_window_is_the_whole_experiment():
    experiment = make_experiment()
    assert experiment.steady() is experiment


# --- atomic writes -----------------------------------------------------------


def test_failed_netcdf_write_leaves_no_file(tmp_path, monkeypatch):
    def write_half_then_fail(self, path, *args, **kwargs):
        Path(path).write_bytes(b"\x89HDF half a file")
        raise OSError("disk full")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", write_half_then_fail)
    target = tmp_path / "out.nc"
    with pytest.raises(OSError, match="disk full"):
        write_netcdf(full_experiment(), target)
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []

    target.write_bytes(b"previous content")
    with pytest.raises(OSError, match="disk full"):
        write_netcdf(full_experiment(), target)
    assert target.read_bytes() == b"previous content"
    assert [p.name for p in tmp_path.iterdir()] == ["out.nc"]


def test_written_files_get_the_umask_permissions_not_owner_only(tmp_path):
    previous = os.umask(0o022)
    try:
        path = write_netcdf(full_experiment(), tmp_path / "out.nc")
    finally:
        os.umask(previous)
    # A report or experiment is shared: 0644 under the common umask 022.
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


# --- stamps repaired by the readers (rules: bayes_jackal.io.stamps) -------------


def test_csv_repeated_stamp_and_dropout_are_repaired_and_listed(tmp_path):
    path = tmp_path / "repaired.csv"
    rows = [f"{DT * i:.1f},{0.01 * i},{10 + i},{5 - i}" for i in (0, 1, 2, 2, 3, 5, 6, 7, 8)]
    path.write_text(csv_text(HEADER, rows))
    experiment = read_csv(path)
    np.testing.assert_allclose(experiment.t, DT * np.arange(9), rtol=0, atol=1e-15)
    # Line 5 repeats line 4's stamp (dropped); tick 4 is missing (interpolated).
    np.testing.assert_allclose(experiment.omega_r, 10 + np.arange(9))
    assert experiment.provenance["repairs"] == [
        "t: 1 duplicate stamps (first at line 5); kept the first message of each",
        "t: 1 gap of at most 2 steps filled with 1 linearly interpolated samples (the first "
        "after line 6, t = 0.3 s)",
    ]
    assert experiment.provenance["time_base"]["rate"] == 10.0


# --- column mapping ----------------------------------------------------------

ODD = "stamp,gyro_z,right,left"
MAPPING = {"t": "stamp", "yaw_rate": "gyro_z", "omega_r": "right", "omega_l": "left"}


def test_csv_with_columns_named_otherwise(tmp_path):
    path = tmp_path / "odd.csv"
    path.write_text(csv_text(ODD, good_rows()))
    experiment = read_csv(path, columns=MAPPING)
    np.testing.assert_array_equal(experiment.omega_l, 5.0 - np.arange(6))
    np.testing.assert_allclose(experiment.yaw_rate, 0.01 * np.arange(6))
    assert experiment.provenance["columns"] == MAPPING
    with pytest.raises(DataError, match=r"t: missing column\(s\) \['t', 'yaw_rate', .*--column"):
        read_csv(path)


def test_unknown_column_role_is_an_input_error(tmp_path):
    path = tmp_path / "odd.csv"
    path.write_text(csv_text(ODD, good_rows()))
    with pytest.raises(InputError, match=r"^columns: unknown column role\(s\) \['gyro'\]"):
        read_csv(path, columns={"gyro": "gyro_z"})
    with pytest.raises(InputError, match=r"unknown column role\(s\) \['gyro'\]"):
        load_experiments([path], columns={"gyro": "gyro_z"})


def test_missing_mapped_column_names_file_and_column(tmp_path):
    path = tmp_path / "odd.csv"
    path.write_text(csv_text(ODD, good_rows()))
    with pytest.raises(
        DataError,
        match=rf"^{re.escape(str(path))}: yaw_z: column 'yaw_z' \(mapped to yaw_rate\) is not in",
    ):
        read_csv(path, columns={**MAPPING, "yaw_rate": "yaw_z"})


def test_a_column_mapped_to_a_role_is_not_read_for_the_role_of_its_name(tmp_path):
    # yaw_rate is read from the column "vx"; the role vx is then unmeasured,
    # not read from the same column.
    path = tmp_path / "gyro_in_vx.csv"
    path.write_text(csv_text("t,vx,omega_r,omega_l", good_rows()))
    experiment = read_csv(path, columns={"yaw_rate": "vx"})
    np.testing.assert_allclose(experiment.yaw_rate, 0.01 * np.arange(6))
    assert experiment.vx is None and experiment.vy is None
    assert experiment.provenance["columns"] == {
        "t": "t",
        "yaw_rate": "vx",
        "omega_r": "omega_r",
        "omega_l": "omega_l",
    }
    # A required role whose column is taken by another is missing, and said so.
    with pytest.raises(
        DataError, match=r"missing column\(s\) \['omega_l'\].*'omega_l' is mapped to omega_r"
    ):
        read_csv(path, columns={"yaw_rate": "vx", "omega_r": "omega_l"})


def test_a_column_mapped_to_two_roles_is_an_input_error(tmp_path):
    path = tmp_path / "odd.csv"
    path.write_text(csv_text(ODD, good_rows()))
    pattern = r"^columns: column 'gyro_z' is mapped to two roles, yaw_rate and vx"
    with pytest.raises(InputError, match=pattern):
        read_csv(path, columns={**MAPPING, "vx": "gyro_z"})
    with pytest.raises(InputError, match=pattern):
        load_experiments([path], columns={**MAPPING, "vx": "gyro_z"})


# --- MATLAB files ------------------------------------------------------------


def test_mat_round_trip_top_level_and_struct(tmp_path):
    original = make_experiment(name="x")
    flat = tmp_path / "flat.mat"
    scipy.io.savemat(flat, {k: getattr(original, k) for k in ("t", *CHANNEL_KEYS)})
    nested = tmp_path / "nested.mat"
    log = {"time": original.t[:, None], "imu": {"gz": original.yaw_rate}, "note": "run 3"}
    log |= {"wr": original.omega_r, "wl": original.omega_l}
    scipy.io.savemat(nested, {"log": log})
    mapping = {
        "t": "log.time",
        "yaw_rate": "log.imu.gz",
        "omega_r": "log.wr",
        "omega_l": "log.wl",
    }
    for path, columns in ((flat, None), (nested, mapping)):
        back = load_experiment(path, columns=columns)
        assert back.name == path.stem and back.provenance["format"] == "mat"
        assert back.provenance["repairs"] == []
        for key in ("t", "yaw_rate", "omega_r", "omega_l"):
            np.testing.assert_allclose(getattr(back, key), getattr(original, key), atol=1e-15)
    assert (
        load_experiment(flat).vx is not None
        and load_experiment(nested, columns=mapping).vx is None
    )


def _write_mat73(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """A MATLAB v7.3 file as MATLAB writes it: HDF5 after a 512-byte text header."""
    with h5py.File(path, "w", userblock_size=512) as file:
        for key, value in arrays.items():
            dataset = file.create_dataset(key, data=np.asarray(value, float)[None, :])
            dataset.attrs["MATLAB_class"] = np.bytes_("double")
        file.create_dataset("label", data=np.frombuffer(b"run", np.uint8).astype(np.uint16))
        file["label"].attrs["MATLAB_class"] = np.bytes_("char")
    with open(path, "r+b") as stream:
        stream.write(
            b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: test HDF5 schema 1.00 ."
        )
        stream.seek(124)
        stream.write(b"\x00\x02IM")


def test_mat_v73_via_h5py(tmp_path):
    original = make_experiment()
    path = tmp_path / "v73.mat"
    _write_mat73(
        path,
        {
            "stamp": original.t,
            "gyro_z": original.yaw_rate,
            "right": original.omega_r,
            "left": original.omega_l,
        },
    )
    with pytest.raises(NotImplementedError):  # scipy.io sees a real v7.3 file
        scipy.io.loadmat(path)
    back = read_mat(path, columns=MAPPING)
    np.testing.assert_allclose(back.yaw_rate, original.yaw_rate)
    np.testing.assert_allclose(back.t, original.t, atol=1e-15)


def test_mat_errors_name_file_variable_and_index(tmp_path):
    t = DT * np.arange(6)
    bad = tmp_path / "bad.mat"
    yaw = np.zeros(6)
    yaw[3] = np.nan
    scipy.io.savemat(bad, {"t": t, "yaw_rate": yaw, "omega_r": np.ones(6), "omega_l": np.ones(6)})
    with pytest.raises(DataError, match=rf"^{re.escape(str(bad))}: yaw_rate: nan at index 4 "):
        read_mat(bad)
    matrix = tmp_path / "matrix.mat"
    scipy.io.savemat(matrix, {"t": t, "yaw_rate": np.ones((6, 2)), "omega_r": t, "omega_l": t})
    with pytest.raises(DataError, match=r"yaw_rate: variable 'yaw_rate' \(yaw_rate\) has shape"):
        read_mat(matrix)
    text = tmp_path / "text.mat"
    text.write_text("not matlab")
    with pytest.raises(DataError, match=rf"^{re.escape(str(text))}: not a readable MATLAB file"):
        read_mat(text)
    with pytest.raises(DataError, match=r"no such file"):
        read_mat(tmp_path / "absent.mat")


# --- command-line input flags -------------------------------------------------


def test_cli_column_and_rate_flags(tmp_path, capsys):
    path = tmp_path / "odd.csv"
    path.write_text(csv_text(ODD, good_rows(40)))
    flags = [f for role, name in MAPPING.items() for f in ("--column", role, name)]
    grid = ["--d-lat", "50", "60", "10", "--d-long", "10", "20", "10"]
    assert main(["grid", str(path), *flags, *grid, "--rate", "10"]) == 0
    capsys.readouterr()
    for extra, pattern in (
        (["--column", "gyro", "gyro_z"], r"--column: unknown column role\(s\) \['gyro'\]"),
        (["--column", "yaw_rate", "yaw_z"], r"--column: role 'yaw_rate' is given 2 times"),
        (["--rate", "25"], r"t: time is not uniformly sampled at line .*declared 25 Hz"),
        (["--rate", "-1"], r"argument --rate: expected a finite number > 0, got '-1'"),
    ):
        code = main(["grid", str(path), *flags, *extra, *grid])
        err = capsys.readouterr().err
        assert code == 2, err
        assert re.search(pattern, err) and "Traceback" not in err, err
    renamed = [f for role, name in MAPPING.items()
               for f in ("--column", role, "yaw_z" if role == "yaw_rate" else name)]  # fmt: skip
    code = main(["grid", str(path), *renamed, *grid, "--rate", "10"])
    err = capsys.readouterr().err
    assert code == 2 and re.search(r"yaw_z: column 'yaw_z' \(mapped to yaw_rate\)", err), err


def test_declared_rate_against_an_experiment_file(tmp_path):
    path = write_netcdf(make_experiment(), tmp_path / "run.nc")
    assert load_experiment(path, rate=10.0).dt == pytest.approx(DT)
    with pytest.raises(
        DataError, match=r"t: the declared rate 25 Hz contradicts the file's 10 Hz"
    ):
        load_experiment(path, rate=25.0)


# --- garbage refused, Excel's CSV accepted (issue 11) -------------------------


@pytest.mark.parametrize(
    ("column", "value", "unit"),
    [
        ("yaw_rate", "6e+297", "rad/s"),  # a yaw rate scaled by 1e300
        ("omega_r", "1e+12", "rad/s"),
        ("vx", "-150", "m/s"),
    ],
)
def test_absurd_magnitudes_name_file_column_line_and_value(tmp_path, capsys, column, value, unit):
    header = HEADER + ",vx"
    rows = replace_cell(
        [f"{row},0.8" for row in good_rows(40)], 3, header.split(",").index(column), value
    )
    path = tmp_path / "garbage.csv"
    path.write_text(csv_text(header, rows))
    pattern = rf"garbage\.csv: {column}: {re.escape(value)}.* {unit} at line 5"
    with pytest.raises(DataError, match=pattern):
        read_csv(path)
    # On the command line: exit 2, no MSE of nan, no "sd": Infinity.
    assert main(["grid", str(path), "--rate", "10"]) == 2
    assert main(["residuals", str(path), "--rate", "10", "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and f"{column}:" in captured.err
    with pytest.raises(DataError, match=rf"<memory>: {column}: .*must be below"):
        dataclasses.replace(make_experiment(), **{column: np.full(N, float(value))})


def test_magnitude_bounds_are_generous():
    # The bounds themselves pass: just below them, and a thesis run, are accepted.
    limits = {"yaw_rate": 99.9, "omega_r": 9999.0, "omega_l": -9999.0, "vx": 99.0, "vy": -99.0}
    columns = {key: np.full(N, value) for key, value in limits.items()}
    assert dataclasses.replace(make_experiment(), **columns).vx[0] == 99.0


def _netcdf_variant(tmp_path: Path, change) -> Path:
    path = write_netcdf(full_experiment(), tmp_path / "run.nc")
    with xr.open_dataset(path, engine="h5netcdf") as dataset:
        dataset = dataset.load()
    change(dataset)
    bad = tmp_path / "bad.nc"
    dataset.to_netcdf(bad, engine="h5netcdf")
    return bad


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (lambda d: d.attrs.update(steady_window=[0.95]), "steady_window", "got 0.95"),
        (lambda d: d.attrs.update(steady_window=[3.0, 1.0]), "steady_window", "start < stop"),
        (lambda d: d.attrs.update(truth="{d_lat: 110"), "truth", "'{d_lat: 110'"),
        (lambda d: d.attrs.update(provenance="[1, 2]"), "provenance", "a JSON object"),
        (
            lambda d: d.__setitem__("yaw_rate", ("time", d["yaw_rate"].values.astype(str))),
            "yaw_rate",
            "expected numbers",
        ),
        (
            lambda d: d.__setitem__("truth_yaw_state", ("time", np.full(N, "x"))),
            "truth_yaw_state",
            "'x'",
        ),
    ],
)
def test_garbage_in_an_experiment_file_names_file_and_field(
    tmp_path, capsys, change, field, words
):
    bad = _netcdf_variant(tmp_path, change)
    with pytest.raises(DataError, match=rf"^{re.escape(str(bad))}: {field}: .*{re.escape(words)}"):
        read_netcdf(bad)
    assert main(["residuals", str(bad), "--rate", "10"]) == 2
    err = capsys.readouterr().err
    assert "bad.nc" in err and field in err and "Traceback" not in err, err


def test_duplicate_csv_columns_are_refused_naming_the_column(tmp_path):
    path = tmp_path / "dup.csv"
    rows = [f"{row},0.5" for row in good_rows(40)]
    path.write_text(csv_text(HEADER + ",yaw_rate", rows))
    with pytest.raises(DataError, match=r"dup\.csv: yaw_rate: column 'yaw_rate' appears 2 times"):
        read_csv(path)
    # Even a duplicated column no role reads is ambiguous.
    path.write_text(csv_text(HEADER + ",note,note", [f"{row},1,2" for row in good_rows(40)]))
    with pytest.raises(DataError, match=r"note: column 'note' appears 2 times"):
        read_csv(path)


@pytest.mark.parametrize(
    ("prefix", "suffix"),
    [("\ufeff", ""), ("", "\n"), ("", "\r\n\r\n"), ("\ufeff", "\n  \n")],
    ids=["bom", "blank-line", "crlf-blank-lines", "bom-and-blank-lines"],
)
def test_excel_bom_and_trailing_blank_lines_are_accepted(tmp_path, prefix, suffix):
    clean = tmp_path / "clean.csv"
    clean.write_text(csv_text(HEADER, good_rows(40)))
    excel = tmp_path / "excel.csv"
    excel.write_bytes((prefix + csv_text(HEADER, good_rows(40)) + suffix).encode("utf-8"))
    expected, read = read_csv(clean), read_csv(excel)
    for key in ("t", "yaw_rate", "omega_r", "omega_l"):
        np.testing.assert_array_equal(getattr(read, key), getattr(expected, key))
    assert main(["residuals", str(excel), "--rate", "10"]) == 0
    # A blank line inside the data is still refused.
    inside = tmp_path / "inside.csv"
    inside.write_text(csv_text(HEADER, [*good_rows(20), "", *good_rows(40)[20:]]))
    with pytest.raises(DataError, match=r"line 22 has 0 fields"):
        read_csv(inside)
