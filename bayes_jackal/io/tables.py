"""CSV and MATLAB tables: column mapping and stamp repair into an Experiment.

Also :func:`load_experiment(s) <load_experiment>`, which reads any experiment
file by its suffix (the NetCDF experiment file lives in
:mod:`bayes_jackal.io.experiment`, the MATLAB container in
:mod:`bayes_jackal.io.matlab`).

CSV format: a header naming the columns ``t, yaw_rate, omega_r, omega_l`` and
optionally ``vx, vy``, the motion-capture pose ``x, y, heading`` (with
``pose_t``, its own time), a command (``cmd_v, cmd_w`` or ``cmd_omega_r,
cmd_omega_l``, which may stand in for the wheel speeds) and a ``segment``
label (any order, extra columns ignored), SI units, t in seconds. With the
pose, vx and vy are modelled through it (docs/design.md §2.2; derived from
it for plots where the file has no vx, vy columns); without it, vx and vy
are modelled as measured, and ``velocities="derived"`` (``--velocities
derived``) records that they were derived from poses the file lacks, which
a posterior warns of. MATLAB files hold the same names as vectors, at the
top level or as fields of a struct (``log.t``). Columns named otherwise are
mapped with ``columns={"yaw_rate": "gyro_z", ...}`` (role to column).

A table may be dense, of sparse rows (an empty cell: no value there), or
hold slower sensors' values repeated on faster rows: each group of columns
is one sensor's stream, placed on the clock of the yaw rate's rows by the
rules of :mod:`bayes_jackal.io._table_streams` (docs/design.md §2.3). The
clock follows :mod:`bayes_jackal.io.stamps` (jitter, repeated and
out-of-order stamps, gaps); what the readers did is in
``provenance["time_base"]`` and ``provenance["repairs"]``.
"""

from __future__ import annotations

import csv
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from .._runtime import (
    OPTIONAL,
    POSE_ROLES,
    POSE_TIME,
    REQUIRED,
    ROLES,
    SEGMENT,
    VELOCITIES,
    VELOCITY_COMMAND,
    WHEEL_COMMAND,
    DataError,
    InputError,
    atomic_path,
    positive_number,
    require_file,
)
from ..model import RobotProfile
from ._table_streams import GROUPS, TableStream, table_experiment
from .experiment import Experiment, read_netcdf
from .matlab import mat_arrays, mat_vector
from .stamps import PLAUSIBLE_RATES, UNIFORM_TOLERANCE

__all__ = [
    "RATE_TOLERANCE",
    "check_column_roles",
    "check_columns_apply",
    "check_declared_rate",
    "check_sample_time",
    "check_stamp_rate",
    "check_unique_names",
    "load_experiment",
    "numeric_column",
    "read_csv",
    "read_csv_table",
    "read_mat",
    "write_csv",
]


def check_columns_apply(paths: Iterable[str | Path], columns: Mapping[str, str] | None) -> None:
    """Refuse a column mapping that none of ``paths`` can use (no CSV or MATLAB file).

    Experiment files (``.nc``) keep their own names and bags their topics:
    a ``--column`` given with only those would be ignored in silence.

    Examples
    --------
    >>> from bayes_jackal.io import check_columns_apply
    >>> check_columns_apply(["a.csv", "b.nc"], {"yaw_rate": "gyro_z"})  # a.csv uses it
    >>> try:
    ...     check_columns_apply(["b.nc"], {"yaw_rate": "gyro_z"})
    ... except ValueError as error:
    ...     print(error)
    columns: a column mapping names columns of CSV and MATLAB files (.csv, .mat), and no
    input is one: an experiment file (.nc) keeps its own names, a bag its topics (--topic)
    """
    paths = list(paths)
    if columns and not any(Path(path).suffix.lower() in _LOG_READERS for path in paths):
        raise InputError(
            "a column mapping names columns of CSV and MATLAB files "
            f"({', '.join(_LOG_READERS)}), and no input is one: an experiment file (.nc) "
            "keeps its own names, a bag its topics (--topic)",
            field="columns",
        )


