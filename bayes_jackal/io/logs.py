"""Logs in, experiments out: any mix of bags and experiment files, each read as it was recorded.

:func:`read_log` reads one input (a ROS bag or bag folder, or an experiment
file: ``.csv``, ``.mat``, ``.nc``); :func:`read_logs` and
:func:`load_experiments` read many, naming each one that cannot be used;
:func:`ingest_logs` also writes each as an experiment file
(``bayes-jackal ingest``, the first step of ``analyse``).
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from .._runtime import VELOCITIES, DataError, describe, each_input, refuse
from ..model import RobotProfile, as_profile
from .bag_reading import bag_format
from .bags import read_bag
from .experiment import Experiment, write_netcdf
from .tables import (
    check_column_roles,
    check_columns_apply,
    check_declared_rate,
    check_unique_names,
    load_experiment,
)

__all__ = ["ReadOptions", "ingest_logs", "load_experiments", "read_log", "read_logs"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)


@dataclass(frozen=True)
class ReadOptions:
    """How logs are read: the window, the longest gap, column roles, rate and velocities.

    The flags ``--window``, ``--max-gap``, ``--column``, ``--rate`` and
    ``--velocities``: one object for every reader of logs (:func:`read_log`,
    :func:`ingest_logs`, :func:`bayes_jackal.workflow.analyse_logs`);
    :func:`load_experiments` and :func:`read_logs` take the same as keywords.

    Parameters
    ----------
    window : (float, float), optional
        Steady window [s on each experiment's time axis; for bags, from the
        first IMU stamp]; detected in bags, the whole run in files, when
        omitted.
    max_gap : float, optional
        Longest tolerated dropout [s]; None: the defaults of
        :func:`~bayes_jackal.io.read_bag` (0.25 s) and of
        :func:`~bayes_jackal.io.load_experiment`.
    columns : mapping of str to str, optional
        Column roles of CSV and MATLAB files (``{"t": "time"}``).
    rate : float, optional
        Declared sample rate of experiment files [Hz].
    velocities : {"measured", "derived"}
        Whether a table's vx, vy were measured or derived from poses.

    Examples
    --------
    >>> from bayes_jackal.io import ReadOptions
    >>> ReadOptions(window=(3, 35), columns={"t": "time"}).table_keywords
    {'columns': {'t': 'time'}, 'rate': None, 'velocities': 'measured'}
    """

    window: tuple[float, float] | None = None
    max_gap: float | None = None
    columns: Mapping[str, str] | None = None
    rate: float | None = None
    velocities: str = VELOCITIES[0]

    @property
    def table_keywords(self) -> dict:
        """The keywords of :func:`~bayes_jackal.io.load_experiment` these options set."""
        return {"columns": self.columns, "rate": self.rate, "velocities": self.velocities}


def read_log(
    path: str | Path,
    robot: RobotProfile,
    *,
    read_options: ReadOptions | None = None,
    progress: bool = False,
) -> Experiment:
    """One input as an experiment: a bag as ``ingest`` reads it, or an experiment file.

    Parameters
    ----------
    path : str or Path
        A bag (:data:`BAG_SUFFIXES`, or a ROS2 bag folder) or an experiment
        file (``.csv``, ``.mat``, ``.nc``).
    robot : RobotProfile
        Topics and wheel joints of a bag; the rate an experiment file's
        sample time must agree with (:func:`~bayes_jackal.io.check_sample_time`).
    read_options : ReadOptions, optional
    progress : bool
        Show a bag's progress on stderr.

    Returns
    -------
    Experiment

    Examples
    --------
    An experiment file as is, or cut to a window [s]:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import Series, simulate_experiment
    >>> from bayes_jackal.io import write_csv
    >>> from bayes_jackal.io import ReadOptions, read_log
    >>> robot = load_profile()
    >>> run = simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = write_csv(run, Path(folder) / "short.csv")
    ...     whole = read_log(path, robot)
    ...     steady = read_log(path, robot, read_options=ReadOptions(window=(2.0, 6.0)))
    >>> print(whole.name, len(whole.t), whole.steady_window, steady.steady_window)
    short 577 None (2.0, 6.0)
    """
    path = Path(path)
    options = read_options or ReadOptions()
    if bag_format(path) is not None:
        gap = {} if options.max_gap is None else {"max_gap": options.max_gap}
        return read_bag(path, robot, window=options.window, progress=progress, **gap)
    experiment = load_experiment(
        path, robot=robot, max_gap=options.max_gap, **options.table_keywords
    )
    window = options.window
    if window is None:
        return experiment
    experiment.window(*window)  # raises DataError when it holds too few samples
    return dataclasses.replace(experiment, steady_window=tuple(float(w) for w in window))


def ingest_logs(
    paths: Sequence[str | Path],
    robot: RobotProfile,
    folder: str | Path,
    *,
    read_options: ReadOptions | None = None,
    progress: bool = False,
    labels: Mapping[str, Mapping] | None = None,
) -> tuple[list[Experiment], dict[str, str]]:
    """Read every input, write each as ``folder/<name>.nc``; keep going past bad ones.

    Two inputs of one experiment name are both kept: the later one is
    written as ``<name>-2.nc`` (``-3``...), named so, with ``renamed_from``
    in its provenance, and the ``bayes_jackal.io`` logger tells.

    Parameters
    ----------
    paths : sequence of str or Path
        Bags (``.bag``, ``.mcap``, ``.db3``, ROS2 bag folders) and
        experiment files (``.csv``, ``.mat``, ``.nc``).
    robot : RobotProfile
        Topics, wheel joints and constants.
    folder : str or Path
        Where the experiment files go.
    read_options : ReadOptions, optional
        The window, the longest dropout and how experiment files are read.
    progress : bool
        Show each bag's progress on stderr.
    labels : mapping, optional
        Per input path (as given), Experiment fields to set, e.g. ``series``
        and ``truth`` of a simulated run.

    Returns
    -------
    experiments : list of Experiment
    failed : dict of str to str
        The reason for each input that could not be used, by path.

    Examples
    --------
    A CSV file, a bag of the same short run (8 s) and a missing file: the
    two are written as experiment files, the third is reported:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.io import write_bag
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import Series, simulate_experiment
    >>> from bayes_jackal.io import write_csv
    >>> from bayes_jackal.io import ingest_logs
    >>> robot = load_profile()
    >>> run = simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     logs = [
    ...         write_csv(run, Path(folder) / "table.csv"),
    ...         write_bag(run, Path(folder) / "recording.bag", robot, "ros1", rng=1),
    ...         Path(folder) / "lost.bag",
    ...     ]
    ...     experiments, failed = ingest_logs(logs, robot, Path(folder) / "experiments")
    ...     written = sorted(path.name for path in (Path(folder) / "experiments").iterdir())
    >>> [(e.name, e.steady_window is not None) for e in experiments], written
    ([('table', False), ('recording', True)], ['recording.nc', 'table.nc'])
    >>> [reason.rsplit(": ", 1)[1] for reason in failed.values()]
    ['no such file']
    """
    owners: dict[str, str] = {}
    inputs = {Path(given).resolve() for given in paths}

    def ingest(given: str | Path) -> Experiment:
        path = Path(given)
        experiment = read_log(path, robot, read_options=read_options, progress=progress)
        name, target = _target(experiment.name, Path(folder), path, inputs, owners)
        experiment = dataclasses.replace(experiment, **(labels or {}).get(str(given), {}))
        if name != experiment.name:  # two inputs of one name: both kept, the second renamed
            taken = owners[experiment.name]
            _log.info(f"  {given}: its name {experiment.name} is {taken}'s; ingested as {name}")
            provenance = {**experiment.provenance, "renamed_from": experiment.name}
            experiment = dataclasses.replace(experiment, name=name, provenance=provenance)
        owners[experiment.name] = str(given)
        write_netcdf(experiment, target)
        window_text = (
            "{:.2f}-{:.2f} s".format(*experiment.steady_window)
            if experiment.steady_window
            else "none (whole run)"
        )
        _log.info(
            f"  ingested {given}: {len(experiment.t)} samples at {1 / experiment.dt:.1f} Hz, "
            f"channels {', '.join(experiment.channels)}, steady window {window_text}"
        )
        return experiment

    # one bad input does not lose the others
    ingested, failed = each_input(
        paths, ingest, on_failure=lambda given, exc: _log.info(f"  skipped {describe(exc, given)}")
    )
    return list(ingested.values()), failed


def _target(
    name: str, folder: Path, source: Path, inputs: set[Path], taken: Mapping[str, str]
) -> tuple[str, Path]:
    """A free name and ``folder/<name>.nc`` for an input.

    A name an earlier input ``taken`` gets a suffix ``-2``, ``-3``...;
    refused for a name that is no plain file name or whose file is an input.
    """
    if name in ("", ".", "..") or any(sep in name for sep in ("/", "\\")):
        raise DataError(
            f"its experiment name {name!r} cannot name a file; rename the experiment",
            source=str(source),
            field="name",
        )
    free, count = name, 1
    while free in taken:
        count += 1
        free = f"{name}-{count}"
    target = folder / f"{free}.nc"
    if target.resolve() in inputs:
        raise DataError(
            f"writing it as {target} would overwrite an input; choose another output folder",
            source=str(source),
        )
    return free, target


def load_experiments(
    paths: str | Path | Sequence[str | Path],
    *,
    robot: RobotProfile | str | Path | None = None,
    columns: Mapping[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    window: tuple[float, float] | None = None,
    progress: bool = False,
    velocities: str = VELOCITIES[0],
) -> list[Experiment]:
    """Read logs as experiments: CSV, MATLAB ``.mat``, NetCDF ``.nc`` files and ROS bags.

    Each input is read as ``bayes-jackal analyse`` reads it
    (:func:`bayes_jackal.io.read_log`): a bag (``.bag``, ``.mcap``,
    ``.db3`` or a ROS2 bag folder) as ``ingest`` does, an experiment file
    by :func:`bayes_jackal.io.load_experiment`. All or none: a bad
    input stops the call, and the error names every bad one.

    Parameters
    ----------
    paths : str, Path or sequence of them
        The logs.
    robot : RobotProfile, str or Path, optional
        A profile or its TOML file; the Jackal's by default (``--robot``).
        Its topics and wheel joints read bags; an experiment file's sample
        rate is checked against its rate unless ``rate`` is given
        (:func:`~bayes_jackal.io.check_sample_time`: a time unit slip is
        refused, another plausible rate said).
    columns : mapping of str to str, optional
        CSV and MATLAB files: the file's column for a role, e.g.
        ``{"yaw_rate": "gyro_z"}`` (``--column``).
    rate : float, optional
        CSV and MATLAB files: the declared sample rate [Hz]; detected from
        the stamps by default (``--rate``).
    velocities : {"measured", "derived"}
        CSV and MATLAB files without pose columns: whether their vx, vy
        were measured or derived from poses (``--velocities``;
        :func:`bayes_jackal.io.read_csv`).
    max_gap : float, optional
        Longest tolerated dropout [s]; by default 0.25 s in bags and 5
        sample steps in files (``--max-gap``).
    window : (float, float), optional
        The steady window [s; in bags from the first IMU stamp]; by default
        detected in bags, the whole run in files (``--window``).
    progress : bool
        Show each bag's progress on stderr.

    Returns
    -------
    list of Experiment
        In the order given; their names are unique.

    Raises
    ------
    DataError
        Naming every input that cannot be read and why, or experiments that
        share a name.
    InputError
        For an unknown column role.

    Examples
    --------
    A CSV of a simulated run (time in s, yaw rate and wheel speeds in
    rad/s, vx and vy in m/s), read back:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1, name="v1_01")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     csv = bj.write_csv(run, Path(folder) / "v1_01.csv")
    ...     [loaded] = bj.load_experiments([csv])
    >>> loaded.name, loaded.channels, round(1 / loaded.dt)
    ('v1_01', ('vx', 'vy', 'yaw'), 72)
    """
    paths = _paths(paths)
    experiments, failed = read_logs(
        paths,
        robot=robot,
        columns=columns,
        rate=rate,
        max_gap=max_gap,
        window=window,
        progress=progress,
        velocities=velocities,
    )
    refuse(failed, len(paths))
    return list(experiments.values())


def read_logs(
    paths: str | Path | Sequence[str | Path],
    *,
    robot: RobotProfile | str | Path | None = None,
    columns: Mapping[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    window: tuple[float, float] | None = None,
    progress: bool = False,
    on_failure: Callable[[str, Exception], None] | None = None,
    velocities: str = VELOCITIES[0],
) -> tuple[dict[str, Experiment], dict[str, str]]:
    """Read each log on its own, past the bad ones (:func:`load_experiments`: all or none).

    The reader of ``bayes-jackal sample``, ``compare``, ``grid`` and
    ``residuals``, which go on with the good inputs when they process each
    on its own.

    Parameters
    ----------
    paths, robot, columns, rate, max_gap, window, progress, velocities
        As in :func:`load_experiments`.
    on_failure : callable, optional
        ``on_failure(path, exception)``, called as each bad input is met.

    Returns
    -------
    experiments : dict of str to Experiment
        By path as given, in order.
    failed : dict of str to str
        Why each bad input cannot be used (the reason names it), by path.

    Raises
    ------
    DataError
        When two experiments that could be read share a name.
    InputError
        For an unknown column role, or a column mapping none of the paths
        can use (:func:`~bayes_jackal.io.check_columns_apply`).

    Examples
    --------
    A simulated run written as CSV, and a file that is not there:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.io import read_logs
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1, name="v1_01")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     csv = str(bj.write_csv(run, Path(folder) / "v1_01.csv"))
    ...     experiments, failed = read_logs([csv, "missing.nc"])
    >>> [e.name for e in experiments.values()], list(failed)
    (['v1_01'], ['missing.nc'])
    """
    robot = as_profile(robot)
    options = ReadOptions(
        window=window,
        max_gap=max_gap,
        columns=check_column_roles(columns),
        rate=check_declared_rate(rate),
        velocities=velocities,
    )
    paths = _paths(paths)
    check_columns_apply(paths, columns)
    experiments, failed = each_input(
        paths,
        lambda path: read_log(path, robot, read_options=options, progress=progress),
        on_failure=on_failure,
    )
    check_unique_names(experiments.values())
    for experiment in experiments.values():
        _warn_of_another_robot(experiment, robot)
    return experiments, failed


def _warn_of_another_robot(experiment: Experiment, robot: RobotProfile) -> None:
    """Warn where an experiment was recorded (or read, simulated) as another robot's.

    Its file says which profile made it; read under another one, its
    damping, prior and grids are that one's (a Husky's run under the
    Jackal's profile fits a Jackal), though a profile of the same robot
    under another name is fine.
    """
    recorded = experiment.provenance.get("robot")
    if recorded is not None and recorded != robot.name:
        warnings.warn(
            f"{experiment.source}: recorded as a {recorded!r} run, read with the "
            f"{robot.name!r} profile ({robot.source}): its fit is the {robot.name}'s; pass "
            f"--robot {recorded} (or that robot's profile) unless this profile is the same robot",
            UserWarning,
            stacklevel=3,
        )


def _paths(paths: str | Path | Sequence[str | Path]) -> list[str | Path]:
    """One path, or several, as a list."""
    return [paths] if isinstance(paths, str | Path) else list(paths)
