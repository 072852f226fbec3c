"""Checks of values a user gives: each failure an :class:`InputError` naming the field."""

from __future__ import annotations

import numpy as np

from .errors import InputError

__all__ = ["positive_number"]


def positive_number(
    value: float | None, *, name: str, unit: str, required: bool = False, what: str = ""
) -> float | None:
    """An option that must be a finite number > 0, as a float; None when not given.

    Parameters
    ----------
    value : float or None
        The option's value [``unit``]; None: not given (refused if ``required``);
        a bool is refused (True is not 1).
    name, unit : str
        The option and its unit, named in the InputError that refuses a value.
    what : str
        What the option is, said first in the error (``"the sample time"``).

    Returns
    -------
    float or None

    Examples
    --------
    >>> from bayes_jackal._runtime.validation import positive_number
    >>> positive_number("100", name="rate", unit="Hz")
    100.0
    >>> for bad in (0.0, True):
    ...     try:
    ...         positive_number(bad, name="dt", unit="s")
    ...     except ValueError as exc:
    ...         print(exc)
    dt: must be a positive number of s, got 0.0
    dt: must be a positive number of s, got True
    """
    if value is None and not required:
        return None
    try:
        number = np.nan if isinstance(value, bool | np.bool_) else float(value)
    except (TypeError, ValueError):
        number = np.nan
    if not (np.isfinite(number) and number > 0):
        said = f"{what} must" if what else "must"
        raise InputError(f"{said} be a positive number of {unit}, got {value!r}", field=name)
    return number
