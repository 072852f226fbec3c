"""The ``bayes-jackal`` command line: simulate and grid, JSON output and exit codes."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayes_jackal.cli import build_parser, main
from bayes_jackal.experiment import read_netcdf
from bayes_jackal.likelihood import ResidualLikelihood
from bayes_jackal.robot import default_profile_path
from bayes_jackal.tables import read_csv

SMALL = ["--v1", "1", "--v2", "1"]
GRID = ["--d-lat", "50", "200", "10", "--d-long", "10", "60", "5"]
ARRAYS = ("t", "yaw_rate", "omega_r", "omega_l", "vx", "vy")


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> list[str]:
    """Two simulated NetCDF experiments (v1_01, v2_01), written once per module."""
    folder = tmp_path_factory.mktemp("simulated")
    assert main(["simulate", "--out", str(folder), "--seed", "1", *SMALL]) == 0
    return [str(folder / "v1_01.nc"), str(folder / "v2_01.nc")]


def assert_bad_input(code: int, captured, *patterns: str) -> str:
    """Exit code 2, one line on stderr matching every pattern, no traceback."""
    assert code == 2
    assert "Traceback" not in captured.err
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("bayes-jackal: error: ")
    for pattern in patterns:
        assert re.search(pattern, lines[0]), (pattern, lines[0])
    return lines[0]


def test_simulate_writes_netcdf_and_prints_json(tmp_path, capsys):
    code = main(["simulate", "--out", str(tmp_path), "--seed", "1", *SMALL, "--json"])
    captured = capsys.readouterr()
    assert code == 0
    payload = json.loads(captured.out)
    assert payload["experiments"] == [str(tmp_path / "v1_01.nc"), str(tmp_path / "v2_01.nc")]
    assert payload["truth"]["d_lat"] == 110.0
    assert payload["truth"]["d_long"] == 30.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v1_01.nc", "v2_01.nc"]
    assert "wrote" in captured.err
    experiment = read_netcdf(tmp_path / "v2_01.nc")
    assert experiment.series == "v2"
    assert experiment.truth["d_lat"] == 110.0
    assert len(experiment.t) > 1000


def test_simulate_csv_format(tmp_path, capsys):
    code = main(["simulate", "--out", str(tmp_path), "--seed", "3", *SMALL, "--format", "csv"])
    captured = capsys.readouterr()
    assert code == 0
    assert "wrote" in captured.out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v1_01.csv", "v2_01.csv"]
    experiment = read_csv(tmp_path / "v1_01.csv")
    assert experiment.channels == ("vx", "vy", "yaw")
    assert len(experiment.t) > 1000


def test_same_seed_same_data(tmp_path, simulated, capsys):
    assert main(["simulate", "--out", str(tmp_path), "--seed", "1", *SMALL]) == 0
    assert main(["simulate", "--out", str(tmp_path / "other"), "--seed", "2", *SMALL]) == 0
    capsys.readouterr()
    for path in simulated:
        first = read_netcdf(path)
        again = read_netcdf(tmp_path / Path(path).name)
        other = read_netcdf(tmp_path / "other" / Path(path).name)
        for key in ARRAYS:
            np.testing.assert_array_equal(getattr(again, key), getattr(first, key))
        for key, value in first.truth_arrays.items():
            np.testing.assert_array_equal(again.truth_arrays[key], value)
        assert not np.array_equal(other.yaw_rate, first.yaw_rate)


@pytest.mark.parametrize("method", ["onestep", "simulation"])
def test_grid_json(simulated, capsys, method):
    code = main(["grid", *simulated, *GRID, "--method", method, "--json"])
    captured = capsys.readouterr()
    assert code == 0
    payload = json.loads(captured.out)
    for key in ("d_lat", "d_long", "mse"):
        assert isinstance(payload[key], float)
    assert 50.0 <= payload["d_lat"] <= 200.0
    assert 10.0 <= payload["d_long"] <= 60.0
    assert payload["mse"] > 0
    assert payload["method"] == method
    assert set(payload["series"]) == {"v1", "v2"}
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}
    assert payload["grid"]["d_lat"] == [50.0, 200.0, 16]
    assert payload["grid"]["d_long"] == [10.0, 60.0, 11]
    assert "MSE" in captured.err


def test_grid_text_goes_to_stdout_without_json(simulated, capsys):
    code = main(["grid", *simulated, *GRID])
    captured = capsys.readouterr()
    assert code == 0
    assert "total (5-3)" in captured.out
    assert captured.err == ""


def test_grid_plot_and_netcdf(simulated, tmp_path, capsys):
    plot, surface = tmp_path / "out.png", tmp_path / "surf.nc"
    code = main(["grid", *simulated, *GRID, "--plot", str(plot), "--out", str(surface), "--json"])
    payload = json.loads(capsys.readouterr().out)
    assert code == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert plot.stat().st_size > 1000
    with xr.open_dataset(surface, engine="h5netcdf") as dataset:
        mse = dataset["mse"].load()
    assert mse.dims == ("d_lat", "d_long")
    assert mse.shape == (16, 11)
    assert float(mse.min()) == pytest.approx(payload["mse"])
    best = mse.where(mse == mse.min(), drop=True)
    assert float(best["d_lat"][0]) == payload["d_lat"]
    assert float(best["d_long"][0]) == payload["d_long"]


def test_grid_on_csv(tmp_path, capsys):
    assert (
        main(["simulate", "--out", str(tmp_path), "--seed", "1", *SMALL, "--format", "csv"]) == 0
    )
    capsys.readouterr()
    files = [str(tmp_path / "v1_01.csv"), str(tmp_path / "v2_01.csv")]
    assert main(["grid", *files, *GRID, "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}
    assert payload["mse"] > 0


def test_grid_missing_experiment_file(tmp_path, capsys):
    missing = tmp_path / "missing.nc"
    code = main(["grid", str(missing), *GRID, "--json"])
    captured = capsys.readouterr()
    assert_bad_input(code, captured, re.escape(str(missing)), "no such file")
    assert captured.out == ""


def test_grid_csv_missing_column(tmp_path, capsys):
    path = tmp_path / "no_yaw.csv"
    path.write_text("t,omega_r,omega_l\n0,1,1\n0.1,1,1\n0.2,1,1\n0.3,1,1\n")
    code = main(["grid", str(path), *GRID])
    assert_bad_input(code, capsys.readouterr(), re.escape(str(path)), "yaw_rate")


@pytest.mark.parametrize(
    ("flag", "values", "pattern"),
    [
        ("--d-lat", ["0", "100", "10"], r"d_lat: .*START=0\.0"),
        ("--d-lat", ["10", "100", "-5"], r"d_lat: .*STEP=-5\.0"),
        ("--d-lat", ["nan", "100", "10"], r"d_lat: .*START=nan"),
        ("--d-long", ["100", "10", "10"], r"d_long: .*START=100\.0 STOP=10\.0"),
    ],
)
def test_grid_bad_range(simulated, capsys, flag, values, pattern):
    code = main(["grid", simulated[0], flag, *values, "--json"])
    captured = capsys.readouterr()
    assert_bad_input(code, captured, pattern)
    assert captured.out == ""


def test_grid_profile_with_negative_mass(simulated, tmp_path, capsys):
    profile = tmp_path / "heavy.toml"
    text = default_profile_path().read_text()
    profile.write_text(text.replace("mass = 16.523", "mass = -16.523"))
    code = main(["grid", simulated[0], *GRID, "--robot", str(profile)])
    assert_bad_input(code, capsys.readouterr(), re.escape(str(profile)), r"mass", r"-16\.523")


def test_grid_unknown_suffix(tmp_path, capsys):
    path = tmp_path / "run.bag"
    path.write_bytes(b"#ROSBAG V2.0\n")
    code = main(["grid", str(path), *GRID])
    assert_bad_input(code, capsys.readouterr(), re.escape(str(path)), r"'\.bag'")
    assert path.read_bytes() == b"#ROSBAG V2.0\n"


def test_console_script_reports_bad_input_without_traceback(tmp_path):
    script = Path(sys.executable).parent / "bayes-jackal"
    assert script.is_file()
    missing = tmp_path / "missing.nc"
    process = subprocess.run(
        [str(script), "grid", str(missing)], capture_output=True, text=True, timeout=120
    )
    assert process.returncode == 2
    assert "Traceback" not in process.stderr
    assert str(missing) in process.stderr
    assert process.stdout == ""


def test_grid_experiment_file_given_as_profile(simulated, capsys):
    code = main(["grid", simulated[0], *GRID, "--robot", simulated[0]])
    assert_bad_input(code, capsys.readouterr(), re.escape(simulated[0]))


QUICK_SAMPLE = ["--max-steps", "80", "--seed", "3", "--no-progress"]


def test_sample_writes_a_posterior_and_prints_the_contract_json(simulated, tmp_path, capsys):
    out = tmp_path / "posterior.nc"
    code = main(["sample", simulated[0], "--out", str(out), *QUICK_SAMPLE, "--json"])
    captured = capsys.readouterr()
    assert code == 0
    payload = json.loads(captured.out)
    # By default every channel the experiment measures, each with its noise.
    assert payload["channels"] == ["yaw", "vx", "vy"]
    assert "on channels yaw, vx, vy" in captured.err
    noise = [f"{name}[{c}]" for c in ("yaw", "vx", "vy") for name in ("sigma_h", "sigma_c")]
    for key in ("d_lat", "d_long", *noise, "ratio"):
        assert {"mean", "sd", "hdi_3%", "hdi_97%", "ess_bulk", "ess_tail", "r_hat"} <= set(
            payload[key]
        )
    assert {"corr_d_lat_d_long", "autocorr_time", "n_steps"} <= set(payload)
    # 80 steps cannot converge: the run says so loudly, on stderr.
    assert "WARNING: NOT CONVERGED" in captured.err
    assert out.is_file() and out.with_suffix(".chain.h5").is_file()


def test_sample_defaults_to_the_library_engine(simulated, tmp_path):
    # The debiased Whittle engine is off by tens of nats for the Gaussian
    # family (README); the command must use the exact `fast` engine unless asked.
    args = build_parser().parse_args(["sample", simulated[0], "--out", str(tmp_path / "p.nc")])
    assert args.engine == "fast" == ResidualLikelihood.__dataclass_fields__["engine"].default


def test_sample_without_pooling_writes_one_posterior_per_experiment(simulated, tmp_path, capsys):
    out = tmp_path / "post.nc"
    yaw = ["--channels", "yaw"]  # narrowed: quicker, and checks the flag
    code = main(["sample", *simulated, "--out", str(out), *QUICK_SAMPLE, *yaw, "--json"])
    payload = json.loads(capsys.readouterr().out)
    assert code == 0
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}
    assert payload["experiments"]["v1_01"]["channels"] == ["yaw"]
    assert (tmp_path / "post.v1_01.nc").is_file() and (tmp_path / "post.v2_01.nc").is_file()
    code = main(
        ["sample", *simulated, "--out", str(out), "--pooled", *QUICK_SAMPLE, *yaw, "--json"]
    )
    pooled = json.loads(capsys.readouterr().out)
    assert code == 0 and "d_lat" in pooled and out.is_file()


@pytest.mark.parametrize(
    ("extra", "pattern"),
    [
        (["--prior", "d_lat", "500", "100"], r"priors\.d_lat: .*\[500\.0, 100\.0\]"),
        (["--prior", "mass", "1", "2"], r"unknown prior 'mass'"),
        (["--prior", "d_lat", "ten", "100"], r"must be numbers"),
        (["--channels", "vx,roll"], r"unknown channel"),
    ],
)
def test_sample_bad_input_exits_2(simulated, tmp_path, capsys, extra, pattern):
    code = main(["sample", simulated[0], "--out", str(tmp_path / "p.nc"), *QUICK_SAMPLE, *extra])
    captured = capsys.readouterr()
    assert code == 2
    assert "Traceback" not in captured.err
    assert re.search(pattern, captured.err), captured.err


def test_simulate_bags_and_ingest_them_back(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path), "--seed", "4", *SMALL, "--bag", "ros2"]) == 0
    bags = sorted(str(p) for p in tmp_path.glob("*.mcap"))
    assert len(bags) == 2
    capsys.readouterr()
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"not a bag")
    code = main(["ingest", *bags, str(broken), "--out", str(tmp_path / "exp"), "--json"])
    captured = capsys.readouterr()
    # One bad bag is reported and does not lose the others' results.
    assert code == 2
    payload = json.loads(captured.out)
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}
    assert list(payload["failed"]) == [str(broken)]
    assert "broken.mcap" in captured.err and "Traceback" not in captured.err
    ingested = read_netcdf(tmp_path / "exp" / "v2_01.nc")
    simulated = read_netcdf(tmp_path / "v2_01.nc")
    np.testing.assert_allclose(ingested.yaw_rate, simulated.yaw_rate[: len(ingested.t)], atol=1e-5)
    assert ingested.provenance["sha256"]


def test_ingest_refuses_a_second_bag_of_the_same_name(tmp_path, capsys):
    # a/v2_01.bag and b/v2_01.bag both become v2_01.nc: the second would
    # overwrite the first's experiment file.
    for folder, seed in (("a", "4"), ("b", "5")):
        one_run = ["--v1", "0", "--v2", "1", "--bag", "ros1"]
        assert main(["simulate", "--out", str(tmp_path / folder), "--seed", seed, *one_run]) == 0
    first, second = (str(tmp_path / folder / "v2_01.bag") for folder in "ab")
    capsys.readouterr()
    code = main(["ingest", first, second, "--out", str(tmp_path / "exp"), "--json"])
    captured = capsys.readouterr()
    assert code == 2 and "Traceback" not in captured.err
    payload = json.loads(captured.out)
    assert list(payload["experiments"]) == ["v2_01"] and list(payload["failed"]) == [second]
    assert f"error: {second}: its experiment name 'v2_01' is that of {first}" in captured.err
    kept = read_netcdf(tmp_path / "exp" / "v2_01.nc")
    simulated = read_netcdf(tmp_path / "a" / "v2_01.nc")
    np.testing.assert_allclose(kept.yaw_rate, simulated.yaw_rate[: len(kept.t)], atol=1e-5)


def test_ingest_topic_override(tmp_path, capsys):
    assert (
        main(
            [
                "simulate",
                "--out",
                str(tmp_path),
                "--seed",
                "4",
                "--v1",
                "0",
                "--v2",
                "1",
                "--bag",
                "ros1",
            ]
        )
        == 0
    )
    bag = str(tmp_path / "v2_01.bag")
    capsys.readouterr()
    # Pointing the IMU role at a topic the bag lacks names that topic ...
    code = main(["ingest", bag, "--out", str(tmp_path / "a"), "--topic", "imu", "/imu/raw"])
    assert code == 2 and "'/imu/raw'" in capsys.readouterr().err
    # ... an unknown role is refused, and the default names still work.
    code = main(["ingest", bag, "--out", str(tmp_path / "b"), "--topic", "lidar", "/scan"])
    assert code == 2 and "unknown topic role" in capsys.readouterr().err
    assert main(["ingest", bag, "--out", str(tmp_path / "c"), "--topic", "imu", "/imu/data"]) == 0


#: Yaw alone keeps these mechanics tests quick (three channels: ~3x the time).
QUICK_COMPARE = [
    "--channels",
    "yaw",
    "--families",
    "white,gaussian",
    "--max-steps",
    "300",
    "--seed",
    "2",
    "--no-progress",
]


def test_compare_prints_the_contract_json_and_keeps_posteriors(simulated, tmp_path, capsys):
    folder = tmp_path / "compare"
    code = main(["compare", simulated[0], *QUICK_COMPARE, "--out", str(folder), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    payload = json.loads(captured.out)
    assert set(payload["families"]) == {"white", "gaussian"}
    assert payload["channels"] == ["yaw"] and "channels yaw (bridge" in captured.err
    for row in payload["families"].values():
        assert {"log_evidence", "log_evidence_err", "log_bayes_factor_vs_white"} <= set(row)
        assert np.isfinite(row["log_evidence"]) and row["log_evidence_err"] > 0
    gaussian = payload["families"]["gaussian"]
    assert gaussian["log_bayes_factor_vs_white"] == pytest.approx(
        gaussian["log_evidence"] - payload["families"]["white"]["log_evidence"]
    )
    assert payload["families"]["white"]["width"] is None
    assert gaussian["width"]["sigma_h"]["hdi_3%"] < gaussian["width"]["sigma_h"]["hdi_97%"]
    assert payload["best"] in payload["families"]
    assert payload["verdict"] in ("coloured", "not coloured", "inconclusive")
    assert payload["verdict_text"].startswith(payload["verdict"])
    # The simulated runs carry Gaussian-coloured noise (sigma_h = 0.047 s):
    # even a short chain puts gaussian hundreds of nats ahead of white.
    assert payload["verdict"] == "coloured"
    assert "Verdict: coloured" in captured.err
    assert (folder / "v1_01.gaussian.nc").is_file() and (folder / "v1_01.compare.json").is_file()


def test_compare_several_experiments_without_pooling(simulated, capsys):
    code = main(["compare", *simulated, *QUICK_COMPARE, "--families", "white", "--json"])
    payload = json.loads(capsys.readouterr().out)
    assert code == 0
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}


@pytest.mark.parametrize(
    ("extra", "pattern"),
    [
        (["--families", "white,pink"], r"unknown families \['pink'\]"),
        (["--families", "white,white"], r"families must be distinct"),
        (["--prior", "sigma_h", "1", "0.1"], r"priors\.sigma_h"),
    ],
)
def test_compare_bad_input_exits_2(simulated, capsys, extra, pattern):
    code = main(["compare", simulated[0], *QUICK_COMPARE, *extra])
    captured = capsys.readouterr()
    assert code == 2
    assert "Traceback" not in captured.err
    assert re.search(pattern, captured.err), captured.err


def test_compare_keeps_each_family_as_it_finishes_when_interrupted(
    simulated, tmp_path, capsys, monkeypatch
):
    import bayes_jackal.cli.commands as cli

    saved = []

    def save_then_interrupt(idata, path):
        saved.append(cli_save(idata, path))
        raise KeyboardInterrupt  # Ctrl-C right after the first family

    cli_save = cli.save_posterior
    monkeypatch.setattr(cli, "save_posterior", save_then_interrupt)
    folder = tmp_path / "compare"
    code = main(
        ["compare", simulated[0], *QUICK_COMPARE, "--processes", "1", "--out", str(folder)]
    )
    assert code == 130
    assert [p.name for p in saved] == ["v1_01.white.nc"]
    assert sorted(p.name for p in folder.iterdir()) == ["v1_01.white.nc"]
