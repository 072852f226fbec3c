"""Experiments: uniformly sampled measured states and wheel-speed inputs.

An :class:`Experiment` is what every analysis consumes: time [s], the
measured yaw rate [rad/s], the wheel speeds (omega_r, omega_l) [rad/s] and,
when known, body-frame vx, vy [m/s]. It comes from a CSV file (DESIGN §2), a
MATLAB ``.mat`` file (v5/v7 via scipy.io, v7.3 via h5py), the package's own
NetCDF experiment file (written by ``simulate`` and ``ingest``), or is built
in memory.

CSV format: a header naming the columns ``t, yaw_rate, omega_r, omega_l`` and
optionally ``vx, vy`` (any order, extra columns ignored), SI units, t in
seconds. MATLAB files hold the same names as vectors, at the top level or as
fields of a struct (``log.t``). Columns named otherwise are mapped with
``columns={"yaw_rate": "gyro_z", ...}`` (role to column). The CSV and MATLAB
readers put the stamps on a uniform clock by the rules of
:mod:`bayes_jackal.stamps` (jitter, repeated and out-of-order stamps, gaps)
and record what they did in ``provenance["time_base"]`` and
``provenance["repairs"]``; an :class:`Experiment` itself must be uniform.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from ._files import atomic_path
from ._matlab import mat_arrays
from .errors import DataError, InputError
from .physics import CHANNELS
from .stamps import MIN_SAMPLES, UNIFORM_TOLERANCE, uniform_clock

__all__ = [
    "Experiment",
    "check_column_roles",
    "load_experiment",
    "load_experiments",
    "read_csv",
    "read_mat",
    "read_netcdf",
    "write_csv",
    "write_netcdf",
]

FORMAT = "bayes_jackal.experiment/1"
REQUIRED = ("t", "yaw_rate", "omega_r", "omega_l")
OPTIONAL = ("vx", "vy")
#: Column roles a file's columns can be mapped to (``columns=``, ``--column``).
ROLES = (*REQUIRED, *OPTIONAL)
UNITS = {
    "t": "s",
    "yaw_rate": "rad/s",
    "omega_r": "rad/s",
    "omega_l": "rad/s",
    "vx": "m/s",
    "vy": "m/s",
}
#: Series label of experiments that carry none (grid and sigma_h tables).
UNLABELLED = "unlabelled"
#: Measured-state field of each model channel.
CHANNEL_FIELDS = {"vx": "vx", "vy": "vy", "yaw": "yaw_rate"}


@dataclass(frozen=True, eq=False)
class Experiment:
    """One uniformly sampled run of the robot.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Sample times [s], strictly increasing and uniform.
    yaw_rate : ndarray, shape (N,)
        Measured yaw rate r [rad/s] (IMU).
    omega_r, omega_l : ndarray, shape (N,)
        Right and left wheel speeds [rad/s], the model input.
    vx, vy : ndarray, shape (N,), optional
        Body-frame longitudinal and lateral velocity [m/s].
    name : str
        Short name (the file stem for files).
    series : str, optional
        Label of the input setting, e.g. ``"v1"``; grid searches average per
        series (thesis eq. 5-2).
    steady_window : (float, float), optional
        Start and end [s] of steady-state cornering.
    truth : dict, optional
        Known parameters of a simulated experiment.
    truth_arrays : dict of str to ndarray
        Known noise-free states and noise of a simulated experiment.
    provenance : dict
        Where the data came from and what was repaired.
    source : str
        File it was read from, or ``"<memory>"``.
    """

    t: np.ndarray
    yaw_rate: np.ndarray
    omega_r: np.ndarray
    omega_l: np.ndarray
    vx: np.ndarray | None = None
    vy: np.ndarray | None = None
    name: str = "experiment"
    series: str | None = None
    steady_window: tuple[float, float] | None = None
    truth: dict | None = None
    truth_arrays: dict[str, np.ndarray] = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    source: str = "<memory>"

    def __post_init__(self) -> None:
        columns = {key: getattr(self, key) for key in (*REQUIRED, *OPTIONAL)}
        columns = {
            key: np.asarray(value, float) for key, value in columns.items() if value is not None
        }
        _check_values(columns, self.source, lambda i: f"sample {i}")
        _check_uniform(columns["t"], self.source, lambda i: f"sample {i}")
        for key, value in columns.items():
            value.setflags(write=False)
            object.__setattr__(self, key, value)

    @property
    def dt(self) -> float:
        """Sample time [s] (mean step)."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    @property
    def inputs(self) -> np.ndarray:
        """Wheel speeds (omega_r, omega_l) [rad/s], shape (N, 2)."""
        return np.column_stack([self.omega_r, self.omega_l])

    @property
    def channels(self) -> tuple[str, ...]:
        """Model channels (``vx``, ``vy``, ``yaw``) this experiment measures."""
        return tuple(c for c in CHANNELS if getattr(self, CHANNEL_FIELDS[c]) is not None)

    def channel(self, name: str) -> np.ndarray:
        """Measured state of one model channel (``"vx"``, ``"vy"`` or ``"yaw"``)."""
        if name not in CHANNEL_FIELDS:
            raise DataError(f"unknown channel {name!r}; use one of {CHANNELS}", field="channel")
        values = getattr(self, CHANNEL_FIELDS[name])
        if values is None:
            raise DataError(
                f"channel {name!r} is not in this experiment",
                source=self.source,
                field=CHANNEL_FIELDS[name],
            )
        return values

    def states(self) -> np.ndarray:
        """States (vx, vy, r), shape (N, 3); channels not measured are NaN."""
        missing = np.full_like(self.t, np.nan)
        return np.column_stack(
            [missing if c not in self.channels else self.channel(c) for c in CHANNELS]
        )

    def window(self, start: float, stop: float) -> Experiment:
        """The samples with ``start <= t <= stop`` [s] as a new experiment."""
        keep = (self.t >= start) & (self.t <= stop)
        if keep.sum() < MIN_SAMPLES:
            raise DataError(
                f"window [{start}, {stop}] s holds {keep.sum()} samples "
                f"(data span {self.t[0]:.3f}..{self.t[-1]:.3f} s)",
                source=self.source,
                field="window",
            )
        cut = {
            key: getattr(self, key)[keep]
            for key in (*REQUIRED, *OPTIONAL)
            if getattr(self, key) is not None
        }
        arrays = {key: value[keep] for key, value in self.truth_arrays.items()}
        return dataclasses.replace(self, **cut, truth_arrays=arrays, steady_window=None)

    def steady(self) -> Experiment:
        """The steady-state window, or the whole experiment when none is set."""
        return self if self.steady_window is None else self.window(*self.steady_window)


