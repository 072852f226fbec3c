"""CSV and MATLAB tables: column mapping and stamp repair into an Experiment.

Also :func:`load_experiment(s) <load_experiment>`, which reads any experiment
file by its suffix (the NetCDF experiment file lives in
:mod:`bayes_jackal.io.experiment`, the MATLAB container in
:mod:`bayes_jackal.io._matlab`).

CSV format: a header naming the columns ``t, yaw_rate, omega_r, omega_l`` and
optionally ``vx, vy`` and the motion-capture pose ``x, y, heading`` (any
order, extra columns ignored), SI units, t in seconds. With the pose, vx and
vy are modelled through it (docs/design.md §2.2; derived from it for plots
where the file has no vx, vy columns); without it, vx and vy are modelled as
measured, and ``velocities="derived"`` (``--velocities derived``) records
that they were derived from poses the file lacks, which a posterior warns
of. MATLAB files hold the same names as vectors, at the top level or as
fields of a struct (``log.t``). Columns named otherwise are mapped with
``columns={"yaw_rate": "gyro_z", ...}`` (role to column). The CSV and MATLAB
readers put the stamps on a uniform clock by the rules of
:mod:`bayes_jackal.io.stamps` (jitter, repeated and out-of-order stamps, gaps)
and record what they did in ``provenance["time_base"]`` and
``provenance["repairs"]``.
"""

from __future__ import annotations

import csv
import warnings
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import numpy as np

from .._runtime.defaults import OPTIONAL, POSE_ROLES, REQUIRED, ROLES, VELOCITIES
from .._runtime.errors import DataError, InputError
from .._runtime.files import atomic_path, require_file
from .._runtime.validation import positive_number
from ..model.robot import RobotProfile
from ._matlab import mat_arrays, mat_vector
from .experiment import Experiment, check_values, read_netcdf
from .pose_track import PoseTrack, body_velocities
from .stamps import PLAUSIBLE_RATES, UNIFORM_TOLERANCE, uniform_clock

__all__ = [
    "RATE_TOLERANCE",
    "check_column_roles",
    "check_columns_apply",
    "check_declared_rate",
    "check_sample_time",
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
    ['t', 'yaw_rate', 'omega_r', 'omega_l', 'vx', 'vy', 'x', 'y', 'heading']
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
    if optional, an error if required).
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
    missing = [role for role in REQUIRED if names.get(role) not in available]
    if missing:
        used = [f"{role!r} is mapped to {taken[role]}" for role in missing if role in taken]
        raise DataError(
            f"missing column(s) {missing}; the file has {available}"
            f"{' (' + ', '.join(used) + ')' if used else ''} (name yours with "
            "--column ROLE NAME, columns= in Python)",
            source=source,
            field=missing[0],
        )
    return {role: name for role, name in names.items() if name in available}


def _from_columns(
    columns: dict[str, np.ndarray],
    names: dict[str, str],
    source: str,
    row_name: Callable[[int], str],
    format: str,
    *,
    name: str,
    series: str | None,
    rate: float | None,
    max_gap: float | None,
    velocities: str,
) -> Experiment:
    """An experiment from a file's columns (by role), on the uniform clock of its stamps.

    The pose columns, where the file has them, become its
    :class:`~bayes_jackal.io.PoseTrack`: the samples kept, at their
    ticks (a filled tick is no pose), the heading unwrapped.
    """
    if velocities not in VELOCITIES:
        raise InputError(
            f"unknown velocities {velocities!r}; use one of {VELOCITIES}", field="velocities"
        )
    check_values(columns, source, row_name)
    clock = uniform_clock(
        columns["t"], rate=rate, max_gap=max_gap, source=source, row_name=row_name
    )
    measured = {
        role: clock.resample(values)
        for role, values in columns.items()
        if role not in ("t", *POSE_ROLES)
    }
    pose = _pose_columns(columns, clock.t[clock.ticks], clock.rows, source)
    if pose is not None:
        velocities = "derived"
        if "vx" not in measured:
            measured["vx"], measured["vy"] = body_velocities(pose, clock.t)
    provenance = {
        "source": source,
        "format": format,
        "columns": names,
        "time_base": clock.provenance,
        "repairs": clock.repairs,
    }
    if "vx" in measured:
        provenance["velocities"] = velocities
    return Experiment(
        t=clock.t,
        **measured,
        pose=pose,
        name=name,
        series=series,
        provenance=provenance,
        source=source,
    )


