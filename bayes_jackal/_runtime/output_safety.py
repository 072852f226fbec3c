"""Where a command may write: checked outputs, protected inputs, one run per output.

The guarantees, in the order a command meets them:

- :func:`check_outputs`, before any work: an output is never one of the
  command's inputs (same resolved path, or the same file by device and
  inode: a hard link or a symbolic link is caught too), a file output has
  a known suffix and is not an existing folder, a folder output is not an
  existing file, two outputs of one command never share a path; the
  outputs' folders are created. A refusal is an :class:`InputError`
  (exit 2) and nothing has been done.
- :func:`protected`, for the whole run: every file written through
  :func:`bayes_jackal._runtime.files.atomic_path` is refused when it would replace
  an input. This catches the names a command computes, such as
  ``sample --out p.nc`` writing ``p.<experiment>.nc`` for each experiment.
- :class:`OutputLock`, for the whole run: a second run on the same output
  is refused at once, naming the run that holds it; a chain is never
  written by two runs. A file the package keeps beside an output (the
  lock, the chain) is never written through a symbolic or hard link
  (:func:`refuse_link`): a link planted in a shared folder cannot make a
  run overwrite another file.

POSIX only (Linux, macOS): the lock is :func:`fcntl.flock`.
"""

from __future__ import annotations

import contextlib
import contextvars
import datetime
import errno
import fcntl
import json
import os
import socket
import stat
import sys
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

from .errors import InputError, OutputError

__all__ = [
    "Output",
    "OutputLock",
    "OutputLockedError",
    "check_outputs",
    "make_folder",
    "protected",
    "refuse_input",
    "refuse_link",
    "removed_if_empty",
    "special_kind",
]


class OutputLockedError(InputError):
    """Another run holds the output: it is refused at once (exit 2).

    Examples
    --------
    An InputError (so a ValueError): the command line exits with 2:

    >>> from bayes_jackal._runtime.output_safety import OutputLockedError
    >>> try:
    ...     raise OutputLockedError("is in use by another run", source="fit.nc")
    ... except ValueError as error:
    ...     print(error)
    fit.nc: is in use by another run
    """


@dataclass(frozen=True)
class Output:
    """One output a command plans to write.

    Attributes
    ----------
    path : Path
    kind : str
        ``"file"`` or ``"folder"``.
    suffixes : tuple of str
        A file's allowed suffixes (lower case, with the dot); empty: any.
    flag : str
        The option that named it, for messages (``--out``, ``--plot``).
    create : bool
        A folder: made with the checks (True), or by the run as it writes
        into it (False: a run refused before then leaves no empty folder).

    Examples
    --------
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import Output
    >>> output = Output(Path("fits/posterior.nc"), suffixes=(".nc",))
    >>> output.kind, output.flag
    ('file', '--out')
    """

    path: Path
    kind: str = "file"
    suffixes: tuple[str, ...] = ()
    flag: str = "--out"
    create: bool = True