def check_column_roles(
    columns: dict[str, str] | None, *, field: str = "columns"
) -> dict[str, str]:
    """Validate a role-to-column mapping (``columns=``, ``--column ROLE NAME``).

    ``field`` names the mapping in errors.

    Raises
    ------
    InputError
        Naming an unknown role, a name that is not a string, or a column
        mapped to two roles.

    Examples
    --------
    >>> from bayes_jackal._runtime.errors import InputError
    >>> from bayes_jackal.io import check_column_roles
    >>> check_column_roles({"yaw_rate": "gyro_z"})
    {'yaw_rate': 'gyro_z'}
    >>> try:
    ...     check_column_roles({"yaw": "gyro_z"})
    ... except InputError as exc:
    ...     print(exc)
    columns: unknown column role(s) ['yaw']; the roles are
    ['t', 'yaw_rate', 'omega_r', 'omega_l', 'vx', 'vy', 'x', 'y', 'heading', 'pose_t', 'cmd_v',
    'cmd_w', 'cmd_omega_r', 'cmd_omega_l', 'segment']
    """
    columns = dict(columns or {})
    unknown = [role for role in columns if role not in ROLES]
    if unknown:
        raise InputError(
            f"unknown column role(s) {unknown}; the roles are {list(ROLES)}", field=field
        )
    bad = {role: name for role, name in columns.items() if not (isinstance(name, str) and name)}
    if bad:
        raise InputError(f"column names must be non-empty strings, got {bad}", field=field)
    roles_of: dict[str, list[str]] = {}
    for role, name in columns.items():
        roles_of.setdefault(name, []).append(role)
    shared = {name: roles for name, roles in roles_of.items() if len(roles) > 1}
    if shared:
        name, roles = next(iter(shared.items()))
        raise InputError(
            f"column {name!r} is mapped to two roles, {roles[0]} and {roles[1]}; a column "
            "holds one role",
            field=field,
        )
    return columns


def _mapped(available: list[str], columns: dict[str, str] | None, source: str) -> dict[str, str]:
    """Role -> column name of a file; a mapped column or a required role must exist.

    An unmapped role is read from the column of its own name, unless that
    column is mapped to another role: then the role has no column (absent
    if optional, an error if required). Required are ``t``, ``yaw_rate``
    and the wheel speeds, which a command (``cmd_v, cmd_w`` or
    ``cmd_omega_r, cmd_omega_l``) can stand in for.
    """
    mapping = check_column_roles(columns)
    absent = {role: name for role, name in mapping.items() if name not in available}
    if absent:
        role, name = next(iter(absent.items()))
        raise DataError(
            f"column {name!r} (mapped to {role}) is not in the file; it has {available}",
            source=source,
            field=name,
        )
    taken = {name: role for role, name in mapping.items()}
    names = {
        role: mapping.get(role, role)
        for role in ROLES
        if role in mapping or taken.get(role, role) == role
    }
    names = {role: name for role, name in names.items() if name in available}
    wheels = GROUPS["wheels"]
    commanded = any(all(role in names for role in command) for command in COMMAND_PAIRS)
    required = [*REQUIRED[:2], *wheels] if any(r in names for r in wheels) or not commanded else []
    missing = [role for role in (required or REQUIRED[:2]) if role not in names]
    if missing:
        used = [f"{role!r} is mapped to {taken[role]}" for role in missing if role in taken]
        raise DataError(
            f"missing column(s) {missing}; the file has {available}"
            f"{' (' + ', '.join(used) + ')' if used else ''} (name yours with "
            "--column ROLE NAME, columns= in Python)",
            source=source,
            field=missing[0],
        )
    for roles, what in ((POSE_ROLES, "a pose"), *((pair, "a command") for pair in COMMAND_PAIRS)):
        present = [role for role in roles if role in names]
        if present and len(present) < len(roles):
            lacking = [role for role in roles if role not in names]
            raise DataError(
                f"{what} needs the columns {list(roles)}; the file has {present}, not {lacking}",
                source=source,
                field=lacking[0],
            )
    if POSE_TIME in names and POSE_ROLES[0] not in names:
        raise DataError(
            f"a pose time ({names[POSE_TIME]!r}) without the pose {list(POSE_ROLES)}",
            source=source,
            field=POSE_TIME,
        )
    return names


#: A command's pairs of roles (either is a command).
COMMAND_PAIRS = (VELOCITY_COMMAND, WHEEL_COMMAND)


