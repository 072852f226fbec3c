"""Every function and class the library offers shows how it is called.

Offered is a name in the ``__all__`` of ``bayes_jackal``, or one a subpackage
offers to users (its ``__all__``) or to the later stages (the other names its
``__init__`` imports), the command line's ``bayes_jackal.cli`` and the private
``bayes_jackal._runtime`` aside. Each has a
numpydoc ``Examples`` section, and its examples run here as doctests, in a
namespace of their own: an example imports what it uses, as a reader would.

No doctest runs emcee. The examples' chains are sampled once per test
process, before any example runs, by the session fixture ``shared_results``:
the calls listed in :func:`shared_calls`, written there as the examples write
them. Most examples share one small posterior,
``bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)``
of ``run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)``;
a few need a coloured family (``family="gaussian"``: the filters, the DEM
prior, the width's plot), the diagonal sensor term (``estimate_each``'s
refused filter), a velocity channel (``derived_velocities``) or two pooled
runs (``PooledPosterior``).

While an example runs, each function of :data:`MEMOISED` (wherever the
package binds it: ``bayes_jackal.sample`` is also
``bayes_jackal.inference.sample`` and ``bayes_jackal.inference.sampling.sample``)
returns a deep copy of the result of the same call (the same arguments,
compared by their pickles) computed by the fixture: the real result of that
call, as the same seed gives the same chain. A call not listed fails, naming
itself. Memoised are the functions whose result is a value (no file written
that the example then reads): ``sample``, ``sample_posterior``, ``compare``,
``compare_families``, ``compare_groups`` (its comparisons, yielded again),
``characterise_noise`` and ``fit_family``.

The guard: while an example runs, constructing an ``emcee.EnsembleSampler``
raises, naming the example, and the test fails
(``test_an_example_that_runs_emcee_fails`` checks that it does).

The chains that cannot be memoised are skipped: the example shows the call
and the lines reading its result, with the output the real call printed,
marked ``# doctest: +SKIP``, and a unit test checks what they show (named in
:data:`RUN_ELSEWHERE`, which ``test_the_examples_run_elsewhere_say_so_and_their_tests_exist``
checks). ``run_chain``'s target and start are functions the example defines
(no call to list); ``ensemble_moves``' example runs emcee itself, on the
moves; ``BufferedHDFBackend``'s reads the chain file ``bj.sample`` writes;
``leave_one_out`` and ``analyse_logs`` write files (the latter's example
lists them).

The private runtime's modules (``bayes_jackal._runtime``) have examples
too; they run as they are (:func:`test_the_runtimes_examples_run`).
"""

from __future__ import annotations

import copy
import doctest
import functools
import hashlib
import importlib
import inspect
import pickle
import re
import sys
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import emcee
import matplotlib
import pytest

import bayes_jackal
from bayes_jackal import inference, noise
from bayes_jackal.inference.sampler_warnings import ConvergenceWarning

matplotlib.use("Agg")


#: The public namespaces: ``bayes_jackal`` and its subpackages (the command
#: line's ``cli`` and the private ``_runtime`` aside).
NAMESPACES = [
    "bayes_jackal",
    *(
        f"bayes_jackal.{folder.name}"
        for folder in sorted(Path(bayes_jackal.__file__).parent.iterdir())
        if (folder / "__init__.py").exists()
        and not folder.name.startswith("_")
        and folder.name not in ("cli", "data")
    ),
]


def _offered(module) -> list[str]:
    """The top level's ``__all__``; every name a subpackage's ``__init__`` imports."""
    if module is bayes_jackal:
        return module.__all__
    return [
        n for n, v in vars(module).items() if not n.startswith("_") and not inspect.ismodule(v)
    ]


def _public_callables() -> list[tuple[str, str, bool]]:
    """Each offered function and class, as (the module defining it, its name, public).

    Public (in an ``__all__``) names must have examples; the others' run if they have.
    """
    cases = {}
    for namespace in NAMESPACES:
        module = importlib.import_module(namespace)
        for name in _offered(module):
            obj = getattr(module, name)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            public = name in module.__all__ or cases.get((obj.__module__, name), False)
            if public or "Examples\n" in (obj.__doc__ or ""):
                cases[obj.__module__, name] = public
    return sorted((module, name, public) for (module, name), public in cases.items())


CASES = _public_callables()


