"""Searches in lockstep (bayes_jackal.inference._lockstep) against scipy's, one at a time."""

from __future__ import annotations

import doctest
import threading

import numpy as np
import pytest
import scipy.optimize

from bayes_jackal.inference import _lockstep
from bayes_jackal.inference._lockstep import lockstep_maxima, negative_with_gradient


def rosenbrock(points: np.ndarray) -> np.ndarray:
    """Minus the Rosenbrock function of each row: a curved valley, many L-BFGS-B steps."""
    x, y = points[:, 0], points[:, 1]
    return -((1 - x) ** 2 + 100 * (y - x**2) ** 2)


def test_each_search_is_the_one_scipy_runs_alone():
    # The reference: scipy's L-BFGS-B from each start in turn, on the same
    # forward differences. A point's value does not depend on its batch here,
    # so every search must take the very same steps: equal to the last bit.
    starts = np.array([[-1.5, 2.0], [0.0, 0.0], [2.0, -1.0], [1.2, 1.2]])
    low, high = np.full(2, -3.0), np.full(2, 3.0)
    calls = []

    def counted(points):
        calls.append(len(points))
        return rosenbrock(points)

    ends = lockstep_maxima(counted, starts, low, high)
    for start, end in zip(starts, ends, strict=True):
        alone = scipy.optimize.minimize(
            negative_with_gradient(rosenbrock, high), start, method="L-BFGS-B", jac=True,
            bounds=list(zip(low, high, strict=True)),
        )  # fmt: skip
        np.testing.assert_array_equal(end.x, alone.x)
        assert end.nfev == alone.nfev and end.fun == alone.fun
    # One call per round: as many as the longest search's evaluations, the
    # first rounds holding every search's three points.
    assert len(calls) == max(end.nfev for end in ends)
    assert calls[0] == 3 * len(starts)


def test_an_error_in_an_evaluation_ends_every_search_and_is_raised():
    def failing(points):
        if len(failing.seen) == 3:
            raise ValueError("bad set")
        failing.seen.append(len(points))
        return rosenbrock(points)

    failing.seen = []
    before = threading.active_count()
    with pytest.raises(ValueError, match="bad set"):
        lockstep_maxima(failing, np.zeros((3, 2)), np.full(2, -3.0), np.full(2, 3.0))
    assert threading.active_count() == before  # no search left waiting


def test_a_stop_in_the_main_thread_ends_the_searches():
    # An interrupt arrives in the main thread, in an evaluation: it propagates
    # as it is, and no search's thread is left behind.
    def interrupted(points):
        raise KeyboardInterrupt

    before = threading.active_count()
    with pytest.raises(KeyboardInterrupt):
        lockstep_maxima(interrupted, np.zeros((2, 2)), np.full(2, -3.0), np.full(2, 3.0))
    assert threading.active_count() == before


def test_the_modules_examples_run():
    # A private module: the public API's doctests (tests/test_docstrings.py) skip it.
    assert doctest.testmod(_lockstep).failed == 0