def _check_values(
    columns: dict[str, np.ndarray], source: str, row_name: Callable[[int], str]
) -> None:
    """Check lengths and finiteness; ``row_name`` labels sample i."""
    lengths = {key: value.shape for key, value in columns.items()}
    if len(set(lengths.values())) != 1 or len(columns["t"].shape) != 1:
        raise DataError(f"columns differ in length or are not 1-D: {lengths}", source=source)
    if len(columns["t"]) < MIN_SAMPLES:
        raise DataError(
            f"only {len(columns['t'])} samples; at least {MIN_SAMPLES} are needed", source=source
        )
    for key, values in columns.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise DataError(
                f"{values[bad[0]]} at {row_name(bad[0])} ({bad.size} non-finite values)",
                source=source,
                field=key,
            )


def _check_uniform(t: np.ndarray, source: str, row_name: Callable[[int], str]) -> None:
    """An experiment's own time must increase uniformly (the readers make it so)."""
    steps = np.diff(t)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise DataError(
            f"time does not increase at {row_name(i)}: {t[i - 1]:.10g} -> {t[i]:.10g} s "
            "(bayes_jackal.stamps.uniform_clock repairs stamps)",
            source=source,
            field="t",
        )
    median = float(np.median(steps))
    off = np.flatnonzero(np.abs(steps - median) > UNIFORM_TOLERANCE * median)
    if off.size:
        i = int(off[0]) + 1
        raise DataError(
            f"time is not uniformly sampled at {row_name(i)}: step {steps[i - 1]:.6g} s, "
            f"median step {median:.6g} s (tolerance {UNIFORM_TOLERANCE:.0%}); resample first "
            "(bayes_jackal.stamps.uniform_clock repairs stamps)",
            source=source,
            field="t",
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
) -> Experiment:
    """An experiment from a file's columns (by role), on the uniform clock of its stamps."""
    _check_values(columns, source, row_name)
    clock = uniform_clock(
        columns["t"], rate=rate, max_gap=max_gap, source=source, row_name=row_name
    )
    provenance = {
        "source": source,
        "format": format,
        "columns": names,
        "time_base": clock.provenance,
        "repairs": clock.repairs,
    }
    return Experiment(
        t=clock.t,
        **{role: clock.resample(values) for role, values in columns.items() if role != "t"},
        name=name,
        series=series,
        provenance=provenance,
        source=source,
    )


