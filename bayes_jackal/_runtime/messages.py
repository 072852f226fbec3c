"""The package's messages: the ``bayes_jackal`` logger tree, and the lines the CLI prints.

Every stage tells what it does through :mod:`logging`, on the logger of its
subpackage (``bayes_jackal.inference``, ``bayes_jackal.workflow`` ...), at
``INFO`` ("sampling v1_01 on channels yaw -> fits/v1_01.nc", "reusing white
from ..."). A library user routes, silences or captures them as any other
library's; by default (no handler configured) nothing is printed, as Python's
last-resort handler shows warnings and errors only. The command line prints
them with :func:`printed`, one line each above any progress bar, on stdout
(on stderr with ``--json``, whose stdout carries the JSON). A step whose
lines would drown the others' runs :func:`silenced` (each of the families'
chains, which run at once). Warnings about the data or the fit stay Python
warnings (``warnings.warn``), which the CLI shows as ``bayes-jackal:
WARNING:`` lines.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import sys
from collections.abc import Iterator

from .progress import write_line

__all__ = ["ROOT_LOGGER", "LineHandler", "printed", "silenced"]

#: The root of the package's logger tree.
ROOT_LOGGER = "bayes_jackal"

#: The loggers silenced in this thread or task (:func:`silenced`).
_SILENCED: contextvars.ContextVar[frozenset[str]] = contextvars.ContextVar(
    "bayes_jackal_silenced", default=frozenset()
)


class LineHandler(logging.Handler):
    """Each record's message as one line on ``sys.stdout`` or ``sys.stderr``.

    Written with :func:`~bayes_jackal._runtime.progress.write_line`, above a
    progress bar that may be drawn: the message as it is (the CLI's lines),
    whatever formatter is set.

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


@contextlib.contextmanager
def printed(stream: str) -> Iterator[None]:
    """While the block runs, the package's ``INFO`` messages are lines on ``stream``.

    Only there: the ``bayes_jackal`` logger does not propagate them to a
    root handler meanwhile (each line would be printed twice). Its level and
    propagation are restored afterwards.

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
    handler, saved = LineHandler(stream), (logger.level, logger.propagate)
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]


class _Silence(logging.Filter):
    """Drops a logger's records below WARNING in a thread or task that silenced it."""

    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno >= logging.WARNING or record.name not in _SILENCED.get()


_SILENCE = _Silence()


@contextlib.contextmanager
def silenced(name: str) -> Iterator[None]:
    """While the block runs, in this thread or task only, logger ``name`` tells no ``INFO``.

    Warnings and errors still pass. Other threads (a threaded executor's
    other jobs) and the logger's children are not affected.

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
    if _SILENCE not in logger.filters:
        logger.addFilter(_SILENCE)
    token = _SILENCED.set(_SILENCED.get() | {name})
    try:
        yield
    finally:
        _SILENCED.reset(token)
