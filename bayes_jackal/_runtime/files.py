"""Writing files so that an interrupted run or a full disk never leaves half a file.

Every file the package writes goes through :func:`atomic_path`: written to
a hidden temporary beside it, renamed into place when complete. A write
error names the user's path and its reason, and leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import math
import os
import resource
import shutil
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import DataError, InputError, OutputError
from .output_safety import make_folder, refuse_input, special_kind

__all__ = [
    "atomic_path",
    "chain_path",
    "check_space",
    "file_sha256",
    "json_text",
    "require_file",
    "write_hdf5",
    "write_json",
]


def require_file(
    path: str | Path, source: str, *, folder: bool = False, error: type[InputError] = DataError
) -> None:
    """Refuse (a DataError naming ``source``) an input that is not a regular file.

    Every reader of an input calls this before it opens it: a named pipe
    (FIFO) would block the read until another process writes into it, for
    ever if none does, and a device or socket is no recording either.
    Links are followed: a link to a regular file is one.

    Parameters
    ----------
    path : str or Path
        The input, as the reader will open it.
    source : str
        Names the input in the error.
    folder : bool
        A folder is an input too (a ROS2 bag is one).
    error : type
        The InputError subclass raised (a robot profile's is a ProfileError).

    Raises
    ------
    DataError (or ``error``)
        ``no such file``, ``is a folder, not a file``, ``not a regular file
        (a named pipe)`` (or a socket, a device), or why it cannot be
        examined (a loop of links, no permission).

    Examples
    --------
    >>> import os
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.files import require_file
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     os.mkfifo(Path(folder) / "x.csv")
    ...     try:
    ...         require_file(Path(folder) / "x.csv", "x.csv")
    ...     except ValueError as error:
    ...         print(error)
    x.csv: not a regular file (a named pipe)
    """
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        raise error("no such file", source=source) from None
    except OSError as failure:
        raise error(f"cannot read: {failure.strerror}", source=source) from None
    if stat.S_ISREG(mode) or (folder and stat.S_ISDIR(mode)):
        return
    if stat.S_ISDIR(mode):
        raise error("is a folder, not a file", source=source)
    raise error(f"not a regular file ({special_kind(mode)})", source=source)


def _umask() -> int:
    """The process' umask (reading it means setting it; it is set straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: Bytes kept free beyond an HDF5 write's estimate: metadata, B-trees, attributes.
SPACE_MARGIN = 256 * 1024


def check_space(path: Path, nbytes: int, *, grows: bool = False, advice: str = "") -> None:
    """Refuse (OutputError) to write ``nbytes`` more to ``path`` where they cannot fit.

    HDF5 (h5py, h5netcdf) cannot recover from a failed write: the file is
    left unreadable and the process may crash when the library shuts down.
    So an HDF5 write is checked first, with room for its estimated size
    plus a quarter (chunk padding and metadata the estimate leaves out) and
    :data:`SPACE_MARGIN`, against the free space of the file system and the
    process' file-size limit (``ulimit -f``); the file's present size counts
    towards the limit when the write ``grows`` it (a chain), not when a new
    file replaces it. ``advice`` ends the message.
    """
    needed = int(nbytes * 1.25) + SPACE_MARGIN
    free = shutil.disk_usage(path.parent).free
    if free < needed:
        raise OutputError(
            path,
            f"no space left on device ({needed / 1e6:.2f} MB needed, {free / 1e6:.2f} MB free)"
            + advice,
            code=errno.ENOSPC,
        )
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    size = path.stat().st_size if grows and path.exists() else 0
    if limit != resource.RLIM_INFINITY and size + needed > limit:
        raise OutputError(
            path,
            f"file too large for the file-size limit of {limit / 1e6:.2f} MB (ulimit -f)" + advice,
            code=errno.EFBIG,
        )


@contextlib.contextmanager
def atomic_path(path: str | Path, *, nbytes: int | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it into place on success.

    The caller writes the whole file to the yielded path. Only when the block
    finishes without an exception is it renamed over ``path`` (atomic on the
    same file system); otherwise it is removed and ``path`` is untouched.
    The file gets the permissions of a plainly created one (0666 less the
    umask), not the temporary file's owner-only 0600.

    Refused with InputError when ``path`` is an input of the running command
    (:func:`bayes_jackal._runtime.output_safety.protected`). Any OSError while writing (a
    full disk, a file-size limit, no permission) removes the temporary and
    becomes :class:`~bayes_jackal._runtime.errors.OutputError` naming ``path``, never
    the temporary. ``nbytes``: the estimated size of an HDF5 file, checked
    against the free space first (:func:`check_space`).
    """
    path = Path(path)
    refuse_input(path)
    make_folder(path.parent, output=path)
    try:
        if nbytes is not None:
            check_space(path, nbytes)
        handle, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
        os.close(handle)
    except OSError as exc:
        if isinstance(exc, OutputError):
            raise
        raise OutputError.from_os_error(path, exc) from None
    temporary = Path(name)
    try:
        yield temporary
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except OSError as exc:
        if isinstance(exc, OutputError):
            raise
        raise OutputError.from_os_error(path, exc) from None
    finally:
        temporary.unlink(missing_ok=True)


def write_hdf5(data, path: str | Path) -> Path:
    """Write an xarray Dataset or arviz InferenceData as NetCDF (h5netcdf), atomically.

    The estimated size (the data's bytes) is checked against the free space
    first (:func:`check_space`): HDF5 never meets a full disk.
    """
    groups = [data[name] for name in data.groups()] if hasattr(data, "groups") else [data]
    with atomic_path(path, nbytes=sum(group.nbytes for group in groups)) as temporary:
        data.to_netcdf(str(temporary), engine="h5netcdf")
    return Path(path)


def finite_json(value: object) -> object:
    """``value`` with every non-finite float (NaN, +-inf) in it replaced by None.

    JSON has no NaN or Infinity (Python's ``json`` writes them, strict
    parsers refuse them), so a number that is not finite is written as
    ``null``: "no value". Dicts, lists and tuples are walked; other values
    are returned as they are.
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_json(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_json(item) for item in value]
    return value


def json_text(payload: object, *, indent: int | None = 2) -> str:
    """``payload`` as strict JSON text: non-finite numbers become null (:func:`finite_json`).

    Dumped with ``allow_nan=False``, so a non-finite number that escaped the
    mapping raises instead of producing invalid JSON. Every JSON output of
    the package (files and ``--json``) goes through here.
    """
    return json.dumps(finite_json(payload), indent=indent, allow_nan=False)


def write_json(path: str | Path, payload: object, *, indent: int = 2) -> Path:
    """Write ``payload`` as JSON (:func:`json_text`) to ``path`` atomically; return the path."""
    path = Path(path)
    with atomic_path(path) as temporary:
        temporary.write_text(json_text(payload, indent=indent))
    return path


def file_sha256(path: Path) -> str:
    """sha256 (hex) of a file, or of a directory's files (a ROS2 bag) in name order.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.files import file_sha256
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     _ = (Path(folder) / "a.txt").write_bytes(b"abc")
    ...     print(file_sha256(Path(folder) / "a.txt")[:16], file_sha256(Path(folder))[:16])
    ba7816bf8f01cfea ba7816bf8f01cfea
    """
    digest = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for file in files:
        with open(file, "rb") as stream:
            for block in iter(lambda s=stream: s.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


def chain_path(posterior: str | Path) -> Path:
    """Where ``sample`` keeps the chain of a posterior file: ``p.nc`` -> ``p.chain.h5``.

    Examples
    --------
    >>> from bayes_jackal._runtime.files import chain_path
    >>> chain_path("fits/posterior.nc").as_posix()
    'fits/posterior.chain.h5'
    """
    return Path(posterior).with_suffix(".chain.h5")
