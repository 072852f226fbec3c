"""The ``bayes-jackal`` command line: simulate and grid, JSON output and exit codes."""

from __future__ import annotations

import inspect
import json
import re
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from cli_helpers import strict_json

from bayes_jackal.cli import main
from bayes_jackal.cli.parser import build_parser
from bayes_jackal.filters.state_space import filter_models
from bayes_jackal.io.bag_writer import write_bag
from bayes_jackal.io.experiment import Experiment, read_netcdf, write_netcdf
from bayes_jackal.io.simulate import SERIES, NoiseSettings, Series, simulate_experiment
from bayes_jackal.io.tables import read_csv, write_csv
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.model.kernels import FAMILIES
from bayes_jackal.model.robot import default_profile_path, load_profile, mass_scaled_damping
from bayes_jackal.posterior.file_format import posterior_layout
from bayes_jackal.posterior.posterior import load_posterior
from bayes_jackal.thesis.gridsearch import grid_search
from bayes_jackal.thesis.residual_analysis import analyse

SMALL = ["--v1", "1", "--v2", "1"]
GRID = ["--d-lat", "50", "200", "10", "--d-long", "10", "60", "5"]
ARRAYS = ("t", "yaw_rate", "omega_r", "omega_l", "vx", "vy")


def assert_usage_error(code: int, captured, command: str, pattern: str) -> None:
    """Exit code 2 from the parser: usage, then ``bayes-jackal CMD: error: argument ...``."""
    assert code == 2 and "Traceback" not in captured.err
    last = captured.err.strip().splitlines()[-1]
    assert last.startswith(f"bayes-jackal {command}: error: argument "), captured.err
    assert re.search(pattern, last), (pattern, last)


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


def test_the_default_families_are_registered():
    # The parser takes --family's default without loading the registry
    # (cli/parser_types.family), so that an output is refused before numpy loads.
    from bayes_jackal._runtime.defaults import DEFAULT_FAMILIES, FAMILY, SHORT_MEMORY
    from bayes_jackal.model.kernels import FAMILIES

    assert FAMILY in FAMILIES and {*DEFAULT_FAMILIES, SHORT_MEMORY} <= set(FAMILIES)


def test_grid_text_goes_to_stdout_without_json(simulated, capsys):
    code = main(["grid", *simulated, *GRID])
    captured = capsys.readouterr()
    assert code == 0
    assert "total (5-3)" in captured.out
    # The one-step minimum is said not to be the estimate (issue 37, item 15).
    assert "note: the one-step minimum is not the damping's estimate" in captured.out
    # stderr has the search's line (on a terminal, a ticking clock) and the
    # warning of the one-step minimum (50, 15) on the grid's low d_lat edge:
    # the criterion is biased down the ridge by the coloured noise
    # (docs/guide/thesis.md), below the truth's (110, 30).
    assert captured.err.splitlines() == [
        "  onestep MSE grid of the yaw channel (16 x 11 points)...",
        "bayes-jackal: WARNING: onestep grid: the minimum (d_lat = 50, d_long = 15 N s/m) lies "
        "on the low edge of the d_lat grid (50-200 N s/m): the MSE may be lower below d_lat = "
        "50 N s/m, outside the grid; widen the grid (--d-lat START STOP STEP)",
    ]


@pytest.mark.parametrize("command", [["grid"], ["residuals", "--channels", "yaw"]])
def test_a_husky_run_read_under_the_jackal_profile_is_said(tmp_path, cli, command):
    # The run's file names the profile that made it; under another one its
    # fit is that robot's, which grid and residuals said nothing of (sample
    # only warned of the rate, filter refuses).
    husky = load_profile("husky")
    path = tmp_path / "h.nc"
    write_netcdf(simulate_experiment(husky, 306.5, 83.6, rng=1, name="h"), path)
    result = cli([*command, "h.nc"], tmp_path)
    assert result.code == 0, result.stderr
    assert ("h.nc: recorded as a 'husky' run, read with the 'jackal' profile" in result.stderr
            and "pass --robot husky" in result.stderr), result.stderr  # fmt: skip
    result = cli([*command, "h.nc", "--robot", "husky"], tmp_path)
    assert result.code == 0 and "recorded as a" not in result.stderr, result.stderr


def test_grid_json_flags_a_minimum_on_the_grids_edge(simulated, capsys):
    # The simulation criterion finds the truth (110, 30) on a grid holding it
    # (tests/test_gridsearch.py); a d_lat grid stopping at 90 puts its
    # minimum on the high edge, 90, with d_long inside.
    grid = ["--d-lat", "50", "90", "10", "--d-long", "10", "60", "5"]
    code = main(["grid", *simulated, *grid, "--method", "simulation", "--json"])
    captured = capsys.readouterr()
    assert code == 0
    payload = json.loads(captured.out)
    assert payload["d_lat"] == 90.0 and 10.0 < payload["d_long"] < 60.0
    assert payload["edge"] == {"d_lat": "high"}
    (warning,) = payload["warnings"]
    assert {key: warning[key] for key in ("kind", "method", "parameter", "side", "value")} == {
        "kind": "grid-edge",
        "method": "simulation",
        "parameter": "d_lat",
        "side": "high",
        "value": 90.0,
    }
    assert "the MSE may be lower above d_lat = 90 N s/m" in warning["message"]
    assert f"WARNING: {warning['message']} (--d-lat START STOP STEP)" in captured.err
    # Each series' and experiment's minimum says its own edge.
    assert {s["edge"].get("d_lat") for s in payload["experiments"].values()} <= {"high", None}