def test_every_public_namespace_is_covered():
    # The namespaces are listed from the package's folders, so a new
    # subpackage joins them; this guards the filter itself.
    found = {module for module, _, _ in CASES}
    assert {"bayes_jackal.model.physics", "bayes_jackal.report.plots"} <= found
    assert "bayes_jackal.posterior.summary" in found


#: The functions that run chains whose examples' calls are computed by the
#: fixture and shared (see the module's docstring).
MEMOISED: list[Callable] = [
    inference.sample,
    inference.sample_posterior,
    inference.compare,
    inference.compare_families,
    inference.compare_groups,
    inference.population,
    inference.population_posterior,
    noise.characterise_noise,
    noise.fit_family,
]

#: Examples whose chain runs elsewhere: the function, and the unit test that
#: checks what its skipped lines show.
RUN_ELSEWHERE = {
    "bayes_jackal.inference.chains.run_chain": (
        "tests/test_inference.py::test_the_chain_stops_on_the_ess_once_longer_than_the_tau_multiple"
    ),
    "bayes_jackal.inference.chains.BufferedHDFBackend": (
        "tests/test_outputs.py::test_a_file_size_limit_leaves_the_chain_resumable"
    ),
    "bayes_jackal.inference.moves.ensemble_moves": (
        "tests/test_moves.py::test_a_curved_ridge_gets_a_mixture_along_it_and_the_chain_its_moments"
    ),
    "bayes_jackal.filters.left_out.leave_one_out": (
        "tests/test_leave_one_out.py::test_each_run_is_filtered_with_the_prior_of_exactly_the_others"
    ),
    "bayes_jackal.workflow.analysis.analyse_logs": (
        "tests/test_leave_one_out.py::test_the_analysis_writes_its_files_and_says_it_did_not_converge"
    ),
}


@dataclass
class Call:
    """One call of a memoised function, as an example makes it."""

    function: Callable
    args: tuple
    kwargs: dict = field(default_factory=dict)


def call(function: Callable, *args, **kwargs) -> Call:
    return Call(function, args, kwargs)


def shared_calls() -> Iterator[Call]:
    """The calls the examples make of the memoised functions, with their arguments."""
    import numpy as np

    import bayes_jackal as bj
    from bayes_jackal.inference import (
        FitOptions,
        compare_families,
        compare_groups,
        population_posterior,
        sample_posterior,
    )
    from bayes_jackal.io import Series
    from bayes_jackal.likelihood import LikelihoodOptions, ResidualLikelihood
    from bayes_jackal.model import get_family
    from bayes_jackal.noise import NoiseSeries, fit_family

    robot = bj.load_profile()
    run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    # The shared posterior, and the few that need another family, sensor term
    # or channel (derived_velocities: a velocity channel).
    yield call(bj.sample, [run], family="white", channels=["yaw"], max_steps=20, seed=1)
    yield call(bj.sample, [run], family="gaussian", channels=["yaw"], max_steps=20, seed=1)
    yield call(
        bj.sample, [run], family="white", channels=["yaw"], sensor="diagonal", max_steps=20, seed=1
    )
    yield call(bj.sample, [run], family="white", channels=["yaw", "vx"], max_steps=20, seed=1)
    # prior_boundary: long enough for the sensor sd to reach its bound.
    yield call(bj.sample, [run], family="white", channels=["yaw"], max_steps=100, seed=1)
    # PooledPosterior: two short runs pooled.
    runs = [
        bj.simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=seed, name=name)
        for seed, name in [(1, "a"), (2, "b")]
    ]
    yield call(bj.sample, runs, family="white", channels=["yaw"], max_steps=200, seed=1)
    # sample_posterior: the shared posterior's call, one level down.
    likelihood = ResidualLikelihood([run], robot, family="white", channels=("yaw",))
    yield call(sample_posterior, likelihood, bj.SamplerSettings(max_steps=20), seed=1)
    # compare, compare_families, compare_groups.
    yield call(
        bj.compare, [run], families=("white", "exponential"), channels=["yaw"], max_steps=20,
        seed=1,
    )  # fmt: skip
    options = FitOptions(
        likelihood_options=LikelihoodOptions(channels=["yaw"]),
        settings=bj.SamplerSettings(max_steps=20), seed=1,
    )  # fmt: skip
    yield call(compare_families, [run], options, families=("white", "exponential"))
    groups = {
        name: [bj.simulate_experiment(robot, 110.0, 30.0, rng=seed, name=name)]
        for seed, name in enumerate(["v1_01", "v1_02"], start=1)
    }
    options = FitOptions(
        robot=robot, likelihood_options=LikelihoodOptions(channels=["yaw"]),
        settings=bj.SamplerSettings(max_steps=20), seed=1,
    )  # fmt: skip
    yield call(compare_groups, groups, options, families=["white"])
    # population (its example, Population's and the forest plot's): two floors.
    runs = [
        bj.simulate_experiment(robot, 110.0, d_long, rng=seed, name=f"run{seed}")
        for seed, d_long in enumerate([30.0, 30.0, 40.0, 40.0])
    ]
    floors = {"run0": "tiles", "run1": "tiles", "run2": "carpet", "run3": "carpet"}
    yield call(
        bj.population, runs, groups=floors, family="white", channels=["yaw"], seed=1,
        max_steps=400, progress=False,
    )  # fmt: skip
    options = FitOptions(
        likelihood_options=LikelihoodOptions(channels=["yaw"]),
        settings=bj.SamplerSettings(max_steps=400), seed=1,
    )  # fmt: skip
    yield call(population_posterior, runs, options, groups=floors, family="white")
    # characterise_noise (its own example and NoiseCharacterisation's), fit_family.
    rng = np.random.default_rng(2)
    taps = get_family("gaussian").taps(0.03, 0.01)
    coloured = np.convolve(rng.standard_normal(600), taps, "same")
    values = coloured + 0.3 * rng.standard_normal(600)
    yield call(
        bj.characterise_noise, values, dt=0.01, families=["white", "gaussian"], seed=1,
        settings=bj.SamplerSettings(max_steps=100),
    )  # fmt: skip
    values = np.random.default_rng(1).standard_normal(300)
    yield call(bj.characterise_noise, values, dt=0.01, families=["white"], seed=1)
    values = np.random.default_rng(1).standard_normal(500)
    yield call(fit_family, NoiseSeries(values=values, dt=0.01, name="white"), "white", seed=1)


