"""Running independent jobs (a family's posterior and evidence): here, in processes, on a cluster.

An :class:`Executor` runs picklable jobs and yields their results as they
finish: :class:`SerialExecutor` in this process, one after the other;
:class:`ProcessExecutor` in local processes (:func:`in_processes`);
:class:`DaskExecutor` as tasks of a Dask distributed cluster (``dask
scheduler`` and ``dask worker``; optional extra ``bayes-jackal[cluster]``).
:class:`Background` runs a job beside the caller's own work, in one more
local process (the report's figures while the filters run).
A job carries everything its result depends on, its seed included, so the
results do not depend on the executor.

:func:`in_processes` runs picklable jobs in worker processes and yields
their results as they finish. The workers are forked from a server process
that imported the package once (multiprocessing's "forkserver": a fresh
interpreter each, as "spawn" started them, spent 2-3 s of CPU importing
it). The workers ignore SIGINT (a terminal's
Ctrl-C reaches the whole process group; the main process stops them) and
die quietly on SIGTERM; on any exception in the main process, an interrupt
included, the workers it started are terminated at once.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import io
import logging
import multiprocessing
import subprocess
import sys
import threading
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeVar

import threadpoolctl

from .._runtime import ROOT_LOGGER, InputError, interrupts_blocked, quiet_worker

__all__ = [
    "Background",
    "DaskExecutor",
    "Executor",
    "Pending",
    "ProcessExecutor",
    "SerialExecutor",
    "executor_for",
    "in_processes",
]

T = TypeVar("T")
R = TypeVar("R")

#: How long to try to reach a Dask scheduler [s].
DEFAULT_TIMEOUT = 5.0
#: What the worker processes' server imports once, before it forks each worker
#: (:func:`in_processes`): a spawned worker imported the package itself, 2-3 s
#: of CPU each.
WORKER_MODULES = ["bayes_jackal.inference"]


@functools.cache
def _worker_context() -> multiprocessing.context.BaseContext:
    """The "forkserver" context preloading :data:`WORKER_MODULES`, or "spawn".

    The fork server is a fresh interpreter with this process's environment
    and working folder, which imports the package before a worker gets
    this process's ``sys.path`` (Python 3.11): where a fresh interpreter
    would find another copy of the package (``sys.path`` changed at run
    time), the workers would run it. There each worker is spawned and
    imports the package from this process's ``sys.path``, as before.
    """
    finder = f"import importlib.util; print(importlib.util.find_spec({__package__!r}).origin)"
    found = subprocess.run(
        [sys.executable, "-c", finder], capture_output=True, text=True, check=False
    ).stdout.strip()
    here = sys.modules[__package__].__file__
    if not found or not here or Path(found).resolve() != Path(here).resolve():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(WORKER_MODULES)
    return context


def _start_worker(single_threaded: bool) -> None:
    """A worker's initializer: quiet on signals and, with ``single_threaded``, one BLAS thread.

    A process per core with threaded BLAS in each oversubscribes the cores:
    five families on 2 cores took 85 s that way and 48 s with one thread
    each. (The demo's two families, one 4x slower, took 74 s threaded and
    83 s not.)
    """
    quiet_worker()
    if single_threaded:
        threadpoolctl.threadpool_limits(limits=1)


@contextlib.contextmanager
def in_processes(
    work: Callable[[T], R], jobs: Sequence[T], *, workers: int, single_threaded: bool = False
) -> Iterator[Iterator[R]]:
    """Results of ``work(job)`` as they finish, from ``workers`` worker processes.

    ``work`` must be picklable (a module-level function or a dataclass
    instance). The workers are forked from a server process that has
    imported :data:`WORKER_MODULES` (started at the first call, kept while
    this process lives), or spawned where that server would import another
    copy of the package than this process's. ``single_threaded``: one BLAS/OpenMP thread in
    each worker, for more jobs than cores.

    The workers ignore SIGINT and die quietly on SIGTERM
    (:func:`bayes_jackal._runtime.interrupt.quiet_worker`); on any exception here,
    an interrupt included, they are terminated at once.

    Examples
    --------
    Three jobs in two worker processes (``abs`` is picklable); the workers are
    gone when the block ends:

    >>> import multiprocessing
    >>> from bayes_jackal.inference.executors import in_processes
    >>> before = set(multiprocessing.active_children())
    >>> with in_processes(abs, [-1, 2, -3], workers=2) as results:
    ...     sorted(results)
    [1, 2, 3]
    >>> set(multiprocessing.active_children()) <= before
    True
    """
    context = _worker_context()
    before = set(multiprocessing.active_children())
    with concurrent.futures.ProcessPoolExecutor(
        workers, mp_context=context, initializer=_start_worker, initargs=(single_threaded,)
    ) as pool:
        try:
            with interrupts_blocked():  # a signal waits until the workers handle it
                futures = [pool.submit(work, job) for job in jobs]
            yield (future.result() for future in concurrent.futures.as_completed(futures))
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            for child in set(multiprocessing.active_children()) - before:
                child.terminate()
            raise


class _Kept(logging.Handler):
    """Keeps the records of the package's loggers (a background job's messages)."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        record.msg, record.args, record.exc_info = record.getMessage(), None, None  # picklable
        self.records.append(record)


