"""Poses and derived velocities in CSV and MATLAB tables, and the warning of derived ones."""

from __future__ import annotations

import numpy as np
import pytest

import bayes_jackal as bj
from bayes_jackal._runtime.errors import DataError
from bayes_jackal.io.bag_writer import SUBSTEPS, pose_path
from bayes_jackal.io.simulate import Series
from bayes_jackal.io.tables import read_csv, write_csv
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.posterior.criticism_inputs import derived_velocities

ROBOT = bj.load_profile()


@pytest.fixture(scope="module")
def run():
    return bj.simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, 0.39, 12.0), rng=4)


def _pose_csv(run, path, *, wrap: bool = False, drop: str | None = None):
    """The run's yaw rate, wheel speeds and true pose at its samples (+ 0.2 mm of noise)."""
    _, fine = pose_path(run, ROBOT)
    x, y, heading = fine[::SUBSTEPS].T
    x, y = (v + 2e-4 * np.random.default_rng(5).standard_normal(len(v)) for v in (x, y))
    if wrap:
        heading = np.angle(np.exp(1j * heading))  # as a driver gives it, in (-pi, pi]
    columns = {"t": run.t, "yaw_rate": run.yaw_rate, "omega_r": run.omega_r,
               "omega_l": run.omega_l, "x": x, "y": y, "heading": heading}  # fmt: skip
    columns.pop(drop, None)
    np.savetxt(path, np.column_stack(list(columns.values())), delimiter=",",
               header=",".join(columns), comments="")  # fmt: skip
    return path


def test_a_tables_pose_columns_are_its_pose_channels(run, tmp_path):
    experiment = read_csv(_pose_csv(run, tmp_path / "run.csv", wrap=True))
    assert (
        experiment.measurement("vx") == "pose" and experiment.provenance["velocities"] == "derived"
    )
    # The pose at each row, the heading unwrapped; the derived vx near the truth
    # (the Savitzky-Golay slope of 0.2 mm noise at 72 Hz: ~5 mm/s).
    assert np.all(np.abs(np.diff(experiment.pose.heading)) < 0.1)
    steady = slice(300, -300)
    error = experiment.vx[steady] - run.truth_arrays["vx_state"][steady]
    assert np.sqrt(np.mean(error**2)) < 0.01
    likelihood = ResidualLikelihood([experiment], ROBOT, family="white")
    assert likelihood.layout.pose_channels == ("vx", "vy")
    assert likelihood.pose_samples == {"run": 1}


def test_a_pose_needs_all_three_columns(run, tmp_path):
    with pytest.raises(DataError, match=r"a pose needs the columns \['x', 'y', 'heading'\]"):
        read_csv(_pose_csv(run, tmp_path / "run.csv", drop="heading"))


def test_velocities_declared_derived_are_warned_of(run, tmp_path):
    path = write_csv(run, tmp_path / "derived.csv")
    measured, derived = read_csv(path), read_csv(path, velocities="derived")
    assert measured.provenance["velocities"] == "measured"
    assert derived.measurement("vx") == "rate"
    with pytest.warns(UserWarning, match="NOT CONVERGED"):  # kept short on purpose
        posterior = bj.sample([derived], family="white", channels=["yaw", "vx"], max_steps=40)
    check = derived_velocities(posterior)
    [warning] = check.warnings
    assert warning["kind"] == "derived-velocity" and warning["channels"] == ["vx"]
    assert "derived from poses" in warning["message"]
    with pytest.raises(ValueError, match="unknown velocities 'guessed'"):
        read_csv(path, velocities="guessed")


def test_the_command_line_declares_velocities_for_every_reader():
    from bayes_jackal.cli.parser import build_parser
    from bayes_jackal.cli.reading import log_options

    for command in ("sample", "compare", "analyse", "grid", "residuals", "filter"):
        extra = ["--prior", "prior.json", "--out", "e.csv"] if command == "filter" else []
        out = ["--out", "out"] if command in ("sample", "analyse") else []
        args = build_parser().parse_args(
            [command, "run.csv", "--velocities", "derived", *out, *extra]
        )
        assert log_options(args)["velocities"] == "derived", command


def test_a_csv_of_an_experiment_with_poses_says_they_are_not_written(run, tmp_path):
    experiment = read_csv(_pose_csv(run, tmp_path / "run.csv"))
    with pytest.warns(UserWarning, match="the poses of run are not written"):
        back = read_csv(write_csv(experiment, tmp_path / "back.csv"), velocities="derived")
    assert back.pose is None and back.provenance["velocities"] == "derived"


def test_simulate_writes_bags_with_the_pose_noise_asked_for(tmp_path, capsys):
    import json

    from bayes_jackal.cli import main
    from bayes_jackal.io.bags import read_bag

    code = main(["simulate", "--out", str(tmp_path), "--v1", "1", "--v2", "0", "--seed", "2",
                 "--bag", "ros1", "--pose-noise", "2e-4", "0", "--json"])  # fmt: skip
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert result["bag_truth"]["sigma_p"] == {"vx": 2e-4, "vy": 2e-4}
    experiment = read_bag(tmp_path / "v1_01.bag", ROBOT)
    truth = bj.simulate_experiment(
        ROBOT, 110.0, 30.0, "v1", rng=np.random.default_rng(2).spawn(1)[0]
    )
    fine_t, path = pose_path(truth, ROBOT)
    error = experiment.pose.x - np.interp(experiment.pose.t, fine_t, path[:, 0])
    # ~13,700 poses: the sd's sampling error is 0.6 %; 3 % is 5 of them.
    assert error.std() == pytest.approx(2e-4, rel=0.03)