def read_csv(
    path: str | Path,
    *,
    name: str | None = None,
    series: str | None = None,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    velocities: str = VELOCITIES[0],
    robot: RobotProfile | None = None,
) -> Experiment:
    """Read an experiment from a CSV file (docs/design.md §2).

    The table may be dense (every row holds every column), of sparse rows
    (an empty cell: no value at that row; the union of several sensors'
    samples), or hold slower sensors' values repeated on faster rows
    (:func:`bayes_jackal.io.held_channel`): the rules are docs/design.md
    §2.3.

    Parameters
    ----------
    path : str or Path
        CSV with a header naming ``t, yaw_rate, omega_r, omega_l`` and
        optionally ``vx, vy``, the pose ``x, y, heading`` (with ``pose_t``,
        its own time), a command (``cmd_v, cmd_w`` or ``cmd_omega_r,
        cmd_omega_l``: the wheel speeds may then be left out) and a
        ``segment`` label (or the names in ``columns``).
    name : str, optional
        Experiment name; the file stem when omitted.
    series : str, optional
        Series label for grid averages.
    columns : dict of str to str, optional
        Column of each role named otherwise, e.g. ``{"yaw_rate": "gyro_z"}``.
    rate : float, optional
        Declared sampling rate [Hz]; detected from the stamps when omitted.
    max_gap : float, optional
        Longest gap [s] filled by interpolation (:func:`bayes_jackal.io.uniform_clock`).
    velocities : {"measured", "derived"}
        What the vx, vy columns of a file without pose columns are: a
        sensor's measurements (the model's assumption), or derived from
        poses the file lacks (recorded in the provenance; a posterior then
        warns: docs/design.md §2.2). With pose columns they are derived.
    robot : RobotProfile, optional
        Whose diff-drive formula turns a ``cmd_v, cmd_w`` command into
        wheel speeds (:func:`bayes_jackal.model.wheel_speeds`); the
        default profile's when omitted.

    Raises
    ------
    DataError
        Naming the file, the column and the line of the first bad value.
    InputError
        For an unknown column role or a rate that is not a positive number.

    Warns
    -----
    UserWarning
        Where a column group holds a slower sensor's values on faster rows,
        or a command is the model's input (also in ``provenance["repairs"]``).

    Examples
    --------
    A log whose columns are named otherwise (100 samples at 72 Hz):

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from bayes_jackal.io import read_csv
    >>> table = np.column_stack([np.arange(100) / 72, np.full(100, 0.4), np.full((100, 2), 10.0)])
    >>> roles = {"t": "time", "yaw_rate": "gyro_z", "omega_r": "right", "omega_l": "left"}
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "circle.csv"
    ...     np.savetxt(path, table, delimiter=",", header="time,gyro_z,right,left", comments="")
    ...     run = read_csv(path, columns=roles)
    >>> print(run.name, len(run.t), run.channels, run.provenance["time_base"]["rate"])
    circle 100 ('yaw',) 72.0

    Sparse rows, as pandas writes an outer join: the IMU at 10 Hz, the
    wheel speeds at 10 Hz on its rows and 5 Hz between them, the poses at
    2 Hz at their own stamps:

    >>> text = "t,yaw_rate,omega_r,omega_l,x,y,heading\\n"
    >>> for k in range(101):
    ...     text += f"{k / 10},0.1,5.0,5.0,,,\\n"
    ...     if k % 2 == 0:
    ...         text += f"{k / 10 + 0.05},,5.0,5.0,,,\\n"
    ...     if k % 5 == 0:
    ...         text += f"{k / 10 + 0.02},,,,{0.049 * k},0.0,{0.01 * k}\\n"
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "joined.csv"
    ...     _ = path.write_text(text)
    ...     run = read_csv(path)
    >>> print(len(run.t), run.pose.t[:3], round(run.pose.rate, 6), run.measurement("vx"))
    101 [0.02 0.52 1.02] 2.0 pose
    """
    path = Path(path)
    source = str(path)
    header, body = read_csv_table(path, source)
    names = _mapped(header, columns, source)
    index = {role: header.index(column) for role, column in names.items()}
    cells = {role: [row[i].strip() for row in body] for role, i in index.items()}
    return table_experiment(
        _csv_streams(cells, source),
        names=names,
        source=source,
        format="csv",
        name=name or path.stem,
        series=series,
        rate=rate,
        max_gap=max_gap,
        velocities=velocities,
        robot=robot,
    )