@pytest.mark.parametrize("method", ["onestep", "simulation"])
def test_grid_default_is_the_jackals_prior_log_spaced(tmp_path, capsys, method):
    # The Jackal's prior is 10-1000 N s/m (models/jackal.toml): the default
    # one-step grid starts at 10 now, not the thesis' 1; 1000 values for the
    # one-step criterion, 100 for the simulation one (GRID_POINTS). An 8 s
    # run keeps the 10^4 simulations quick.
    run = simulate_experiment(load_profile(), 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=1)
    path = write_netcdf(run, tmp_path / "short.nc")
    code = main(["grid", str(path), "--method", method, "--json"])
    payload = json.loads(capsys.readouterr().out)
    assert code == 0
    count = {"onestep": 1000, "simulation": 100}[method]
    assert payload["grid"] == {"d_lat": [10.0, 1000.0, count], "d_long": [10.0, 1000.0, count]}


def test_grid_given_start_stop_step_is_the_thesis_grid(simulated, capsys):
    # A user reproducing the thesis' ch. 9-1-2: 1..1000 step 1, STOP
    # included, (1000 - 1) / 1 + 1 = 1000 values, below the prior's floor.
    thesis = ["--d-lat", "1", "1000", "1", "--d-long", "1", "1000", "1"]
    code = main(["grid", simulated[0], *thesis, "--json"])
    payload = json.loads(capsys.readouterr().out)
    assert code == 0
    assert payload["grid"] == {"d_lat": [1.0, 1000.0, 1000], "d_long": [1.0, 1000.0, 1000]}
    # Integer values, as the thesis': its minimum is a whole N s/m.
    assert payload["d_lat"] == round(payload["d_lat"])


def test_grid_default_spans_the_warthogs_prior(tmp_path, capsys):
    # The Warthog's prior is the Jackal's scaled to its 200 kg body,
    # 121.04-12104.34 N s/m; the simulated truth, scaled the same way, is
    # (1331.5, 363.1) N s/m.
    robot = load_profile("warthog")
    run = simulate_experiment(robot, *mass_scaled_damping(robot.mass), "v2", rng=1)
    path = write_netcdf(run, tmp_path / "warthog.nc")
    code = main(["grid", str(path), "--robot", "warthog", "--json"])
    captured = capsys.readouterr()
    assert code == 0
    payload = json.loads(captured.out)
    for name in ("d_lat", "d_long"):
        low, high, count = payload["grid"][name]
        assert (low, high) == pytest.approx(robot.priors[name], rel=1e-12) and count == 1000
    # The case: the one-step criterion is biased down the ridge by the
    # coloured noise (the demo's (15, 4) for a truth of (110, 30): a factor
    # ~7), so the Warthog's minimum would lie near 363 / 7 = 52 N s/m, below
    # its prior's floor: it sits on the grid's low d_long edge, and says so.
    assert payload["edge"] == {"d_long": "low"}
    (warning,) = payload["warnings"]
    assert (warning["parameter"], warning["side"]) == ("d_long", "low")
    assert warning["value"] == pytest.approx(robot.priors["d_long"][0], rel=1e-12)
    assert "bayes-jackal: WARNING: onestep grid: the minimum" in captured.err


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
        ("--d-lat", ["0", "100", "10"], r"--d-lat: grid needs .*START=0\.0"),
        ("--d-lat", ["10", "100", "-5"], r"--d-lat: grid needs .*STEP=-5\.0"),
        ("--d-lat", ["nan", "100", "10"], r"--d-lat: expected a finite number, got 'nan'"),
        ("--d-long", ["100", "10", "10"], r"--d-long: grid needs .*START=100\.0 STOP=10\.0"),
    ],
)
def test_grid_bad_range(simulated, capsys, flag, values, pattern):
    # Checked by the parser, with damping_grid's own rule, before any work.
    code = main(["grid", simulated[0], flag, *values, "--json"])
    captured = capsys.readouterr()
    assert_usage_error(code, captured, "grid", pattern)
    assert captured.out == ""


def test_grid_profile_with_negative_mass(simulated, tmp_path, capsys):
    profile = tmp_path / "heavy.toml"
    text = default_profile_path().read_text()
    profile.write_text(text.replace("mass = 16.523", "mass = -16.523"))
    code = main(["grid", simulated[0], *GRID, "--robot", str(profile)])
    assert_bad_input(code, capsys.readouterr(), re.escape(str(profile)), r"mass", r"-16\.523")


def test_grid_unknown_suffix(tmp_path, capsys):
    path = tmp_path / "run.txt"
    path.write_bytes(b"#ROSBAG V2.0\n")
    code = main(["grid", str(path), *GRID])
    assert_bad_input(code, capsys.readouterr(), re.escape(str(path)), r"'\.txt'")
    assert path.read_bytes() == b"#ROSBAG V2.0\n"


