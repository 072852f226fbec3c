"""Opening ROS bags and reading their stamps: what every bag reader of the package shares.

:func:`bayes_jackal.io.read_bag` (a robot's run) and
:func:`bayes_jackal.noise.read_noise_series` (one field of one topic)
both open a bag with rosbags' AnyReader in the typestore of its format
(:func:`typestore`, :func:`bag_format`), turn rosbags' errors on an
unreadable file into a :class:`~bayes_jackal._runtime.errors.DataError` naming it
(:func:`open_bag`), stamp messages by their header (:func:`header_stamp`)
and give a zero header stamp the message's receive time
(:func:`receive_time_for_zero`), a repair recorded in words.
"""

from __future__ import annotations

import contextlib
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_typestore

from .._runtime import BAG_FORMATS, DataError, InputError

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    "BAG_SUFFIXES",
    "READ_ERRORS",
    "bag_format",
    "header_stamp",
    "open_bag",
    "receive_time_for_zero",
    "typestore",
]

#: File suffixes of ROS bags: ROS1's, then ROS2's storage files (a ROS2 bag may also
#: be a folder). A file's suffix is compared in lower case (:func:`bag_format`).
BAG_SUFFIXES = (".bag", ".mcap", ".db3")
#: What rosbags raises on unreadable or corrupt files (its readers check some
#: record fields with ``assert``, hence AssertionError).
READ_ERRORS = (
    AssertionError,
    ArithmeticError,
    AnyReaderError,
    Reader1Error,
    Reader2Error,
    SerdeError,
    TypesysError,
    OSError,
    ValueError,
    KeyError,
    IndexError,
    EOFError,
    struct.error,
)


def typestore(format: str) -> Typestore:
    """The rosbags typestore of a bag format (``"ros1"``: Noetic, ``"ros2"``: Humble).

    Examples
    --------
    >>> from bayes_jackal.io import typestore
    >>> "sensor_msgs/msg/Imu" in typestore("ros1").types
    True
    """
    if format not in BAG_FORMATS:
        raise InputError(
            f"unknown bag format {format!r}; use one of {BAG_FORMATS}", field="format"
        )
    return get_typestore(Stores.ROS1_NOETIC if format == "ros1" else Stores.ROS2_HUMBLE)


def bag_format(path: Path) -> str | None:
    """A bag's ROS version by its path; None for a file that is not a bag.

    The one rule of what is read as a bag: ``"ros1"`` for a ``.bag`` file,
    ``"ros2"`` for a ``.mcap`` or ``.db3`` file or a folder, the suffix in any
    case (:data:`BAG_SUFFIXES`).

    Parameters
    ----------
    path : Path
        A file or folder (a folder need not exist to be named here).

    Returns
    -------
    str or None
        ``"ros1"``, ``"ros2"`` or None.

    Examples
    --------
    >>> from pathlib import Path
    >>> from bayes_jackal.io import bag_format
    >>> bag_format(Path("run.bag")), bag_format(Path("RUN.BAG")), bag_format(Path("run.mcap"))
    ('ros1', 'ros1', 'ros2')
    >>> print(bag_format(Path("run.csv")))
    None
    """
    if path.is_dir():
        return "ros2"
    suffix = path.suffix.lower()
    return "ros1" if suffix == BAG_SUFFIXES[0] else "ros2" if suffix in BAG_SUFFIXES else None


@contextlib.contextmanager
def open_bag(path: Path, source: str) -> Iterator[AnyReader]:
    """A bag's AnyReader; rosbags' errors in the block become a DataError naming ``source``.

    A DataError raised in the block passes unchanged (a reader's own, more
    precise message).

    Parameters
    ----------
    path : Path
        A bag file or a ROS2 bag folder (:func:`bag_format`).
    source : str
        Names the bag in errors.

    Yields
    ------
    rosbags.highlevel.AnyReader
        Open, in the typestore of the bag's format (:func:`typestore`).

    Raises
    ------
    DataError
        ``cannot read bag (<error>)`` for any of :data:`READ_ERRORS`; for a
        file that is not a bag, or a bag's suffix not in lower case (rosbags
        tells the formats apart by the suffix as written).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.io import open_bag
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "broken.bag"
    ...     _ = path.write_bytes(b"not a bag")
    ...     try:
    ...         with open_bag(path, "broken.bag") as reader:
    ...             pass
    ...     except ValueError as exc:
    ...         print(exc)
    broken.bag: cannot read bag (AnyReaderError: File magic is invalid.)
    """
    format = bag_format(path)
    if format is None:
        raise DataError(
            f"not a bag: expected a {', '.join(BAG_SUFFIXES)} file or a ROS2 bag folder",
            source=source,
        )
    if not (path.is_dir() or path.suffix in BAG_SUFFIXES):
        raise DataError(
            "rosbags tells a bag's format by its suffix in lower case: rename the file (or "
            f"link it) as {path.stem}{path.suffix.lower()}",
            source=source,
        )
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise DataError(
            "is a folder but no ROS2 bag (it has no metadata.yaml); give a bag, or a "
            "CSV, MATLAB or experiment file",
            source=source,
        )
    try:
        with AnyReader([path], default_typestore=typestore(format)) as reader:
            yield reader
    except DataError:
        raise
    except READ_ERRORS as exc:
        raise DataError(f"cannot read bag ({type(exc).__name__}: {exc})", source=source) from None


def header_stamp(message: object) -> int:
    """A message's header stamp [ns] (0 when the publisher left it unset).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from bayes_jackal.io import header_stamp, typestore
    >>> from bayes_jackal.io import stamped_header
    >>> header = stamped_header(typestore("ros2"), 1_500_000_000, "imu_link", 0)
    >>> header_stamp(SimpleNamespace(header=header))
    1500000000
    """
    stamp = message.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def receive_time_for_zero(
    stamp: np.ndarray, recv: np.ndarray, what: str
) -> tuple[np.ndarray, list[str]]:
    """Header stamps [ns] with each zero replaced by the receive time [ns], and the repair.

    Parameters
    ----------
    stamp, recv : ndarray of int, shape (n,)
        Header stamps and receive times [ns] of a topic's messages.
    what : str
        The topic (and its role) that the repair names.

    Returns
    -------
    stamps : ndarray of int, shape (n,)
    repairs : list of str
        One sentence when some stamp was zero, else empty.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.io import receive_time_for_zero
    >>> stamps, repairs = receive_time_for_zero(np.array([0, 20, 30]), np.array([11, 21, 31]),
    ...                                         "/imu/data")
    >>> stamps.tolist()
    [11, 20, 30]
    >>> print(*repairs)
    /imu/data: 1 of 3 messages have a zero header stamp; used their receive time
    """
    zero = stamp == 0
    if not zero.any():
        return stamp, []
    repair = (
        f"{what}: {zero.sum()} of {len(stamp)} messages have a zero header stamp; used their "
        "receive time"
    )
    return np.where(zero, recv, stamp), [repair]
