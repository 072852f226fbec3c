"""The ``bayes-jackal`` command line: a thin layer over the library.

Commands, flags, JSON keys and exit codes follow docs/design.md §6. Exit codes:
0 success, 2 bad input (the message names file, field and value), 1 any
other failure; no traceback reaches the user. The parser lives in
:mod:`.parser`, the commands in :mod:`.commands`, what they print in
:mod:`.output`.
"""

from __future__ import annotations

import sys

from ..errors import InputError
from .output import EXIT_BAD_INPUT, EXIT_FAILURE
from .parser import build_parser

__all__ = ["build_parser", "main"]


def main(argv: list[str] | None = None) -> int:
    """Run ``bayes-jackal``; return the exit code."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # usage errors (2) and --help/--version (0)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        return args.func(args)
    except InputError as exc:
        print(f"bayes-jackal: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("bayes-jackal: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        print(f"bayes-jackal: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
