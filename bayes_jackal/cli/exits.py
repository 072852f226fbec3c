"""The command line's exit codes and its one-line failure message (the stdlib only).

Light, so that ``bayes-jackal`` can refuse an output before it loads numpy
and the rest (:func:`bayes_jackal.cli.main`).
"""

from __future__ import annotations

import sys
import traceback

from .._runtime import InputError, describe

__all__ = ["EXIT_BAD_INPUT", "EXIT_FAILURE", "EXIT_OK", "print_failure"]

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2


def print_failure(exc: Exception, source: str | None = None, *, debug: bool = False) -> int:
    """One line on stderr naming ``source`` (with ``--debug``, the traceback first); the exit code.

    Bad input (:class:`~bayes_jackal._runtime.errors.InputError`) reads ``bayes-jackal:
    error: ...`` and gives 2; any other exception ``bayes-jackal: failed: Type:
    message (source)`` and 1.
    """
    if debug:
        traceback.print_exception(exc, file=sys.stderr)
    bad = isinstance(exc, InputError)
    kind = "error" if bad else "failed"
    print(f"bayes-jackal: {kind}: {describe(exc, source)}", file=sys.stderr)
    return EXIT_BAD_INPUT if bad else EXIT_FAILURE
