"""Experiments: CSV and NetCDF reading and writing, their errors, windows and atomic writes."""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayes_jackal.errors import DataError
from bayes_jackal.experiment import (
    Experiment,
    load_experiment,
    load_experiments,
    read_csv,
    read_netcdf,
    write_csv,
    write_netcdf,
)

DT = 0.1
N = 40


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
    np.testing.assert_array_equal(experiment.t, [0.0, 0.1, 0.2, 0.3, 0.4])
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
            r"non-numeric value '' at line 2$",
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
            csv_text(HEADER, replace_cell(good_rows(), 2, 0, "0.1")),
            "t",
            r"time does not increase at line 4: 0\.1 -> 0\.1 s$",
        ),
        (
            csv_text(HEADER, replace_cell(good_rows(), 2, 0, "0.05")),
            "t",
            r"time does not increase at line 4",
        ),
        (
            csv_text(HEADER, [f"{DT * i:.1f},0,0,0" for i in (0, 1, 2, 4, 5, 6, 7)]),
            "t",
            r"not uniformly sampled at line 5: step 0\.2 s",
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
        "repeated-time",
        "decreasing-time",
        "dropout",
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
    with pytest.raises(DataError, match=rf"^{re.escape(str(path))}: cannot read CSV"):
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
        load_experiments([tmp_path / "a" / "run.csv", tmp_path / "b" / "run.nc"])


def test_load_experiments_keeps_order(tmp_path):
    paths = [
        write_netcdf(make_experiment(name="second"), tmp_path / "second.nc"),
        write_csv(make_experiment(), tmp_path / "first.csv"),
    ]
    assert [e.name for e in load_experiments(paths)] == ["second", "first"]


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
