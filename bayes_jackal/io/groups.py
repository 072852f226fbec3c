"""Which group each run belongs to, and its covariates: the groups CSV of a campaign.

A campaign's runs fall into groups (a floor, a speed, a day). The groups
file is a small CSV with a header: a ``run`` column naming each run (its
experiment's name, or its file's name or path), a ``group`` column with its
label, and any number of numeric covariate columns, such as ``speed``
[m/s]; other text columns (``surface``, ``notes``) are kept as labels and
not used. Without a file, each experiment's ``provenance`` may carry its
``group`` and a ``covariates`` mapping.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .._runtime import InputError, require_file
from .experiment import Experiment

__all__ = ["RunGroups", "as_run_groups", "group_runs", "read_groups", "run_group"]

#: Suffixes of the files a run is read from, dropped when a row is matched to a run's name.
_DATA_SUFFIXES = (".bag", ".mcap", ".db3", ".csv", ".mat", ".nc")
#: Covariates that must be numbers: a text column of this name is refused, not ignored.
_NUMERIC = ("speed",)
#: Accepted headers of the run and group columns (case and spaces ignored).
_RUN_HEADERS = ("run", "experiment", "file", "bag", "name")
_GROUP_HEADERS = ("group", "label", "condition")
#: A unit after a header's name, dropped: ``speed [m/s]`` and ``speed (m/s)`` are ``speed``.
_UNIT = re.compile(r"\s*(\[[^\]]*\]|\([^)]*\))\s*$")


@dataclass(frozen=True)
class RunGroups:
    """Each run's group label and numeric covariates.

    Attributes
    ----------
    groups : dict of str to str
        Run -> group label.
    covariates : dict of str to dict of str to float
        Run -> {covariate name: value}.
    source : str
        Where the table was read from.
    text_columns : tuple of str
        The table's other columns, which hold text (a surface's name, say):
        named, not covariates.

    Examples
    --------
    >>> from bayes_jackal.io import RunGroups
    >>> table = RunGroups({"v1_01": "concrete", "v1_02": "carpet"}, {"v1_01": {"speed": 0.3}})
    >>> table.label_of("data/v1_01.bag"), table.label_of("v1_02")
    ('concrete', 'carpet')
    """

    groups: dict[str, str]
    covariates: dict[str, dict[str, float]] = field(default_factory=dict)
    source: str = "<memory>"
    text_columns: tuple[str, ...] = ()

    def _key(self, run: str) -> str | None:
        """The table's row of ``run`` (a name or a path), None when no row names it.

        In turn: the row that is ``run`` itself; the row whose path is the end
        of ``run``'s (``b/v1.bag`` for ``/data/b/v1.bag``); the row whose file
        name, a data file's suffix dropped, is ``run``'s (``v1.bag`` for the
        experiment ``v1``). Two rows matching at one step are refused.
        """
        steps = (
            lambda key: key == run,
            lambda key: Path(run).parts[-len(Path(key).parts) :] == Path(key).parts,
            lambda key: _bare(key) == _bare(run),
        )
        for matches in steps:
            found = [key for key in self.groups if matches(key)]
            if len(found) > 1:
                raise InputError(
                    f"run {run!r} matches the rows {found}: name it by its path",
                    source=self.source,
                    field="run",
                )
            if found:
                return found[0]
        return None

    def label_of(self, run: str) -> str | None:
        """The group of ``run`` (an experiment's name or source), None when not listed."""
        key = self._key(run)
        return None if key is None else self.groups[key]

    def of(self, experiment: Experiment) -> tuple[str | None, dict[str, float]]:
        """(group label, covariates) of an experiment, by its name or its file."""
        for run in (experiment.source, experiment.name):  # the file first: names repeat
            key = self._key(run)
            if key is not None:
                return self.groups[key], self.covariates.get(key, {})
        return None, {}

    @property
    def covariate_names(self) -> tuple[str, ...]:
        """Covariates given for at least one run, in the order first seen."""
        return tuple(dict.fromkeys(name for row in self.covariates.values() for name in row))


def read_groups(path: str | Path) -> RunGroups:
    """Read a groups CSV: run, group and numeric covariate columns.

    Parameters
    ----------
    path : str or Path
        CSV with a header row. The run column is headed ``run`` (or
        ``experiment``, ``file``, ``bag``, ``name``), the group column
        ``group`` (or ``label``, ``condition``); headers are matched without
        case, surrounding spaces or a unit in brackets (``speed [m/s]``). A
        column whose every value is a number is a covariate (an empty cell:
        not given for that run).

    Returns
    -------
    RunGroups

    Raises
    ------
    InputError
        Naming the file, row and column: a missing run or group column, a
        header naming a column twice, a row of more cells than the header
        (an unquoted decimal comma), an empty or repeated run, an empty
        group label, a covariate that is not a finite number.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.io import read_groups
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "groups.csv"
    ...     rows = ["Run, Group, Speed, floor", "v1_01, A, 0.3, tile", "v2_01.bag, B, 0.4, mat"]
    ...     _ = path.write_text("\\n".join(rows))
    ...     table = read_groups(path)
    >>> table.groups, table.covariates["v2_01.bag"]
    ({'v1_01': 'A', 'v2_01.bag': 'B'}, {'speed': 0.4})
    """
    source = str(path)
    require_file(Path(path), source)
    try:
        with open(path, newline="", encoding="utf-8-sig") as stream:
            rows = list(csv.reader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read the groups CSV ({exc})", source=source) from None
    rows = [row for row in rows if any(cell.strip() for cell in row)]
    if not rows:
        raise InputError("the groups CSV is empty", source=source)
    header = [_UNIT.sub("", cell).strip().lower() for cell in rows[0]]
    repeated = sorted({name for name in header if name and header.count(name) > 1})
    if repeated:
        raise InputError(
            f"the header names {repeated[0]!r} twice: which column is meant?",
            source=source,
            field="header",
        )
    run_column = _column(header, _RUN_HEADERS, source)
    group_column = _column(header, _GROUP_HEADERS, source)
    for line, row in enumerate(rows[1:], start=2):
        if any(cell.strip() for cell in row[len(header) :]):
            raise InputError(
                f"{len(row)} cells under a header of {len(header)} (an unquoted decimal comma? "
                'quote it, "0,3", or write 0.3)',
                source=source,
                field=f"row {line}",
            )
    body = [[cell.strip() for cell in row] + [""] * (len(header) - len(row)) for row in rows[1:]]
    groups: dict[str, str] = {}
    for line, row in enumerate(body, start=2):
        run, label = row[run_column], row[group_column]
        where = f"row {line}"
        if not run or not label:
            empty = header[run_column] if not run else header[group_column]
            raise InputError(f"empty {empty!r}", source=source, field=where)
        if run in groups:
            raise InputError(f"run {run!r} is listed twice", source=source, field=where)
        groups[run] = label
    covariates: dict[str, dict[str, float]] = {run: {} for run in groups}
    text_columns = []
    for column, name in enumerate(header):
        if column in (run_column, group_column):
            continue
        if not _numeric(body, column, name, source):
            if any(row[column] for row in body):
                text_columns.append(name)
            continue
        for line, row in enumerate(body, start=2):
            if row[column]:
                value = float(row[column])
                if not math.isfinite(value):
                    raise InputError(
                        f"{name} must be a finite number, got {row[column]!r}",
                        source=source,
                        field=f"row {line}, column {name!r}",
                    )
                covariates[row[run_column]][name] = value
    return RunGroups(groups, covariates, source, tuple(text_columns))


def _bare(run: str) -> str:
    """The file name of ``run``, a data file's suffix dropped (``/a/v1.bag`` -> ``v1``)."""
    name = Path(run).name
    suffix = Path(name).suffix
    return name[: -len(suffix)] if suffix.lower() in _DATA_SUFFIXES else name


def _column(header: list[str], names: tuple[str, ...], source: str) -> int:
    for name in names:
        if name in header:
            return header.index(name)
    raise InputError(
        f"no column headed {' or '.join(repr(n) for n in names)}; the header is {header}",
        source=source,
        field="header",
    )


def _numeric(body: list[list[str]], column: int, name: str, source: str) -> bool:
    """Whether the column is a covariate: every non-empty cell a number (one at least).

    A column of numbers and text, or a text column named as a covariate
    (:data:`_NUMERIC`), is refused, naming its first text cell: a decimal
    comma or a typo would otherwise drop the covariate without a word.
    """
    text = []
    for line, row in enumerate(body, start=2):
        try:
            float(row[column] or "0")
        except ValueError:
            text.append((line, row[column]))
    filled = sum(bool(row[column]) for row in body)
    if text and (len(text) < filled or name in _NUMERIC):
        line, value = text[0]
        raise InputError(
            f"{name} must be a number, got {value!r} (a decimal comma?)",
            source=source,
            field=f"row {line}, column {name!r}",
        )
    return filled > 0 and not text


def as_run_groups(groups: RunGroups | Mapping[str, str] | str | Path | None) -> RunGroups | None:
    """A groups table as given, read from its CSV, or made from a mapping run -> label.

    None stays None: the groups are then in each experiment's provenance.

    Examples
    --------
    >>> from bayes_jackal.io import as_run_groups
    >>> as_run_groups({"v1_01": "tiles"}).groups, as_run_groups(None)
    ({'v1_01': 'tiles'}, None)
    """
    if isinstance(groups, (str, Path)):
        return read_groups(groups)
    return RunGroups(dict(groups)) if isinstance(groups, Mapping) else groups


def group_runs(
    experiments: Sequence[Experiment], groups: RunGroups | Mapping[str, str] | None = None
) -> dict[str, list[Experiment]]:
    """The experiments by group label, in the order their groups first appear.

    Parameters
    ----------
    experiments : sequence of Experiment
    groups : RunGroups or mapping of str to str, optional
        Run (experiment name, file name or path) -> group label. Default:
        each experiment's ``provenance["group"]``.

    Raises
    ------
    InputError
        Naming an experiment that has no group.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.io import group_runs
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=s, name=f"r{s}") for s in (1, 2, 3)]
    >>> grouped = group_runs(runs, {"r1": "tiles", "r2": "carpet", "r3": "tiles"})
    >>> {label: [run.name for run in group] for label, group in grouped.items()}
    {'tiles': ['r1', 'r3'], 'carpet': ['r2']}
    """
    table = as_run_groups(groups)
    grouped: dict[str, list[Experiment]] = {}
    for experiment in experiments:
        label, _ = run_group(experiment, table)
        if label is None:
            where = "its provenance has no 'group'" if table is None else f"not in {table.source}"
            raise InputError(
                f"experiment {experiment.name!r} has no group ({where})",
                source=experiment.source,
                field="group",
            )
        grouped.setdefault(str(label), []).append(experiment)
    return grouped


def run_group(
    experiment: Experiment, table: RunGroups | None
) -> tuple[str | None, dict[str, float]]:
    """(group label, covariates) of an experiment: from the table, else its provenance.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.io import run_group
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1, name="r1")
    >>> run.provenance.update(group="tiles", covariates={"speed": 0.3})
    >>> run_group(run, None)
    ('tiles', {'speed': 0.3})
    """
    if table is not None:
        return table.of(experiment)
    label = experiment.provenance.get("group")
    return (None if label is None else str(label)), _provenance_covariates(experiment)


def _provenance_covariates(experiment: Experiment) -> dict[str, float]:
    """An experiment's ``provenance["covariates"]``: a mapping of names to finite numbers."""
    covariates = experiment.provenance.get("covariates", {})
    if not isinstance(covariates, Mapping):
        raise InputError(
            f"must map covariate names to numbers, got {covariates!r}",
            source=experiment.source,
            field="provenance.covariates",
        )
    values = {}
    for name, value in covariates.items():
        try:
            values[str(name)] = number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if not math.isfinite(number):
            raise InputError(
                f"{name} must be a finite number, got {value!r}",
                source=experiment.source,
                field=f"provenance.covariates.{name}",
            )
    return values