@dataclass(frozen=True)
class _Outcome:
    """What a background job gave: its value or error, its messages and warnings."""

    value: Any = None
    error: BaseException | None = None
    records: tuple[logging.LogRecord, ...] = ()
    warned: tuple[tuple[type[Warning], str], ...] = ()


def _kept_outcome(work: Callable[..., R], args: tuple) -> _Outcome:
    """``work(*args)`` with its INFO messages and warnings kept, nothing on stderr.

    Runs in the background worker: no ticking line of its own (its stderr,
    the terminal's, is a buffer meanwhile), and what it tells the user comes
    back with its value, told where the value is taken (:meth:`Pending.result`).
    """
    logger, handler = logging.getLogger(ROOT_LOGGER), _Kept()
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # each one, to be filtered where it is told
        try:
            with contextlib.redirect_stderr(io.StringIO()):
                outcome = _outcome_of(work, args)
        finally:
            logger.removeHandler(handler)
    warned = tuple((w.category, str(w.message)) for w in caught)
    return replace(outcome, records=tuple(handler.records), warned=warned)


def _outcome_of(work: Callable[..., R], args: tuple) -> _Outcome:
    """``work(*args)``'s value, or its error, to be raised where the result is taken."""
    try:
        return _Outcome(work(*args))
    except Exception as exc:
        return _Outcome(error=exc)


class Pending:
    """A background job's result, to take once it is needed (:meth:`Background.submit`)."""

    def __init__(self, work: Callable, args: tuple, future: concurrent.futures.Future | None):
        self._work, self._args, self._future = work, args, future
        self._outcome: _Outcome | None = None

    @property
    def taken(self) -> bool:
        """Whether the result was taken (its messages told, its error raised)."""
        return self._outcome is not None

    def result(self) -> Any:
        """The job's value, waiting for it, or its error raised; its messages told the first time.

        Of a job that did not run in the background (a serial analysis), the job runs now, here.
        """
        if self._outcome is None:
            if self._future is None:  # raised below, and not again at the block's end
                self._outcome = _outcome_of(self._work, self._args)
            else:
                self._outcome = self._future.result()
                for record in self._outcome.records:  # as if logged here
                    logger = logging.getLogger(record.name)
                    if logger.isEnabledFor(record.levelno):
                        logger.handle(record)
                for category, message in self._outcome.warned:
                    warnings.warn(message, category, stacklevel=2)
        if self._outcome.error is not None:
            raise self._outcome.error
        return self._outcome.value


