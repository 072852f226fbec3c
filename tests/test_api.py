"""The top-level API (``import bayes_jackal as bj``): the modules' numbers, the CLI's defaults."""

from __future__ import annotations

import doctest
import inspect
import logging
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest
import scipy.io

import bayes_jackal as bj
from bayes_jackal.cli import main
from bayes_jackal.cli.parser import build_parser
from bayes_jackal.inference import sampling
from bayes_jackal.inference.sampling import sample_posterior
from bayes_jackal.io import ingest_logs
from bayes_jackal.io.bags import read_bag
from bayes_jackal.io.experiment import read_netcdf, write_netcdf
from bayes_jackal.io.tables import read_csv, read_mat
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.report.page import _labelled
from bayes_jackal.workflow.demo import demo_folder

#: A quick white-noise chain on the yaw channel (far from converged: 80 steps).
QUICK = {"family": "white", "channels": ["yaw"], "max_steps": 80, "seed": 3}
#: The same, as flags of ``bayes-jackal sample``.
QUICK_FLAGS = ["--family", "white", "--channels", "yaw", "--max-steps", "80", "--seed", "3"]
#: The public functions, with the count of their leading positional parameters.
FUNCTIONS = {
    "load_experiments": 1,
    "sample": 1,
    "compare": 1,
    "export_prior": 1,
    "write_report": 2,
}


