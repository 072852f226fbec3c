"""Clean stops on SIGINT and SIGTERM (stdlib only: the CLI installs it before any import).

:func:`install_interrupts` makes both signals raise :class:`Interrupted`, a
:class:`KeyboardInterrupt` that knows its signal and exit code, so every
``finally`` runs (a chain is flushed, finished results stay saved).
Third-party code with catch-all handlers must not see it raised in its
midst: emcee's ``except:`` around the log-probability prints the walkers on
stdout, and its ``random_state`` setter swallows the interrupt whole. Such
code runs inside :func:`interrupts_deferred`, where a signal only records a stop that
:func:`check_interrupt` raises between steps; a second signal raises at once.
A stop raised where Python cannot propagate it (a finaliser, a weakref
callback of the garbage collector, Cython) is sent again as soon as that
code has returned. Once a stop has been raised, the finaliser of an object
it cut short mid-construction fails quietly (h5netcdf's ``File`` stopped
in its ``__init__`` has no ``_closed`` to close by).

Worker processes call :func:`quiet_worker` first: they ignore SIGINT (the
terminal sends Ctrl-C to them too; the main process stops them) and die
without a word on SIGTERM.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator

__all__ = [
    "Interrupted",
    "check_interrupt",
    "hold_late_interrupts",
    "install_interrupts",
    "interrupt_cause",
    "interrupt_pending",
    "interrupts_blocked",
    "interrupts_deferred",
    "late_interrupt",
    "quiet_worker",
    "restore_interrupts",
]

#: The signals that stop a run.
SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """A run stopped by a signal.

    Attributes
    ----------
    signum : int
        The signal (SIGINT or SIGTERM).
    exit_code : int
        128 + signum: 130 for SIGINT, 143 for SIGTERM.

    Examples
    --------
    A :class:`KeyboardInterrupt` that carries the command's exit code:

    >>> import signal
    >>> from bayes_jackal._runtime.interrupt import Interrupted
    >>> stop = Interrupted(signal.SIGTERM)
    >>> print(stop, stop.exit_code, isinstance(stop, KeyboardInterrupt))
    SIGTERM 143 True
    """

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)
        self.exit_code = 128 + self.signum


_pending: int | None = None
_deferring = 0
_resent = False  # the next signal is a swallowed stop sent again, not a second one
_raised = False  # a stop was raised: what it cut short may fail in its finaliser


def _handler(signum: int, frame) -> None:
    global _pending, _resent
    first = _pending is None or _resent
    _pending, _resent = signum, False  # kept until check_interrupt() raises it
    if _deferring and first:
        return
    _stop(signum)


def _stop(signum: int) -> None:
    """Raise :class:`Interrupted`, noting that the run is stopping."""
    global _raised
    _raised = True
    raise Interrupted(signum)


def _unraisable(hook: sys.UnraisableHookArgs) -> None:
    """Drop an :class:`Interrupted` raised where Python cannot propagate it, and resend it.

    A signal landing in a finaliser, a weakref callback run by the garbage
    collector (matplotlib's figures hold many), or Cython code that cannot
    raise (scipy's Sobol set-up reads its tables so) raises there, and
    Python would print "Exception ignored" and carry on for as long as the
    command has left (6.7 s of report figures, in CI). The stop stays
    pending instead and :func:`_resend` delivers it again once the code
    that swallowed it has returned.

    Once a stop has been raised, any other exception here comes from the
    finaliser of an object the stop cut short (a file closed before it was
    opened): it is dropped, as the run's last line has said why it stopped.
    """
    if isinstance(hook.exc_value, Interrupted):
        _resend(hook.exc_value.signum)
    elif not _raised:
        _previous_hooks["unraisablehook"](hook)


def _excepthook(kind, value, traceback) -> None:
    """As :func:`_unraisable`, for Cython's print of such an exception's traceback."""
    if isinstance(value, Interrupted):
        _resend(value.signum)
    else:
        _previous_hooks["excepthook"](kind, value, traceback)


#: Seconds before a swallowed stop is sent again: the hook that saw it swallowed
#: must have returned, or the handler would raise inside the hook itself.
RESEND_DELAY = 0.01


def _resend(signum: int) -> None:
    """Signal the main thread again after :data:`RESEND_DELAY` s, unless it has been raised.

    A real signal (not ``_thread.interrupt_main``), so that it also wakes a
    main thread blocked in a system call.
    """

    def send() -> None:
        global _resent
        if _pending is not None:
            _resent = True
            signal.pthread_kill(threading.main_thread().ident, signum)

    timer = threading.Timer(RESEND_DELAY, send)
    timer.daemon = True
    timer.start()


#: sys hooks in place before :func:`install_interrupts`.
_previous_hooks = {"unraisablehook": sys.unraisablehook, "excepthook": sys.excepthook}


def interrupt_pending() -> int | None:
    """The signal of a stop that was requested and not yet raised by :func:`check_interrupt`.

    Examples
    --------
    A signal inside :func:`interrupts_deferred` is pending until :func:`check_interrupt` raises it
    (the handlers installed for the example, and put back after):

    >>> import signal
    >>> from bayes_jackal._runtime import interrupt
    >>> previous = interrupt.install_interrupts()
    >>> try:
    ...     with interrupt.interrupts_deferred():
    ...         print(interrupt.interrupt_pending())
    ...         signal.raise_signal(signal.SIGINT)
    ...         print(interrupt.interrupt_pending() == signal.SIGINT)
    ...         interrupt.check_interrupt()
    ... except interrupt.Interrupted as stop:
    ...     print(f"stopped by {stop}; pending: {interrupt.interrupt_pending()}")
    ... finally:
    ...     interrupt.restore_interrupts(previous)
    None
    True
    stopped by SIGINT; pending: None
    """
    return _pending


def install_interrupts() -> dict:
    """Make SIGINT and SIGTERM raise :class:`Interrupted`, ignore SIGXFSZ (main thread only).

    Returns
    -------
    dict
        The previous handlers by signal, and the previous
        ``sys.unraisablehook`` and ``sys.excepthook`` (see
        :func:`_unraisable`), for :func:`restore_interrupts`.

    Examples
    --------
    The CLI installs the handlers once; here they are put back at once:

    >>> import signal
    >>> from bayes_jackal._runtime import interrupt
    >>> previous = interrupt.install_interrupts()
    >>> signal.getsignal(signal.SIGTERM) is previous[signal.SIGTERM]
    False
    >>> signal.getsignal(signal.SIGXFSZ) == signal.SIG_IGN
    True
    >>> interrupt.restore_interrupts(previous)
    >>> signal.getsignal(signal.SIGTERM) is previous[signal.SIGTERM]
    True
    """
    global _pending, _raised
    _pending, _raised = None, False
    previous = {signum: signal.signal(signum, _handler) for signum in SIGNALS}
    # Beyond a file-size limit (ulimit -f) a write then fails with EFBIG, which
    # the writers report naming the file, instead of the signal killing the run.
    previous[signal.SIGXFSZ] = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    if sys.unraisablehook is not _unraisable:  # installed twice: keep the first's
        _previous_hooks.update(unraisablehook=sys.unraisablehook, excepthook=sys.excepthook)
    sys.unraisablehook, sys.excepthook = _unraisable, _excepthook
    return previous | _previous_hooks


def restore_interrupts(previous: dict) -> None:
    """Put back the handlers :func:`install_interrupts` returned, and forget any stop they caught.

    The command line checks for a held stop before it restores them, so none
    is lost; a stop already raised is not raised again by a later
    :func:`check_interrupt`.

    Examples
    --------
    >>> import signal
    >>> from bayes_jackal._runtime import interrupt
    >>> before = signal.getsignal(signal.SIGINT)
    >>> previous = interrupt.install_interrupts()
    >>> interrupt.restore_interrupts(previous)
    >>> signal.getsignal(signal.SIGINT) is before
    True
    """
    global _pending, _resent
    _pending, _resent = None, False  # a stop raised or held under them ends with them
    previous = dict(previous)
    sys.unraisablehook = previous.pop("unraisablehook", sys.unraisablehook)
    sys.excepthook = previous.pop("excepthook", sys.excepthook)
    for signum, handler in previous.items():
        signal.signal(signum, handler)


def interrupt_cause(exc: BaseException) -> Interrupted | None:
    """The stop behind ``exc``, where a signal was turned into another exception.

    A signal landing while a C extension initialises (scipy's HiGHS
    module, during the imports) comes out as its ``ImportError:
    initialization failed``, raised from the :class:`Interrupted`: the
    chain of causes and contexts says it was a stop, not a failure.

    Examples
    --------
    >>> import signal
    >>> from bayes_jackal._runtime.interrupt import Interrupted, interrupt_cause
    >>> try:
    ...     try:
    ...         raise Interrupted(signal.SIGINT)
    ...     except Interrupted as stop:
    ...         raise ImportError("initialization failed") from stop
    ... except ImportError as exc:
    ...     print(interrupt_cause(exc), interrupt_cause(ValueError("x")))
    SIGINT None
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, Interrupted):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def check_interrupt() -> None:
    """Raise the stop a signal recorded inside :func:`interrupts_deferred`, if any.

    Examples
    --------
    Nothing pending: nothing raised.

    >>> from bayes_jackal._runtime import interrupt
    >>> interrupt.check_interrupt()

    A long loop checks between steps; a signal landing in a step is raised at
    the next check (the handlers installed for the example, and put back after):

    >>> import signal
    >>> previous = interrupt.install_interrupts()
    >>> done = []
    >>> try:
    ...     for step in range(5):
    ...         with interrupt.interrupts_deferred():  # third-party code: not stopped midway
    ...             done.append(step)
    ...             if step == 2:
    ...                 signal.raise_signal(signal.SIGTERM)
    ...             interrupt.check_interrupt()
    ... except interrupt.Interrupted as stop:
    ...     print(f"{stop} after steps {done}: exit code {stop.exit_code}")
    ... finally:
    ...     interrupt.restore_interrupts(previous)
    SIGTERM after steps [0, 1, 2]: exit code 143
    """
    global _pending
    signum, _pending = _pending, None
    if signum is not None:
        _stop(signum)


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Hold a signal back as a pending stop while third-party code runs.

    Call :func:`check_interrupt` where stopping is safe; leaving the outermost block
    normally raises a stop still pending. A second signal raises at once.

    Examples
    --------
    The block runs on after a signal; leaving it raises the stop (the
    handlers installed for the example, and put back after):

    >>> import signal
    >>> from bayes_jackal._runtime import interrupt
    >>> previous = interrupt.install_interrupts()
    >>> try:
    ...     with interrupt.interrupts_deferred():
    ...         signal.raise_signal(signal.SIGINT)
    ...         print("the block finishes")
    ... except interrupt.Interrupted as stop:
    ...     print(f"then stops: exit code {stop.exit_code}")
    ... finally:
    ...     interrupt.restore_interrupts(previous)
    the block finishes
    then stops: exit code 130
    """
    global _deferring
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
    if not _deferring:
        check_interrupt()


_late: int | None = None


def _record_late(signum: int, frame) -> None:
    global _late
    _late = _late or signum


def hold_late_interrupts() -> None:
    """From the command's last line on, record SIGINT and SIGTERM instead of raising them.

    The interpreter's shutdown (its exit functions, the modules' teardown)
    runs after the command has written everything; a signal raised there
    would print a traceback, and one ignored would let a stopped process
    exit 0. :func:`late_interrupt` says which arrived, for the exit code.
    """
    for signum in SIGNALS:
        signal.signal(signum, _record_late)


def late_interrupt() -> int | None:
    """The signal recorded since :func:`hold_late_interrupts`, if any."""
    return _late


def quiet_worker() -> None:
    """Initializer of worker processes: ignore SIGINT, die quietly on SIGTERM.

    Examples
    --------
    A worker pool's initializer, e.g. of :class:`concurrent.futures.ProcessPoolExecutor`:

    >>> import concurrent.futures
    >>> import multiprocessing
    >>> from bayes_jackal._runtime.interrupt import quiet_worker
    >>> context = multiprocessing.get_context("spawn")
    >>> with concurrent.futures.ProcessPoolExecutor(
    ...     1, mp_context=context, initializer=quiet_worker
    ... ) as pool:
    ...     print(pool.submit(sum, [1, 2, 3]).result())
    6
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)


@contextlib.contextmanager
def interrupts_blocked() -> Iterator[None]:
    """Block SIGINT and SIGTERM while starting worker processes.

    The children inherit the mask, so a signal during their start-up waits
    until :func:`quiet_worker` has set their handlers; here it is delivered
    when the block ends.

    Examples
    --------
    SIGINT and SIGTERM wait while the block runs, e.g. while workers start:

    >>> import signal
    >>> from bayes_jackal._runtime.interrupt import interrupts_blocked
    >>> with interrupts_blocked():
    ...     print(signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, []))
    True
    >>> signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])
    False
    """
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
