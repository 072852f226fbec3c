"""What the calibration tests share: their seeds, their worker processes, the binomial bound.

``BAYES_JACKAL_CALIBRATION_SEEDS`` sets the seeds per case (each test's full
form by default; CI runs 1, the reduced form, from .ci/run) and
``BAYES_JACKAL_CALIBRATION_PROCESSES`` the worker processes the rows run in
(1: in the test's own).
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import warnings
from collections.abc import Callable

import scipy.stats

#: The credible mass of the HDIs whose coverage the tests check.
HDI_PROB = 0.94


def seeds(default: int) -> range:
    """``BAYES_JACKAL_CALIBRATION_SEEDS`` seeds per case (``default`` when unset)."""
    count = int(os.environ.get("BAYES_JACKAL_CALIBRATION_SEEDS", str(default)))
    if count < 1:
        raise ValueError(f"BAYES_JACKAL_CALIBRATION_SEEDS must be >= 1, got {count}")
    return range(count)


def processes() -> int:
    """``BAYES_JACKAL_CALIBRATION_PROCESSES`` worker processes for the rows (1: in this one)."""
    count = int(os.environ.get("BAYES_JACKAL_CALIBRATION_PROCESSES", "1"))
    if count < 1:
        raise ValueError(f"BAYES_JACKAL_CALIBRATION_PROCESSES must be >= 1, got {count}")
    return count


def map_rows(function: Callable, work: list) -> list:
    """``function`` over ``work``, in :func:`processes` fresh worker processes if more than one.

    The workers turn warnings into errors, as pytest's configuration does here.
    """
    count = processes()
    if count == 1:
        return [function(item) for item in work]
    with concurrent.futures.ProcessPoolExecutor(
        count,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=warnings.simplefilter,
        initargs=("error",),
    ) as pool:
        return list(pool.map(function, work))


def least_inside(cases: int) -> float:
    """The 0.1 % quantile of Binomial(cases, 0.94): a calibrated 94 % HDI holds
    the truth in fewer of ``cases`` independent cases once in a thousand."""
    return scipy.stats.binom.ppf(0.001, cases, HDI_PROB)
