"""Exceptions raised for bad input.

Every error about user input names where the problem is (file, field, row)
and the offending value, so that the command line can print it as is and
exit with status 2.
"""

from __future__ import annotations


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
    """

    def __init__(self, message: str, *, source: str | None = None, field: str | None = None):
        self.source = source
        self.field = field
        where = ": ".join(part for part in (source, field) if part)
        super().__init__(f"{where}: {message}" if where else message)


class ProfileError(InputError):
    """A robot profile is missing a constant or holds a non-physical one."""


class DataError(InputError):
    """An experiment file (CSV, NetCDF, bag) cannot be used as it is."""