#: What a path that is neither a regular file nor a folder is, by its ``stat`` test.
_SPECIAL_FILES = (
    (stat.S_ISFIFO, "a named pipe"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def special_kind(mode: int) -> str:
    """What a file of ``stat`` mode ``mode`` that is neither regular nor a folder is."""
    return next((what for test, what in _SPECIAL_FILES if test(mode)), "of an unknown kind")


def _identity(path: Path) -> tuple[int, int] | None:
    """(device, inode) of an existing path, following links; None if it does not exist."""
    try:
        status = path.stat()
    except OSError:
        return None
    return status.st_dev, status.st_ino


def _resolved(path: Path) -> Path | None:
    """The path with its links followed; None for a symbolic-link loop.

    (Python before 3.13 raises RuntimeError there, 3.13 an OSError.)
    """
    try:
        return path.resolve()
    except (RuntimeError, OSError):
        return None


def _check_one(output: Output, inputs: dict[tuple[int, int] | Path, str]) -> None:
    path, where = output.path, f"{output.flag} {output.path}"
    resolved = _resolved(path)
    if resolved is None:
        raise InputError("is a loop of symbolic links; choose another", source=where)
    if resolved in inputs or _identity(path) in inputs:
        given = inputs.get(resolved) or inputs[_identity(path)]
        raise InputError(
            f"is the input {given}; an output never replaces an input, choose another",
            source=where,
        )
    parent = next((p for p in path.parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise InputError(f"{parent} is a file, not a folder; choose another", source=where)
    if output.kind == "folder":
        if path.exists() and not path.is_dir():
            raise InputError("is an existing file; give a folder", source=where)
        return
    if path.is_dir():
        raise InputError("is an existing folder; give a file name", source=where)
    if path.exists() and not path.is_file():  # written in place, it would be replaced
        kind = special_kind(path.stat().st_mode)
        raise InputError(f"is {kind}, not a file; give a file name", source=where)
    if output.suffixes and path.suffix.lower() not in output.suffixes:
        suffix = repr(path.suffix) if path.suffix else "no suffix"
        raise InputError(
            f"{suffix} is not a known suffix; use {', '.join(output.suffixes)}", source=where
        )


def check_outputs(outputs: Sequence[Output], *, inputs: Iterable[str | Path]) -> None:
    """Refuse bad outputs before any work; create their folders.

    Parameters
    ----------
    outputs : sequence of Output
        Everything the command plans to write under names the user gave.
    inputs : iterable of str or Path
        The command's input files and folders (missing ones are ignored here;
        reading reports them).

    Raises
    ------
    InputError
        An output is an input, has an unknown suffix, is a folder where a
        file is wanted or the other way round, is a named pipe, socket or
        device (which writing in place would replace), or two outputs share
        a path.
    OutputError
        A folder cannot be created (permission, read-only file system).

    Examples
    --------
    An output that would replace an input is refused before any work:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import Output, check_outputs
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = Path(folder) / "run.csv"
    ...     run.touch()
    ...     check_outputs([Output(Path(folder) / "fits" / "p.nc")], inputs=[run])
    ...     created = (Path(folder) / "fits").is_dir()
    ...     try:
    ...         check_outputs([Output(run)], inputs=[run])
    ...     except ValueError as error:
    ...         refused = str(error).endswith("an output never replaces an input, choose another")
    >>> created, refused
    (True, True)
    """
    known: dict[tuple[int, int] | Path, str] = {}
    for given in inputs:  # a link loop is no file: its reading fails, named, alone
        if (resolved := _resolved(Path(given))) is not None:
            known[resolved] = str(given)
        if (identity := _identity(Path(given))) is not None:
            known[identity] = str(given)
    seen: dict[Path, Output] = {}
    for output in outputs:
        _check_one(output, known)
        resolved = output.path.resolve()
        if resolved in seen:
            raise InputError(
                f"is also {seen[resolved].flag}; two outputs cannot share a path",
                source=f"{output.flag} {output.path}",
            )
        seen[resolved] = output
    for output in outputs:
        made_now = output.kind == "folder" and output.create
        make_folder(output.path if made_now else output.path.parent)


def make_folder(folder: Path, *, output: str | Path | None = None) -> None:
    """Create ``folder`` and its parents; OutputError naming ``output`` (or it) on failure.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import make_folder
    >>> with tempfile.TemporaryDirectory() as root:
    ...     make_folder(Path(root) / "a" / "b")
    ...     (Path(root) / "file").write_text("x")
    ...     try:
    ...         make_folder(Path(root) / "file")
    ...     except OSError as error:
    ...         print("refused:", error.__class__.__name__)
    ...     print((Path(root) / "a" / "b").is_dir())
    1
    refused: OutputError
    True
    """
    # One level at a time: pathlib's mkdir(parents=True) recurses per missing
    # level and runs out of Python's stack beneath ~1,000 of them.
    missing = [path for path in (folder, *folder.parents) if not path.is_dir()]
    try:
        for path in reversed(missing):
            path.mkdir(exist_ok=True)
    except FileExistsError:
        raise OutputError(output or folder, f"{folder} is a file, not a folder") from None
    except OSError as exc:
        raise OutputError.from_os_error(output or folder, exc) from None


@contextlib.contextmanager
def removed_if_empty(folders: Iterable[Path], *, on_success: bool = True) -> Iterator[None]:
    """Remove, when the block ends, the folders made in it that are still empty.

    Of ``folders`` and their parents, those that do not exist on entry: a
    run that fails, or is refused, before writing into a folder it made
    leaves no empty folder behind. Deepest first; a folder that holds
    anything (another run's file too) stays. With ``on_success=False`` only
    when the block raises.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import removed_if_empty
    >>> with tempfile.TemporaryDirectory() as root:
    ...     made, used = Path(root) / "a" / "b", Path(root) / "c"
    ...     with removed_if_empty([made, used]):
    ...         made.mkdir(parents=True)
    ...         used.mkdir()
    ...         _ = (used / "result.json").write_text("{}")
    ...     print(sorted(path.name for path in Path(root).iterdir()))
    ['c']
    """
    missing = {f for folder in folders for f in (folder, *folder.parents) if not f.exists()}
    deepest_first = sorted(missing, key=lambda f: len(f.parts), reverse=True)
    try:
        yield
    except BaseException:
        _remove_empty(deepest_first)
        raise
    if on_success:
        _remove_empty(deepest_first)


def _remove_empty(folders: list[Path]) -> None:
    for folder in folders:
        with contextlib.suppress(OSError):
            folder.rmdir()


#: The protected inputs, (device, inode) -> the path as given; a mapping that is never mutated.
_PROTECTED: contextvars.ContextVar[Mapping] = contextvars.ContextVar(
    "protected", default=MappingProxyType({})
)


@contextlib.contextmanager
def protected(inputs: Iterable[str | Path]) -> Iterator[None]:
    """Within the block, :func:`refuse_input` refuses to replace any of ``inputs``.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import protected, refuse_input
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = Path(folder) / "run.csv"
    ...     run.touch()
    ...     with protected([run]):
    ...         try:
    ...             refuse_input(run)
    ...         except ValueError as error:
    ...             print("refused")
    ...     refuse_input(run)  # outside the block: allowed
    refused
    """
    identities = {}
    for given in inputs:
        if (identity := _identity(Path(given))) is not None:
            identities[identity] = str(given)
    token = _PROTECTED.set({**_PROTECTED.get(), **identities})
    try:
        yield
    finally:
        _PROTECTED.reset(token)


def refuse_input(path: Path) -> None:
    """Raise InputError when writing ``path`` would replace a protected input.

    Examples
    --------
    A path that is no protected input passes; the input itself is refused:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import protected, refuse_input
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = Path(folder) / "run.csv"
    ...     run.touch()
    ...     with protected([run]):
    ...         refuse_input(Path(folder) / "p.nc")
    ...         try:
    ...             refuse_input(run)
    ...         except ValueError as error:
    ...             print(str(error).split(": ", 1)[1])
    writing it would replace the input ...run.csv; choose another output
    """
    given = _PROTECTED.get().get(_identity(path))
    if given is not None:
        raise InputError(
            f"writing it would replace the input {given}; choose another output",
            source=str(path),
        )


#: Flags that open a file the package keeps beside an output without
#: following a symbolic link or blocking on a FIFO or device.
_NO_LINK = os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY


def refuse_link(
    path: str | Path, status: os.stat_result | None = None, *, folder: bool = False
) -> None:
    """Refuse (InputError, exit 2) a file beside an output that is a link or not a regular file.

    The package writes its own files beside an output (the lock, the chain,
    a report's figure folder) only when each is a plain file or folder of
    its own: a symbolic link, a hard link (a second name of another file) or
    a FIFO or device there would make the run write into something else.
    ``status``: the file's :func:`os.fstat` once opened (without following
    links); without it the path is examined as it stands, and a missing file
    passes. ``folder``: the path is a folder the package makes; only a
    link there is refused (a file in its way fails when it is made).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import refuse_link
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     _ = (Path(folder) / "precious.csv").write_text("t,yaw")
    ...     (Path(folder) / ".p.nc.lock").symlink_to("precious.csv")
    ...     try:
    ...         refuse_link(Path(folder) / ".p.nc.lock")
    ...     except ValueError as error:
    ...         print(str(error).split(": ", 1)[1].split(";")[0])
    is a symbolic link (to precious.csv)
    """
    path = Path(path)
    if status is None:
        try:
            status = path.lstat()
        except FileNotFoundError:
            return
    if stat.S_ISLNK(status.st_mode):
        what = f"a symbolic link (to {os.readlink(path)})"
    elif folder:
        return  # a file in the folder's way fails where the folder is made
    elif not stat.S_ISREG(status.st_mode):
        what = "not a regular file"
    elif status.st_nlink > 1:
        what = f"a hard link (one of {status.st_nlink} names of one file)"
    else:
        return
    raise InputError(
        f"is {what}; bayes-jackal does not write through links beside an output: "
        "remove it, or choose another output",
        source=str(path),
    )


def lock_path(path: str | Path, *, folder: bool = False) -> Path:
    """An output's lock file: ``.NAME.lock`` beside a file, ``.bayes-jackal.lock`` in a folder."""
    path = Path(path)
    return path / ".bayes-jackal.lock" if folder else path.parent / f".{path.name}.lock"


class OutputLock:
    """A lock per run on an output, naming its holder; use as a context manager.

    Entering takes an exclusive :func:`fcntl.flock` on :func:`lock_path`
    without waiting and writes the holder (pid, host, command line, start
    time) into the lock file; when another run holds it,
    :class:`OutputLockedError` names that run. Leaving removes the lock
    file. The kernel releases the lock when a process dies, even by
    SIGKILL, so a stale lock file never blocks a later run. POSIX only;
    on a network file system flock may not exclude other hosts.

    Parameters
    ----------
    path : str or Path
        The output.
    folder : bool
        The output is a folder (it must exist): the lock file goes inside it.

    Examples
    --------
    A second run on a locked output is refused at once, naming the holder:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal._runtime.output_safety import OutputLock, OutputLockedError
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     output = Path(folder) / "posterior.nc"
    ...     with OutputLock(output) as lock:
    ...         print(lock.lock_file.name)
    ...         try:
    ...             OutputLock(output).__enter__()
    ...         except OutputLockedError as error:
    ...             print("refused:", "is in use by another run (pid" in str(error))
    ...     print(lock.lock_file.exists())
    .posterior.nc.lock
    refused: True
    False
    """

    def __init__(self, path: str | Path, *, folder: bool = False):
        self.path = Path(path)
        self.lock_file = lock_path(self.path, folder=folder)
        self._fd: int | None = None

    def __enter__(self) -> OutputLock:
        while self._fd is None:
            try:
                fd = os.open(self.lock_file, _NO_LINK | os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:  # a read-only folder, no permission, a link
                refuse_link(self.lock_file)
                raise OutputError.from_os_error(self.path, exc) from None
            try:
                refuse_link(self.lock_file, os.fstat(fd))
            except InputError:
                os.close(fd)
                raise
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                    raise
                raise OutputLockedError(
                    f"is in use by another run ({self._holder()}); wait for it to finish "
                    "or choose another output",
                    source=str(self.path),
                ) from None
            locked = os.fstat(fd)
            if _identity(self.lock_file) == (locked.st_dev, locked.st_ino):
                self._fd = fd  # the file we locked is still the lock file
            else:  # its holder removed it between our open and flock: try again
                os.close(fd)
        holder = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "command": " ".join(["bayes-jackal", *sys.argv[1:]]),
            "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        }
        try:
            os.ftruncate(self._fd, 0)
            os.write(self._fd, json.dumps(holder).encode())
        except OSError as exc:  # a full disk, a file-size limit: before any work
            self.__exit__()
            raise OutputError.from_os_error(self.path, exc) from None
        return self

    def __exit__(self, *exc_info) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.lock_file.unlink()  # still holding the lock: no one else removes it
        os.close(self._fd)
        self._fd = None

    def _holder(self) -> str:
        """The holding run, in words, from the lock file."""
        try:
            holder = json.loads(self.lock_file.read_text())
            return (
                f"pid {holder['pid']} on {holder['host']}, started {holder['started']}: "
                f"{holder['command']}"
            )
        except (OSError, ValueError, KeyError, TypeError):
            return f"lock file {self.lock_file}"
