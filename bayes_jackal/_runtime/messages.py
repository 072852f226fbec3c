"""The package's messages: the ``bayes_jackal`` logger tree, and the lines the CLI prints.

Every stage tells what it does through :mod:`logging`, on the logger of its
subpackage (``bayes_jackal.inference``, ``bayes_jackal.workflow`` ...), at
``INFO`` ("sampling v1_01 on channels yaw -> fits/v1_01.nc", "reusing white
from ...") . A library user routes, silences or captures them as any other
library's; by default (no handler configured) nothing is printed, as Python's
last-resort handler shows warnings and errors only. The command line prints
them with :func:`printed`, one line each above any progress bar, on stdout
(on stderr with ``--json``, whose stdout carries the JSON). Worker processes
print with the same handlers (:func:`worker_handlers`, :func:`install_handlers`).
Warnings about the data or the fit stay Python warnings (``warnings.warn``),
which the CLI shows as ``bayes-jackal: WARNING:`` lines.
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Iterable, Iterator

from .progress import write_line

__all__ = [
    "ROOT_LOGGER",
    "LineHandler",
    "install_handlers",
    "printed",
    "silenced",
    "worker_handlers",
]

#: The root of the package's logger tree.
ROOT_LOGGER = "bayes_jackal"


class LineHandler(logging.Handler):
    """Each record's message as one line on ``sys.stdout`` or ``sys.stderr``.

    Written with :func:`~bayes_jackal._runtime.progress.write_line`, above a
    progress bar that may be drawn. Pickled by the stream's name, so that a
    worker process writes to its own (inherited) stream.

    Parameters
    ----------
    stream : {"stdout", "stderr"}
        The ``sys`` attribute written to, looked up at each record.

    Examples
    --------
    >>> import logging
    >>> log = logging.getLogger("bayes_jackal.example")
    >>> handler = LineHandler("stdout")
    >>> log.addHandler(handler); log.setLevel(logging.INFO)
    >>> log.info("sampling v1_01 on channels yaw")
    sampling v1_01 on channels yaw
    >>> log.removeHandler(handler)
    """

    def __init__(self, stream: str = "stdout"):
        if stream not in ("stdout", "stderr"):
            raise ValueError(f"stream: {stream!r} is neither 'stdout' nor 'stderr'")
        super().__init__(logging.INFO)
        self.stream = stream

    def emit(self, record: logging.LogRecord) -> None:
        # A closed stdout (``| head``) stops the command as a print would:
        # the error is not swallowed, as logging's own handlers swallow it.
        write_line(record.getMessage(), getattr(sys, self.stream))

    def __reduce__(self):
        return LineHandler, (self.stream,)


def install_handlers(handlers: Iterable[logging.Handler]) -> list[logging.Handler]:
    """Print the package's ``INFO`` messages with ``handlers`` (and nowhere else).

    Returns the handlers, added to the ``bayes_jackal`` logger at level
    ``INFO``. In a worker process they stay until it exits; :func:`printed`
    removes its own and restores the logger's level.

    Examples
    --------
    >>> handlers = install_handlers(worker_handlers())  # a worker: the parent's
    """
    logger = logging.getLogger(ROOT_LOGGER)
    handlers = list(handlers)
    for handler in handlers:
        logger.addHandler(handler)
    if handlers:
        logger.setLevel(logging.INFO)
        logger.propagate = False  # a root handler would print each line twice
    return handlers


@contextlib.contextmanager
def printed(stream: str) -> Iterator[None]:
    """While the block runs, the package's ``INFO`` messages are lines on ``stream``.

    Parameters
    ----------
    stream : {"stdout", "stderr"}
        Where the lines go (the CLI: stderr with ``--json``).

    Examples
    --------
    >>> import logging
    >>> with printed("stdout"):
    ...     logging.getLogger("bayes_jackal.workflow").info("writing the report")
    writing the report
    >>> logging.getLogger("bayes_jackal.workflow").info("not shown")
    """
    logger = logging.getLogger(ROOT_LOGGER)
    saved = logger.level, logger.propagate
    (handler,) = install_handlers([LineHandler(stream)])
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]


def worker_handlers() -> list[LineHandler]:
    """The :class:`LineHandler` s printing the package's messages here (for workers)."""
    return [h for h in logging.getLogger(ROOT_LOGGER).handlers if isinstance(h, LineHandler)]


@contextlib.contextmanager
def silenced(name: str) -> Iterator[None]:
    """While the block runs, logger ``name`` tells warnings and errors only.

    For a step whose lines would drown the others' (the start search of
    each of the families' chains, which run at once).

    Examples
    --------
    >>> import logging
    >>> with printed("stdout"):
    ...     with silenced("bayes_jackal.inference"):
    ...         logging.getLogger("bayes_jackal.inference").info("MAP search: ...")
    ...     logging.getLogger("bayes_jackal.inference").info("shown")
    shown
    """
    logger = logging.getLogger(name)
    level = logger.level
    logger.setLevel(logging.WARNING)
    try:
        yield
    finally:
        logger.setLevel(level)