class Background:
    """Jobs that run beside the caller's own work, in one more local process.

    Within ``with Background(local=True) as background:``,
    :meth:`submit` starts a job in a worker process (forked as
    :func:`in_processes`'s, with one BLAS thread) and returns at once; the
    job's value, messages and warnings reach the caller where it takes the
    :class:`Pending` result. Leaving the block takes every result not yet
    taken, in the order submitted (its messages told, its error raised);
    on an exception (an interrupt included) the worker is terminated at once.
    With ``local=False`` (a serial analysis) a job runs where its result
    is first taken, here, as if it had not been sent away. A job's value
    never depends on where it ran.

    Parameters
    ----------
    local : bool
        Run the jobs in a worker process (True) or here, at once (False).

    Examples
    --------
    >>> from bayes_jackal.inference.executors import Background
    >>> with Background(local=True) as background:
    ...     pending = background.submit(sum, [1, 2, 3])
    ...     pending.result()
    6
    >>> Background(local=False).submit(abs, -4).result()
    4
    """

    def __init__(self, local: bool):
        self.local = local
        self._pool: concurrent.futures.ProcessPoolExecutor | None = None
        self._before: set = set()
        self._submitted: list[Pending] = []

    def __enter__(self) -> Background:
        return self

    def __exit__(self, kind, *exc_info) -> None:
        if kind is not None:
            self._stop()
            return
        try:
            for pending in self._submitted:  # each told, and its error raised, once
                if not pending.taken:
                    pending.result()
        except BaseException:
            self._stop()
            raise
        if self._pool is not None:
            self._pool.shutdown(wait=True)

    def _stop(self) -> None:
        """Cancel the jobs not started and end the worker at once."""
        if self._pool is None:
            return
        self._pool.shutdown(wait=False, cancel_futures=True)
        for child in set(multiprocessing.active_children()) - self._before:
            child.terminate()
            child.join(timeout=5.0)  # SIGTERM ends a worker at once (quiet_worker)

    def submit(self, work: Callable[..., R], *args) -> Pending:
        """Start ``work(*args)`` (picklable, as an executor's jobs); its result to take later."""
        future = None
        if self.local:
            if self._pool is None:
                self._before = set(multiprocessing.active_children())
                self._pool = concurrent.futures.ProcessPoolExecutor(
                    1, mp_context=_worker_context(), initializer=_start_worker, initargs=(True,)
                )
            with interrupts_blocked():  # a signal waits until the worker handles it
                future = self._pool.submit(_kept_outcome, work, args)
        self._submitted.append(Pending(work, args, future))
        return self._submitted[-1]


class Executor:
    """Where independent, picklable jobs run; :meth:`run` yields their results as they finish.

    An executor is also a context manager: within ``with executor:`` it
    may hold a connection (:class:`DaskExecutor`) for several runs;
    outside, each :meth:`run` makes its own.

    Attributes
    ----------
    terminal : bool
        Whether the jobs share the caller's terminal (progress bars make
        sense); False on a cluster, whose workers have none.

    Examples
    --------
    Results come as the jobs finish; the base class runs them here, in order:

    >>> from bayes_jackal.inference.executors import Executor
    >>> with Executor().run(abs, [-1, 2, -3]) as results:
    ...     sorted(results)
    [1, 2, 3]
    """

    terminal = True

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc_info) -> None:
        return None

    def slots(self, jobs: int) -> int:
        """How many of ``jobs`` jobs run at once (one progress line each)."""
        return 1

    def run(
        self, work: Callable[[T], R], jobs: Sequence[T]
    ) -> AbstractContextManager[Iterator[R]]:
        """``work(job)`` for each job, as a context holding an iterator of the results.

        The results come as the jobs finish, in any order; a job's result
        never depends on which executor ran it. Leaving the context early
        (an exception, an interrupt) stops or cancels the jobs still pending.
        """
        return contextlib.nullcontext(map(work, jobs))


class SerialExecutor(Executor):
    """Every job in this process, one after the other (what :class:`Executor` does).

    Examples
    --------
    >>> from bayes_jackal.inference.executors import SerialExecutor
    >>> executor = SerialExecutor()
    >>> with executor.run(abs, [-1, 2, -3]) as results:
    ...     sorted(results)
    [1, 2, 3]
    >>> executor.slots(3)  # one job at a time
    1
    """