def _key(function: Callable, args: tuple, kwargs: dict) -> str:
    """The call's digest: the function and its arguments as passed (pickled)."""
    bound = inspect.signature(function).bind(*args, **kwargs)
    named = f"{function.__module__}.{function.__qualname__}"
    return hashlib.sha256(pickle.dumps((named, dict(bound.arguments)))).hexdigest()


def _describe(function: Callable, args: tuple, kwargs: dict) -> str:
    """The call as text, experiments by name (for the message of a call not listed)."""

    def text(value) -> str:
        if isinstance(value, list | tuple) and value and hasattr(value[0], "yaw_rate"):
            return f"[{', '.join(f'<Experiment {run.name!r}>' for run in value)}]"
        return re.sub(r"\s+", " ", repr(value))[:120]

    shown = [text(a) for a in args] + [f"{k}={text(v)}" for k, v in kwargs.items()]
    return f"{function.__name__}({', '.join(shown)})"


@pytest.fixture(scope="session")
def shared_results() -> dict[str, object]:
    """The result of each of :func:`shared_calls`, by its key: chains run here, once."""
    results = {}
    with warnings.catch_warnings():
        # Short chains on purpose (the examples say so).
        warnings.simplefilter("ignore", ConvergenceWarning)
        for each in shared_calls():
            key = _key(each.function, each.args, each.kwargs)
            result = each.function(*each.args, **each.kwargs)
            results[key] = list(result) if inspect.isgenerator(result) else result
    return results


class EmceeInExample(RuntimeError):
    """An example constructed an emcee sampler."""


class UnlistedCall(LookupError):
    """An example called a memoised function with arguments shared_calls does not list."""


def _bindings(function: Callable) -> list[tuple[object, str]]:
    """Every (module, name) of the package that binds ``function``."""
    return [
        (module, name)
        for module_name, module in list(sys.modules.items())
        if module_name.split(".")[0] == "bayes_jackal" and module is not None
        for name, value in list(vars(module).items())
        if value is function
    ]


def _memoised(function: Callable, results: dict, problems: list[str]) -> Callable:
    """``function`` answering from ``results``, or failing for a call not in them."""

    @functools.wraps(function)
    def shared(*args, **kwargs):
        key = _key(function, args, kwargs)
        if key not in results:
            problem = (
                f"{_describe(function, args, kwargs)} is not a shared call: list it in "
                "tests/test_docstrings.py (shared_calls) or make the example use one that is"
            )
            problems.append(problem)
            raise UnlistedCall(problem)
        result = copy.deepcopy(results[key])
        return iter(result) if inspect.isgeneratorfunction(function) else result

    return shared


