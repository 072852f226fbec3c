"""MATLAB ``.mat`` files as named numeric arrays (v5/v7 via scipy.io, v7.3 via h5py).

The container only; :func:`bayes_jackal.io.read_mat` maps the arrays to an Experiment.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import scipy.io

from .._runtime import DataError, require_file

__all__ = ["mat_arrays", "mat_vector"]

#: What scipy.io and h5py raise on files they cannot read.
_MAT_ERRORS = (
    OSError,
    ValueError,
    TypeError,
    KeyError,
    NotImplementedError,
    scipy.io.matlab.MatReadError,
)
#: MATLAB classes of numeric arrays in v7.3 files.
_MAT_NUMERIC = {
    "double",
    "single",
    "int8",
    "int16",
    "int32",
    "int64",
    "uint8",
    "uint16",
    "uint32",
    "uint64",
}


#: MATLAB classes of v7.3 variables that hold no numbers, in words.
_MAT_WORDS = {"char": "text (char)", "cell": "a cell array", "string": "text (string)"}


def mat_arrays(path: Path, source: str) -> dict[str, np.ndarray | str]:
    """A MATLAB file's variables by name (struct fields as ``struct.field``).

    Numeric ones as arrays; text and cell arrays as what they hold in words
    (``"text (char)"``, ``"a cell array"``), so that asking for one as a
    column says so (:func:`mat_vector`) instead of calling it missing.
    """
    require_file(path, source)
    try:
        if h5py.is_hdf5(path):
            with h5py.File(path, "r") as file:
                return _hdf5_arrays(file, "")
        return _arrays(scipy.io.loadmat(path, simplify_cells=True), "")
    except _MAT_ERRORS as exc:
        raise DataError(
            f"not a readable MATLAB file ({type(exc).__name__}: {exc})", source=source
        ) from None


def mat_vector(
    variables: dict[str, np.ndarray], name: str, source: str, *, role: str | None = None
) -> np.ndarray:
    """The variable ``name`` of :func:`mat_arrays` as a float vector (``role``: named in errors).

    Parameters
    ----------
    variables : dict of str to ndarray
        The file's numeric arrays (:func:`mat_arrays`), struct fields as ``struct.field``.
    name : str
        The variable read; a key of ``variables``.
    source : str
        The file named in the error.
    role : str, optional
        What the variable stands for (e.g. ``"t"``), named in the error.

    Returns
    -------
    ndarray of float, shape (n,)
        Row and column vectors alike (singleton axes squeezed).

    Raises
    ------
    DataError
        For a variable that holds text or cells, or is not a vector once
        squeezed (naming its shape).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.io.matlab import mat_vector
    >>> mat_vector({"log.t": np.arange(3).reshape(1, 3)}, "log.t", "log.mat")
    array([0., 1., 2.])
    """
    what = "" if role is None else f" ({role})"
    if isinstance(variables[name], str):
        raise DataError(
            f"variable {name!r}{what} holds {variables[name]}, not numbers",
            source=source,
            field=name,
        )
    vector = np.squeeze(variables[name])
    if vector.ndim != 1:
        raise DataError(
            f"variable {name!r}{what} has shape {variables[name].shape}; a vector is needed",
            source=source,
            field=name,
        )
    return vector.astype(float)


def _arrays(contents: dict, prefix: str) -> dict[str, np.ndarray | str]:
    """The variables of scipy.io.loadmat's nested dicts (:func:`mat_arrays`)."""
    arrays = {}
    for key, value in contents.items():
        if key.startswith("__"):
            continue
        if isinstance(value, dict):
            arrays |= _arrays(value, f"{prefix}{key}.")
        elif isinstance(value, (np.ndarray, int, float)) and np.asarray(value).dtype.kind in "iuf":
            arrays[prefix + key] = np.asarray(value)
        elif isinstance(value, str) or (
            isinstance(value, np.ndarray) and value.dtype.kind in "US"
        ):
            arrays[prefix + key] = "text (char)"
        elif isinstance(value, (list, np.ndarray)):
            arrays[prefix + key] = "a cell array"
    return arrays


def _hdf5_arrays(group: h5py.Group, prefix: str) -> dict[str, np.ndarray]:
    """Numeric arrays of a v7.3 MATLAB file (HDF5 groups are structs)."""
    arrays = {}
    for key, item in group.items():
        if key.startswith("#"):
            continue
        if isinstance(item, h5py.Group):
            arrays |= _hdf5_arrays(item, f"{prefix}{key}.")
            continue
        kind = item.attrs.get("MATLAB_class", b"double")
        kind = kind.decode() if isinstance(kind, bytes) else str(kind)
        if kind in _MAT_NUMERIC and "MATLAB_empty" not in item.attrs:
            arrays[prefix + key] = np.asarray(item[()])
        elif kind in _MAT_WORDS:
            arrays[prefix + key] = _MAT_WORDS[kind]
    return arrays
