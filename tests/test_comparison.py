"""Families compared on several groups at once: the same numbers as one group at a time.

The runs are tiny (simulated runs of 8 s at the v2 command, yaw channel, 60
steps: more than the 16 that bridge sampling needs, MIN_EVIDENCE_STEPS): the
point is the bookkeeping of many (group, family) jobs, not the posterior, and
every check is an exact equality or a file's presence, which no run length
changes (with 26 s runs the module took 13 s, with these 10 s).
"""

from __future__ import annotations

import json
import pickle
import warnings

import numpy as np
import pytest

from bayes_jackal import InputError, ProfileError, load_profile
from bayes_jackal.cli import main
from bayes_jackal.inference import FitOptions
from bayes_jackal.inference.chains import SamplerSettings
from bayes_jackal.inference.comparison import _FamilyRun, compare_families, compare_groups
from bayes_jackal.inference.executors import ProcessExecutor, SerialExecutor
from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
from bayes_jackal.inference.sampling import sample_posterior
from bayes_jackal.io.experiment import write_netcdf
from bayes_jackal.io.simulate import Series, simulate_experiment
from bayes_jackal.likelihood import LikelihoodOptions
from bayes_jackal.workflow import RunContext

ROBOT = load_profile()
#: The v2 command (0.4 m/s, 30 deg/s) for 8 s instead of its 26 s.
SHORT_V2 = Series(0.4, float(np.deg2rad(30.0)), 8.0)
FAMILIES = ("white", "exponential")
SETTINGS = SamplerSettings(max_steps=60, progress=False)
OPTIONS = LikelihoodOptions(channels=("yaw",))
#: Every chain of these tests: the yaw channel, 60 steps, seed 3.
FIT = FitOptions(robot=ROBOT, likelihood_options=OPTIONS, settings=SETTINGS, seed=3)
#: Flags of a quick comparison, the families in this process one after the other.
QUICK = ["--families", ",".join(FAMILIES), "--seed", "3", "--max-steps", "60"]
QUICK += ["--channels", "yaw", "--no-progress", "--json", "--processes", "1"]


@pytest.fixture(scope="module")
def runs():
    """Two groups of one short simulated v2 run each, their noise drawn from seeds 1 and 2."""
    return {
        f"run{seed}": [
            simulate_experiment(ROBOT, 110.0, 30.0, SHORT_V2, rng=seed, name=f"v2_{seed}")
        ]
        for seed in (1, 2)
    }


def test_every_group_equals_its_comparison_alone(runs):
    """All jobs at once in two processes, against each group alone in this process."""
    finished = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # 60 steps do not converge
        together = dict(
            compare_groups(
                runs,
                FIT,
                families=FAMILIES,
                executor=ProcessExecutor(2),  # four jobs, two at a time
                on_family=lambda key, family, *_: finished.append((key, family)),
            )
        )
        alone = {
            key: compare_families(group, FIT, families=FAMILIES, executor=SerialExecutor())
            for key, group in runs.items()
        }
    assert sorted(finished) == sorted((key, family) for key in runs for family in FAMILIES)
    assert together.keys() == alone.keys()
    for key, comparison in together.items():
        assert comparison.experiments == alone[key].experiments == [runs[key][0].name]
        for family, evidence in alone[key].evidence.items():
            # The same chain (below, exactly); the workers run one BLAS thread
            # (executors.in_processes), this process the machine's, and
            # BLAS rounds differently with the thread count: the error
            # differed by 2e-17 (equal with OMP/OPENBLAS_NUM_THREADS=1 here).
            assert comparison.evidence[family].log_evidence == evidence.log_evidence
            assert comparison.evidence[family].error == pytest.approx(evidence.error, rel=1e-12)
        assert list(comparison.evidence) == list(FAMILIES)
        assert comparison.convergence_messages() == alone[key].convergence_messages()
        for family in FAMILIES:
            mine, theirs = comparison.posteriors[family], alone[key].posteriors[family]
            for name, values in theirs.posterior.data_vars.items():
                np.testing.assert_array_equal(mine.posterior[name].values, values.values)
    # Different data, different numbers: the groups did not share a job.
    assert together["run1"].evidence["white"] != together["run2"].evidence["white"]


def test_a_group_that_fails_is_reported_and_the_others_go_on(runs):
    def save(key, family, evidence, idata):
        if key == "run1":
            raise OSError("disk full")  # a write error while saving run1's family

    failed = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        done = list(
            compare_groups(
                runs,
                FIT.with_settings(max_steps=80),
                families=("white",),
                on_family=save,
                on_failure=lambda key, exc: failed.append((key, str(exc))),
            )
        )
    assert failed == [("run1", "disk full")]
    assert [key for key, _ in done] == ["run2"]
    with pytest.raises(OSError, match="disk full"):  # without on_failure it propagates
        list(compare_groups(runs, FIT, families=("white",), on_family=save))


