"""Running independent jobs (a family's posterior and evidence) in worker processes.

:func:`in_processes` runs picklable jobs in spawned processes and yields
their results as they finish. The workers ignore SIGINT (a terminal's
Ctrl-C reaches the whole process group; the main process stops them) and
die quietly on SIGTERM; on any exception in the main process, an interrupt
included, the workers it started are terminated at once.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from typing import TypeVar

from . import interrupt

__all__ = ["in_processes", "single_threaded_children"]

T = TypeVar("T")
R = TypeVar("R")

#: Thread counts of the numerical libraries, read once when a process loads them.
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def single_threaded_children() -> Iterator[None]:
    """One BLAS/OpenMP thread in the processes started meanwhile (they inherit os.environ).

    A process per core with threaded BLAS in each oversubscribes the cores:
    five families on 2 cores took 85 s that way and 48 s with one thread each.
    (The demo's two families, one 4x slower, took 74 s threaded and 83 s not.)
    """
    saved = {name: os.environ.get(name) for name in _THREAD_VARIABLES}
    os.environ.update(dict.fromkeys(_THREAD_VARIABLES, "1"))
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def in_processes(
    work: Callable[[T], R], jobs: Sequence[T], *, workers: int, single_threaded: bool = False
) -> Iterator[Iterator[R]]:
    """Results of ``work(job)`` as they finish, from ``workers`` spawned processes.

    ``work`` must be picklable (a module-level function or a dataclass
    instance). ``single_threaded``: one BLAS/OpenMP thread in each worker
    (:func:`single_threaded_children`), for more jobs than cores.

    The workers ignore SIGINT and die quietly on SIGTERM
    (:func:`bayes_jackal.interrupt.quiet_worker`); on any exception here,
    an interrupt included, they are terminated at once.
    """
    context = multiprocessing.get_context("spawn")
    before = set(multiprocessing.active_children())
    with concurrent.futures.ProcessPoolExecutor(
        workers, mp_context=context, initializer=interrupt.quiet_worker
    ) as pool:
        try:
            threads = single_threaded_children() if single_threaded else contextlib.nullcontext()
            with threads, interrupt.blocked():  # a signal waits until the workers handle it
                futures = [pool.submit(work, job) for job in jobs]
            yield (future.result() for future in concurrent.futures.as_completed(futures))
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            for child in set(multiprocessing.active_children()) - before:
                child.terminate()
            raise