def _line(row: int) -> str:
    """A CSV's data row (from 0) as the line that holds it (the header is line 1)."""
    return f"line {row + 2}"


def _csv_streams(cells: dict[str, list[str]], source: str) -> dict[str, TableStream]:
    """A CSV's column groups as streams: each group's rows are those its cells fill."""
    filled = {
        role: np.array([cell != "" for cell in column], bool) for role, column in cells.items()
    }
    if not filled["t"].all():
        row = int(np.flatnonzero(~filled["t"])[0])
        raise DataError(
            f"empty cell at {_line(row)}: every row needs its time stamp", source=source, field="t"
        )
    t = _numbers(cells["t"], np.arange(len(cells["t"])), "t", source)
    streams = {}
    for group, roles in GROUPS.items():
        roles = tuple(role for role in roles if role in cells)
        if not roles:
            continue
        present = np.column_stack([filled[role] for role in roles])
        partial = np.flatnonzero(present.any(axis=1) & ~present.all(axis=1))
        if partial.size:
            row = int(partial[0])
            have = [role for role, here in zip(roles, present[row], strict=True) if here]
            lack = [role for role in roles if role not in have]
            raise DataError(
                f"{_line(row)} has {', '.join(have)} but not {', '.join(lack)}: a row holds all "
                f"of {', '.join(roles)} or none (an empty cell is no value)",
                source=source,
                field=lack[0],
            )
        rows = np.flatnonzero(present[:, 0])
        if group == "sample" and len(t) and not rows.size:
            raise DataError("no values (every cell is empty)", source=source, field=roles[0])
        if group != "sample" and not rows.size:
            continue
        values = {}
        for role in roles:
            column = [cells[role][i] for i in rows]
            values[role] = (
                np.array(column, dtype=object)
                if role == SEGMENT
                else _numbers(column, rows, role, source)
            )
        own = POSE_TIME in values
        stamps = values.pop(POSE_TIME) if own else t[rows]
        streams[group] = TableStream(rows, stamps, values, _line, own_time=own)
    return streams


def read_mat(
    path: str | Path,
    *,
    name: str | None = None,
    series: str | None = None,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    velocities: str = VELOCITIES[0],
    robot: RobotProfile | None = None,
) -> Experiment:
    """Read an experiment from a MATLAB ``.mat`` file (v5/v7, or v7.3 HDF5).

    The columns are numeric vectors named as the CSV columns (or as mapped by
    ``columns``), at the top level or as fields of structs, named
    ``struct.field`` (e.g. ``{"yaw_rate": "log.imu.gyro_z"}``), each as long
    as ``t``; the pose's may have a length of their own with their own time
    ``pose_t`` (a struct ``pose`` with fields ``t, x, y, heading``, mapped
    as ``{"pose_t": "pose.t", "x": "pose.x", ...}``). A segment label is a
    numeric vector. Samples are named by their MATLAB index (from 1) in
    messages. Parameters, returns and errors are those of :func:`read_csv`.

    Examples
    --------
    Columns as fields of a struct ``log``, named ``log.<field>``:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import scipy.io
    >>> from bayes_jackal.io import read_mat
    >>> t = np.arange(100) / 72
    >>> log = {"t": t, "r": np.full_like(t, 0.4), "R": np.full_like(t, 12.0)}
    >>> log["L"] = np.full_like(t, 8.0)
    >>> roles = {"t": "log.t", "yaw_rate": "log.r", "omega_r": "log.R", "omega_l": "log.L"}
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     scipy.io.savemat(Path(folder) / "circle.mat", {"log": log})
    ...     run = read_mat(Path(folder) / "circle.mat", columns=roles)
    >>> print(run.name, len(run.t), round(1 / run.dt, 6))
    circle 100 72.0

    With the poses of a 120 Hz motion capture in a struct of their own (kept:
    the 167 within an IMU step of the samples):

    >>> s = np.arange(170) / 120
    >>> pose = {"t": s, "x": 0.3 * s, "y": 0 * s, "heading": 0 * s}
    >>> roles = {"pose_t": "pose.t", "x": "pose.x", "y": "pose.y", "heading": "pose.heading"}
    >>> flat = {"t": t, "yaw_rate": log["r"], "omega_r": log["R"], "omega_l": log["L"]}
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     scipy.io.savemat(Path(folder) / "mocap.mat", {"pose": pose, **flat})
    ...     run = read_mat(Path(folder) / "mocap.mat", columns=roles)
    >>> print(len(run.t), len(run.pose.t), round(run.pose.rate, 6), run.measurement("vx"))
    100 167 120.0 pose
    """
    path = Path(path)
    source = str(path)
    variables = mat_arrays(path, source)
    names = _mapped(sorted(variables), columns, source)
    vectors = {
        role: mat_vector(variables, name, source, role=role) for role, name in names.items()
    }
    streams = {}
    for group, roles in GROUPS.items():
        values = {role: vectors[role] for role in roles if role in vectors}
        if not values:
            continue
        stamps = values.pop(POSE_TIME, None)
        own = stamps is not None
        stamps = vectors["t"] if stamps is None else stamps
        time = names[POSE_TIME if own else "t"]
        for role, vector in values.items():
            if len(vector) != len(stamps):
                raise DataError(
                    f"{len(vector)} values for the {len(stamps)} of {time!r}: a vector is as "
                    f"long as its time ({POSE_TIME} is the pose's own; the others are on t)",
                    source=source,
                    field=names[role],
                )
        streams[group] = TableStream(
            np.arange(len(stamps)), stamps, values,
            (lambda i, time=time: f"index {i + 1} of {time}") if own else _index, own_time=own,
        )  # fmt: skip
    return table_experiment(
        streams,
        names=names,
        source=source,
        format="mat",
        name=name or path.stem,
        series=series,
        rate=rate,
        max_gap=max_gap,
        velocities=velocities,
        robot=robot,
    )


