"""Every public function and class of the library shows how it is called.

A public name is one in a library module's ``__all__`` (the command line's
package ``bayes_jackal.cli`` and the private ``_*`` modules aside). Each has a
numpydoc ``Examples`` section, and its examples run here as doctests, in a
namespace of their own: an example imports what it uses, as a reader would.

Dozens of examples build their posterior the same way, e.g. the 20-step chain
``bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)``
of one simulated run. Here each distinct call of ``bj.sample`` is sampled
once per test process, by the first example that makes it; a later example
making the same call (the same experiments and options) gets a copy of that
posterior, which is the chain it would sample (same seed, same chain).
``sample``'s own examples, and calls that write a chain file, always sample.
"""

from __future__ import annotations

import copy
import doctest
import hashlib
import importlib
import inspect
import pickle
import pkgutil
import warnings

import matplotlib
import pytest

import bayes_jackal
from bayes_jackal import api
from bayes_jackal.inference import ConvergenceWarning

matplotlib.use("Agg")


def _library_modules() -> list[str]:
    """The library's public modules: no ``cli``, no ``_private``, no data."""
    names = []
    for module in pkgutil.walk_packages(bayes_jackal.__path__, "bayes_jackal."):
        parts = module.name.split(".")[1:]
        if parts[0] in ("cli", "data") or any(part.startswith("_") for part in parts):
            continue
        names.append(module.name)
    return sorted(names)


def _public_callables(module_name: str) -> list[str]:
    """The functions and classes in ``module.__all__`` that the module defines."""
    module = importlib.import_module(module_name)
    if not hasattr(module, "__all__"):
        raise AttributeError(f"{module_name} has no __all__")
    return [
        name
        for name in module.__all__
        if (inspect.isfunction(obj := getattr(module, name)) or inspect.isclass(obj))
        and obj.__module__ == module_name
    ]


CASES = [(module, name) for module in _library_modules() for name in _public_callables(module)]


def test_every_library_module_is_covered():
    # The list above is built from the package, so a new module joins it; this
    # guards the filter itself (the API, physics and plots are public).
    modules = {module for module, _ in CASES}
    assert {"bayes_jackal.api", "bayes_jackal.physics", "bayes_jackal.plots"} <= modules


def test_the_top_level_names_are_covered():
    covered = {name for _, name in CASES}
    callables = [
        name
        for name in bayes_jackal.__all__
        if inspect.isfunction(obj := getattr(bayes_jackal, name)) or inspect.isclass(obj)
    ]
    assert set(callables) <= covered


#: The posteriors of the examples' calls of ``bj.sample``, by call (module text).
SAMPLED: dict[str, object] = {}
SAMPLE = api.sample


def shared_sample(experiments, **options):
    """``bj.sample``, sampling each distinct call once and copying it after."""
    if options.get("chain_file") is not None:
        return SAMPLE(experiments, **options)
    key = hashlib.sha256(pickle.dumps((experiments, sorted(options.items())))).hexdigest()
    if key not in SAMPLED:
        SAMPLED[key] = SAMPLE(experiments, **options)
    return copy.deepcopy(SAMPLED[key])


@pytest.mark.parametrize(("module", "name"), CASES, ids=[f"{m[13:]}.{n}" for m, n in CASES])
def test_docstring_examples_run(module, name, monkeypatch):
    obj = getattr(importlib.import_module(module), name)
    [test] = doctest.DocTestFinder(recurse=False).find(obj, f"{module}.{name}", globs={})
    assert test.examples, f"{module}.{name} has no Examples"
    if obj is not SAMPLE:
        monkeypatch.setattr(api, "sample", shared_sample)
        monkeypatch.setattr(bayes_jackal, "sample", shared_sample)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    # Examples that run a short chain on purpose say so; its warning is expected.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        runner.run(test)
    assert runner.summarize(verbose=False).failed == 0, f"{module}.{name}: an example failed"