def read_csv(
    path: str | Path,
    *,
    name: str | None = None,
    series: str | None = None,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
) -> Experiment:
    """Read an experiment from a CSV file (DESIGN §2).

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
        Longest gap [s] filled by interpolation (:func:`bayes_jackal.stamps.uniform_clock`).

    Raises
    ------
    DataError
        Naming the file, the column and the line of the first bad value.
    InputError
        For an unknown column role or a rate that is not a positive number.
    """
    path = Path(path)
    source = str(path)
    try:
        with open(path, newline="") as stream:
            rows = list(csv.reader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"cannot read CSV ({exc})", source=source) from None
    if not rows:
        raise DataError("file is empty", source=source)
    header = [cell.strip() for cell in rows[0]]
    names = _mapped(header, columns, source)
    body = rows[1:]
    short = [i for i, row in enumerate(body) if len(row) != len(header)]
    if short:
        raise DataError(
            f"line {short[0] + 2} has {len(body[short[0]])} fields, the header has {len(header)}",
            source=source,
        )
    values = {
        role: _numeric_column(body, header.index(column), column, source)
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
    )


def read_mat(
    path: str | Path,
    *,
    name: str | None = None,
    series: str | None = None,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
) -> Experiment:
    """Read an experiment from a MATLAB ``.mat`` file (v5/v7, or v7.3 HDF5).

    The columns are numeric vectors named as the CSV columns (or as mapped by
    ``columns``), at the top level or as fields of structs, named
    ``struct.field`` (e.g. ``{"yaw_rate": "log.imu.gyro_z"}``). Samples are
    named by their MATLAB index (from 1) in messages. Parameters, returns
    and errors are those of :func:`read_csv`.
    """
    path = Path(path)
    source = str(path)
    variables = mat_arrays(path, source)
    names = _mapped(sorted(variables), columns, source)
    values = {}
    for role, variable in names.items():
        vector = np.squeeze(variables[variable])
        if vector.ndim != 1:
            raise DataError(
                f"variable {variable!r} ({role}) has shape {variables[variable].shape}; a vector "
                "is needed",
                source=source,
                field=variable,
            )
        values[role] = vector.astype(float)
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
    )


def _numeric_column(rows: list[list[str]], index: int, key: str, source: str) -> np.ndarray:
    cells = [row[index] for row in rows]
    try:
        return np.array(cells, dtype=float)
    except ValueError:
        for line, cell in enumerate(cells, start=2):
            try:
                float(cell)
            except ValueError:
                raise DataError(
                    f"non-numeric value {cell!r} at line {line}", source=source, field=key
                ) from None
        raise


def write_csv(experiment: Experiment, path: str | Path) -> Path:
    """Write the measured columns of an experiment as CSV (atomically)."""
    path = Path(path)
    keys = [k for k in (*REQUIRED, *OPTIONAL) if getattr(experiment, k) is not None]
    table = np.column_stack([getattr(experiment, k) for k in keys])
    with atomic_path(path) as temporary:
        np.savetxt(
            temporary, table, delimiter=",", header=",".join(keys), comments="", fmt="%.10g"
        )
    return path