def _index(row: int) -> str:
    """A MATLAB vector's element (from 0) as MATLAB counts it (from 1)."""
    return f"index {row + 1}"


def read_csv_table(path: Path, source: str) -> tuple[list[str], list[list[str]]]:
    """A CSV file's header (stripped, unique names) and its rows of text cells.

    Shared by :func:`read_csv` and :func:`bayes_jackal.noise.read_noise_series`;
    :func:`numeric_column` reads a column of the rows as numbers.

    Raises
    ------
    DataError
        For an unreadable or empty file, a column named twice, or a line
        with more or fewer fields than the header (naming the line).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.io import numeric_column, read_csv_table
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "gyro.csv"
    ...     _ = path.write_text("t, gyro\\n0,0.5\\n0.01,x\\n")
    ...     header, rows = read_csv_table(path, "gyro.csv")
    >>> header, rows
    (['t', 'gyro'], [['0', '0.5'], ['0.01', 'x']])
    """
    require_file(path, source)
    try:  # utf-8-sig: a byte-order mark (Excel's "CSV UTF-8") is not part of the header
        with open(path, newline="", encoding="utf-8-sig") as stream:
            rows = list(csv.reader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"cannot read CSV ({exc})", source=source) from None
    while rows and not "".join(rows[-1]).strip():  # trailing blank lines
        rows.pop()
    if not rows:
        raise DataError("file is empty", source=source)
    header = [cell.strip() for cell in rows[0]]
    if all(_is_number(name) for name in header if name) and any(header):
        shown = ", ".join(header[:4]) + (", ..." if len(header) > 4 else "")
        raise DataError(
            f"line 1 holds numbers ({shown}), not column names: the header row is missing; "
            "add a first line naming the columns",
            source=source,
        )
    repeated = [name for i, name in enumerate(header) if name and name in header[:i]]
    if repeated:
        raise DataError(
            f"column {repeated[0]!r} appears {header.count(repeated[0])} times in the header; "
            "which one is meant is ambiguous (rename one)",
            source=source,
            field=repeated[0],
        )
    body = rows[1:]
    short = [i for i, row in enumerate(body) if len(row) != len(header)]
    if short:
        raise DataError(
            f"line {short[0] + 2} has {len(body[short[0]])} fields, the header has {len(header)}",
            source=source,
        )
    return header, body


