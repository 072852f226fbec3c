"""Exceptions raised for bad input.

Every error about user input names where the problem is (file, field, row)
and the offending value, so that the command line can print it as is and
exit with status 2. :class:`OutputError` is the one that is not about input:
an output that could not be written (exit status 1). :func:`each_input`
runs a piece of work on each of several inputs so that a bad one does not
stop the others; :func:`refuse` names every bad one at once.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")

__all__ = [
    "DataError",
    "InputError",
    "OutputError",
    "ProfileError",
    "describe",
    "each_input",
    "refuse",
]


class InputError(ValueError):
    """Bad user input: a file, a field in it, or a parameter value.

    Parameters
    ----------
    message : str
        What is wrong, including the offending value.
    source : str, optional
        The file (or other origin) the bad input came from.
    field : str, optional
        The column, key or parameter name.

    Examples
    --------
    The message starts with the file and the field; it is a ``ValueError``:

    >>> from bayes_jackal._runtime.errors import InputError
    >>> try:
    ...     raise InputError("must be > 0, got -72", source="run.csv", field="rate")
    ... except ValueError as exc:
    ...     print(exc)
    run.csv: rate: must be > 0, got -72
    """

    def __init__(self, message: str, *, source: str | None = None, field: str | None = None):
        self.source = source
        self.field = field
        where = ": ".join(part for part in (source, field) if part)
        super().__init__(f"{where}: {message}" if where else message)


class ProfileError(InputError):
    """A robot profile is missing a constant or holds a non-physical one.

    Examples
    --------
    >>> from bayes_jackal._runtime.errors import InputError, ProfileError
    >>> try:
    ...     raise ProfileError("must be > 0, got -17", source="jackal.toml", field="mass")
    ... except InputError as exc:
    ...     print(exc, isinstance(exc, ValueError))
    jackal.toml: mass: must be > 0, got -17 True
    """


class DataError(InputError):
    """An experiment file (CSV, NetCDF, bag) cannot be used as it is.

    Examples
    --------
    >>> from bayes_jackal._runtime.errors import DataError
    >>> try:
    ...     raise DataError("non-finite value nan in row 12", source="run.csv", field="yaw_rate")
    ... except ValueError as exc:
    ...     print(exc)
    run.csv: yaw_rate: non-finite value nan in row 12
    """


class OutputError(OSError):
    """An output could not be written: a full disk, a file-size limit, no permission.

    The message names the user's path (never a hidden temporary) and the
    reason, e.g. ``p.nc: cannot write: no space left on device``.

    Parameters
    ----------
    path : str or Path
        The output the user asked for.
    reason : str
        Why it cannot be written, in words.
    code : int, optional
        The ``errno`` of the failure (``errno.ENOSPC``, ``errno.EFBIG``...).

    Examples
    --------
    An ``OSError`` whose message names the user's path:

    >>> import errno
    >>> from bayes_jackal._runtime.errors import OutputError
    >>> try:
    ...     raise OutputError("posterior.nc", "no space left on device", code=errno.ENOSPC)
    ... except OSError as exc:
    ...     print(exc, exc.errno == errno.ENOSPC)
    posterior.nc: cannot write: no space left on device True
    """

    def __init__(self, path, reason: str, *, code: int | None = None):
        super().__init__(code, reason, str(path))

    def __str__(self) -> str:
        return f"{self.filename}: cannot write: {self.strerror}"

    @classmethod
    def from_os_error(cls, path, error: OSError, *, advice: str = "") -> OutputError:
        """The OutputError of a failed system call while writing ``path``."""
        reason = os.strerror(error.errno).lower() if error.errno else str(error)
        return cls(path, f"{reason}{advice}", code=error.errno)


def describe(exc: Exception, source: str | None = None) -> str:
    """One line on what went wrong, naming the input ``source`` when it is known.

    An :class:`InputError` names its file already (``source`` is put in front
    when it does not), an :class:`OutputError` the output it could not write;
    any other exception reads ``Type: message (source)``.

    Examples
    --------
    >>> from bayes_jackal._runtime.errors import DataError, describe
    >>> describe(DataError("too few samples", field="t"), "run.csv")
    'run.csv: t: too few samples'
    >>> describe(KeyError("yaw_rate"), "run.mat")
    "KeyError: 'yaw_rate' (run.mat)"
    """
    if isinstance(exc, InputError):
        return f"{source}: {exc}" if source and not exc.source else str(exc)
    if isinstance(exc, OutputError):  # names the output it could not write
        return str(exc)
    what = " ".join(f"{type(exc).__name__}: {exc}".split()).removesuffix(":")
    return f"{what} ({source})" if source else what


def each_input(
    inputs: Iterable[T],
    work: Callable[[T], R],
    *,
    catch: type[Exception] | tuple[type[Exception], ...] = InputError,
    on_failure: Callable[[str, Exception], None] | None = None,
) -> tuple[dict[str, R], dict[str, str]]:
    """Run ``work`` on every input on its own: one that fails does not stop the others.

    Parameters
    ----------
    inputs : iterable
        The inputs, e.g. file paths as the user gave them.
    work : callable
        ``work(input)``: the result of one input.
    catch : exception type or tuple of them
        Failures recorded against their input (default: bad input). Any other
        exception propagates with the input in its ``input_source`` attribute.
    on_failure : callable, optional
        ``on_failure(input, exception)``, called as each input fails.

    Returns
    -------
    results : dict
        ``str(input)`` -> its result, in the order given.
    failed : dict of str to str
        ``str(input)`` -> why it failed (:func:`describe`: the reason names it);
        an input given twice fails the second time.

    Examples
    --------
    A bad input is recorded with its reason; the others are done:

    >>> from bayes_jackal._runtime.errors import InputError, each_input
    >>> def inverse(text):
    ...     if float(text) == 0:
    ...         raise InputError("cannot invert 0", field="value")
    ...     return 1 / float(text)
    >>> results, failed = each_input(["2", "0", "4"], inverse)
    >>> results
    {'2': 0.5, '4': 0.25}
    >>> failed
    {'0': '0: value: cannot invert 0'}
    """
    results: dict[str, R] = {}
    failed: dict[str, str] = {}
    for given in inputs:
        key = str(given)
        try:
            if key in results or key in failed:
                raise DataError("given more than once", source=key)
            results[key] = work(given)
        except catch as exc:
            failed.setdefault(key, describe(exc, key))
            if on_failure is not None:
                on_failure(key, exc)
        except Exception as exc:
            if getattr(exc, "input_source", None) is None:
                exc.input_source = key
            raise
    return results, failed


def refuse(failed: Mapping[str, str], total: int) -> None:
    """Raise one :class:`DataError` naming every input that failed; nothing when none did.

    Parameters
    ----------
    failed : mapping of str to str
        Input -> reason, as :func:`each_input` returns.
    total : int
        How many inputs there were.

    Examples
    --------
    >>> from bayes_jackal._runtime.errors import DataError, refuse
    >>> refuse({}, 3)  # nothing failed: nothing raised
    >>> try:
    ...     refuse({"b.csv": "b.csv: t: too few samples"}, 3)
    ... except DataError as exc:
    ...     print(exc)
    1 of 3 inputs cannot be used: b.csv: t: too few samples
    """
    if len(failed) == 1 and total == 1:
        raise DataError(next(iter(failed.values())))
    if failed:
        raise DataError(
            f"{len(failed)} of {total} inputs cannot be used: " + "; ".join(failed.values())
        )