def run_examples(test: doctest.DocTest, results: dict, monkeypatch) -> tuple[int, list[str]]:
    """Run one docstring's examples: (the failures, what broke the rules).

    The memoised functions answer from ``results``; an emcee sampler cannot
    be constructed.
    """
    problems: list[str] = []
    for function in MEMOISED:
        shared = _memoised(function, results, problems)
        for module, name in _bindings(function):
            monkeypatch.setattr(module, name, shared)

    def refuse(sampler, *args, **kwargs):
        problem = f"{test.name}: an example runs emcee (constructs an emcee.EnsembleSampler)"
        problems.append(problem)
        raise EmceeInExample(problem)

    monkeypatch.setattr(emcee.EnsembleSampler, "__init__", refuse)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    try:
        # Examples that run a short chain on purpose say so; its warning is expected.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            runner.run(test)
    finally:
        monkeypatch.undo()
    return runner.summarize(verbose=False).failed, problems


@pytest.mark.parametrize(
    ("module", "name", "public"), CASES, ids=[f"{m[13:]}.{n}" for m, n, _ in CASES]
)
def test_docstring_examples_run(module, name, public, shared_results, monkeypatch):
    obj = getattr(importlib.import_module(module), name)
    # A class's methods' examples run with it (DocTestFinder's recursion).
    own, *methods = doctest.DocTestFinder().find(obj, f"{module}.{name}", globs={})
    assert own.name == f"{module}.{name}", own.name
    assert own.examples or not public, f"{module}.{name} has no Examples"
    for test in [own, *methods]:
        failed, problems = run_examples(test, shared_results, monkeypatch)
        assert not problems, "\n".join(problems)
        assert failed == 0, f"{test.name}: an example failed"


def _doctest(text: str, name: str) -> doctest.DocTest:
    return doctest.DocTestParser().get_doctest(text, {}, name, None, 0)


def test_an_example_that_runs_emcee_fails(shared_results, monkeypatch):
    example = _doctest(
        ">>> import emcee\n>>> emcee.EnsembleSampler(4, 1, lambda z: 0.0)  # doctest: +ELLIPSIS\n"
        "<emcee...>\n",
        "an_example",
    )
    failed, problems = run_examples(example, shared_results, monkeypatch)
    assert failed == 1
    assert problems == ["an_example: an example runs emcee (constructs an emcee.EnsembleSampler)"]


def test_a_call_not_shared_fails_naming_itself(shared_results, monkeypatch):
    example = _doctest(
        ">>> import bayes_jackal as bj\n"
        ">>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)\n"
        '>>> posterior = bj.sample([run], family="white", channels=["vx"], max_steps=20,'
        " seed=1)\n",
        "another_example",
    )
    failed, problems = run_examples(example, shared_results, monkeypatch)
    assert failed == 1
    assert problems == [
        "sample([<Experiment 'v1'>], family='white', channels=['vx'], max_steps=20, seed=1) "
        "is not a shared call: list it in tests/test_docstrings.py (shared_calls) or make the "
        "example use one that is"
    ]


def test_the_examples_run_elsewhere_say_so_and_their_tests_exist():
    root = Path(__file__).parent.parent
    for target, covering in RUN_ELSEWHERE.items():
        module, name = target.rsplit(".", 1)
        assert "# doctest: +SKIP" in getattr(importlib.import_module(module), name).__doc__
        path, test = covering.split("::")
        assert f"def {test}(" in (root / path).read_text(), covering


#: The private runtime's modules: their examples run too (none samples a chain).
RUNTIME = sorted(
    f"bayes_jackal._runtime.{path.stem}"
    for path in (Path(bayes_jackal.__file__).parent / "_runtime").glob("*.py")
    if path.name != "__init__.py"
)


@pytest.mark.parametrize("module", RUNTIME, ids=[m.rsplit(".", 1)[1] for m in RUNTIME])
def test_the_runtimes_examples_run(module):
    runner, report = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS), []
    for test in doctest.DocTestFinder().find(importlib.import_module(module)):
        runner.run(test, out=report.append)
    failed, attempted = runner.failures, runner.tries
    assert failed == 0, "".join(report)
    # Only the modules of constants show no call.
    assert attempted > 0 or module.endswith(("arviz_quiet", "defaults", "warning_kinds")), module