def quiet(function, *args, **kwargs):
    """``function(*args, **kwargs)`` with the expected ConvergenceWarning of a short chain."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", bj.ConvergenceWarning)
        return function(*args, **kwargs)


@pytest.fixture(scope="module")
def run():
    """One simulated run (series v1, truth d_lat = 110, d_long = 30 N s/m)."""
    return bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1, name="v1_01")


@pytest.fixture(scope="module")
def posterior(run):
    return quiet(bj.sample, [run], **QUICK)


def test_import_stays_lazy():
    code = "import sys, bayes_jackal as bj; bj.__all__; print('numpy' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.stdout.strip() == "False", result.stderr


def test_every_public_name_resolves():
    for name in bj.__all__:
        assert getattr(bj, name) is not None, name
    assert bj.sample is sampling.sample and bj.export_prior.__module__ == "bayes_jackal.dem.export"


@pytest.mark.parametrize("name", FUNCTIONS)
def test_options_are_keyword_only(name):
    parameters = list(inspect.signature(getattr(bj, name)).parameters.values())
    positional = FUNCTIONS[name]
    assert all(p.kind is p.POSITIONAL_OR_KEYWORD for p in parameters[:positional])
    assert all(p.kind is p.KEYWORD_ONLY for p in parameters[positional:]), parameters


def test_a_positional_option_is_refused(run, posterior, tmp_path):
    with pytest.raises(TypeError):
        bj.sample([run], "white")
    with pytest.raises(TypeError):
        bj.export_prior(posterior, 0)
    with pytest.raises(TypeError):
        bj.write_report(posterior, tmp_path / "r.html", ("png",))


def test_sample_is_sample_posterior_on_the_same_likelihood(run, posterior):
    likelihood = ResidualLikelihood([run], bj.load_profile(), family="white", channels=("yaw",))
    expected = quiet(sample_posterior, likelihood, bj.SamplerSettings(max_steps=80), seed=3)
    for name in ("d_lat", "d_long", "sigma_c", "sigma_n"):
        np.testing.assert_array_equal(posterior.posterior[name], expected.posterior[name])


def test_sample_defaults_are_the_cli_defaults(tmp_path):
    args = build_parser().parse_args(["sample", "e.nc", "--out", str(tmp_path / "p.nc")])
    defaults = {
        name: parameter.default
        for name, parameter in inspect.signature(bj.sample).parameters.items()
    }
    assert defaults["family"] == args.family == "gaussian"
    assert defaults["sensor"] == args.sensor_noise == "ma1"
    assert defaults["noise"] == args.noise == "shared"
    assert defaults["engine"] == args.engine == "fast"
    assert defaults["max_steps"] == args.max_steps == 20_000
    assert defaults["walkers"] == args.walkers == 0
    assert defaults["seed"] is args.seed is None and defaults["channels"] is args.channels is None
    compared = build_parser().parse_args(["compare", "e.nc"]).families
    assert inspect.signature(bj.compare).parameters["families"].default == compared
    assert compared is None  # every registered family (bj.FAMILIES), read at the call:
    # tests/test_cli.py::test_compare_ranks_every_registered_family_by_default
    order = build_parser().parse_args(["export-prior", "p.nc", "--out", "prior.json"]).order
    assert inspect.signature(bj.export_prior).parameters["order"].default == order == 2


def test_sample_and_compare_show_their_progress_by_default(run, capsys):
    """Issue 24, item 12: ``bj.sample`` was silent for minutes; the CLI shows its chains."""
    for function in (bj.sample, bj.compare):
        assert inspect.signature(function).parameters["progress"].default is True
    quiet(bj.sample, [run], **QUICK)
    # Not a terminal here: the closing plain line (lines every 10 s before it).
    assert re.search(r"emcee: 80/80 steps, \d+ s, done", capsys.readouterr().err)
    quiet(bj.sample, [run], **QUICK, progress=False)
    assert capsys.readouterr().err == ""


def test_a_library_user_captures_every_message_with_logging(run, tmp_path, capsys):
    """Issue 38: the package's messages go through ``logging``, and nothing else prints them.

    Captured by a handler the user adds to the ``bayes_jackal`` logger; each
    record comes from its stage's logger. Unconfigured, nothing is printed.
    """
    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    csv = bj.write_csv(run, tmp_path / "v1_01.csv")
    logger, handler = logging.getLogger("bayes_jackal"), Keep()
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        experiments, _ = ingest_logs([csv, tmp_path / "lost.bag"], bj.load_profile(), tmp_path)
        quiet(bj.sample, experiments, **QUICK, progress=False)
    finally:
        logger.removeHandler(handler)
        logger.setLevel(logging.NOTSET)
    lines = [record.getMessage() for record in records]
    assert lines[0].startswith(f"  ingested {csv}: ") and lines[1].startswith("  skipped ")
    assert lines[2].startswith("MAP search: ") and lines[3].startswith("MAP found in ")
    assert [r.name for r in records] == ["bayes_jackal.io"] * 2 + ["bayes_jackal.inference"] * 2
    assert {r.levelno for r in records} == {logging.INFO}
    assert capsys.readouterr() == ("", "")  # the messages went to the handler only
    quiet(bj.sample, experiments, **QUICK, progress=False)  # unconfigured: silent
    assert capsys.readouterr() == ("", "")


def test_sample_gives_the_chain_of_the_cli(run, posterior, tmp_path):
    # Flags left out take their defaults on both sides (engine, sensor, noise, walkers).
    source = write_netcdf(run, tmp_path / "v1_01.nc")
    out = tmp_path / "posterior.nc"
    assert main(["sample", str(source), "--out", str(out), *QUICK_FLAGS, "--no-progress"]) == 0
    cli = bj.load_posterior(out)
    for name in ("d_lat", "d_long", "sigma_c", "sigma_n"):
        np.testing.assert_array_equal(posterior.posterior[name], cli.posterior[name])


def test_compare_gives_the_posteriors_of_sample(run, posterior):
    options = {key: value for key, value in QUICK.items() if key != "family"}
    comparison = quiet(bj.compare, [run], families=("white", "exponential"), **options)
    assert set(comparison.posteriors) == {"white", "exponential"}
    assert comparison.best in comparison.posteriors
    assert comparison.to_dict()["best"] == comparison.best
    for name in ("d_lat", "d_long", "sigma_c"):
        np.testing.assert_array_equal(
            comparison.posteriors["white"].posterior[name], posterior.posterior[name]
        )


def test_load_experiments_reads_each_format_as_its_module(run, tmp_path):
    robot = bj.load_profile()
    mat = tmp_path / "v1_01.mat"
    scipy.io.savemat(
        mat, {key: getattr(run, key) for key in ("t", "yaw_rate", "omega_r", "omega_l")}
    )
    csv = bj.write_csv(run, tmp_path / "v1_01.csv")
    netcdf = write_netcdf(run, tmp_path / "v1_01.nc")
    bag = demo_folder() / "v1_01.bag"
    for path, expected in (
        (csv, read_csv(csv)),
        (mat, read_mat(mat)),
        (netcdf, read_netcdf(netcdf)),
        (bag, read_bag(bag, robot)),
    ):
        [loaded] = bj.load_experiments(path)
        assert loaded.name == expected.name and loaded.steady_window == expected.steady_window
        for key in ("t", "yaw_rate", "omega_r", "omega_l", "vx", "vy"):
            np.testing.assert_array_equal(getattr(loaded, key), getattr(expected, key))
    with pytest.raises(bj.DataError, match=r"1 of 2 inputs .*missing\.csv"):
        bj.load_experiments([csv, tmp_path / "missing.csv"])


def report_text(path) -> str:
    """The report's HTML without its images and creation time."""
    text = re.sub(r"data:image/png;base64,[^\"]+", "", path.read_text())
    return re.sub(r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", "", text)


def test_report_of_a_posterior_in_memory_is_that_of_its_file(posterior, tmp_path):
    saved = bj.save_posterior(posterior, tmp_path / "white.nc")
    from_file = bj.write_report(saved, tmp_path / "file" / "r.html", formats=("png",))
    in_memory = bj.write_report(posterior, tmp_path / "memory" / "r.html", formats=("png",))
    # A posterior in memory is labelled by its family where a file shows its name.
    expected = report_text(from_file).replace(str(saved), "white").replace("white.nc", "white")
    expected = expected.replace("#white-nc-", "#white-").replace('id="white-nc-', 'id="white-')
    assert report_text(in_memory) == expected
    figures = [
        sorted(p.name for p in (r.parent / "r_figures").iterdir()) for r in (from_file, in_memory)
    ]
    assert figures[0] == figures[1] and figures[0]


def test_report_labels_posteriors_in_memory(posterior, tmp_path):
    # The labels alone (rendering is tested above): a mapping's keys, else the
    # family, -2 for the second of a name; files keep their paths, in order.
    saved = bj.save_posterior(posterior, tmp_path / "white.nc")
    labelled, failed, count = _labelled([posterior, saved, posterior])
    assert [str(label) for label, _ in labelled] == ["white", str(saved), "white-2"]
    assert labelled[0][1] is posterior and not failed and count == 3
    labelled, _, _ = _labelled({"run A": posterior, "run B": posterior})
    assert [str(label) for label, _ in labelled] == ["run A", "run B"]
    _, failed, _ = _labelled([posterior, tmp_path / "missing.nc"])
    assert list(failed) == [str(tmp_path / "missing.nc")]


@pytest.mark.parametrize(
    ("call", "pattern"),
    [
        (lambda run: bj.sample([run], family="pink"), r"family: unknown noise family 'pink'"),
        (lambda run: bj.sample([run], channels=["yaw", "z"]), r"channels: .*'z'"),
        (lambda run: bj.sample([run], noise="private"), r"noise: unknown noise 'private'"),
        (lambda run: bj.sample([run], engine="slow"), r"engine: unknown engine 'slow'"),
        (lambda run: bj.sample([run], max_steps=0), r"max_steps: must be an integer >= 1"),
        (lambda run: bj.sample([run], priors={"d_late": (1, 2)}), r"d_late"),
        (lambda run: bj.compare([run], families=("white", "pink")), r"families: .*'pink'"),
        (lambda run: bj.load_experiments("x.csv", columns={"yaw": "gz"}), r"'yaw'"),
        (lambda run: bj.write_report(42, "r.html"), r"posteriors: expected .* got 42"),
    ],
)
def test_a_bad_option_is_an_input_error_naming_it(run, call, pattern):
    with pytest.raises(bj.InputError, match=pattern):
        call(run)


@pytest.mark.parametrize("name", FUNCTIONS)
def test_docstring_examples_show_the_call(name):
    # Each example calls its function; tests/test_docstrings.py runs every
    # public function's examples (these among them), so they are not run twice.
    function = getattr(bj, name)
    [test] = doctest.DocTestFinder(recurse=False).find(function, name)
    assert test.examples, f"{name} has no Examples"
    assert any(f"{name}(" in example.source for example in test.examples), name