class ProcessExecutor(Executor):
    """Jobs in local worker processes, at most ``processes`` at once (:func:`in_processes`).

    One process, or a single job, runs in this process. With more jobs than
    processes every worker gets one BLAS thread (every core stays busy);
    with as many, the longest job runs alone at the end and keeps its
    threads.

    Parameters
    ----------
    processes : int
        Jobs at once, one per process (e.g. one per core), >= 1.

    Examples
    --------
    Two processes for five jobs; a single job runs in this process:

    >>> from bayes_jackal.inference.executors import ProcessExecutor
    >>> executor = ProcessExecutor(2)
    >>> executor.slots(5), executor.slots(1)
    (2, 1)
    >>> with executor.run(abs, [-4]) as results:
    ...     list(results)
    [4]
    """

    def __init__(self, processes: int):
        if processes < 1:
            raise InputError(
                f"processes must be an integer >= 1, got {processes!r}", field="processes"
            )
        self.processes = processes

    def slots(self, jobs: int) -> int:
        return min(self.processes, jobs) if self._parallel(jobs) else 1

    def _parallel(self, jobs: int) -> bool:
        return self.processes > 1 and jobs > 1

    def run(
        self, work: Callable[[T], R], jobs: Sequence[T]
    ) -> AbstractContextManager[Iterator[R]]:
        if not self._parallel(len(jobs)):
            return super().run(work, jobs)
        return in_processes(
            work,
            jobs,
            workers=self.slots(len(jobs)),
            single_threaded=len(jobs) > self.processes,
        )


