"""``bayes-jackal filter``: estimates CSV, scores as JSON, bad priors and bad runs."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import strict_json
from synthetic_posteriors import posterior_at
from test_cli import assert_bad_input

import bayes_jackal as bj
from bayes_jackal.cli import main
from bayes_jackal.io.experiment import write_netcdf

ROBOT = bj.load_profile()
HEADER = (
    "t,kalman.yaw_rate,kalman-coloured.yaw_rate,generalised.yaw_rate,"
    "kalman-smoothed.yaw_rate,kalman-coloured-smoothed.yaw_rate"
)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Two runs the prior has not seen (.nc keeps the truth, .csv does not) and the prior."""
    folder = tmp_path_factory.mktemp("filter")
    seen = bj.simulate_experiment(ROBOT, 110.0, 30.0, "v1", rng=100)
    prior = bj.export_prior(posterior_at([seen], [110.0, 30.0, 0.047, 0.01, 0.005]), order=2)
    runs = [bj.simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=seed) for seed in (1, 2)]
    # yaw and vx: theta = (d_lat, d_long, then sigma_h, sigma_c, sigma_n per channel)
    two = posterior_at([seen], [110.0, 30.0, 0.047, 0.01, 0.005, 0.05, 0.005, 0.003],
                       channels=("yaw", "vx"))  # fmt: skip
    yaw_only = dataclasses.replace(runs[1], vx=None, vy=None)
    # White noise with the diagonal sensor term: one total sd, no sensor-noise sd.
    total = posterior_at([seen], [110.0, 30.0, 0.011], family="white", sensor="diagonal")
    return {
        "total_prior": str(bj.write_prior(bj.export_prior(total, order=0), folder / "total.json")),
        "yaw_vx_prior": str(bj.write_prior(bj.export_prior(two, order=2), folder / "yaw_vx.json")),
        "yaw_only": str(bj.write_csv(yaw_only, folder / "yaw_only.csv")),
        "nc": str(write_netcdf(runs[0], folder / "left.nc")),
        "csv": str(bj.write_csv(runs[1], folder / "right.csv")),
        "prior": str(bj.write_prior(prior, folder / "prior.json")),
        "runs": runs,
        "seen": str(write_netcdf(seen, folder / "seen.nc")),
    }


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_filter_writes_estimates_and_scores(tmp_path, capsys, files):
    out = tmp_path / "estimates.csv"
    before = {key: digest(files[key]) for key in ("nc", "prior")}
    code = main(["filter", files["nc"], "--prior", files["prior"], "--out", str(out), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert out.read_text().splitlines()[0] == HEADER
    result = strict_json(captured.out)
    scores = result["experiments"][bj.load_experiments([files["nc"]])[0].name]
    assert list(scores) == ["kalman", "kalman-coloured", "generalised"]
    # The library's scores, to the JSON's digits.
    run = files["runs"][0]
    prior = bj.read_prior(files["prior"])
    expected = bj.score_estimates(run, bj.estimate_states(run, prior))
    for name, score in expected.items():
        got = scores[name]
        assert got["state_rmse"]["yaw"] == pytest.approx(score["state_rmse"]["yaw"], rel=1e-12)
        assert got["nis"]["yaw"]["mean"] == pytest.approx(score["nis"]["yaw"]["mean"], rel=1e-12)
        assert got["nis"]["yaw"]["band"] == pytest.approx(score["nis"]["yaw"]["band"], rel=1e-12)
        assert got["nis"]["yaw"]["consistent"] == score["nis"]["yaw"]["consistent"]
    back = np.loadtxt(out, delimiter=",", skiprows=1)
    estimates = bj.estimate_states(run, prior)
    np.testing.assert_allclose(back[:, 3], estimates["generalised"]["yaw"].mean, rtol=1e-9)
    assert before == {key: digest(files[key]) for key in ("nc", "prior")}  # inputs unchanged


def test_a_run_the_prior_was_sampled_on_is_said_to_be_in_sample(tmp_path, capsys, files):
    """Issue 37 item 17: the prior's own training run is scored, and said to be in-sample."""
    out = str(tmp_path / "estimates.csv")
    code = main(["filter", files["seen"], files["nc"], "--prior", files["prior"], "--out", out,
                 "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert strict_json(captured.out)["in_sample"] == ["v1"]
    assert "note: v1 is a run the prior was sampled on" in captured.err
    assert "in-sample" in captured.err and "note: v2" not in captured.err


def test_filter_options_reach_the_filters(tmp_path, capsys, files):
    out = tmp_path / "estimates.csv"
    code = main(
        ["filter", files["csv"], "--prior", files["prior"], "--out", str(out),
         "--filters", "generalised", "--order", "1", "--parameters", "averaged",
         "--sensor-precision", "exported", "--lookahead", "1"]
    )  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "generalised" in captured.out and "state RMSE" in captured.out
    run = bj.load_experiments([files["csv"]])[0]
    expected = bj.filters.generalised_filter(
        run, bj.read_prior(files["prior"]), order=1, parameters="averaged",
        sensor_precision="exported", lookahead=1,
    )["yaw"].mean  # fmt: skip
    back = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0] == "t,generalised.yaw_rate"
    np.testing.assert_allclose(back[:, 1], expected, rtol=1e-9, atol=1e-12)


def test_a_prior_that_does_not_fit_is_named(tmp_path, capsys, files):
    prior = json.loads(Path(files["prior"]).read_text())
    fast = tmp_path / "fast.json"
    fast.write_text(json.dumps(prior | {"dt": 0.01}))
    out = tmp_path / "estimates.csv"
    code = main(["filter", files["nc"], "--prior", str(fast), "--out", str(out)])
    assert_bad_input(code, capsys.readouterr(), "fast.json", "left.nc", "dt", "100 Hz")
    assert not out.exists()
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    code = main(["filter", files["nc"], "--prior", str(broken), "--out", str(out)])
    assert_bad_input(code, capsys.readouterr(), "broken.json", "not JSON")
    code = main(["filter", files["nc"], "--prior", files["nc"], "--out", str(out)])
    assert_bad_input(code, capsys.readouterr(), "left.nc", "not JSON")
    code = main(["filter", files["yaw_only"], "--prior", files["yaw_vx_prior"], "--out", str(out)])
    assert_bad_input(code, capsys.readouterr(), "yaw_only.csv", "channel 'vx' is not in")


def _set(path: str, value):
    """An edit of a prior: the field at ``path`` (keys joined by dots; a list index) set."""

    def edit(prior: dict) -> None:
        *parents, last = path.split(".")
        node = prior
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value

    return edit


#: Issue 24, item 3: priors the filters accepted (exit 0, or a bare LinAlgError).
UNTRUSTED = {
    "negative-sensor-sd": (_set("noise.parameters.sigma_n.mean", -1), [],
                           (r"noise\.parameters\.sigma_n\.mean", "-1")),
    "nan-in-draws": (_set("draws.sigma_c.3", float("nan")), ["--parameters", "averaged"],
                     (r"draws\.sigma_c", "nan")),
    "newer-format": (_set("format", "bayes_jackal.prior/99"), [], ("format", "prior/99")),
    "nan-in-A": (_set("model.A.0.0", float("nan")), [], (r"model\.A", "non-finite")),
    "infinite-in-Ad": (_set("model.Ad.1.1", float("inf")), [], (r"model\.Ad", "non-finite")),
    "text-in-A": (_set("model.A.2", "x"), [], (r"model\.A", "expected numbers")),
    "huge-pole": (_set("model.A.0.0", 1e308), [], (r"model\.A", "poles")),
    "coupled-A": (_set("model.A.0.1", 1e308), [], (r"model\.A", "diagonal")),
    "wrong-shape-Bd": (_set("model.Bd", [[0.0, 0.0]]), [], (r"model\.Bd", r"3 x 2")),
}  # fmt: skip


@pytest.mark.parametrize(("edit", "flags", "words"), UNTRUSTED.values(), ids=list(UNTRUSTED))
def test_a_prior_the_filters_cannot_trust_is_refused_by_field(
    tmp_path, capsys, files, edit, flags, words
):
    prior = json.loads(Path(files["prior"]).read_text())
    edit(prior)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(prior))
    out = tmp_path / "estimates.csv"
    code = main(["filter", files["nc"], "--prior", str(path), "--out", str(out), *flags])
    assert_bad_input(code, capsys.readouterr(), "edited.json", *words)
    assert not out.exists()


@pytest.mark.parametrize(
    ("flags", "words"),
    [
        (["--order", "99"], (r"order 99 gives a precision", "allowed here are 0, 1, 2, 3, 4")),
        (["--lookahead", "100000"], ("lookahead must lie in 0 .. 2", "100000")),
    ],
    ids=["order-99", "lookahead-100000"],
)
def test_generalised_options_it_cannot_honour_are_refused(tmp_path, capsys, files, flags, words):
    """Issue 24, item 3: the generalised filter was dropped, the run exited 0."""
    out = tmp_path / "estimates.csv"
    code = main(["filter", files["nc"], "--prior", files["prior"], "--out", str(out), *flags])
    assert_bad_input(code, capsys.readouterr(), "left.nc", *words)
    assert not out.exists()


def test_one_bad_run_does_not_stop_the_others(tmp_path, capsys, files):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,yaw_rate,omega_r,omega_l\n0,1,2\n")
    out = tmp_path / "estimates.csv"
    code = main(
        ["filter", str(bad), files["csv"], "--prior", files["prior"], "--out", str(out), "--json"]
    )
    captured = capsys.readouterr()
    assert code == 2
    assert "bad.csv" in captured.err and "Traceback" not in captured.err
    result = strict_json(captured.out)
    assert list(result["experiments"]) == ["right"] and list(result["failed"]) == [str(bad)]
    assert result["experiments"]["right"]["kalman"]["state_rmse"] == {"yaw": None}  # no truth
    assert out.read_text().splitlines()[0] == HEADER


def test_a_prior_from_another_install_fits_and_other_constants_do_not(tmp_path, capsys, files):
    # The profile's path is where it was read, not a constant of the robot.
    prior = json.loads(Path(files["prior"]).read_text())
    moved = tmp_path / "moved.json"
    moved.write_text(json.dumps(prior | {"robot": prior["robot"] | {"source": "/elsewhere.toml"}}))
    out = tmp_path / "estimates.csv"
    code = main(["filter", files["nc"], "--prior", str(moved), "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    other = tmp_path / "other.json"
    other.write_text(json.dumps(prior | {"robot": prior["robot"] | {"wheel_radius": 0.2}}))
    code = main(["filter", files["nc"], "--prior", str(other), "--out", str(tmp_path / "o.csv")])
    assert_bad_input(code, capsys.readouterr(), "other.json", r"robot\.wheel_radius", "0.2")


def test_a_filter_the_prior_cannot_drive_is_skipped_and_named(tmp_path, capsys, files):
    # White noise fitted with the diagonal sensor term has no sensor-noise sd,
    # which the generalised filter needs; the Kalman filters run.
    out = tmp_path / "estimates.csv"
    code = main(["filter", files["nc"], "--prior", files["total_prior"], "--out", str(out),
                 "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    result = strict_json(captured.out)
    name = bj.load_experiments([files["nc"]])[0].name
    assert list(result["experiments"][name]) == ["kalman", "kalman-coloured"]
    assert list(result["filters_failed"][name]) == ["generalised"]
    assert "generalised cannot run with this prior" in captured.err
    assert out.read_text().splitlines()[0] == (
        "t,kalman.yaw_rate,kalman-coloured.yaw_rate,"
        "kalman-smoothed.yaw_rate,kalman-coloured-smoothed.yaw_rate"
    )
    code = main(["filter", files["nc"], "--prior", files["total_prior"], "--out",
                 str(tmp_path / "g.csv"), "--filters", "generalised"])  # fmt: skip
    assert_bad_input(code, capsys.readouterr(), "no filter can run", "sensor-noise sd")