def numeric_column(rows: list[list[str]], index: int, key: str, source: str) -> np.ndarray:
    """Column ``index`` of :func:`read_csv_table`'s rows as floats, named ``key`` in errors.

    Raises
    ------
    DataError
        For a cell that is not a number, naming ``source``, ``key`` and its line.

    Examples
    --------
    >>> from bayes_jackal.io import numeric_column
    >>> rows = [["0", "0.5"], ["0.01", "x"]]
    >>> numeric_column(rows, 0, "t", "gyro.csv")
    array([0.  , 0.01])
    >>> try:
    ...     numeric_column(rows, 1, "gyro", "gyro.csv")
    ... except ValueError as exc:
    ...     print(exc)
    gyro.csv: gyro: non-numeric value 'x' at line 3
    """
    return _numbers([row[index] for row in rows], np.arange(len(rows)), key, source)


def _numbers(cells: list[str], rows: np.ndarray, key: str, source: str) -> np.ndarray:
    """CSV cells as floats; ``rows`` (from 0) name the line of a cell that is not a number."""
    try:
        return np.array(cells, dtype=float)
    except ValueError:
        bad = next(((r, c) for r, c in zip(rows, cells, strict=True) if not _is_number(c)), None)
        if bad is None:
            raise
        raise DataError(
            f"non-numeric value {bad[1]!r} at {_line(int(bad[0]))}", source=source, field=key
        ) from None


def _is_number(cell: str) -> bool:
    """Whether a CSV cell reads as a number, as :func:`numeric_column` reads it."""
    try:
        float(cell)
    except ValueError:
        return False
    return True


def write_csv(experiment: Experiment, path: str | Path) -> Path:
    """Write the measured columns of an experiment as CSV (atomically).

    An experiment's poses are on a clock of their own and are not written
    (a UserWarning says so): read back, its vx, vy are derived velocities,
    which ``velocities="derived"`` declares; the NetCDF experiment file
    (:func:`bayes_jackal.io.write_netcdf`) keeps the poses.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> from bayes_jackal.io import read_csv, write_csv
    >>> run = simulate_experiment(load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = write_csv(run, Path(folder) / "v2.csv")
    ...     header = path.read_text().splitlines()[0]
    ...     back = read_csv(path)
    >>> print(header, len(back.t), back.provenance["repairs"])
    t,yaw_rate,omega_r,omega_l,vx,vy 1873 []
    """
    path = Path(path)
    if experiment.pose is not None:
        warnings.warn(
            f"{path}: the poses of {experiment.name} are not written, only the velocities "
            "derived from them: read the file with velocities='derived' (--velocities derived), "
            "or keep the experiment as .nc, which holds the poses",
            UserWarning,
            stacklevel=2,
        )
    keys = [k for k in (*REQUIRED, *OPTIONAL) if getattr(experiment, k) is not None]
    table = np.column_stack([getattr(experiment, k) for k in keys])
    with atomic_path(path) as temporary:
        np.savetxt(
            temporary, table, delimiter=",", header=",".join(keys), comments="", fmt="%.10g"
        )
    return path


#: Readers of the log formats, by file suffix.
_LOG_READERS = {".csv": read_csv, ".mat": read_mat}


#: Largest relative difference between an experiment's sample rate and its
#: robot profile's rate. A real sensor runs within a fraction of a per cent
#: of its nominal rate, and a profile may round it (72 Hz for 72.3 Hz);
#: time in the wrong unit is off by a factor of 1000 or more.
RATE_TOLERANCE = 0.05
#: Time units a time column is mistaken for, by their size in seconds.
_TIME_UNITS = {"milliseconds": 1e-3, "microseconds": 1e-6, "nanoseconds": 1e-9}


def check_declared_rate(rate: float | None) -> float | None:
    """A declared sample rate [Hz] (``--rate``), refused outside :data:`PLAUSIBLE_RATES`.

    Examples
    --------
    >>> from bayes_jackal.io import check_declared_rate
    >>> check_declared_rate(72), check_declared_rate(None)
    (72.0, None)
    >>> try:
    ...     check_declared_rate(0.072)
    ... except ValueError as error:
    ...     print(error)
    rate: a declared rate of 0.072 Hz (a sample every 13.9 s), outside the rates of sensor
    logs (1-10000 Hz): is the time column in milliseconds? Time must be in seconds
    """
    rate = positive_number(rate, name="rate", unit="Hz")
    if rate is None or (hint := _implausible(rate, "declare the rate in Hz")) is None:
        return rate
    raise InputError(f"a declared rate of {hint}", field="rate")


