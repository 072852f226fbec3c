"""A bare noise series: one channel of a CSV, MATLAB file or ROS bag, on a uniform clock.

What ``bayes-jackal noise`` characterises: a sensor recorded standing still,
or the residual of some other model. :func:`read_noise_series` reads the
inputs that experiments come in (docs/design.md §2):

- CSV (``.csv``): a header and numeric columns; the stamps [s] are the
  column named ``t`` or ``time`` (any case; another with ``time_column=``),
  or a declared ``rate`` [Hz] stands for them (sample k at k / rate).
- MATLAB (``.mat``, v5/v7 or v7.3): numeric vectors, struct fields named
  ``struct.field`` (:func:`bayes_jackal.io.matlab.mat_arrays`); the stamps as
  in a CSV file, or a struct field so named (``log.t``).
- ROS bags (``.bag``, ``.mcap``, ``.db3`` or a ROS2 bag directory, the one
  kind of directory read, known by its ``metadata.yaml``; read with
  rosbags as :mod:`bayes_jackal.io.bags` reads them): one numeric field of one
  topic, ``topic="/imu/data", field="angular_velocity.z"`` (a number in the
  path indexes an array: ``velocity.0``). Stamps are the header stamps;
  a zero header stamp, or a message without a header, takes its receive time.

The data column is ``column``; without it, the one column besides the
stamps (an error lists them when there are several). Stamps get the
experiments' repairs (:func:`bayes_jackal.io.uniform_clock`, docs/design.md
§2.1: sorting, duplicates, jitter onto the uniform clock, short gaps filled,
the longest piece kept at long gaps), recorded in ``provenance``. A series
needs :data:`MIN_SERIES_SAMPLES` finite samples on the clock that are not
all equal. Input files are only read.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._runtime import DataError, InputError, file_sha256, require_file
from ..io import (
    BAG_SUFFIXES,
    bag_format,
    check_declared_rate,
    check_finite,
    check_stamp_rate,
    header_stamp,
    mat_arrays,
    mat_vector,
    numeric_column,
    open_bag,
    read_csv_table,
    receive_time_for_zero,
    uniform_clock,
)
from ..likelihood import check_length, check_series

__all__ = ["MIN_SERIES_SAMPLES", "ROS2_METADATA", "TIME_NAMES", "NoiseSeries", "read_noise_series"]

#: Fewest samples of a noise series: the thesis' fit (:func:`bayes_jackal.thesis.thesis_fit`)
#: uses 30 lags, which need 31 samples, and the mean takes one more.
MIN_SERIES_SAMPLES = 32
#: Names of a stamps column [s] found without ``time_column`` (compared in lower case).
TIME_NAMES = ("t", "time")
#: The file that makes a directory a ROS2 bag (rosbags reads the bag from it).
ROS2_METADATA = "metadata.yaml"


@dataclass(frozen=True, kw_only=True)
class NoiseSeries:
    """A uniformly sampled noise series and where it came from.

    Attributes
    ----------
    values : ndarray, shape (n,)
        Samples [series unit], n >= :data:`MIN_SERIES_SAMPLES`, finite, not constant.
    dt : float
        Sample time [s].
    name : str
        Short name (the file stem for files).
    source : str
        File it was read from, or ``"<memory>"``.
    field : str
        The column, or ``topic.field`` of a bag (named in errors).
    provenance : dict
        ``source``, ``format`` (``csv``, ``mat``, ``ros1``, ``ros2``), the
        ``column`` or ``topic``/``field``, ``time_column`` (None: stamps from
        a declared rate), ``time_base`` (:class:`bayes_jackal.io.UniformClock`'s
        provenance) and ``repairs`` (every change to the stamps, in words).

    Raises
    ------
    DataError
        For values that are not a 1-D series of numbers, non-finite values,
        too few samples or a constant series (naming source and field).
    InputError
        For a sample time that is not a positive number.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.noise import NoiseSeries
    >>> series = NoiseSeries(values=np.random.default_rng(1).standard_normal(100), dt=0.01)
    >>> print(series.name, series.source, len(series.values), series.dt)
    series <memory> 100 0.01
    >>> try:
    ...     NoiseSeries(values=np.full(100, 0.5), dt=0.01, source="still.csv", field="gyro_z")
    ... except ValueError as exc:
    ...     print(exc)
    still.csv: gyro_z: the series is constant (every sample 0.5): a constant series has no
    noise to characterise
    """

    values: np.ndarray
    dt: float
    name: str = "series"
    source: str = "<memory>"
    field: str = "values"
    provenance: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        values, dt = check_series(self.values, self.dt, source=self.source, field=self.field,
                                  minimum=MIN_SERIES_SAMPLES)  # fmt: skip
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "dt", dt)


def read_noise_series(
    path: str | Path,
    *,
    column: str | None = None,
    time_column: str | None = None,
    rate: float | None = None,
    topic: str | None = None,
    field: str | None = None,
    max_gap: float | None = None,
    name: str | None = None,
) -> NoiseSeries:
    """Read one noise series from a CSV, MATLAB or bag file (see the module text).

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.mat``, or a bag (:data:`BAG_SUFFIXES` or a ROS2 bag
        directory). Never modified.
    column : str, optional
        The data column of a CSV or MATLAB file; default the only column
        besides the stamps.
    time_column : str, optional
        The stamps column [s]; default the one named as in :data:`TIME_NAMES`.
    rate : float, optional
        Sampling rate [Hz]: declared for the stamps, or standing for them in
        a file without a stamps column.
    topic, field : str, optional
        For a bag (both needed): the topic and the dotted path of a numeric
        field in its messages, e.g. ``"/imu/data"`` and ``"angular_velocity.z"``.
    max_gap : float, optional
        Longest gap [s] filled by interpolation
        (:func:`bayes_jackal.io.uniform_clock`; default 5 steps).
    name : str, optional
        The series' name; the file stem when omitted.

    Returns
    -------
    NoiseSeries

    Raises
    ------
    DataError
        Naming the file, the field and the value: a missing file, an unknown
        column, topic or field, a choice of data columns, no stamps and no
        rate, non-numeric text, non-finite values, stamps no uniform clock
        fits, too few samples or a constant series.
    InputError
        For options that do not fit the file type, or a rate or max_gap
        that is not a positive number.

    Examples
    --------
    A gyro recorded standing still at 100 Hz, one message stamped twice; the
    stamps are repaired as an experiment's:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from bayes_jackal.noise import read_noise_series
    >>> t = np.insert(np.arange(200) / 100, 10, 0.1)
    >>> gyro = 0.01 * np.random.default_rng(1).standard_normal(len(t))
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "still.csv"
    ...     np.savetxt(path, np.column_stack([t, gyro]), delimiter=",", header="time,gyro z",
    ...                comments="")
    ...     series = read_noise_series(path)
    >>> print(series.name, series.field, len(series.values), series.dt)
    still gyro z 200 0.01
    >>> series.provenance["repairs"]
    ['time: 1 duplicate stamps (first at line 13); kept the first message of each']
    """
    path = Path(path)
    source = str(path)
    require_file(path, source, folder=True)
    bag = _is_bag(path, source)
    _check_options(bag, column=column, time_column=time_column, topic=topic, field=field)
    if bag:
        stamps, values, provenance, repairs = _bag_channel(path, source, topic, field)
        row_name = "message {}".format
        time_name, data_name = "stamp", f"{topic}.{field}"
    else:
        names, numeric, read, row_name, format = _table_columns(path, source)
        time_name, data_name = _choose(names, numeric, column, time_column, rate, source)
        values = read(data_name)
        stamps = None if time_name is None else read(time_name)
        provenance = {"source": source, "format": format, "column": data_name}
        provenance["time_column"] = time_name
        repairs = []
        time_name = time_name or "t"
    rate = check_declared_rate(rate)
    check_finite(values, source, data_name, row_name)
    check_length(len(values), minimum=MIN_SERIES_SAMPLES, source=source, field=data_name)
    if stamps is None:  # the declared rate's clock
        stamps = np.arange(len(values)) / rate
    check_finite(stamps, source, time_name, row_name)
    steps = np.diff(np.unique(stamps))
    if rate is None and len(steps):  # ms or ns read as s: a series 1000 times too slow
        check_stamp_rate(1.0 / float(np.median(steps)), source, time_name)
    clock = uniform_clock(
        stamps, rate=rate, max_gap=max_gap, source=source, row_name=row_name, field=time_name
    )
    check_length(len(clock.t), minimum=MIN_SERIES_SAMPLES, source=source, field=data_name,
                 where=" on the uniform clock")  # fmt: skip
    return NoiseSeries(
        values=clock.resample(values),
        dt=1.0 / clock.provenance["rate"],
        name=name or path.stem,
        source=source,
        field=data_name,
        provenance={
            **provenance,
            "time_base": clock.provenance,
            "repairs": [*repairs, *clock.repairs],
        },
    )


def _is_bag(path: Path, source: str) -> bool:
    """Whether ``path`` is a bag; a directory without :data:`ROS2_METADATA` is an error."""
    if not path.is_dir():
        return bag_format(path) is not None
    if (path / ROS2_METADATA).is_file():
        return True
    files = sorted(p.name for p in path.iterdir())
    raise DataError(
        f"a folder is read only as a ROS2 bag, which has a {ROS2_METADATA}; this one has none "
        f"(it holds {len(files)} files: {files[:5]}{' ...' if len(files) > 5 else ''}). Give the "
        "series files themselves (e.g. folder/*.csv), or the bag's folder",
        source=source,
    )


def _check_options(bag: bool, **options: str | None) -> None:
    """Refuse options of the other file type; a bag needs a topic and a field."""
    given = [key for key, value in options.items() if value is not None]
    wrong = [key for key in given if (key in ("topic", "field")) != bag]
    if wrong:
        kind = "a bag (use topic and field)" if bag else "CSV and MATLAB files (use column)"
        raise InputError(f"{wrong[0]} does not apply to {kind}", field=wrong[0])
    if bag and len(given) < 2:
        raise InputError(
            "a bag needs a topic and a field (--topic NAME --field PATH; topic=, field= in "
            "Python), e.g. /imu/data and angular_velocity.z",
            field="field" if "topic" in given else "topic",
        )


def _table_columns(
    path: Path, source: str
) -> tuple[list[str], list[str], Callable[[str], np.ndarray], Callable[[int], str], str]:
    """A CSV or MATLAB file's column names, those that may hold numbers, their reader, the
    row namer and the format (a MATLAB text field is a column, read only when named)."""
    suffix = path.suffix.lower()
    if suffix == ".csv":
        header, body = read_csv_table(path, source)

        def column(name: str) -> np.ndarray:
            return numeric_column(body, header.index(name), name, source)

        return header, header, column, lambda i: f"line {i + 2}", "csv"
    if suffix == ".mat":
        variables = mat_arrays(path, source)

        def vector(name: str) -> np.ndarray:
            return mat_vector(variables, name, source)

        numeric = sorted(name for name, value in variables.items() if not isinstance(value, str))
        return sorted(variables), numeric, vector, lambda i: f"index {i + 1}", "mat"
    raise DataError(
        f"unknown series file type {suffix!r}; expected .csv, .mat or a bag "
        f"({', '.join(BAG_SUFFIXES)} or a ROS2 bag directory)",
        source=source,
    )


def _is_time(name: str) -> bool:
    """Whether a column (or the last part of a struct field, ``log.t``) is named as stamps."""
    return name.lower().rsplit(".", 1)[-1] in TIME_NAMES


def _choose(
    names: list[str],
    numeric: list[str],
    column: str | None,
    time_column: str | None,
    rate: float | None,
    source: str,
) -> tuple[str | None, str]:
    """The stamps column (None: from the rate) and the data column of a table.

    A column named is looked up among all ``names`` (its reader says if it
    holds text); one chosen for the user, among the ``numeric`` ones.
    """
    for given in (time_column, column):
        if given is not None and given not in names:
            raise DataError(
                f"column {given!r} is not in the file; it has {names}", source=source, field=given
            )
    time = time_column or next((n for n in numeric if _is_time(n)), None)
    if column is None:
        data = [n for n in numeric if n != time]
        if len(data) != 1:
            stamps = "" if time else "; the stamps' with --time-column NAME (time_column=)"
            text = [n for n in names if n not in numeric]
            held = f" ({', '.join(map(repr, text))}: text, not numbers)" if text else ""
            raise DataError(
                f"{len(data)} data columns {data}{held}: name the one to read (--column NAME; "
                f"column= in Python){stamps}",
                source=source,
                field="column",
            )
        column = data[0]
    if column == time:
        raise DataError(
            f"column {column!r} holds the stamps; name the data column (--column NAME)",
            source=source,
            field=column,
        )
    if time is None and rate is None:
        raise DataError(
            f"no stamps: no column named {' or '.join(TIME_NAMES)} in {names}; name it "
            "(--time-column NAME; time_column= in Python) or declare the rate (--rate HZ; "
            "rate= in Python)",
            source=source,
            field="t",
        )
    return time, column


def _bag_channel(
    path: Path, source: str, topic: str, field: str
) -> tuple[np.ndarray, np.ndarray, dict, list[str]]:
    """Stamps [s from the first], values, provenance and repairs of one field of a topic."""
    label = f"{topic}.{field}"
    with open_bag(path, source) as reader:
        if topic not in reader.topics or reader.topics[topic].msgcount == 0:
            have = {t: info.msgcount for t, info in reader.topics.items()}
            raise DataError(
                f"topic {topic!r} is not in the bag or has no messages; it has (topic: "
                f"messages) {have}",
                source=source,
                field=topic,
            )
        msgtype = reader.topics[topic].msgtype
        connections = [c for c in reader.connections if c.topic == topic]
        rows = [  # one row per message: deserialising is a loop in rosbags
            _message_row(reader.deserialize(raw, msgtype), time, field, msgtype, source, label)
            for _, time, raw in reader.messages(connections=connections)
        ]
    stamp, recv, values = (np.array(part) for part in zip(*rows, strict=True))
    if (stamp == 0).all():  # no header (or none set): the receive time is the clock, no repair
        stamps_from, stamp, repairs = "receive time", recv, []
    else:
        stamps_from = "header"
        stamp, repairs = receive_time_for_zero(stamp, recv, topic)
    origin = int(stamp.min())
    provenance = {
        "source": source,
        "format": bag_format(path),
        "sha256": file_sha256(path),
        "topic": topic,
        "field": field,
        "msgtype": msgtype,
        "messages": len(stamp),
        "stamps": stamps_from,
        "time_zero": origin * 1e-9,
        "time_column": None if stamps_from == "receive time" else "header.stamp",
    }
    return (stamp - origin) * 1e-9, values.astype(float), provenance, repairs


def _message_row(
    message: object, time: int, field: str, msgtype: str, source: str, label: str
) -> tuple[int, int, float]:
    """(header stamp [ns] or 0, receive time [ns], the field's number) of one message."""
    value = message
    for part in field.split("."):
        if part.isdigit() and isinstance(value, (list, tuple, np.ndarray)):
            if int(part) >= len(value):
                raise DataError(
                    f"index {part} is out of range: {msgtype} has {len(value)} values there",
                    source=source,
                    field=label,
                )
            value = value[int(part)]
        elif dataclasses.is_dataclass(value) and hasattr(value, part):
            value = getattr(value, part)
        else:
            fields = (
                [f.name for f in dataclasses.fields(value)]
                if dataclasses.is_dataclass(value)
                else []
            )
            raise DataError(
                f"{msgtype} has no field {part!r} there (fields {fields or type(value).__name__})",
                source=source,
                field=label,
            )
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise DataError(
            f"{msgtype} field {field!r} is {type(value).__name__}, not a number",
            source=source,
            field=label,
        )
    stamp = header_stamp(message) if hasattr(message, "header") else 0
    return stamp, time, float(value)