def test_compare_of_two_runs_saves_both_and_a_rerun_reuses_every_family(runs, tmp_path, capsys):
    names = [group[0].name for group in runs.values()]
    paths = [
        str(write_netcdf(group[0], tmp_path / f"{group[0].name}.nc")) for group in runs.values()
    ]
    command = ["compare", *paths, *QUICK, "--out", str(tmp_path / "out")]
    assert main(command) == 0
    done = capsys.readouterr()
    result = json.loads(done.out)
    assert list(result["experiments"]) == names and result["failed"] == {}
    for name in names:
        summary = json.loads((tmp_path / "out" / f"{name}.compare.json").read_text())
        assert summary == result["experiments"][name]
        assert set(summary["families"]) == set(FAMILIES)
        for family in FAMILIES:
            assert (tmp_path / "out" / f"{name}.{family}.nc").is_file()
            assert f"  {name} {family}: log Z =" in done.err
    assert main(command) == 0
    rerun = capsys.readouterr()
    for name in names:
        for family in FAMILIES:
            assert f"reusing {family} from {tmp_path / 'out' / f'{name}.{family}.nc'}" in rerun.err
    assert "log Z =" not in rerun.err  # no family ran again
    assert json.loads(rerun.out) == result


@pytest.fixture()
def overflowing_sampler(monkeypatch):
    """The sampler of the compare and sample commands, run after numpy's overflow warning.

    No code of ours warns on valid data (numpy's warnings are silenced where
    they are expected), so a real numpy warning, raised twice, is put in
    front of the real sampler: the one monkeypatch, of our own function.
    """

    def overflowing(*args, **kwargs):
        for _ in range(2):
            np.exp(np.array([1000.0]))  # numpy: "overflow encountered in exp"
        return sample_posterior(*args, **kwargs)

    monkeypatch.setattr("bayes_jackal.inference.comparison.sample_posterior", overflowing)
    monkeypatch.setattr("bayes_jackal.cli.commands.sample_posterior", overflowing)


def test_a_warning_raised_while_sampling_is_kept_once_and_carried_back(runs, overflowing_sampler):
    run = _FamilyRun(runs["run1"], FIT, cross_check=False)
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # each raised warning recorded, not pytest's "error"
        kept = run((0, "white")).kept
    kept = pickle.loads(pickle.dumps(kept))  # as it comes back from a worker process
    assert kept.other == [(RuntimeWarning, "overflow encountered in exp")]
    [message] = kept.convergence  # 60 steps do not converge; kept apart, as before
    assert message.startswith("NOT CONVERGED")


@pytest.mark.parametrize("command", ["compare", "sample"])
def test_a_warning_raised_while_sampling_reaches_the_user_once(
    runs, tmp_path, capsys, overflowing_sampler, command
):
    path = str(write_netcdf(runs["run1"][0], tmp_path / "run1.nc"))
    argv = [command, path, "--seed", "3", "--max-steps", "60", "--channels", "yaw"]
    out = tmp_path / ("out" if command == "compare" else "out.nc")  # a folder, a posterior
    argv += ["--no-progress", "--out", str(out)]
    argv += ["--families", "white", "--processes", "1"] if command == "compare" else []
    with warnings.catch_warnings():
        warnings.simplefilter("default")  # Python's default action, not pytest's "error"
        assert main(argv) == 0
    err = capsys.readouterr().err.splitlines()
    named = "white: " if command == "compare" else ""  # compare names the family
    shown = [line for line in err if "overflow" in line]
    assert shown == [f"bayes-jackal: WARNING: {named}overflow encountered in exp"]
    assert any("WARNING: " in line and "NOT CONVERGED" in line for line in err)


def test_fit_options_refuse_a_bad_prior_or_robot_on_construction(tmp_path):
    # Before any chain: a misspelt name, an empty range, a profile that is not there.
    with pytest.raises(InputError, match="unknown prior 'd_latt'") as misspelt:
        FitOptions(prior_overrides={"d_latt": (50.0, 500.0)})
    assert misspelt.value.field == "prior_overrides"
    with pytest.raises(InputError, match=r"0 < low < high, got \[500\.0, 50\.0\]") as empty:
        FitOptions(prior_overrides={"d_lat": (500.0, 50.0)})
    assert empty.value.field == "priors.d_lat"
    with pytest.raises(ProfileError, match=r"nowhere\.toml"):
        FitOptions(robot=tmp_path / "nowhere.toml")
    with pytest.raises(InputError, match="unknown prior 'd_latt'"):  # the analysis' context too
        RunContext(inputs=["a.csv"], out=tmp_path, executor=SerialExecutor(),
                   prior_overrides={"d_latt": (50.0, 500.0)})  # fmt: skip
    # A robot where the options go (the old signature) is named, not an AttributeError.
    with pytest.raises(InputError, match=r"must be a FitOptions .* got a RobotProfile"):
        list(compare_groups({"run1": []}, ROBOT))
    # Keys normalised once: a width's range under either name is sigma_h's.
    assert FitOptions(prior_overrides={"width": (0.01, 0.5)}).prior_overrides == {
        "sigma_h": (0.01, 0.5)
    }
    assert FitOptions(prior_overrides={}).prior_overrides is None
