"""Every public function and class of the library shows how it is called.

A public name is one in the ``__all__`` of ``bayes_jackal`` or of one of its
subpackages (the command line's ``bayes_jackal.cli`` and the private
``bayes_jackal._runtime`` aside). Each has a
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
import warnings
from pathlib import Path

import matplotlib
import pytest

import bayes_jackal
from bayes_jackal import inference
from bayes_jackal.inference import sampling
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


def _public_callables() -> list[tuple[str, str]]:
    """Each public function and class, as (the module defining it, its name)."""
    cases = set()
    for namespace in NAMESPACES:
        module = importlib.import_module(namespace)
        for name in module.__all__:
            obj = getattr(module, name)
            if inspect.isfunction(obj) or inspect.isclass(obj):
                cases.add((obj.__module__, name))
    return sorted(cases)


CASES = _public_callables()


def test_every_public_namespace_is_covered():
    # The namespaces are listed from the package's folders, so a new
    # subpackage joins them; this guards the filter itself.
    found = {module for module, _ in CASES}
    assert {"bayes_jackal.model.physics", "bayes_jackal.report.plots"} <= found
    assert "bayes_jackal.posterior.summary" in found


#: The posteriors of the examples' calls of ``bj.sample``, by call (module text).
SAMPLED: dict[str, object] = {}
SAMPLE = sampling.sample


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
        monkeypatch.setattr(sampling, "sample", shared_sample)
        monkeypatch.setattr(inference, "sample", shared_sample)
        monkeypatch.setattr(bayes_jackal, "sample", shared_sample)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    # Examples that run a short chain on purpose say so; its warning is expected.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        runner.run(test)
    assert runner.summarize(verbose=False).failed == 0, f"{module}.{name}: an example failed"