def write_netcdf(experiment: Experiment, path: str | Path) -> Path:
    """Write an experiment, with its truth and provenance, as NetCDF (atomically)."""
    path = Path(path)
    data = {
        key: ("time", getattr(experiment, key), {"units": UNITS[key]})
        for key in (*REQUIRED[1:], *OPTIONAL)
        if getattr(experiment, key) is not None
    }
    data |= {f"truth_{key}": ("time", value) for key, value in experiment.truth_arrays.items()}
    attrs = {
        "format": FORMAT,
        "name": experiment.name,
        "series": experiment.series or "",
        "truth": json.dumps(experiment.truth),
        "provenance": json.dumps(experiment.provenance),
    }
    if experiment.steady_window is not None:
        attrs["steady_window"] = list(experiment.steady_window)
    dataset = xr.Dataset(
        data, coords={"time": ("time", experiment.t, {"units": "s"})}, attrs=attrs
    )
    with atomic_path(path) as temporary:
        dataset.to_netcdf(temporary, engine="h5netcdf")
    return path


def read_netcdf(path: str | Path) -> Experiment:
    """Read an experiment file written by :func:`write_netcdf`.

    Raises
    ------
    DataError
        When the file is missing, not NetCDF, not an experiment file, or
        lacks a required variable.
    """
    path = Path(path)
    source = str(path)
    try:
        with xr.open_dataset(path, engine="h5netcdf") as dataset:
            dataset = dataset.load()
    except FileNotFoundError:
        raise DataError("no such file", source=source) from None
    except (OSError, ValueError) as exc:
        raise DataError(f"not a readable NetCDF file ({exc})", source=source) from None
    if dataset.attrs.get("format") != FORMAT:
        raise DataError(
            f"not a bayes_jackal experiment file (format {dataset.attrs.get('format')!r})",
            source=source,
            field="format",
        )
    missing = [key for key in REQUIRED[1:] if key not in dataset]
    if missing:
        raise DataError(f"missing variable(s) {missing}", source=source, field=missing[0])
    window = dataset.attrs.get("steady_window")
    return Experiment(
        t=dataset["time"].values,
        **{key: dataset[key].values for key in (*REQUIRED[1:], *OPTIONAL) if key in dataset},
        name=str(dataset.attrs.get("name") or path.stem),
        series=str(dataset.attrs.get("series", "")) or None,
        steady_window=None if window is None else (float(window[0]), float(window[1])),
        truth=json.loads(dataset.attrs.get("truth", "null")),
        truth_arrays={
            key.removeprefix("truth_"): dataset[key].values
            for key in dataset.data_vars
            if key.startswith("truth_")
        },
        provenance=json.loads(dataset.attrs.get("provenance", "{}")),
        source=source,
    )


#: Readers of the log formats, by file suffix.
_LOG_READERS = {".csv": read_csv, ".mat": read_mat}


def load_experiment(
    path: str | Path,
    *,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
) -> Experiment:
    """Read a CSV (``.csv``), MATLAB (``.mat``) or NetCDF experiment file (``.nc``).

    ``columns``, ``rate`` and ``max_gap`` are those of :func:`read_csv`. The
    column mapping applies to CSV and MATLAB files; a NetCDF experiment file
    is already uniform, and a declared rate must agree with its own (within
    :data:`~bayes_jackal.stamps.UNIFORM_TOLERANCE`).
    """
    suffix = Path(path).suffix.lower()
    if suffix in _LOG_READERS:
        return _LOG_READERS[suffix](path, columns=columns, rate=rate, max_gap=max_gap)
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
        "(ingest bags first with `bayes-jackal ingest`)",
        source=str(path),
    )


def load_experiments(
    paths: list[str | Path],
    *,
    columns: dict[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
) -> list[Experiment]:
    """Read several experiment files (:func:`load_experiment`); names must be unique."""
    check_column_roles(columns)
    experiments = [
        load_experiment(path, columns=columns, rate=rate, max_gap=max_gap) for path in paths
    ]
    names = [e.name for e in experiments]
    duplicated = {
        n: [e.source for e in experiments if e.name == n] for n in names if names.count(n) > 1
    }
    if duplicated:
        raise DataError(f"experiment names are not unique: {duplicated}", field="name")
    return experiments