def _pose_columns(
    columns: dict[str, np.ndarray], t: np.ndarray, rows: np.ndarray, source: str
) -> PoseTrack | None:
    """The pose of the columns x, y, heading at the times ``t`` of their ``rows``; None without."""
    present = [role for role in POSE_ROLES if role in columns]
    if not present:
        return None
    if len(present) < len(POSE_ROLES):
        missing = [role for role in POSE_ROLES if role not in columns]
        raise DataError(
            f"a pose needs the columns {list(POSE_ROLES)}; the file has {present}, not {missing}",
            source=source,
            field=missing[0],
        )
    x, y, heading = (columns[role][rows] for role in POSE_ROLES)
    return PoseTrack(t, x, y, np.unwrap(heading), source=source)


def read_csv(
    path: str | Path,
    *,
    name: str | None = None,
    series: str | None = None,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    velocities: str = VELOCITIES[0],
) -> Experiment:
    """Read an experiment from a CSV file (docs/design.md §2).

    Parameters
    ----------
    path : str or Path
        CSV with a header naming ``t, yaw_rate, omega_r, omega_l`` and
        optionally ``vx, vy`` (or the names in ``columns``).
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

    Raises
    ------
    DataError
        Naming the file, the column and the line of the first bad value.
    InputError
        For an unknown column role or a rate that is not a positive number.

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
    """
    path = Path(path)
    source = str(path)
    header, body = read_csv_table(path, source)
    names = _mapped(header, columns, source)
    values = {
        role: numeric_column(body, header.index(column), column, source)
        for role, column in names.items()
    }
    return _from_columns(
        values,
        names,
        source,
        lambda i: f"line {i + 2}",
        "csv",
        name=name or path.stem,
        series=series,
        rate=rate,
        max_gap=max_gap,
        velocities=velocities,
    )


def read_mat(
    path: str | Path,
    *,
    name: str | None = None,
    series: str | None = None,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    velocities: str = VELOCITIES[0],
) -> Experiment:
    """Read an experiment from a MATLAB ``.mat`` file (v5/v7, or v7.3 HDF5).

    The columns are numeric vectors named as the CSV columns (or as mapped by
    ``columns``), at the top level or as fields of structs, named
    ``struct.field`` (e.g. ``{"yaw_rate": "log.imu.gyro_z"}``). Samples are
    named by their MATLAB index (from 1) in messages. Parameters, returns
    and errors are those of :func:`read_csv`.

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
    """
    path = Path(path)
    source = str(path)
    variables = mat_arrays(path, source)
    names = _mapped(sorted(variables), columns, source)
    values = {}
    for role, variable in names.items():
        values[role] = mat_vector(variables, variable, source, role=role)
    return _from_columns(
        values,
        names,
        source,
        lambda i: f"index {i + 1}",
        "mat",
        name=name or path.stem,
        series=series,
        rate=rate,
        max_gap=max_gap,
        velocities=velocities,
    )


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
    cells = [row[index] for row in rows]
    try:
        return np.array(cells, dtype=float)
    except ValueError:
        bad = next(((n, c) for n, c in enumerate(cells, start=2) if not _is_number(c)), None)
        if bad is None:
            raise
        raise DataError(
            f"non-numeric value {bad[1]!r} at line {bad[0]}", source=source, field=key
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
    rate: a declared rate of 0.072 Hz (a sample every 13.9 s) is outside the rates of sensor
    logs (1-10000 Hz): is the time column in milliseconds? Time must be in seconds
    """
    rate = positive_number(rate, name="rate", unit="Hz")
    low, high = PLAUSIBLE_RATES
    if rate is None or low <= rate <= high:
        return rate
    units = [name for name, size in _TIME_UNITS.items() if low <= rate / size <= high]
    hint = f"is the time column in {units[0]}? Time must be in seconds" if units else (
        "declare the rate in Hz")  # fmt: skip
    raise InputError(
        f"a declared rate of {rate:g} Hz (a sample every {1 / rate:.3g} s) is outside the "
        f"rates of sensor logs ({low:g}-{high:g} Hz): {hint}",
        field="rate",
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
    unless a rate is declared: the declared rate overrides the profile's.

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
        velocities=velocities,
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
) -> Experiment:
    """An experiment file read by its suffix (:func:`load_experiment`)."""
    suffix = Path(path).suffix.lower()
    if suffix in _LOG_READERS:
        return _LOG_READERS[suffix](
            path, columns=columns, rate=rate, max_gap=max_gap, velocities=velocities
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
