"""``analyse``'s state estimation on runs left out of the prior (issue 14).

One analysis of two short simulated runs (8 s, white noise on the yaw
channel, chains capped at 100 steps: the files and their links are checked
here, not the statistics) serves every test; the reruns reuse its saved
posteriors, so they sample nothing.
"""

from __future__ import annotations

import inspect
import json
import shutil

import numpy as np
import pytest

from bayes_jackal.cli import main
from bayes_jackal.cli.parser import build_parser
from bayes_jackal.defaults import STATE_ESTIMATION
from bayes_jackal.demo import run_demo
from bayes_jackal.errors import InputError
from bayes_jackal.estimate_plots import SHOWN_SECONDS, plot_state_estimates, shown_window
from bayes_jackal.executors import SerialExecutor
from bayes_jackal.experiment import read_netcdf, write_netcdf
from bayes_jackal.inference import SamplerSettings
from bayes_jackal.kalman import KALMAN_FILTERS, StateEstimate
from bayes_jackal.leave_one_out import FOLDER, SUMMARY, leave_one_out
from bayes_jackal.robot import load_profile
from bayes_jackal.simulate import Series, simulate_experiment
from bayes_jackal.state_estimation import FILTERS
from bayes_jackal.workflow import analyse_logs

ROBOT = load_profile()
RUNS = ("a", "b")
#: As the CLI's ``--max-steps 100 --no-progress`` (so that analyse reuses these chains).
SETTINGS = SamplerSettings(max_steps=100, progress=False)
OPTIONS = {"channels": ["yaw"]}


@pytest.fixture(scope="module")
def analysis(tmp_path_factory) -> tuple:
    """(inputs, output folder, result) of analyse_logs on two 8 s runs, one family."""
    folder = tmp_path_factory.mktemp("loo")
    children = np.random.default_rng(14).spawn(len(RUNS))
    inputs = [
        write_netcdf(
            simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=rng, name=name),
            folder / f"{name}.nc",
        )
        for name, rng in zip(RUNS, children, strict=True)
    ]
    # 100 steps, on purpose: the convergence warnings go into the result.
    result = analyse_logs(
        inputs,
        folder / "out",
        robot=ROBOT,
        families=("white",),
        channels=("yaw",),
        settings=SETTINGS,
        seed=1,
        executor=SerialExecutor(),
    )
    return inputs, folder / "out", result


def test_each_run_is_filtered_with_the_prior_of_exactly_the_others(analysis):
    _, out, result = analysis
    state = result["state_estimation"]
    assert state["skipped"] is None and state["failed"] == {} and state["family"] == "white"
    assert list(state["runs"]) == list(RUNS)
    for run, record in state["runs"].items():
        others = [name for name in RUNS if name != run]
        prior = json.loads((out / FOLDER / f"{run}.prior.json").read_text())
        assert prior["experiments"] == record["trained_on"] == others
        assert prior["noise"]["family"] == "white"
        # Every filter scored, the simulated truth gives the state RMSE.
        assert list(record["scores"]) == list(FILTERS) and record["filters_failed"] == {}
        for score in record["scores"].values():
            assert set(score["state_rmse"]) == {"yaw"}
        header = (out / FOLDER / f"{run}.csv").read_text().splitlines()[0]
        smoothers = [f"{name}-smoothed" for name in KALMAN_FILTERS]
        assert header == "t," + ",".join(f"{name}.yaw_rate" for name in (*FILTERS, *smoothers))
        assert (out / FOLDER / "posteriors" / f"{run}.nc").exists()
    assert json.loads((out / SUMMARY).read_text()) == state
    assert result["files"]["state_estimation"] == str(out / SUMMARY)
    # The left-out chains' convergence is reported with the run left out.
    left_out = [w["left_out"] for w in result["warnings"] if "left_out" in w]
    assert left_out == list(RUNS)


def test_the_report_has_the_section_its_table_and_figure(analysis):
    _, out, result = analysis
    report = (out / "report.html").read_text()
    # The summary at the top says how each filter did (issue 24, item 11), counted here
    # independently from the scores: a consistent NIS per run and channel.
    summary = report[report.index('<section class="summary">') :]
    summary = summary[: summary.index("</section>")]
    runs = result["state_estimation"]["runs"].values()
    for name in FILTERS:
        nis = [record["scores"][name]["nis"]["yaw"] for record in runs]
        consistent = sum(value["consistent"] for value in nis)
        assert f"<b>{name}</b> consistent on {consistent} of {len(RUNS)}, lowest" in summary
    section = report[report.index("<h2>State estimation with this prior</h2>") :]
    section = section[: section.index("</section>")]
    assert "normalised innovation squared" in section
    assert section.count("<tr><td>") == len(RUNS) * len(FILTERS)  # one row per run, filter
    assert "<tr><td>b</td><td>a</td><td>kalman-coloured</td><td>yaw</td>" in section
    # One figure per run left out (issue 24, item 12: only the first had one).
    assert section.count("data:image/png;base64,") == len(RUNS)
    for run in RUNS:
        assert (out / "report_figures" / f"state-estimation-{run}.png").exists()