class DaskExecutor(Executor):
    """Jobs as tasks of a Dask distributed cluster (optional extra ``bayes-jackal[cluster]``).

    The workers need this package installed, at the same version. Dask is
    imported only here, when a scheduler is used.

    Parameters
    ----------
    scheduler : str, distributed.Client or cluster
        The scheduler's address (``tcp://host:8786``, as ``dask scheduler``
        prints it), a connected ``distributed.Client`` (used as it is, never
        closed here) or a cluster object such as ``distributed.LocalCluster``
        (a client of its own is connected to it, and closed after; the
        cluster is left running).
    timeout : float
        How long to try to reach the scheduler [s].

    Raises
    ------
    InputError
        Without dask installed (naming the extra to install).

    Examples
    --------
    An executor for a scheduler (none is reached until it runs jobs):

    >>> from bayes_jackal.inference.executors import DaskExecutor
    >>> executor = DaskExecutor("tcp://127.0.0.1:8786", timeout=10.0)
    >>> executor.slots(5), executor.terminal  # the scheduler spreads the jobs; no terminal
    (5, False)
    """

    terminal = False

    def __init__(self, scheduler: Any, *, timeout: float = DEFAULT_TIMEOUT):
        try:
            import distributed
        except ImportError:
            raise InputError(
                "a Dask scheduler needs dask.distributed: pip install 'bayes-jackal[cluster]'",
                field="scheduler",
            ) from None
        self._distributed = distributed
        self.scheduler = scheduler
        self.timeout = timeout
        self._client = scheduler if isinstance(scheduler, distributed.Client) else None
        self._owned = None  # the client this executor opened, closed on __exit__

    def _address(self) -> str:
        """The scheduler's address, for messages."""
        return str(getattr(self.scheduler, "scheduler_address", self.scheduler))

    def _connect(self):
        """A new client of the scheduler; InputError naming it when it cannot be reached."""
        try:
            if isinstance(self.scheduler, str):
                self._check_scheduler()
            return self._distributed.Client(
                self.scheduler, timeout=self.timeout, set_as_default=False
            )
        # Unreachable, not an address, or a port that is not a scheduler's
        # (asyncio.TimeoutError is no OSError before Python 3.11).
        except (OSError, ValueError, TypeError, asyncio.TimeoutError) as exc:
            reason = str(exc) or "no Dask handshake: something else may listen there"
            raise InputError(
                f"cannot reach the Dask scheduler at {self._address()!r} within "
                f"{self.timeout:g} s ({reason}); start one with `dask scheduler` and its "
                "workers with `dask worker ADDRESS`",
                field="scheduler",
            ) from None

    def _check_scheduler(self) -> None:
        """Ask the address who it is, within the timeout, before a client is made.

        A ``distributed.Client`` waits for ever on a port where another
        service (a web server) accepts the connection but never answers
        Dask's handshake, and one that fails leaves a traceback from its
        ``__del__``. The question runs on an event loop of its own, in a
        thread, so a caller's running loop (a notebook) is not disturbed.
        """
        answer: dict[str, Any] = {}

        def ask() -> None:
            try:
                answer["identity"] = asyncio.run(
                    asyncio.wait_for(_identity(self.scheduler, self.timeout), self.timeout)
                )
            except Exception as exc:  # handed to the caller's thread
                answer["error"] = exc

        thread = threading.Thread(target=ask, name="dask-scheduler-check", daemon=True)
        thread.start()
        thread.join(self.timeout + 5.0)
        error = answer.get("error")
        if isinstance(error, (OSError, asyncio.TimeoutError)):
            raise error
        if error is not None:  # garbage read as Dask's framing: a struct error, 3 EiB to allocate
            raise ValueError(
                f"no Dask handshake: its answer is not Dask's ({type(error).__name__}: {error})"
            )
        kind = answer.get("identity", {}).get("type")
        if kind != "Scheduler":
            raise ValueError(f"it answers as {kind or 'nothing'}, not as a Dask scheduler")

    def __enter__(self) -> DaskExecutor:
        if self._client is None:
            self._client = self._owned = self._connect()
        return self

    def __exit__(self, *exc_info) -> None:
        if self._owned is not None:
            self._owned.close()  # the client only: the scheduler and workers keep running
            self._client = self._owned = None

    def slots(self, jobs: int) -> int:
        return jobs  # the scheduler spreads them; no progress lines on a cluster

    @contextlib.contextmanager
    def run(self, work: Callable[[T], R], jobs: Sequence[T]) -> Iterator[Iterator[R]]:
        with self if self._client is None else contextlib.nullcontext():
            client = self._client
            # pure=False: a job is run even when an identical one ran before;
            # priorities keep the order the jobs were handed out in (Dask's
            # scheduler would otherwise pick among them freely).
            futures = [
                client.submit(work, job, pure=False, priority=len(jobs) - index)
                for index, job in enumerate(jobs)
            ]
            try:
                finished = self._distributed.as_completed(futures, loop=client.loop)
                yield (future.result() for future in finished)
            finally:  # left early (an error, an interrupt): nothing keeps running for us
                client.cancel([future for future in futures if not future.done()])


async def _identity(address: str, timeout: float) -> dict:
    """The ``identity`` of the Dask server at ``address`` (its ``type``: Scheduler, Worker)."""
    from distributed.core import rpc

    server = rpc(address, timeout=timeout)
    try:
        return await server.identity()
    finally:
        await server.close_rpc()


def executor_for(scheduler: Any = None, *, processes: int = 1) -> Executor:
    """The executor of a ``--scheduler`` option: Dask when given, else local processes.

    Parameters
    ----------
    scheduler : str, distributed.Client, cluster or None
        As in :class:`DaskExecutor`.
    processes : int
        Jobs at once without a scheduler (:class:`ProcessExecutor`).

    Examples
    --------
    >>> from bayes_jackal.inference.executors import executor_for
    >>> executor = executor_for(processes=2)
    >>> type(executor).__name__, executor.processes
    ('ProcessExecutor', 2)
    >>> type(executor_for("tcp://127.0.0.1:8786")).__name__
    'DaskExecutor'
    """
    return ProcessExecutor(processes) if scheduler is None else DaskExecutor(scheduler)
