"""Progress of long loops on stderr: a bar on a terminal, plain lines in a log.

tqdm redraws its bar with carriage returns and ANSI cursor moves, which a
log file (CI, ``nohup``, a cluster's batch output) keeps as garbage. Where
the stream is a terminal, :class:`Progress` shows tqdm's bar; elsewhere it
prints a plain line every :data:`LOG_INTERVAL` seconds, e.g.
``gaussian: 1200/~1800 steps (cap 20000), tau ~ 35, 40 s, ~ 20 s left``,
and one when the loop ends. Where the loop can tell how many items it will
need (a chain, from its autocorrelation time), :meth:`Progress.expect`
makes that the bar's total and the base of the time left.
Every progress display of the package (emcee sampling, bag ingest, compare's
families in parallel processes) goes through it. A step that cannot count
its items (the search for a chain's start, a grid search, a report's
figures) is a :class:`Phase`: on a terminal a line whose clock ticks every
second, elsewhere one line when it starts. Lines written while a bar or a
phase is shown go through :func:`write_line`, which keeps them apart.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterable, Iterator
from typing import TextIO, TypeVar

from tqdm import tqdm

__all__ = ["LOG_INTERVAL", "Phase", "Progress", "write_line"]

#: Seconds between the plain lines written where the stream is not a terminal.
LOG_INTERVAL = 10.0

#: Seconds between the redraws of a :class:`Phase`'s clock on a terminal.
TICK = 1.0

T = TypeVar("T")


def _is_terminal(stream: TextIO) -> bool:
    return getattr(stream, "isatty", lambda: False)()


def write_line(text: str, stream: TextIO) -> None:
    """Write ``text`` and a newline to ``stream``, clearing and redrawing any bar shown.

    A bar or :class:`Phase` line is drawn without a newline; a line printed
    plainly would be glued to its end. This is :func:`tqdm.tqdm.write`,
    which is a plain write where nothing is shown (a log file).
    """
    tqdm.write(text, file=stream)


class Progress:
    """Count a loop's items and show it: tqdm on a terminal, periodic lines otherwise.

    Parameters
    ----------
    total : int
        Items expected (the count may stop short, e.g. a converged chain).
    label : str
        What is counted, starting each line (e.g. a family or a file name).
    unit : str
        Name of the items (``steps``, ``msg``).
    enabled : bool
        Show nothing when False.
    position : int
        tqdm's line on the terminal (one per process running at once).
    initial : int
        Items already done (a resumed chain).
    stream : file, optional
        Where to write (default: ``sys.stderr`` at construction).
    interval : float, optional
        Seconds between plain lines (default :data:`LOG_INTERVAL`).

    Examples
    --------
    Where the stream is not a terminal (here a string buffer, like a log
    file), a plain line every ``interval`` seconds and one at the end; with
    ``interval=0`` every update writes one:

    >>> import io
    >>> from bayes_jackal._runtime.progress import Progress
    >>> log = io.StringIO()
    >>> with Progress(3, "white", stream=log, interval=0) as progress:
    ...     for step in range(3):
    ...         progress.update(tau="35")
    >>> print(log.getvalue().rstrip())
    white: 1/3 steps, tau ~ 35, 0 s
    white: 2/3 steps, tau ~ 35, 0 s
    white: 3/3 steps, tau ~ 35, 0 s
    white: 3/3 steps, tau ~ 35, 0 s, done

    Once the loop knows how many items it will need, the lines say so and
    how long that will take at the rate so far:

    >>> log = io.StringIO()
    >>> with Progress(20000, "gaussian", stream=log, interval=0) as progress:
    ...     progress.expect(1800)
    ...     progress.update(1200, tau="35")
    >>> first = log.getvalue().splitlines()[0]
    >>> print(first.rsplit(", ", 2)[0]), first.endswith(" s left")
    gaussian: 1200/~1800 steps (cap 20000), tau ~ 35
    (None, True)

    :meth:`wrap` counts the items of a loop; the default interval (10 s)
    leaves only the last line here:

    >>> log = io.StringIO()
    >>> total = sum(Progress(4, "run.bag", unit="msg", stream=log).wrap([1, 2, 3, 4]))
    >>> print(total, log.getvalue().strip())
    10 run.bag: 4/4 msg, 0 s, done
    """

    def __init__(
        self,
        total: int,
        label: str,
        *,
        unit: str = "steps",
        enabled: bool = True,
        position: int = 0,
        initial: int = 0,
        stream: TextIO | None = None,
        interval: float | None = None,
    ):
        self.total, self.label, self.unit = total, label.strip(), unit
        self.stream = sys.stderr if stream is None else stream
        self.interval = LOG_INTERVAL if interval is None else interval
        self.count = self.initial = initial
        self.expected: int | None = None
        self.status: dict[str, str] = {}
        self.enabled = enabled
        self.start = self.last = time.monotonic()
        is_terminal = enabled and _is_terminal(self.stream)
        self.bar = (
            tqdm(
                total=total,
                desc=label,
                unit=unit,
                position=position,
                initial=initial,
                mininterval=1.0,
                file=self.stream,
            )
            if is_terminal
            else None
        )

    def update(self, n: int = 1, **status: str) -> None:
        """Count ``n`` more items; ``status`` (e.g. ``tau="35"``) joins the shown text."""
        if not self.enabled:
            return
        self.count += n
        self.status.update(status)
        if self.bar is not None:
            self.bar.update(n)
            if status:
                self.bar.set_postfix(self.status, refresh=False)
            return
        now = time.monotonic()
        if now - self.last >= self.interval:
            self.last = now
            self._line()

    def expect(self, expected: int) -> None:
        """The loop now expects to end after ``expected`` items (at most ``total``).

        The lines show ``count/~expected (cap total)`` and the time left at
        the rate so far; a bar takes ``expected`` as its total.
        """
        if not self.enabled:
            return
        self.expected = min(int(expected), self.total)
        if self.bar is not None:
            self.bar.total = self.expected
            self.bar.refresh()

    def _line(self, end: str = "") -> None:
        extra = "".join(f", {key} ~ {value}" for key, value in self.status.items())
        elapsed = time.monotonic() - self.start
        of = f"{self.total} {self.unit}"  # the closing line: the count against the cap
        if not end and self.expected is not None and self.expected < self.total:
            of = f"~{self.expected} {self.unit} (cap {self.total})"
        left = "" if end else self._time_left(elapsed)
        self.stream.write(f"{self.label}: {self.count}/{of}{extra}, {elapsed:.0f} s{left}{end}\n")
        self.stream.flush()

    def _time_left(self, elapsed: float) -> str:
        """``, ~ N s left`` at the rate so far, once an end is expected."""
        done = self.count - self.initial
        if self.expected is None or done <= 0 or self.expected <= self.count:
            return ""
        return f", ~ {(self.expected - self.count) * elapsed / done:.0f} s left"

    def close(self, outcome: str = "done") -> None:
        """End the display: close the bar, or write the last plain line ending in ``outcome``."""
        if not self.enabled:
            return
        if self.bar is not None:
            if outcome == "done":  # converged before the expected end: the bar ends full
                self.bar.total = self.bar.n
            self.bar.close()
        else:
            self._line(f", {outcome}")
        self.enabled = False

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        self.close("done" if kind is None else "stopped")

    def wrap(self, items: Iterable[T]) -> Iterator[T]:
        """Yield ``items``, counting each; close when they run out, or as stopped on an error."""
        outcome = "stopped"
        try:
            for item in items:
                yield item
                self.update()
            outcome = "done"
        finally:
            self.close(outcome)


class Phase:
    """A step of unknown length, shown while it runs: a ticking line on a terminal.

    On a terminal, ``label`` and the seconds elapsed are redrawn every
    :data:`TICK` seconds from a background thread (the step itself need not
    report anything) and the line is removed when the step ends; elsewhere
    (a log file) ``label`` is written once, as it starts, ending in ``...``.

    Parameters
    ----------
    label : str
        What the step does, e.g. ``gaussian: finding the chain's start``.
    enabled : bool
        Show nothing when False.
    position : int
        The terminal line (that of the chain's bar, with jobs in parallel).
    stream : file, optional
        Where to write (default: ``sys.stderr`` at construction).
    terminal_only : bool
        Write nothing where the stream is not a terminal (the caller says
        in its own line that the step started).

    Examples
    --------
    In a log (here a string buffer), one line as the step starts:

    >>> import io
    >>> from bayes_jackal._runtime.progress import Phase
    >>> log = io.StringIO()
    >>> with Phase("simulation MSE grid (64 x 64 points)", stream=log):
    ...     total = sum(range(1000))
    >>> print(log.getvalue().strip())
    simulation MSE grid (64 x 64 points)...
    """

    def __init__(
        self,
        label: str,
        *,
        enabled: bool = True,
        position: int = 0,
        stream: TextIO | None = None,
        terminal_only: bool = False,
    ):
        self.label, self.enabled, self.position = label, enabled, position
        self.stream = sys.stderr if stream is None else stream
        self.terminal_only = terminal_only
        self.bar: tqdm | None = None
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None

    def __enter__(self) -> Phase:
        if not self.enabled:
            return self
        if not _is_terminal(self.stream):
            if not self.terminal_only:
                self.stream.write(f"{self.label}...\n")
                self.stream.flush()
            return self
        self.bar = tqdm(
            total=None,
            desc=self.label,
            bar_format="{desc}: {elapsed}",
            position=self.position,
            leave=False,
            file=self.stream,
        )
        self._ticker = threading.Thread(target=self._tick, name="phase-clock", daemon=True)
        self._ticker.start()
        return self

    def _tick(self) -> None:
        while not self._stop.wait(TICK):
            self.bar.refresh()

    def __exit__(self, kind, value, traceback) -> None:
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        if self.bar is not None:
            self.bar.close()