def test_a_failing_run_does_not_stop_the_others(analysis, tmp_path):
    # A folder where a's estimates go makes its write fail (a real OSError);
    # the chains are the analysis' own, reused: nothing is sampled again.
    _, out, result = analysis
    shutil.copytree(out / FOLDER / "posteriors", tmp_path / FOLDER / "posteriors")
    (tmp_path / FOLDER / "a.csv").mkdir()
    lines = []
    experiments = [read_netcdf(path) for path in analysis[0]]
    again = leave_one_out(
        experiments,
        ROBOT,
        "white",
        tmp_path,
        settings=SETTINGS,
        seed=1,
        likelihood_options=OPTIONS,
        say=lines.append,
    )
    assert list(again.failed) == ["a"] and "a.csv: cannot write" in again.failed["a"]
    assert list(again.runs) == ["b"]
    assert again.runs["b"]["scores"] == result["state_estimation"]["runs"]["b"]["scores"]
    assert sum(line.startswith("  reusing white") for line in lines) == len(RUNS)
    assert json.loads((tmp_path / SUMMARY).read_text())["failed"] == again.failed
    assert list(again.estimates) == ["b"]  # the runs done


def test_no_state_estimation_skips_it(analysis, tmp_path, capsys):
    # analyse again on the same inputs: the family's posterior is reused.
    inputs, out, _ = analysis
    shutil.copytree(out / "posteriors", tmp_path / "out" / "posteriors")
    quick = ["--families", "white", "--channels", "yaw", "--max-steps", "100", "--seed", "1"]
    flags = ["--no-progress", "--processes", "1", "--no-state-estimation", "--json"]
    code = main(["analyse", *map(str, inputs), "--out", str(tmp_path / "out"), *quick, *flags])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "reusing white" in captured.err
    state = json.loads(captured.out)["state_estimation"]
    assert state["skipped"] == "turned off (--no-state-estimation)" and state["runs"] == {}
    assert not (tmp_path / "out" / FOLDER).exists() and not (tmp_path / "out" / SUMMARY).exists()
    report = (tmp_path / "out" / "report.html").read_text()
    assert "State estimation with this prior</h2>" in report
    assert "Not run: turned off (--no-state-estimation)." in report


def test_one_run_has_nothing_to_leave_out(analysis, tmp_path):
    experiments = [read_netcdf(analysis[0][0])]
    result = leave_one_out(experiments, ROBOT, "white", tmp_path)
    assert result.skipped == "needs two or more runs; 1 analysed" and not any(tmp_path.iterdir())


def test_the_figure_draws_each_filters_two_sd_band_over_a_short_window():
    run = simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=1)
    n, sd = len(run.t), 0.01
    estimate = StateEstimate(run.yaw_rate, np.full(n, sd**2), np.zeros(n), np.ones(n), 0)
    estimates = {name: {"yaw": estimate} for name in ("kalman", "generalised")}
    _, axes = plot_state_estimates(run, estimates)
    start, stop = shown_window(run)
    assert stop - start == pytest.approx(SHOWN_SECONDS)  # the run (8 s) is longer
    for ax in axes:
        t, y = ax.collections[0].get_paths()[0].vertices.T
        index = np.searchsorted(run.t, t - 1e-9)
        assert np.allclose(np.abs(y - run.yaw_rate[index]), 2 * sd)
        measured = ax.lines[0].get_xdata()
        assert measured.min() >= start and measured.max() <= stop
    with pytest.raises(InputError, match="no estimates of channel 'vx'"):
        plot_state_estimates(run, estimates, channel="vx")


def test_analyse_and_demo_read_the_flags_default_from_the_library():
    default = inspect.signature(analyse_logs).parameters["state_estimation"].default
    demo = inspect.signature(run_demo).parameters["state_estimation"].default
    analyse = build_parser().parse_args(["analyse", "x.bag", "--out", "o"])
    assert analyse.state_estimation is default is demo is STATE_ESTIMATION
    assert build_parser().parse_args(["demo", "--no-state-estimation"]).state_estimation is False
