"""The ``bayes-jackal`` command line: a thin layer over the library.

Commands, flags, JSON keys and exit codes follow docs/design.md §6. Exit codes:
0 success, 2 bad input (the message names file, field and value), 1 any
other failure; no traceback reaches the user (unless ``--debug``). A Python
warning that reaches the top is one ``bayes-jackal: WARNING:`` line. The
parser lives in :mod:`.parser`, the commands in :mod:`.commands`, what they
print in :mod:`.output`.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import importlib
import os
import signal
import sys
import warnings
from collections.abc import Iterator

__all__ = ["build_parser", "console", "main"]

#: The module of each command not in :mod:`.commands`.
_MODULES = {"noise": ".noise_command"}


def __getattr__(name: str):
    """``build_parser`` on first use: importing this package loads only the stdlib."""
    if name == "build_parser":
        from .parser import build_parser

        return build_parser
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def console(argv: list[str] | None = None) -> None:
    """The ``bayes-jackal`` console script: :func:`main`, then the process exits.

    A signal after the command's last line would meet Python's own handler
    during the interpreter's shutdown and print a traceback: from then on
    SIGINT and SIGTERM are recorded instead (:func:`.interrupt.hold_late_interrupts`),
    and the last of the exit functions ends the process with 128 + the
    signal, having said that everything was written.
    """
    atexit.register(_exit_if_stopped)  # registered first: run after every other
    sys.exit(main(argv, _exiting=True))


def _exit_if_stopped() -> None:
    """Exit with 128 + a signal that arrived as the command exited (after its last line)."""
    from .._runtime import late_interrupt

    signum = late_interrupt()
    if signum is None:
        return
    print(
        f"bayes-jackal: interrupted by {signal.Signals(signum).name} as it exited, after "
        "everything it was to write had been written",
        file=sys.stderr,
    )
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(128 + signum)


def main(argv: list[str] | None = None, *, _exiting: bool = False) -> int:
    """Run ``bayes-jackal``; return the exit code.

    The signal handlers come first, then the imports: SIGINT or SIGTERM at
    any moment prints one line and exits 130 or 143
    (:mod:`bayes_jackal._runtime.interrupt`). The previous handlers are restored on
    return (``_exiting``, for :func:`console`: later signals are recorded, for the exit code).
    """
    from .._runtime import (
        Interrupted,
        check_interrupt,
        hold_late_interrupts,
        install_interrupts,
        interrupt_cause,
        restore_interrupts,
    )

    previous = install_interrupts()
    try:
        code = _run(argv)
        check_interrupt()  # a stop that landed where it could not be raised
        return code
    except Interrupted as exc:
        return _interrupted(exc)
    except KeyboardInterrupt:
        print("bayes-jackal: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a stop another exception carries (an extension's import)
        stop = interrupt_cause(exc)
        if stop is None:
            raise
        return _interrupted(stop)
    finally:
        restore_interrupts(previous)
        if _exiting:
            hold_late_interrupts()


def _interrupted(stop: BaseException) -> int:
    """Say the run was stopped by a signal; its exit code (128 + the signal)."""
    print(
        f"bayes-jackal: interrupted by {stop}; what had finished is kept, "
        "and the same command resumes",
        file=sys.stderr,
    )
    gc.freeze()  # the exit's collection of every object loaded would take ~1 s more
    return stop.exit_code


def _run(argv: list[str] | None) -> int:
    """Parse and dispatch; map exceptions to exit codes."""
    if (sys.argv[1:] if argv is None else argv) == ["--version"]:  # without the imports
        from .. import __version__

        print(f"bayes-jackal {__version__}")
        return 0
    from .._runtime import check_interrupt, interrupt_cause
    from .exits import EXIT_BAD_INPUT, print_failure
    from .parser import build_parser

    try:  # the parser loads no numpy: --help answers at once
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # usage errors (2) and --help/--version (0)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    from .._runtime import InputError
    from .paths import command_inputs, guarded

    try:
        # Warnings on stderr; outputs checked (before the imports: a refused
        # output costs no wait), inputs protected, main output locked.
        with _warnings_shown(debug=args.debug), guarded(args):
            # The command's module and its imports, numpy and the rest.
            commands = importlib.import_module(_MODULES.get(args.command, ".commands"), __name__)
            from .._runtime import one_blas_thread, printed

            check_interrupt()  # a signal swallowed during the imports (code that cannot raise)
            command = getattr(commands, f"cmd_{args.command.replace('-', '_')}")
            # One BLAS thread for the package's small linear algebra (_runtime.threads);
            # the package's messages are lines on stdout (on stderr beside --json).
            stream = "stderr" if getattr(args, "json", False) else "stdout"
            with one_blas_thread(), printed(stream):
                return command(args)
    except InputError as exc:  # names its file, field and value
        return print_failure(exc, debug=args.debug)
    except Exception as exc:  # one line naming the input (exit 1); --debug: the traceback
        if (stop := interrupt_cause(exc)) is not None:
            raise stop from None  # a signal an extension's import turned into its error
        source = getattr(exc, "input_source", None) or ", ".join(command_inputs(args))
        return print_failure(exc, source, debug=args.debug)


@contextlib.contextmanager
def _warnings_shown(*, debug: bool) -> Iterator[None]:
    """Each Python warning that reaches the top as one line on stderr, in the CLI's style.

    ``bayes-jackal: WARNING: message``, as the convergence and criticism
    warnings (:func:`.output.print_criticism`); with ``--debug``, followed by
    its category and where it was raised. A message already shown is not
    shown again. Python's filters still decide which warnings are shown
    (``-W``, ``PYTHONWARNINGS``).
    """
    shown: set[tuple[type[Warning], str]] = set()

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        if (category, str(message)) in shown:
            return
        shown.add((category, str(message)))
        from .._runtime import write_line  # tqdm: imported once a warning shows

        where = f" ({category.__name__} at {filename}:{lineno})" if debug else ""
        write_line(f"bayes-jackal: WARNING: {message}{where}", sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


if __name__ == "__main__":
    console()