def check_stamp_rate(rate: float, source: str, field: str) -> None:
    """Refuse a rate the stamps give [Hz] outside :data:`PLAUSIBLE_RATES` (time not in s).

    Examples
    --------
    >>> from bayes_jackal.io.tables import check_stamp_rate
    >>> check_stamp_rate(100.0, "gyro.csv", "t")
    >>> try:
    ...     check_stamp_rate(0.1, "gyro.csv", "t")
    ... except ValueError as error:
    ...     print(error)
    gyro.csv: t: the stamps give 0.1 Hz (a sample every 10 s), outside the rates of sensor
    logs (1-10000 Hz): is the time column in milliseconds? Time must be in seconds
    """
    hint = _implausible(rate, "declare the rate in Hz (--rate; rate= in Python)")
    if hint is not None:
        raise DataError(f"the stamps give {hint}", source=source, field=field)


def _implausible(rate: float, otherwise: str) -> str | None:
    """What is wrong with a rate outside :data:`PLAUSIBLE_RATES` [Hz]; None inside."""
    low, high = PLAUSIBLE_RATES
    if low <= rate <= high:
        return None
    units = [name for name, size in _TIME_UNITS.items() if low <= rate / size <= high]
    hint = f"is the time column in {units[0]}? Time must be in seconds" if units else otherwise
    return (
        f"{rate:g} Hz (a sample every {1 / rate:.3g} s), outside the rates of sensor logs "
        f"({low:g}-{high:g} Hz): {hint}"
    )


def check_sample_time(experiment: Experiment, robot: RobotProfile) -> None:
    """Refuse a sample time no robot log has; say when it differs from the robot's rate.

    A rate within :data:`RATE_TOLERANCE` of the profile's passes. Time in
    the wrong unit (milliseconds, nanoseconds) is refused: a rate that the
    unit would bring to the profile's, or one outside
    :data:`PLAUSIBLE_RATES`, would otherwise be read as a robot sampled a
    thousand (or a billion) times too slowly. Another plausible rate (a
    1 kHz log under the 72 Hz Jackal profile) is accepted with a warning
    naming both rates: the model is discretised at the data's rate.

    Raises
    ------
    DataError
        Naming the file, the sample time and both rates, and what to do.

    Examples
    --------
    Time written in milliseconds is caught against the profile's 72 Hz:

    >>> import dataclasses
    >>> import warnings
    >>> from bayes_jackal._runtime.errors import DataError
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> from bayes_jackal.io import check_sample_time
    >>> robot = load_profile()
    >>> run = simulate_experiment(robot, 110.0, 30.0, "v2", rng=1)
    >>> check_sample_time(run, robot)  # 72 Hz: accepted
    >>> try:
    ...     check_sample_time(dataclasses.replace(run, t=1000 * run.t), robot)
    ... except DataError as exc:
    ...     print(exc)
    <memory>: t: sample time 13.8889 s (0.072 Hz) disagrees with the profile's rate 72 Hz (...)
    by more than 5%: the time column looks like milliseconds; time must be in seconds. ...

    Sampled at 144 Hz, it is accepted and said:

    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     check_sample_time(dataclasses.replace(run, t=run.t / 2), robot)
    >>> print(caught[0].message)
    <memory>: sampled at 144 Hz, not at the profile's 72 Hz (...): the model is discretised
    at 144 Hz; --rate 144 (rate= in Python) says it is meant
    """
    rate = 1.0 / experiment.dt
    if abs(rate / robot.rate - 1.0) <= RATE_TOLERANCE:
        return
    unit = [
        name
        for name, size in _TIME_UNITS.items()
        if abs(experiment.dt * size * robot.rate - 1.0) <= RATE_TOLERANCE
    ]
    low, high = PLAUSIBLE_RATES
    if not unit and low <= rate <= high:
        warnings.warn(
            f"{experiment.source}: sampled at {rate:.6g} Hz, not at the profile's "
            f"{robot.rate:g} Hz ({robot.source}): the model is discretised at {rate:.6g} Hz; "
            f"--rate {rate:.6g} (rate= in Python) says it is meant",
            UserWarning,
            stacklevel=2,
        )
        return
    hint = f"the time column looks like {unit[0]}; " if unit else "time in milliseconds? "
    raise DataError(
        f"sample time {experiment.dt:.6g} s ({rate:.6g} Hz) disagrees with the profile's rate "
        f"{robot.rate:g} Hz ({robot.source}) by more than {RATE_TOLERANCE:.0%}: {hint}time "
        f"must be in seconds. If {rate:.6g} Hz is the true rate, declare it with --rate "
        f"{rate:.6g} (rate= in Python) or use a robot profile with that [sampling] rate",
        source=experiment.source,
        field="t",
    )