def test_grid_refuses_a_bag_it_cannot_read(tmp_path, capsys):
    # grid reads bags (as bj.load_experiments does): a bag with a header and
    # nothing else is refused, naming the file, and left as it was.
    path = tmp_path / "run.bag"
    path.write_bytes(b"#ROSBAG V2.0\n")
    code = main(["grid", str(path), *GRID])
    assert_bad_input(code, capsys.readouterr(), re.escape(str(path)), r"cannot read bag")
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


@pytest.fixture(scope="module")
def short_runs(tmp_path_factory) -> list[str]:
    """Two 8 s runs at the v1 and v2 commands, named as ``simulated``'s (v1_01, v2_01).

    For the tests of what ``sample`` prints and writes: its JSON's keys, its
    files, its warning that 80 steps did not converge (the chains' tau was
    4 to 5 steps on these runs, with one channel or three, and convergence
    needs 50 tau: 200 steps or more), none of which depends on a run's
    length (the two tests took 5.8 s on the 38 s and 26 s runs, 4.3 s on
    these).
    """
    folder = tmp_path_factory.mktemp("short_runs")
    robot = load_profile()
    paths = []
    for seed, (name, series) in enumerate(SERIES.items(), start=1):
        short = Series(series.v, series.w, 8.0)
        run = simulate_experiment(robot, 110.0, 30.0, short, rng=seed, name=f"{name}_01")
        paths.append(str(write_netcdf(run, folder / f"{name}_01.nc")))
    return paths


def test_sample_writes_a_posterior_and_prints_the_contract_json(short_runs, tmp_path, capsys):
    out = tmp_path / "posterior.nc"
    code = main(["sample", short_runs[0], "--out", str(out), *QUICK_SAMPLE, "--json"])
    captured = capsys.readouterr()
    assert code == 0
    payload = json.loads(captured.out)
    # By default every channel the experiment measures, each with its noise.
    assert payload["channels"] == ["yaw", "vx", "vy"]
    assert "on channels yaw, vx, vy" in captured.err
    # Each phase is said, with --json on stderr (issue 37, item 16): the MAP
    # search was silent (a minute under load).
    for said in ("MAP search: the profile likelihood", "MAP found in", f"wrote {out}; the summ"):
        assert said in captured.err, captured.err
    noise = [f"{name}[{c}]" for c in ("yaw", "vx", "vy") for name in ("sigma_h", "sigma_c")]
    for key in ("d_lat", "d_long", *noise, "ratio"):
        assert {"mean", "sd", "hdi_3%", "hdi_97%", "ess_bulk", "ess_tail", "r_hat"} <= set(
            payload[key]
        )
    assert {"corr_d_lat_d_long", "autocorr_time", "n_steps"} <= set(payload)
    # 80 steps cannot converge: the run says so loudly, on stderr.
    assert "WARNING: NOT CONVERGED" in captured.err
    assert out.is_file() and out.with_suffix(".chain.h5").is_file()


