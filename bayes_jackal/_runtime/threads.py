"""One BLAS thread while a log-posterior is evaluated.

The likelihood's linear algebra is many small calls (banded Cholesky
factors of a few hundred lags, matrix products of a few thousand rows), on
which OpenBLAS's threads cost more than they save: LAPACK's banded factor
``dpbtrf`` of 1,578 samples and a band of 148 lags took 1.1 s with two
threads on a busy 2-core machine and 2 ms with one, and a demo run's
``sample`` 31 s against 14 s. One thread also makes a chain the same on every
machine: threaded BLAS sums in an order that depends on the thread count.
threadpoolctl (BSD, the scikit-learn maintainers') finds every BLAS library
loaded in the process, numpy's and scipy's alike, and sets their thread
counts at run time; environment variables act only before a library loads.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import scipy.linalg  # noqa: F401  (loads scipy's BLAS before the controller looks)
from threadpoolctl import ThreadpoolController

__all__ = ["one_blas_thread"]

_CONTROLLER: ThreadpoolController | None = None


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Every loaded BLAS library on one thread inside the block (about 10 µs).

    Examples
    --------
    >>> import threadpoolctl
    >>> from bayes_jackal._runtime.threads import one_blas_thread
    >>> with one_blas_thread():
    ...     {pool["num_threads"] for pool in threadpoolctl.threadpool_info()
    ...      if pool["user_api"] == "blas"}
    {1}
    """
    global _CONTROLLER
    if _CONTROLLER is None:
        _CONTROLLER = ThreadpoolController()
    with _CONTROLLER.limit(limits=1, user_api="blas"):
        yield