def load_experiment(
    path: str | Path,
    *,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    robot: RobotProfile | None = None,
    velocities: str = VELOCITIES[0],
) -> Experiment:
    """Read a CSV (``.csv``), MATLAB (``.mat``) or NetCDF experiment file (``.nc``).

    ``columns``, ``rate``, ``max_gap`` and ``velocities`` are those of
    :func:`read_csv` (``velocities`` for CSV and MATLAB files). The
    column mapping applies to CSV and MATLAB files; a NetCDF experiment file
    is already uniform, and a declared rate must agree with its own (within
    :data:`~bayes_jackal.io.UNIFORM_TOLERANCE`). Given a ``robot``, the
    sample time must agree with its profile's rate (:func:`check_sample_time`)
    unless a rate is declared: the declared rate overrides the profile's; its
    diff-drive formula converts a table's ``cmd_v, cmd_w`` command.

    Examples
    --------
    The reader is chosen by the suffix; with a robot, the rate is checked:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.io import write_netcdf
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> from bayes_jackal.io import load_experiment, write_csv
    >>> robot = load_profile()
    >>> run = simulate_experiment(robot, 110.0, 30.0, "v2", rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     csv = load_experiment(write_csv(run, Path(folder) / "a.csv"), robot=robot)
    ...     nc = load_experiment(write_netcdf(run, Path(folder) / "b.nc"), robot=robot)
    >>> print(csv.name, csv.truth, nc.name, nc.truth["d_lat"])
    a None v2 110.0
    """
    experiment = _read_experiment(
        path, columns=columns, rate=check_declared_rate(rate), max_gap=max_gap,
        velocities=velocities, robot=robot,
    )  # fmt: skip
    if robot is not None and rate is None:
        check_sample_time(experiment, robot)
    return experiment


def _read_experiment(
    path: str | Path,
    *,
    columns: dict[str, str] | None,
    rate: float | None,
    max_gap: float | None,
    velocities: str,
    robot: RobotProfile | None,
) -> Experiment:
    """An experiment file read by its suffix (:func:`load_experiment`)."""
    suffix = Path(path).suffix.lower()
    if suffix in _LOG_READERS:
        return _LOG_READERS[suffix](
            path, columns=columns, rate=rate, max_gap=max_gap, velocities=velocities, robot=robot
        )
    if suffix == ".nc":
        check_column_roles(columns)
        experiment = read_netcdf(path)
        if rate is not None and not abs(experiment.dt * rate - 1.0) <= UNIFORM_TOLERANCE:
            raise DataError(
                f"the declared rate {rate:g} Hz contradicts the file's {1 / experiment.dt:.6g} Hz",
                source=str(path),
                field="t",
            )
        return experiment
    raise DataError(
        f"unknown experiment file type {suffix!r}; expected .csv, .mat or .nc "
        "(bags: read them with bayes_jackal.load_experiments)",
        source=str(path),
    )


def check_unique_names(experiments: Iterable[Experiment]) -> None:
    """Refuse experiments that share a name (a posterior and its files name them).

    Raises
    ------
    DataError
        Naming each shared name and the files of its experiments.

    Examples
    --------
    >>> from bayes_jackal._runtime.errors import DataError
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> from bayes_jackal.io import check_unique_names
    >>> run = simulate_experiment(load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> try:
    ...     check_unique_names([run, run])
    ... except DataError as exc:
    ...     print(exc)
    name: experiment names are not unique: {'v2': ['<memory>', '<memory>']}
    """
    experiments = list(experiments)
    names = [e.name for e in experiments]
    duplicated = {
        n: [e.source for e in experiments if e.name == n] for n in names if names.count(n) > 1
    }
    if duplicated:
        raise DataError(f"experiment names are not unique: {duplicated}", field="name")