def test_sample_one_width_writes_one_width_and_export_prior_says_so(simulated, tmp_path, capsys):
    # --noise one-width: one width for both channels in the summary and the
    # file, which reloads with it; export-prior marks it shared (with the
    # --sensor-smoothness asked) and the filters read that prior.
    out, prior_path = tmp_path / "posterior.nc", tmp_path / "prior.json"
    model = ["--family", "exponential", "--channels", "yaw,vx", "--noise", "one-width"]
    code = main(["sample", simulated[0], "--out", str(out), *model, *QUICK_SAMPLE, "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    payload = json.loads(captured.out)
    assert "width" in payload and "width[yaw]" not in payload and "sigma_c[vx]" in payload
    layout = posterior_layout(load_posterior(out))
    assert layout.shared_width is True
    assert layout.names == (
        "d_lat",
        "d_long",
        "width",
        "sigma_c[yaw]",
        "sigma_n[yaw]",
        "sigma_c[vx]",
        "sigma_n[vx]",
    )
    export = ["--order", "0", "--sensor-smoothness", "1.5"]
    assert main(["export-prior", str(out), "--out", str(prior_path), *export]) == 0
    capsys.readouterr()
    prior = json.loads(prior_path.read_text())
    assert prior["noise"]["shared_width"] is True and "width" in prior["draws"]
    assert prior["sensor_noise"]["smoothness_bins"] == 1.5
    assert list(filter_models(prior)) == ["yaw", "vx"]


def test_sample_defaults_to_the_library_engine(simulated, tmp_path):
    # The debiased Whittle engine is off by tens of nats for the Gaussian
    # family (README); the command must use the exact `fast` engine unless asked.
    args = build_parser().parse_args(["sample", simulated[0], "--out", str(tmp_path / "p.nc")])
    assert args.engine == "fast" == ResidualLikelihood.__dataclass_fields__["engine"].default


def test_sample_without_pooling_writes_one_posterior_per_experiment(short_runs, tmp_path, capsys):
    out = tmp_path / "post.nc"
    yaw = ["--channels", "yaw"]  # narrowed: quicker, and checks the flag
    code = main(["sample", *short_runs, "--out", str(out), *QUICK_SAMPLE, *yaw, "--json"])
    payload = json.loads(capsys.readouterr().out)
    assert code == 0
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}
    assert payload["experiments"]["v1_01"]["channels"] == ["yaw"]
    assert (tmp_path / "post.v1_01.nc").is_file() and (tmp_path / "post.v2_01.nc").is_file()
    code = main(
        ["sample", *short_runs, "--out", str(out), "--pooled", *QUICK_SAMPLE, *yaw, "--json"]
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


def test_ingest_keeps_both_bags_of_one_name(tmp_path, capsys):
    # a/v2_01.bag and b/v2_01.mcap both are v2_01: once the second overwrote the
    # first's experiment file (issue 11); now it is ingested as v2_01-2 and a line says so.
    for folder, seed, kind in (("a", "4", "ros1"), ("b", "5", "ros2")):
        one_run = ["--v1", "0", "--v2", "1", "--bag", kind]
        assert main(["simulate", "--out", str(tmp_path / folder), "--seed", seed, *one_run]) == 0
    first, second = str(tmp_path / "a" / "v2_01.bag"), str(tmp_path / "b" / "v2_01.mcap")
    capsys.readouterr()
    code = main(["ingest", first, second, "--out", str(tmp_path / "exp")])
    assert code == 0 and "renamed: v2_01 was another input's name" in capsys.readouterr().out
    code = main(["ingest", first, second, "--out", str(tmp_path / "exp"), "--json"])
    captured = capsys.readouterr()
    assert code == 0 and "Traceback" not in captured.err
    payload = json.loads(captured.out)
    assert list(payload["experiments"]) == ["v2_01", "v2_01-2"] and not payload["failed"]
    assert payload["experiments"]["v2_01-2"]["file"] == str(tmp_path / "exp" / "v2_01-2.nc")
    for name, folder in (("v2_01", "a"), ("v2_01-2", "b")):
        kept = read_netcdf(tmp_path / "exp" / f"{name}.nc")
        simulated = read_netcdf(tmp_path / folder / "v2_01.nc")
        assert kept.name == name
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


#: Yaw alone keeps these mechanics tests quick (three channels: ~3x the time);
#: the flags of the session's ``compared`` (tests/conftest.py) too.
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


def test_compare_prints_the_contract_json_and_keeps_posteriors(compared):
    # The session's comparison of v1_01 (QUICK_COMPARE, --out, --json; tests/conftest.py).
    folder = compared.folder
    assert compared.code == 0, compared.err
    payload = json.loads(compared.out)
    assert set(payload["families"]) == {"white", "gaussian"}
    assert payload["channels"] == ["yaw"] and "channels yaw (bridge" in compared.err
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
    assert "Verdict: coloured" in compared.err
    assert (folder / "v1_01.gaussian.nc").is_file() and (folder / "v1_01.compare.json").is_file()


def test_compare_several_experiments_without_pooling(simulated, capsys):
    # In this process: several groups on worker processes are tests/test_comparison.py's.
    quick = [*QUICK_COMPARE, "--families", "white", "--processes", "1"]
    code = main(["compare", *simulated, *quick, "--json"])
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
    # The first family handed out (the likely longest first: gaussian before white).
    assert [p.name for p in saved] == ["v1_01.gaussian.nc"]
    assert sorted(p.name for p in folder.iterdir()) == ["v1_01.gaussian.nc"]


# One bad input never stops the others (issue 11, item 9); escaping exceptions (item 10).

#: The cheapest sampling that still writes a posterior: white noise on yaw, 80 steps.
QUICK_WHITE = [*QUICK_SAMPLE, "--family", "white", "--channels", "yaw"]


@pytest.fixture
def empty_csv(tmp_path) -> str:
    path = tmp_path / "empty.csv"
    path.write_bytes(b"")
    return str(path)


def error_lines(captured) -> list[str]:
    """The error lines on stderr (no traceback anywhere)."""
    assert "Traceback" not in captured.err
    return [line for line in captured.err.splitlines() if line.startswith("bayes-jackal: error")]


def test_sample_without_pooling_finishes_the_good_inputs_and_names_the_bad_one(
    simulated, empty_csv, tmp_path, capsys
):
    out = tmp_path / "post.nc"
    inputs = [simulated[0], empty_csv, simulated[1]]
    code = main(["sample", *inputs, "--out", str(out), *QUICK_WHITE, "--json"])
    captured = capsys.readouterr()
    assert code == 2
    payload = json.loads(captured.out)
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}
    assert payload["failed"] == {empty_csv: f"{empty_csv}: file is empty"}
    assert error_lines(captured) == [f"bayes-jackal: error: {empty_csv}: file is empty"]
    assert "2 of 3 experiments done" in captured.err
    assert (tmp_path / "post.v1_01.nc").is_file() and (tmp_path / "post.v2_01.nc").is_file()
    # report: an unreadable posterior among two: the report is written from the others.
    posteriors = [str(tmp_path / "post.v1_01.nc"), simulated[0], str(tmp_path / "post.v2_01.nc")]
    report = tmp_path / "report" / "r.html"
    code = main(["report", *posteriors, "--out", str(report), "--formats", "png"])
    captured = capsys.readouterr()
    assert code == 2
    [line] = error_lines(captured)
    assert line.startswith(f"bayes-jackal: error: {simulated[0]}: not a bayes_jackal posterior")
    assert f"posteriors: {posteriors[0]}, {posteriors[2]}. Figures" in report.read_text()
    # A line as each posterior's criticism and figures begin (issue 24, item 12: silent).
    assert "report: post.v1_01.nc (1 of 2): criticism and figures" in captured.out
    assert "report: post.v2_01.nc (2 of 2): criticism and figures" in captured.out


def test_sample_goes_on_past_an_input_without_a_requested_channel(simulated, tmp_path, capsys):
    # A yaw-only log among runs that measure vx: the channel check names it
    # and the others are sampled (the check once ran outside each input's guard).
    run = read_netcdf(simulated[0])
    yaw_only = tmp_path / "yaw_only.csv"
    write_csv(Experiment(run.t, run.yaw_rate, run.omega_r, run.omega_l), yaw_only)
    out = tmp_path / "post.nc"
    quick = [*QUICK_SAMPLE, "--family", "white", "--channels", "yaw,vx"]
    code = main(["sample", str(yaw_only), simulated[1], "--out", str(out), *quick, "--json"])
    captured = capsys.readouterr()
    assert code == 2
    [line] = error_lines(captured)
    assert str(yaw_only) in line and "['vx'] not measured" in line
    assert list(json.loads(captured.out)["experiments"]) == ["v2_01"]
    assert (tmp_path / "post.v2_01.nc").is_file()


def test_compare_without_pooling_finishes_the_good_input(simulated, empty_csv, tmp_path, capsys):
    folder = tmp_path / "compare"
    quick = [*QUICK_COMPARE, "--families", "white", "--processes", "1"]
    code = main(["compare", empty_csv, simulated[0], *quick, "--out", str(folder), "--json"])
    captured = capsys.readouterr()
    assert code == 2
    payload = json.loads(captured.out)
    assert list(payload["experiments"]) == ["v1_01"] and list(payload["failed"]) == [empty_csv]
    assert error_lines(captured) == [f"bayes-jackal: error: {empty_csv}: file is empty"]
    assert sorted(p.name for p in folder.iterdir()) == ["v1_01.compare.json", "v1_01.white.nc"]


def test_residuals_analyse_the_good_inputs_and_name_the_bad_one(simulated, empty_csv, capsys):
    code = main(["residuals", simulated[0], empty_csv, simulated[1], "--json"])
    captured = capsys.readouterr()
    assert code == 2
    payload = json.loads(captured.out)
    assert list(payload["experiments"]) == ["v1_01", "v2_01"]
    assert set(payload["sigma_h"]) == {"v1", "v2", "all"}
    assert payload["failed"] == {empty_csv: f"{empty_csv}: file is empty"}
    assert error_lines(captured) == [f"bayes-jackal: error: {empty_csv}: file is empty"]


@pytest.mark.parametrize(
    "command",
    [
        ["sample", "--pooled", "--out", "{tmp}/p.nc", *QUICK_WHITE],
        ["compare", "--pooled", "--out", "{tmp}/compare", *QUICK_COMPARE],
        ["grid", *GRID, "--out", "{tmp}/grid.nc", "--plot", "{tmp}/grid.png"],
    ],
)
def test_pooled_commands_name_every_bad_input_before_any_work(
    simulated, empty_csv, tmp_path, capsys, command
):
    outputs = tmp_path / "outputs"
    outputs.mkdir()
    missing = str(tmp_path / "missing.nc")
    argv = [part.replace("{tmp}", str(outputs)) for part in command]
    code = main([*argv, simulated[0], empty_csv, missing])
    line = assert_bad_input(code, capsys.readouterr(), "2 of 3 inputs cannot be used")
    assert f"{empty_csv}: file is empty" in line and f"{missing}: no such file" in line
    assert [path for path in outputs.rglob("*") if not path.is_dir()] == []  # nothing written


@pytest.fixture
def failing_chi2(monkeypatch):
    """A library function deep in the residual analysis that fails unexpectedly."""
    import scipy.stats

    def fail(*args, **kwargs):
        raise RuntimeError("simulated failure")

    monkeypatch.setattr(scipy.stats.chi2, "sf", fail)


def test_an_escaping_exception_is_one_line_naming_the_input(simulated, capsys, failing_chi2):
    code = main(["residuals", simulated[0]])
    captured = capsys.readouterr()
    assert code == 1
    assert captured.err.splitlines() == [
        f"bayes-jackal: failed: RuntimeError: simulated failure ({simulated[0]})"
    ]
    # Without pooling, each input fails on its own, named; the exit code is 1.
    code = main(["residuals", *simulated, "--json"])
    captured = capsys.readouterr()
    assert code == 1 and "Traceback" not in captured.err
    assert set(json.loads(captured.out)["failed"]) == set(simulated)
    for path in simulated:
        assert f"bayes-jackal: failed: RuntimeError: simulated failure ({path})" in captured.err


@pytest.mark.parametrize("where", ["before", "after", "environment"])
def test_debug_shows_the_traceback(simulated, capsys, monkeypatch, failing_chi2, where):
    argv = ["residuals", simulated[0]]
    if where == "environment":
        monkeypatch.setenv("BAYES_JACKAL_DEBUG", "1")
    debug = {"before": ["--debug", *argv], "after": [*argv, "--debug"]}
    code = main(debug.get(where, argv))
    captured = capsys.readouterr()
    assert code == 1
    assert captured.err.startswith("Traceback (most recent call last):")
    assert "in _ljung_box\n" in captured.err
    last = captured.err.splitlines()[-1]
    assert last == f"bayes-jackal: failed: RuntimeError: simulated failure ({simulated[0]})"


# --- warnings and the version (issue 13) ---------------------------------------

#: matplotlib's warning when plots.plot_grid sets the limits of a one-value grid.
SINGULAR_XLIMS = (
    "Attempting to set identical low and high xlims makes transformation singular; "
    "automatically expanding."
)


@pytest.mark.parametrize("debug", [False, True])
def test_a_library_warning_reaches_stderr_as_one_line(simulated, tmp_path, capsys, debug):
    argv = ["grid", simulated[0], "--d-lat", "110", "110", "10", "--d-long", "30", "30", "5"]
    argv += ["--plot", str(tmp_path / "grid.png"), *(["--debug"] if debug else [])]
    with warnings.catch_warnings():
        warnings.simplefilter("default")  # Python's default action, not pytest's "error"
        code = main(argv)
    err = capsys.readouterr().err
    assert code == 0 and (tmp_path / "grid.png").exists()
    [line] = [line for line in err.splitlines() if "xlims" in line]
    where = r" \(UserWarning at .*plots\.py:\d+\)" if debug else ""
    assert re.fullmatch(f"bayes-jackal: WARNING: {re.escape(SINGULAR_XLIMS)}{where}", line)
    assert "Warning:" not in err.replace("bayes-jackal: WARNING:", "")  # no raw form


def test_a_warning_is_shown_once(capsys):
    from bayes_jackal.cli import _warnings_shown

    with warnings.catch_warnings():
        warnings.simplefilter("always")  # Python alone would show each
        with _warnings_shown(debug=False):
            warnings.warn("the same message", UserWarning, stacklevel=1)
            warnings.warn("the same message", UserWarning, stacklevel=1)
            warnings.warn("another message", RuntimeWarning, stacklevel=1)
    assert capsys.readouterr().err.splitlines() == [
        "bayes-jackal: WARNING: the same message",
        "bayes-jackal: WARNING: another message",
    ]


def test_criticism_warnings_are_one_line_per_kind_and_a_line_of_meaning(capsys):
    """Issue 24, item 10: 47 WARNING lines buried the answer; repeats are one line."""
    from bayes_jackal.cli.output import print_criticism

    acf = [
        {"kind": "predictive-acf", "experiment": run, "channel": "yaw", "statistic": s,
         "message": f"{run}, yaw: the residuals' {s} is higher than in 200 of 200"}
        for run in ("v1_01", "v2_01") for s in ("acf[1]", "acf[5]")
    ]  # fmt: skip
    bound = {"kind": "prior-boundary", "parameter": "d_long", "message": "d_long: piled"}
    print_criticism([*acf, bound], where="compare.json")
    assert capsys.readouterr().err.splitlines() == [
        "bayes-jackal: WARNING: predictive-acf x4: v1_01, yaw: the residuals' acf[1] is higher "
        "than in 200 of 200; the same at v1_01 yaw acf[5], v2_01 yaw acf[1], v2_01 yaw acf[5]",
        "bayes-jackal: WARNING: d_long: piled",
        "bayes-jackal: note: 5 warning(s): predictive-acf: the fitted noise misses the "
        "residuals' colour: try another family; prior-boundary: a parameter is piled at its "
        "prior's bound: the data give only a limit. In full: compare.json",
    ]
    print_criticism([])
    assert capsys.readouterr().err == ""
    # Warnings told apart only by their text (a chain's convergence) are each shown whole.
    chains = [{"kind": "not-converged", "message": f"{f}: NOT CONVERGED"} for f in ("a", "b")]
    print_criticism(chains)
    assert capsys.readouterr().err.splitlines()[:2] == [
        "bayes-jackal: WARNING: a: NOT CONVERGED",
        "bayes-jackal: WARNING: b: NOT CONVERGED",
    ]


def test_version_is_the_installed_distributions(capsys):
    import importlib.metadata

    import bayes_jackal

    version = importlib.metadata.version("bayes-jackal")
    assert version == bayes_jackal.__version__
    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"bayes-jackal {version}\n"


# --- numeric flags and strict JSON (issue 11) ----------------------------------


@pytest.mark.parametrize(
    ("command", "pattern"),
    [
        (["simulate", "--out", "OUT", "--v1", "-1"], r"--v1: expected an integer >= 0, got '-1'"),
        (["simulate", "--out", "OUT", "--seed", "-1"], r"--seed: expected an integer >= 0"),
        (["simulate", "--out", "OUT", "--d-lat", "inf"], r"--d-lat: expected a finite number > 0"),
        (["simulate", "--out", "OUT", "--width", "-0.1"], r"--sigma-h: expected a finite num"),
        (["simulate", "--out", "OUT", "--sigma-n", "0", "0", "nan"], r"--sigma-n: .* >= 0"),
        (["sample", "EXP", "--out", "OUT/p.nc", "--max-steps", "0"], r"--max-steps: .* >= 1"),
        (["sample", "EXP", "--out", "OUT/p.nc", "--walkers", "-4"], r"--walkers: .* >= 0"),
        (["compare", "EXP", "--processes", "0"], r"--processes: expected an integer >= 1"),
        (["residuals", "EXP", "--lags", "0"], r"--lags: expected an integer >= 1, got '0'"),
        (["residuals", "EXP", "--d-long", "-30"], r"--d-long: expected a finite number > 0"),
        (["residuals", "EXP", "--rate", "nan"], r"--rate: expected a finite number > 0"),
        (["grid", "EXP", "--d-lat", "10", "100", "0"], r"--d-lat: grid needs .*STEP=0\.0"),
        (["export-prior", "EXP", "--out", "OUT/p.json", "--order", "1.5"], r"--order: .* >= 0"),
        (
            ["export-prior", "EXP", "--out", "OUT/p.json", "--sensor-smoothness", "0"],
            r"--sensor-smoothness: expected a finite number > 0, got '0'",
        ),
        (["ingest", "EXP", "--out", "OUT", "--window", "30", "10"], r"--window: expected T0 < T1"),
        (["analyse", "EXP", "--out", "OUT", "--max-gap", "0"], r"--max-gap: .*> 0, got '0'"),
    ],
)
def test_bad_numeric_flags_are_refused_before_any_work(
    simulated, tmp_path, capsys, command, pattern
):
    argv = [
        simulated[0] if a == "EXP" else a.replace("OUT", str(tmp_path / "out")) for a in command
    ]
    code = main(argv)
    captured = capsys.readouterr()
    assert_usage_error(code, captured, command[0], pattern)
    assert captured.out == "" and not (tmp_path / "out").exists()


def test_every_json_output_maps_non_finite_numbers_to_null(tmp_path, capsys):
    from bayes_jackal._runtime.files import json_text, write_json
    from bayes_jackal.cli.output import Reporter

    payload = {
        "sd": float("inf"),
        "p": [float("nan"), 1.5, -float("inf")],
        "n": (np.float64("nan"),),
    }
    expected = {"sd": None, "p": [None, 1.5, None], "n": [None]}
    Reporter(True).result(payload)
    assert strict_json(capsys.readouterr().out) == expected
    assert strict_json(write_json(tmp_path / "x.json", payload).read_text()) == expected
    assert strict_json(json_text(payload, indent=None)) == expected


def test_command_json_parses_strictly(simulated, capsys):
    for command in (["grid", *GRID], ["residuals", "--channels", "yaw,vx"]):
        assert main([command[0], simulated[0], *command[1:], "--json"]) == 0
        assert strict_json(capsys.readouterr().out)


@pytest.fixture(scope="module")
def bag_and_ingested(tmp_path_factory):
    """A simulated v2 run as a ROS1 bag, and the experiment file ``ingest`` makes of it."""
    folder = tmp_path_factory.mktemp("bag")
    robot = load_profile()
    run = simulate_experiment(robot, 110.0, 30.0, "v2", rng=7, name="run")
    bag = write_bag(run, folder / "run.bag", robot, "ros1", rng=3)
    ingested = folder / "ingested"
    assert main(["ingest", str(bag), "--out", str(ingested), "--window", "3", "20"]) == 0
    return bag, ingested / "run.nc"


def test_residuals_read_a_bag_as_ingest_does(bag_and_ingested, capsys):
    # grid, residuals, sample and compare read bags through bj.load_experiments,
    # with ingest's flags: the numbers of the experiment file ingest writes.
    bag, ingested = bag_and_ingested
    capsys.readouterr()
    results = []
    for argv in ([str(bag), "--window", "3", "20"], [str(ingested)]):
        assert main(["residuals", *argv, "--channels", "yaw,vx", "--json"]) == 0
        results.append(strict_json(capsys.readouterr().out))
    assert results[0] == results[1]
    assert results[0]["experiments"]["run"]["yaw"]["n"] > 0


def test_a_bad_bag_among_experiments_is_named_and_the_others_done(
    bag_and_ingested, tmp_path, capsys
):
    _, ingested = bag_and_ingested
    bad = tmp_path / "bad.bag"
    bad.write_bytes(b"#ROSBAG V2.0\n")
    code = main(["residuals", str(ingested), str(bad), "--json"])
    captured = capsys.readouterr()
    assert code == 2
    result = strict_json(captured.out)
    assert list(result["experiments"]) == ["run"] and list(result["failed"]) == [str(bad)]
    assert f"bayes-jackal: error: {bad}: cannot read bag" in captured.err


def test_help_loads_no_numerical_library():
    # Every --help answers at once (issue 13: < 0.5 s): the parser takes the
    # library's names and defaults from bayes_jackal._runtime.defaults, and a command's
    # modules are imported only when it runs. Checked without timing.
    script = """
import argparse, contextlib, io, sys
from bayes_jackal.cli import build_parser, main
parser = build_parser()
[commands] = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
for command in ([], *([name] for name in commands.choices)):
    with contextlib.redirect_stdout(io.StringIO()):
        assert main([*command, "--help"]) == 0, command
heavy = [m for m in ("numpy", "scipy", "arviz", "matplotlib") if m in sys.modules]
print(len(commands.choices), heavy)
"""
    process = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert process.returncode == 0, process.stderr
    assert process.stdout == "13 []\n"  # ten commands, filter (14), noise (15), population (27)


def test_parser_defaults_are_the_librarys():
    # The flags show the library's values: one constant serves both.
    sim = build_parser().parse_args(["simulate", "--out", "x"])
    noise = NoiseSettings()
    assert (sim.width, tuple(sim.sigma_c), tuple(sim.sigma_n), sim.family) == (
        noise.width,
        noise.sigma_c,
        noise.sigma_n,
        noise.family,
    )
    assert (sim.v1, sim.v2) == (10, 5) and set(SERIES) == {"v1", "v2"}
    grid = build_parser().parse_args(["grid", "e.nc"])
    search = inspect.signature(grid_search).parameters
    for name in ("method", "channel", "discretisation"):
        assert getattr(grid, name) == search[name].default
    # None: the profile's prior range (thesis.prior_grid), known once --robot is read.
    assert grid.d_lat is None and grid.d_long is None
    residuals = build_parser().parse_args(["residuals", "e.nc"])
    analysis = inspect.signature(analyse).parameters
    assert residuals.channels == analysis["channels"].default == ("yaw",)
    assert residuals.lags == analysis["lags"].default
    # None: the thesis' damping scaled to the robot's mass, (110, 30) for the Jackal.
    assert (residuals.d_lat, residuals.d_long) == (sim.d_lat, sim.d_long) == (None, None)
    assert mass_scaled_damping(load_profile().mass) == (110.0, 30.0)


def test_compare_ranks_every_registered_family_by_default(simulated, capsys):
    # No --families: the registry at the call, whatever it holds (here two
    # families, to keep the test quick), not a list fixed at import; 20
    # steps (more than bridge sampling's 16) and in this process, as only the
    # order is checked.
    registry = dict(FAMILIES)  # restored in place and in order: seeds follow the order
    try:
        FAMILIES.clear()
        FAMILIES.update({name: registry[name] for name in ("white", "exponential")})
        quick = ["--channels", "yaw", "--max-steps", "20", "--seed", "2", "--no-progress"]
        quick += ["--processes", "1"]
        assert main(["compare", simulated[0], *quick, "--json"]) == 0
    finally:
        FAMILIES.clear()
        FAMILIES.update(registry)
    assert list(json.loads(capsys.readouterr().out)["families"]) == ["white", "exponential"]


def test_the_family_flags_take_the_registry_and_nothing_else(monkeypatch, capsys):
    # The registry kernels.FAMILIES is the one list of families (docs/families.md):
    # a family put into it is offered by every family flag, with no other change.
    parse = build_parser().parse_args
    assert parse(["compare", "e.nc"]).families is None  # cmd_compare: every one
    monkeypatch.setitem(FAMILIES, "boxcar", FAMILIES["moving-average"])
    assert parse(["sample", "e.nc", "--out", "p.nc", "--family", "boxcar"]).family == "boxcar"
    assert parse(["compare", "e.nc", "--families", "white,boxcar"]).families == ("white", "boxcar")
    assert parse(["simulate", "--out", "x", "--family", "boxcar"]).family == "boxcar"
    for flags in (
        ["sample", "e.nc", "--out", "p.nc", "--family"],
        ["compare", "e.nc", "--families"],
    ):
        with pytest.raises(SystemExit) as stopped:
            parse([*flags, "pink"])
        assert stopped.value.code == 2
        assert "'pink'" in capsys.readouterr().err
    monkeypatch.delitem(FAMILIES, "boxcar")
    with pytest.raises(SystemExit):
        parse(["sample", "e.nc", "--out", "p.nc", "--family", "boxcar"])
    assert "use one of white,gaussian,exponential,triangular,moving-average" in (
        capsys.readouterr().err
    )


def test_sample_with_a_speed_damping_prints_its_ratios(tmp_path, capsys):
    # A DRIVE-like table of the tests' independent simulator (command steps at
    # several speeds), its columns mapped as a user maps them: the speed
    # model's ratios are parameters of the posterior and its summary.
    import lab_simulator as lab

    run = lab.write_drive_run(tmp_path / "drive.csv", n_steps=6, speed_dependent=True, rng=5)
    roles = lab.DRIVE_ALL_ROLES.items()
    columns = [word for role, name in roles for word in ("--column", role, name)]
    with warnings.catch_warnings():
        warnings.simplefilter("default", UserWarning)  # what the command says of the table
        code = main(["sample", str(run.path), *columns, "--robot", "husky", "--damping", "speed",
                     "--family", "white", "--channels", "yaw", "--max-steps", "60",
                     "--seed", "1", "--no-progress", "--out", str(tmp_path / "p.nc"),
                     "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0 and "held" in captured.err, captured.err  # the held encoders, said
    summary = strict_json(captured.out)
    assert {"speed_ratio_lat", "speed_ratio_long"} <= set(summary)
    assert load_posterior(tmp_path / "p.nc").layout.damping == "speed"
