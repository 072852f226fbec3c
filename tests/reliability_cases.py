"""The reliability table of issue 11: hostile but realistic inputs, one row per case.

Each :class:`Case` names the files to create (by builder functions below,
which derive every input from one small simulated experiment, its CSV, MATLAB
file, bags and posterior, built once per session), the command line, the
expected exit code and the words (regular expressions, case-insensitive) that
stderr must hold. ``tests/test_reliability.py`` runs each through the real
command line in a subprocess and also checks what every case must satisfy:
no traceback, inputs byte-identical and untouched, no ``.part`` file left,
stdout empty or strict JSON with ``--json``.

Expected behaviour is issue 11's; where it is silent, what a careful tool
does: exit 2 for bad input, named with its file and field, before any work;
1 for other failures (a full disk); 130/143 for SIGINT/SIGTERM. Cases whose
point is "refused before any work" run with the default, expensive settings
and a short timeout, so a check made only after the work fails the case.
"""

from __future__ import annotations

import csv
import functools
import io
import json
import os
import re
import shutil
import signal
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib.resources import files as package_files
from pathlib import Path

import numpy as np

#: Settings that keep a successful run short (seconds, not minutes).
SAMPLE = "--family white --channels yaw --max-steps 200 --walkers 32 --seed 1 --no-progress"
COMPARE = (
    "--families white --channels yaw --max-steps 200 --walkers 32 --seed 1 --no-progress "
    "--processes 1"
)
ANALYSE = COMPARE
GRID = "--d-lat 10 300 10 --d-long 10 100 10"
#: Timeout [s] of cases that must fail before any work.
FAST = 30.0


@dataclass(frozen=True)
class Library:
    """The session's source files, from which every case's inputs are derived."""

    root: Path
    nc: Path  # simulate --seed 1 --v1 1 --v2 0: runs/v1_01.nc
    csv: Path  # the same run as CSV
    mat: Path  # the same columns in a MATLAB file
    bag: Path  # the run as a ROS1 bag
    mcap: Path  # the run as a ROS2 bag (another seed)
    posterior: Path  # sample --family gaussian --channels yaw, 200 steps
    white_posterior: Path  # the same with --family white


Builder = Callable[[Library, Path], None]


@dataclass(frozen=True)
class Case:
    """One row: files to build, argv, expected exit, words stderr must hold, checks.

    ``kind`` is ``run`` (one run), ``signal`` (a signal once ``trigger``
    exists or after ``delay`` seconds), ``lock`` (a second run while a first
    holds the output), ``fsize`` (RLIMIT_FSIZE of ``limit`` bytes) or
    ``tmpfs`` (the output on a full tmpfs). ``rerun`` is a follow-up of the
    same argv without the signal or limit: (exit, words).
    """

    id: str
    argv: str
    exit: int | tuple[int, ...]
    words: tuple[str, ...] = ()
    files: dict[str, Builder] = field(default_factory=dict)
    exists: tuple[str, ...] = ()
    absent: tuple[str, ...] = ()
    json_files: tuple[str, ...] = ()
    count: dict[str, int] = field(default_factory=dict)
    stdout_lacks: tuple[str, ...] = ()
    mutable: tuple[str, ...] = ()
    timeout: float = 90.0
    kind: str = "run"
    signum: int = 0
    trigger: str = ""
    delay: float = 0.0
    limit: int = 0
    rerun: tuple[int, tuple[str, ...]] | None = None
    script: bool = False  # exec the console script, not python -m


def C(id: str, argv: str, exit, *words: str, **options) -> Case:
    """A row, compactly: ``C(id, argv, exit, *words, files=..., ...)``."""
    return Case(id=id, argv=argv, exit=exit, words=words, **options)


# ---------------------------------------------------------------- builders


def experiment(name: str | None = None, **attrs) -> Builder:
    """The simulated experiment file, named ``name`` (default: the file's stem)."""

    def build(lib: Library, path: Path) -> None:
        _nc_edit(lib, path, lambda ds: ds.assign_attrs(name=name or path.stem, **attrs))

    build.__name__ = f"experiment({name or ''})"
    return build


def nc_edit(edit: Callable) -> Builder:
    """The experiment file with ``edit(dataset) -> dataset`` applied."""

    def build(lib: Library, path: Path) -> None:
        _nc_edit(lib, path, lambda ds: edit(ds.assign_attrs(name=path.stem)))

    return build


def _nc_edit(lib: Library, path: Path, edit: Callable) -> None:
    # A deep copy of the library's experiment as read once (the edits return
    # new datasets; the copy keeps the cached one safe from any that would not).
    dataset = edit(_nc_source(lib.nc).copy(deep=True))
    dataset.to_netcdf(path, engine="h5netcdf")


@functools.cache
def _nc_source(path: Path):
    """The experiment file at ``path`` read into memory, once per session."""
    import xarray as xr

    with xr.open_dataset(path, engine="h5netcdf") as source:
        return source.load()


def nc_scaled(variable: str, factor: float) -> Builder:
    return nc_edit(lambda ds: ds.assign({variable: ds[variable] * factor}))


def nc_cell(variable: str, value: float, row: int = 100) -> Builder:
    def edit(ds):
        values = ds[variable].values.copy()
        values[row] = value
        return ds.assign({variable: ("time", values)})

    return nc_edit(edit)


def nc_string_variable(variable: str) -> Builder:
    return nc_edit(
        lambda ds: ds.assign({variable: ("time", np.array(["fast"] * ds.sizes["time"]))})
    )


def h5_two_columns(variable: str) -> Builder:
    """The experiment's columns written by h5py (no dimension scales), ``variable`` twice over."""

    def build(lib: Library, path: Path) -> None:
        import h5py
        import xarray as xr

        with xr.open_dataset(lib.nc, engine="h5netcdf") as source:
            dataset = source.load()
        with h5py.File(path, "w") as written:
            written.attrs["format"] = dataset.attrs["format"]
            for name in ("time", "yaw_rate", "omega_r", "omega_l"):
                values = dataset[name].values
                written[name] = np.column_stack([values, values]) if name == variable else values

    return build


def nc_drop(variable: str) -> Builder:
    return nc_edit(lambda ds: ds.drop_vars(variable))


def nc_time(edit: Callable[[np.ndarray], np.ndarray]) -> Builder:
    return nc_edit(lambda ds: ds.assign_coords(time=edit(ds["time"].values.copy())))


def nc_short(rows: int) -> Builder:
    return nc_edit(lambda ds: ds.isel(time=slice(0, rows)))


def copy(what: str) -> Builder:
    """A byte copy of a library file (``nc``, ``csv``, ``mat``, ``bag``, ``posterior``...)."""

    def build(lib: Library, path: Path) -> None:
        shutil.copyfile(getattr(lib, what), path)

    build.__name__ = f"copy({what})"
    return build


def truncated(what: str, fraction: float = 0.5) -> Builder:
    def build(lib: Library, path: Path) -> None:
        data = getattr(lib, what).read_bytes()
        path.write_bytes(data[: int(len(data) * fraction)])

    return build


def raw(content: bytes) -> Builder:
    def build(lib: Library, path: Path) -> None:
        path.write_bytes(content)

    return build


def folder() -> Builder:
    def build(lib: Library, path: Path) -> None:
        path.mkdir(parents=True)

    return build


def symlink(target: str) -> Builder:
    def build(lib: Library, path: Path) -> None:
        path.symlink_to(target)

    return build


def hardlink(target: str) -> Builder:
    def build(lib: Library, path: Path) -> None:
        os.link(path.parent / target, path)

    return build


def fifo() -> Builder:
    def build(lib: Library, path: Path) -> None:
        os.mkfifo(path)

    return build


#: Another user's recording in a shared folder, and links planted beside an output.
PRECIOUS = {"a.nc": experiment(), "precious.csv": raw(b"t,yaw_rate\n0,0.1\n")}


def csv_text(edit: Callable[[str], str]) -> Builder:
    """The simulated run's CSV text with ``edit(text) -> text`` applied."""

    def build(lib: Library, path: Path) -> None:
        path.write_bytes(edit(lib.csv.read_text()).encode())

    return build


def csv_table(edit: Callable[[list[str], np.ndarray], tuple[list[str], np.ndarray]]) -> Builder:
    """The CSV's header and values with ``edit(header, values)`` applied, written back."""

    def build(lib: Library, path: Path) -> None:
        header, values = read_table(lib.csv)
        header, values = edit(list(header), values.copy())
        buffer = io.StringIO()
        buffer.write(",".join(header) + "\n")
        np.savetxt(buffer, values, delimiter=",", fmt="%.12g")
        path.write_text(buffer.getvalue())

    return build


def read_table(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open() as handle:
        header = next(csv.reader(handle))
    return header, np.loadtxt(path, delimiter=",", skiprows=1)


def _column(header: list[str], name: str) -> int:
    return header.index(name)


def csv_scaled(name: str, factor: float) -> Builder:
    def edit(header, values):
        values[:, _column(header, name)] *= factor
        return header, values

    return csv_table(edit)


def csv_cell(name: str, value: float, row: int = 100) -> Builder:
    def edit(header, values):
        values[row, _column(header, name)] = value
        return header, values

    return csv_table(edit)


def csv_rows(select: Callable[[np.ndarray], np.ndarray]) -> Builder:
    return csv_table(lambda header, values: (header, values[select(values)]))


def csv_header(edit: Callable[[list[str]], list[str]]) -> Builder:
    return csv_table(lambda header, values: (edit(header), values))


def csv_columns(keep: Callable[[list[str]], list[int]]) -> Builder:
    def edit(header, values):
        index = keep(header)
        return [header[i] for i in index], values[:, index]

    return csv_table(edit)


def mat(edit: Callable[[dict], dict] = lambda columns: columns) -> Builder:
    def build(lib: Library, path: Path) -> None:
        import scipy.io

        header, values = read_table(lib.csv)
        scipy.io.savemat(path, edit({name: values[:, i] for i, name in enumerate(header)}))

    return build


def profile(edit: Callable[[str], str] = lambda text: text) -> Builder:
    """The Jackal profile's TOML text with ``edit(text) -> text`` applied."""

    def build(lib: Library, path: Path) -> None:
        text = (package_files("bayes_jackal.models") / "jackal.toml").read_text()
        path.write_text(edit(text))

    return build


def replace(old: str, new: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)

    return edit


def json_text(payload: str) -> Builder:
    return raw(payload.encode())


def prior_file(edit: Callable[[dict], object] = lambda prior: None) -> Builder:
    """The posterior's exported prior (order 2) as JSON, ``edit(prior)`` applied in place."""

    def build(lib: Library, path: Path) -> None:
        import json

        prior = json.loads(_exported_prior(lib).read_text())
        edit(prior)
        path.write_text(json.dumps(prior))

    return build


def _exported_prior(lib: Library) -> Path:
    """``export-prior`` of the library's posterior, made once per session in its folder."""
    path = lib.root / "prior.json"
    if not path.exists():
        from bayes_jackal.dem.export import export_prior, write_prior
        from bayes_jackal.posterior.posterior import load_posterior

        prior = export_prior(load_posterior(lib.posterior), order=2, source=str(lib.posterior))
        write_prior(prior, path)
    return path


def series(
    edit: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] = lambda t, x: (t, x),
) -> Builder:
    """The run's yaw rate as a bare noise series (columns t, gyro), ``edit(t, x)`` applied."""
    return csv_table(
        lambda h, v: (["t", "gyro"], np.column_stack(edit(v[:, 0].copy(), v[:, 1].copy())))
    )


GOOD = {"a.nc": experiment()}
GOOD2 = {"a.nc": experiment(), "b.nc": experiment()}
GOOD_CSV = {"a.csv": copy("csv")}
POST = {"post.nc": copy("posterior")}
EMPTY = raw(b"")
GARBAGE = raw(bytes(range(256)) * 64)
BOM = "\ufeff"


def shuffled_pairs(values: np.ndarray) -> np.ndarray:
    """Row order with 5 neighbouring pairs swapped (stamps out of order)."""
    order = np.arange(len(values))
    for i in range(200, 1200, 200):
        order[[i, i + 1]] = order[[i + 1, i]]
    return order


def repeated_rows(values: np.ndarray) -> np.ndarray:
    """Row order with 5 rows logged twice (repeated stamps)."""
    return np.sort(np.concatenate([np.arange(len(values)), np.arange(300, 1300, 200)]))


def hole(values: np.ndarray) -> np.ndarray:
    """Rows with 10 s missing in the middle (a dropout far beyond --max-gap)."""
    t = values[:, 0]
    return (t < 10.0) | (t > 20.0)


# ---------------------------------------------------------------- the table

_EXP_COMMANDS = {
    "grid": f"grid {{}} {GRID}",
    "residuals": "residuals {} --json",
    "sample": "sample {} --out p.nc",
    "compare": "compare {} --out cmp",
}

#: Bad experiment files: (id, file name, builder, words), each refused by every reader.
BAD_EXPERIMENTS = [
    ("csv-empty", "e.csv", EMPTY, (r"e\.csv", r"empty|no (data|header|rows)")),
    ("csv-header-only", "h.csv", csv_text(lambda t: t.splitlines()[0] + "\n"), (r"h\.csv",)),
    ("csv-1e300", "x.csv", csv_scaled("yaw_rate", 1e300), (r"x\.csv", "yaw_rate")),
    ("csv-inf", "x.csv", csv_cell("omega_r", np.inf), (r"x\.csv", "omega_r")),
    ("csv-nan", "x.csv", csv_cell("yaw_rate", np.nan), (r"x\.csv", "yaw_rate")),
    ("csv-time-ns", "x.csv", csv_scaled("t", 1e9), (r"x\.csv", r"rate|sample time|\bt\b")),
    ("csv-time-ms", "x.csv", csv_scaled("t", 1e3), (r"x\.csv", r"rate|sample time")),
    (
        "csv-duplicate-column",
        "x.csv",
        csv_header(lambda h: [*h[:4], "yaw_rate", h[5]]),
        (r"x\.csv", r"duplicate|appears 2 times|twice", "yaw_rate"),
    ),
    (
        "csv-missing-column",
        "x.csv",
        csv_columns(lambda h: [i for i, n in enumerate(h) if n != "yaw_rate"]),
        (r"x\.csv", "yaw_rate"),
    ),
    (
        "csv-renamed-column",
        "x.csv",
        csv_header(lambda h: ["gyro_z" if n == "yaw_rate" else n for n in h]),
        (r"x\.csv", "yaw_rate", "--column"),
    ),
    ("csv-garbage", "x.csv", GARBAGE, (r"x\.csv",)),
    (
        "csv-text-cell",
        "x.csv",
        csv_text(lambda t: t.replace("\n", "\n0.5,fast,1,1,0,0\n", 1)),
        (r"x\.csv", r"fast|row|line"),
    ),
    (
        "csv-truncated-line",
        "x.csv",
        csv_text(lambda t: t[: len(t) // 2].rsplit(",", 2)[0]),
        (r"x\.csv", r"row|line|column|field"),
    ),
    ("csv-too-short", "x.csv", csv_text(lambda t: "\n".join(t.splitlines()[:6])), (r"x\.csv",)),
    (
        "csv-all-stamps-equal",
        "x.csv",
        csv_table(lambda h, v: (h, np.column_stack([np.zeros(len(v)), v[:, 1:]]))),
        (r"x\.csv", r"\bt\b|stamp|time"),
    ),
    (
        "csv-semicolons",
        "x.csv",
        csv_text(lambda t: t.replace(",", ";")),
        (r"x\.csv", r"column|yaw_rate"),
    ),
    ("nc-empty", "e.nc", EMPTY, (r"e\.nc",)),
    ("nc-truncated", "x.nc", truncated("nc"), (r"x\.nc",)),
    ("nc-garbage", "x.nc", GARBAGE, (r"x\.nc",)),
    ("nc-is-csv", "x.nc", copy("csv"), (r"x\.nc",)),
    ("nc-is-posterior", "x.nc", copy("posterior"), (r"x\.nc", r"experiment|format")),
    ("nc-missing-variable", "x.nc", nc_drop("omega_l"), (r"x\.nc", "omega_l")),
    ("nc-1e300", "x.nc", nc_scaled("yaw_rate", 1e300), (r"x\.nc", "yaw_rate")),
    ("nc-inf", "x.nc", nc_cell("omega_l", np.inf), (r"x\.nc", "omega_l")),
    ("nc-nan", "x.nc", nc_cell("yaw_rate", np.nan), (r"x\.nc", "yaw_rate")),
    ("nc-time-ms", "x.nc", nc_time(lambda t: t * 1e3), (r"x\.nc", r"rate|sample time")),
    ("nc-time-reversed", "x.nc", nc_time(lambda t: t[::-1]), (r"x\.nc", r"\bt\b|time|increas")),
    ("nc-short", "x.nc", nc_short(4), (r"x\.nc", r"samples|short|rows")),
    (
        "nc-steady-window-one-element",
        "x.nc",
        experiment(steady_window=[5.0]),
        (r"x\.nc", "steady_window"),
    ),
    (
        "nc-steady-window-reversed",
        "x.nc",
        experiment(steady_window=[30.0, 5.0]),
        (r"x\.nc", "steady_window"),
    ),
    ("nc-truth-not-json", "x.nc", experiment(truth="{d_lat: 110"), (r"x\.nc", "truth")),
    (
        "nc-provenance-not-json",
        "x.nc",
        experiment(provenance="not json"),
        (r"x\.nc", "provenance"),
    ),
    ("nc-string-variable", "x.nc", nc_string_variable("yaw_rate"), (r"x\.nc", "yaw_rate")),
    # Issue 24, item 8: h5netcdf's phony_dims warning led the message.
    (
        "nc-2d-variable-from-h5py",
        "x.nc",
        h5_two_columns("yaw_rate"),
        (r"x\.nc: yaw_rate: shape \(\d+, 2\): a column must be 1-D", r"\A(?![\s\S]*phony)"),
    ),
    ("mat-empty", "e.mat", EMPTY, (r"e\.mat",)),
    # Issue 24, item 8: text or cells were reported as a missing column.
    (
        "mat-text-variable",
        "x.mat",
        mat(lambda columns: columns | {"yaw_rate": "not numbers"}),
        (r"x\.mat", r"'yaw_rate' \(yaw_rate\) holds text \(char\), not numbers"),
    ),
    (
        "mat-cell-variable",
        "x.mat",
        mat(lambda columns: columns | {"yaw_rate": np.array([[1.0, "a"]], dtype=object)}),
        (r"x\.mat", r"'yaw_rate' \(yaw_rate\) holds a cell array, not numbers"),
    ),
    ("mat-truncated", "x.mat", truncated("mat"), (r"x\.mat",)),
    (
        "mat-missing-variable",
        "x.mat",
        mat(lambda c: {k: v for k, v in c.items() if k != "omega_r"}),
        (r"x\.mat", "omega_r"),
    ),
    (
        "mat-1e300",
        "x.mat",
        mat(lambda c: c | {"yaw_rate": c["yaw_rate"] * 1e300}),
        (r"x\.mat", "yaw_rate"),
    ),
    ("suffix-txt", "x.txt", copy("csv"), (r"x\.txt", r"suffix|\.txt|format")),
    ("suffix-h5", "x.h5", copy("nc"), (r"x\.h5", r"suffix|\.h5|format")),
    ("is-a-folder", "x.nc", folder(), (r"x\.nc",)),
    ("missing", None, None, (r"nothere\.nc", r"no such|not found|does not exist")),
]


def _bad_experiment_cases() -> list[Case]:
    """Every bad experiment file under grid, residuals, sample and compare (fast refusals)."""
    cases = []
    commands = {
        "grid": "grid",
        "residuals": "residuals",
        "sample": "sample",
        "compare": "compare",
    }
    # Each file under one command, in turn: every reader is hit by every command.
    names = list(commands)
    for index, (case_id, name, builder, words) in enumerate(BAD_EXPERIMENTS):
        for command in (names[index % 4],):
            path = name or "nothere.nc"
            files = {name: builder} if name else {}
            cases.append(
                C(
                    f"{command}-{case_id}",
                    _EXP_COMMANDS[command].format(path),
                    2,
                    *words,
                    files=files,
                    absent=("p.nc", "p.chain.h5", "cmp/*.nc"),
                    timeout=FAST,
                )
            )
    return cases


ACCEPTED = [
    # Excel's CSV: a UTF-8 BOM, CRLF lines, a trailing blank line (item 11).
    ("csv-bom", csv_text(lambda t: BOM + t)),
    ("csv-trailing-blank-line", csv_text(lambda t: t + "\n")),
    ("csv-trailing-blank-lines-spaces", csv_text(lambda t: t + "\n  \n\n")),
    ("csv-crlf", csv_text(lambda t: t.replace("\n", "\r\n"))),
    ("csv-bom-crlf-blank", csv_text(lambda t: BOM + t.replace("\n", "\r\n") + "\r\n")),
    ("csv-columns-reordered", csv_columns(lambda h: [5, 4, 3, 2, 1, 0])),
    ("csv-extra-column", csv_table(lambda h, v: ([*h, "battery"], np.c_[v, np.ones(len(v))]))),
    ("csv-stamps-swapped", csv_rows(shuffled_pairs)),
    ("csv-stamps-repeated", csv_rows(repeated_rows)),
    ("csv-without-vx-vy", csv_columns(lambda h: [0, 1, 2, 3])),
    # A long dropout splits the series; the longest piece is kept (bayes_jackal.io.stamps, rule 3).
    ("csv-dropout", csv_rows(hole)),
]


def _accepted_cases() -> list[Case]:
    cases = []
    for case_id, builder in ACCEPTED:
        cases.append(
            C(f"grid-accepts-{case_id}", f"grid x.csv {GRID} --json", 0, files={"x.csv": builder})
        )
    cases += [
        C(
            "residuals-accepts-csv-bom",
            "residuals x.csv --json",
            0,
            files={"x.csv": ACCEPTED[0][1]},
        ),
        C(
            "residuals-accepts-csv-trailing-blank",
            "residuals x.csv --json",
            0,
            files={"x.csv": ACCEPTED[1][1]},
        ),
        C(
            "grid-accepts-renamed-column-with-flag",
            f"grid x.csv {GRID} --column yaw_rate gyro_z --json",
            0,
            files={"x.csv": csv_header(lambda h: ["gyro_z" if n == "yaw_rate" else n for n in h])},
        ),
        # Issue 24, item 5: a declared rate confirmed a unit slip (time in ms).
        C(
            "grid-refuses-time-ms-with-rate-0.072",
            f"grid x.csv {GRID} --rate 0.072 --json",
            2,
            r"rate",
            r"0\.072 Hz",
            r"milliseconds",
            files={"x.csv": csv_scaled("t", 1e3)},
            timeout=FAST,
        ),
        C(
            "sample-refuses-column-without-a-table",
            f"sample a.nc --out p.nc --column yaw_rate gyro_z {SAMPLE}",
            2,
            r"column",
            r"CSV and MATLAB",
            files={"a.nc": experiment()},
            timeout=FAST,
        ),
        C(
            "sample-refuses-a-role-given-twice",
            f"sample a.csv --out p.nc --column yaw_rate vx --column yaw_rate vy {SAMPLE}",
            2,
            r"--column",
            r"'yaw_rate' is given 2 times: \['vx', 'vy'\]",
            files=GOOD_CSV,
            timeout=FAST,
        ),
        C("grid-accepts-mat", f"grid x.mat {GRID} --json", 0, files={"x.mat": mat()}),
        C("residuals-accepts-mat", "residuals x.mat --json", 0, files={"x.mat": mat()}),
        C(
            "grid-accepts-csv-nc-mat-mixed",
            f"grid a.csv b.nc c.mat {GRID} --json",
            0,
            files={"a.csv": copy("csv"), "b.nc": experiment(), "c.mat": mat()},
        ),
    ]
    return cases


# Item 1 and the output checks: never an input, folder created, suffix known.
OUTPUT_CASES = [
    C(
        "sample-out-is-input-nc",
        "sample runs/v1_01.nc --out runs/v1_01.nc",
        2,
        r"v1_01\.nc",
        r"input",
        files={"runs/v1_01.nc": copy("nc")},
        timeout=FAST,
    ),
    C(
        "sample-out-is-input-csv",
        "sample v1_01.csv --out v1_01.csv",
        2,
        r"v1_01\.csv",
        files={"v1_01.csv": copy("csv")},
        timeout=FAST,
    ),
    C(
        "sample-out-is-input-dotdot",
        "sample runs/a.nc --out ./runs/../runs/a.nc",
        2,
        r"a\.nc",
        r"input",
        files={"runs/a.nc": experiment()},
        timeout=FAST,
    ),
    C(
        "sample-out-is-input-symlink",
        "sample a.nc --out link.nc",
        2,
        r"(link|a)\.nc",
        r"input",
        files={"a.nc": experiment(), "link.nc": symlink("a.nc")},
        timeout=FAST,
    ),
    C(
        "sample-out-is-input-hardlink",
        "sample a.nc --out hard.nc",
        2,
        r"(hard|a)\.nc",
        r"input",
        files={"a.nc": experiment(), "hard.nc": hardlink("a.nc")},
        timeout=FAST,
    ),
    # Issue 24, item 1: a planted link beside an output is never written through.
    *(
        C(
            f"lock-file-is-{kind}",
            f"sample a.nc --out p.nc {SAMPLE}",
            2,
            r"\.p\.nc\.lock",
            words,
            files={**PRECIOUS, ".p.nc.lock": planted},
            timeout=FAST,
        )
        for kind, planted, words in (
            ("symlink", symlink("precious.csv"), r"symbolic link \(to precious\.csv\)"),
            ("hardlink", hardlink("precious.csv"), r"hard link"),
            ("fifo", fifo(), r"not a regular file"),
        )
    ),
    C(
        "lock-in-folder-is-symlink",
        f"compare a.nc --out cmp {COMPARE}",
        2,
        r"cmp/\.bayes-jackal\.lock",
        r"symbolic link",
        files={**PRECIOUS, "cmp/.bayes-jackal.lock": symlink("../precious.csv")},
        timeout=FAST,
    ),
    C(
        "chain-file-is-symlink",
        f"sample a.nc --out p.nc {SAMPLE}",
        2,
        r"p\.chain\.h5",
        r"symbolic link \(to precious\.csv\)",
        files={**PRECIOUS, "p.chain.h5": symlink("precious.csv")},
        timeout=FAST,
    ),
    C(
        "report-figure-folder-is-symlink",
        "report post.nc --out r.html --formats png",
        2,
        r"r_figures",
        r"symbolic link \(to theirs\)",
        files={**POST, "theirs/trace.png": raw(b"their figure"), "r_figures": symlink("theirs")},
        absent=("r.html",),
        timeout=FAST,
    ),
    # Issue 24, item 8: messages that named the wrong thing.
    C(
        "sample-input-is-a-symlink-loop",
        f"sample a.nc --out p.nc {SAMPLE}",
        2,
        r"a\.nc",
        r"symbolic links",
        files={"a.nc": symlink("a.nc")},
        timeout=FAST,
    ),
    C(
        "sample-out-is-a-symlink-loop",
        f"sample a.nc --out p.nc {SAMPLE}",
        2,
        r"p\.nc",
        r"loop of symbolic links",
        files={"a.nc": experiment(), "p.nc": symlink("p.nc")},
        timeout=FAST,
    ),
    C(
        "sample-input-is-a-folder-named-csv",
        f"sample x.csv --out p.nc {SAMPLE}",
        2,
        r"x\.csv",
        r"is a folder",
        files={"x.csv": folder()},
        timeout=FAST,
    ),
    C(
        "export-prior-posterior-is-a-folder",
        "export-prior posts --out prior.json",
        2,
        r"posts: is a folder, not a file",
        files={"posts": folder()},
        timeout=FAST,
    ),
    C(
        "sample-out-is-second-input-pooled",
        "sample a.nc b.nc --pooled --out b.nc",
        2,
        r"b\.nc",
        r"input",
        files=GOOD2,
        timeout=FAST,
    ),
    C(
        # a's output p.a.nc is an input: refused before any work; x is done (exit 2)
        "sample-per-experiment-out-is-input",
        f"sample a.nc p.a.nc --out p.nc {SAMPLE}",
        2,
        r"p\.a\.nc",
        r"input",
        files={"a.nc": experiment(), "p.a.nc": experiment("x")},
        exists=("p.x.nc",),
    ),
    C(
        "grid-out-is-input",
        f"grid runs/v1_01.nc {GRID} --out runs/v1_01.nc",
        2,
        r"v1_01\.nc",
        r"input",
        files={"runs/v1_01.nc": copy("nc")},
        timeout=FAST,
    ),
    C(
        "grid-plot-is-input",
        f"grid a.png.nc {GRID} --plot a.png.nc",
        2,
        r"a\.png\.nc",
        files={"a.png.nc": experiment()},
        timeout=FAST,
    ),
    C(
        "grid-out-is-input-csv",
        f"grid a.csv {GRID} --out a.csv",
        2,
        r"a\.csv",
        files=GOOD_CSV,
        timeout=FAST,
    ),
    C(
        "export-prior-out-is-input",
        "export-prior post.nc --out post.nc",
        2,
        r"post\.nc",
        r"input",
        files=POST,
        timeout=FAST,
    ),
    # Issue 24, item 4: a sensor smoothness whose Pi_z is ill conditioned.
    *(
        C(
            f"export-prior-sensor-smoothness-{value}",
            f"export-prior post.nc --out prior.json --order {order} --sensor-smoothness {value}",
            2,
            r"sensor_smoothness",
            re.escape(value),
            r"order \d allows [0-9.e+-]+ to [0-9.e+-]+ bins",
            files=POST,
            absent=("prior.json",),
            timeout=FAST,
        )
        for order, value in ((2, "1e-05"), (2, "1e-300"), (2, "1e+300"))
    ),
    C(
        "report-out-is-input",
        "report post.nc --out post.nc",
        2,
        r"post\.nc",
        r"input|suffix",
        files=POST,
        timeout=FAST,
    ),
    C(
        "compare-out-file-is-input",
        "compare v1_01.white.nc --families white --out .",
        2,
        r"v1_01\.white\.nc",
        r"input",
        files={"v1_01.white.nc": experiment("v1_01")},
        timeout=FAST,
    ),
    C(
        "analyse-out-holds-input",
        "analyse out/experiments/v1_01.nc --out out",
        2,
        r"v1_01\.nc",
        r"input",
        files={"out/experiments/v1_01.nc": experiment("v1_01")},
        timeout=FAST,
    ),
    # Outputs in a folder that does not exist yet are created (item 11).
    C(
        "sample-out-new-folder",
        f"sample a.nc --out new/dir/p.nc {SAMPLE}",
        0,
        files=GOOD,
        exists=("new/dir/p.nc",),
    ),
    C(
        "grid-out-new-folder",
        f"grid a.nc {GRID} --out new/dir/g.nc",
        0,
        files=GOOD,
        exists=("new/dir/g.nc",),
    ),
    C(
        "grid-plot-new-folder",
        f"grid a.nc {GRID} --plot new/dir/s.png",
        0,
        files=GOOD,
        exists=("new/dir/s.png",),
    ),
    C(
        "export-prior-out-new-folder",
        "export-prior post.nc --out new/dir/prior.json",
        0,
        files=POST,
        exists=("new/dir/prior.json",),
        json_files=("new/dir/prior.json",),
    ),
    C(
        "report-out-new-folder",
        "report post.nc --out new/dir/r.html --formats png",
        0,
        files=POST,
        exists=("new/dir/r.html",),
    ),
    C(
        "simulate-out-new-folder",
        "simulate --out new/dir --seed 3 --v1 1 --v2 0",
        0,
        exists=("new/dir/v1_01.nc",),
    ),
    C(
        "ingest-out-new-folder",
        "ingest a.bag --out new/dir",
        0,
        files={"a.bag": copy("bag")},
        exists=("new/dir/*.nc",),
    ),
    # An existing output of the wrong kind is refused before any work (item 11).
    C(
        "sample-out-existing-folder",
        "sample a.nc --out outdir",
        2,
        r"outdir",
        r"folder|directory",
        files={**GOOD, "outdir": folder()},
        absent=("outdir.chain.h5",),
        timeout=FAST,
    ),
    C(
        "sample-out-existing-folder-nc",
        "sample a.nc --out out.nc",
        2,
        r"out\.nc",
        r"folder|directory",
        files={**GOOD, "out.nc": folder()},
        absent=("out.chain.h5",),
        timeout=FAST,
    ),
    C(
        "grid-out-existing-folder",
        f"grid a.nc {GRID} --out g.nc",
        2,
        r"g\.nc",
        r"folder|directory",
        files={**GOOD, "g.nc": folder()},
        timeout=FAST,
    ),
    C(
        "grid-plot-existing-folder",
        f"grid a.nc {GRID} --plot s.png",
        2,
        r"s\.png",
        r"folder|directory",
        files={**GOOD, "s.png": folder()},
        timeout=FAST,
    ),
    C(
        "export-prior-out-existing-folder",
        "export-prior post.nc --out prior.json",
        2,
        r"prior\.json",
        r"folder|directory",
        files={**POST, "prior.json": folder()},
        timeout=FAST,
    ),
    C(
        "report-out-existing-folder",
        "report post.nc --out r.html",
        2,
        r"r\.html",
        r"folder|directory",
        files={**POST, "r.html": folder()},
        timeout=FAST,
    ),
    C(
        "compare-out-existing-file",
        "compare a.nc --out taken",
        2,
        r"taken",
        r"file|folder|directory",
        files={**GOOD, "taken": raw(b"mine\n")},
        timeout=FAST,
        stdout_lacks=("log Z",),
    ),
    C(
        "simulate-out-existing-file",
        "simulate --out taken --v1 1 --v2 0",
        2,
        r"taken",
        r"file|folder|directory",
        files={"taken": raw(b"mine\n")},
        timeout=FAST,
    ),
    C(
        "ingest-out-existing-file",
        "ingest a.bag --out taken",
        2,
        r"taken",
        r"file|folder|directory",
        files={"a.bag": copy("bag"), "taken": raw(b"mine\n")},
        timeout=FAST,
    ),
    C(
        "analyse-out-existing-file",
        "analyse a.nc --out taken",
        2,
        r"taken",
        r"file|folder|directory",
        files={**GOOD, "taken": raw(b"mine\n")},
        timeout=FAST,
    ),
    C(
        "demo-out-existing-file",
        "demo --out taken --no-progress",
        2,
        r"taken",
        r"file|folder|directory",
        files={"taken": raw(b"mine\n")},
        timeout=FAST,
    ),
    C(
        "sample-out-parent-is-file",
        "sample a.nc --out notdir/p.nc",
        2,
        r"notdir",
        files={**GOOD, "notdir": raw(b"mine\n")},
        timeout=FAST,
    ),
    # Suffixes are known before any work (item 11: grid --plot x.xyz).
    C(
        "grid-plot-unknown-suffix",
        "grid a.nc --method simulation --plot x.xyz",
        2,
        r"x\.xyz",
        r"suffix|format|xyz",
        files=GOOD,
        absent=("x.xyz",),
        timeout=FAST,
    ),
    C(
        "grid-out-wrong-suffix",
        f"grid a.nc {GRID} --out g.csv",
        2,
        r"g\.csv",
        r"suffix|\.nc",
        files=GOOD,
        absent=("g.csv",),
        timeout=FAST,
    ),
    C(
        "sample-out-wrong-suffix",
        "sample a.nc --out p.csv",
        2,
        r"p\.csv",
        r"suffix|\.nc",
        files=GOOD,
        absent=("p.csv", "p.chain.h5"),
        timeout=FAST,
    ),
    C(
        "sample-out-no-suffix",
        "sample a.nc --out posterior",
        2,
        r"posterior",
        r"suffix|\.nc",
        files=GOOD,
        absent=("posterior", "posterior.chain.h5"),
        timeout=FAST,
    ),
    C(
        "export-prior-out-wrong-suffix",
        "export-prior post.nc --out prior.nc",
        2,
        r"prior\.nc",
        r"suffix|\.json",
        files=POST,
        absent=("prior.nc",),
        timeout=FAST,
    ),
    C(
        "report-out-wrong-suffix",
        "report post.nc --out r.pdf",
        2,
        r"r\.pdf",
        r"suffix|\.html",
        files=POST,
        absent=("r.pdf",),
        timeout=FAST,
    ),
    C(
        "grid-plot-and-out-same-name",
        f"grid a.nc {GRID} --plot g.png --out g.png",
        2,
        r"g\.png",
        files=GOOD,
        absent=("g.png",),
        timeout=FAST,
    ),
]

# Item 2: ingest never writes two bags onto one experiment file.
INGEST_CASES = [
    C(
        "ingest-same-stem-bag-and-mcap",
        "ingest one/v1_01.bag two/v1_01.mcap --out exps",
        0,
        r"v1_01",
        files={"one/v1_01.bag": copy("bag"), "two/v1_01.mcap": copy("mcap")},
        exists=("exps/*.nc",),
        count={"exps/*.nc": 2},
    ),
    C(
        "ingest-same-stem-two-folders",
        "ingest one/run.bag two/run.bag --out exps --json",
        0,
        files={"one/run.bag": copy("bag"), "two/run.bag": copy("bag")},
        count={"exps/*.nc": 2},
    ),
    C(
        "ingest-one-bad-of-two",
        "ingest good.bag bad.bag --out exps",
        2,
        r"bad\.bag",
        files={"good.bag": copy("bag"), "bad.bag": truncated("bag", 0.3)},
        exists=("exps/good.nc",),
        absent=("exps/bad.nc",),
    ),
    C(
        "ingest-empty-bag",
        "ingest e.bag --out exps",
        2,
        r"e\.bag",
        files={"e.bag": EMPTY},
        absent=("exps/*.nc",),
        timeout=FAST,
    ),
    C(
        "ingest-garbage-bag",
        "ingest x.bag --out exps",
        2,
        r"x\.bag",
        files={"x.bag": GARBAGE},
        timeout=FAST,
    ),
    C(
        "ingest-csv-named-bag",
        "ingest x.bag --out exps",
        2,
        r"x\.bag",
        files={"x.bag": copy("csv")},
        timeout=FAST,
    ),
    C(
        "ingest-empty-mcap",
        "ingest e.mcap --out exps",
        2,
        r"e\.mcap",
        files={"e.mcap": EMPTY},
        timeout=FAST,
    ),
    C(
        "ingest-truncated-mcap",
        "ingest x.mcap --out exps",
        2,
        r"x\.mcap",
        files={"x.mcap": truncated("mcap", 0.5)},
        absent=("exps/x.nc",),
        timeout=FAST,
    ),
    C(
        "ingest-wrong-suffix",
        "ingest x.txt --out exps",
        2,
        r"x\.txt",
        files={"x.txt": copy("csv")},
        timeout=FAST,
    ),
    C(
        "ingest-missing-topic",
        "ingest x.bag --out exps --topic imu /nope",
        2,
        r"x\.bag",
        r"/nope|imu",
        files={"x.bag": copy("bag")},
        timeout=FAST,
    ),
    C(
        "ingest-unknown-topic-role",
        "ingest x.bag --out exps --topic sonar /s",
        2,
        r"sonar",
        files={"x.bag": copy("bag")},
        timeout=FAST,
    ),
    C(
        "ingest-max-gap-negative",
        "ingest x.bag --out exps --max-gap -1",
        2,
        r"max.gap",
        files={"x.bag": copy("bag")},
        timeout=FAST,
    ),
    C(
        "ingest-max-gap-nan",
        "ingest x.bag --out exps --max-gap nan",
        2,
        r"max.gap",
        files={"x.bag": copy("bag")},
        timeout=FAST,
    ),
    C(
        "ingest-window-reversed",
        "ingest x.bag --out exps --window 20 5",
        2,
        r"window",
        files={"x.bag": copy("bag")},
        timeout=FAST,
    ),
    C(
        "ingest-window-nan",
        "ingest x.bag --out exps --window nan 5",
        2,
        r"window",
        files={"x.bag": copy("bag")},
        timeout=FAST,
    ),
    C("ingest-missing-bag", "ingest nothere.bag --out exps", 2, r"nothere\.bag", timeout=FAST),
]

# Item 7: export orders whose precision is not finite and well conditioned.
EXPORT_CASES = [
    C(
        "export-prior-order-99",
        "export-prior post.nc --out prior.json --order 99",
        2,
        r"order",
        r"99",
        files=POST,
        absent=("prior.json",),
        timeout=FAST,
    ),
    C(
        "export-prior-order-20",
        "export-prior post.nc --out prior.json --order 20",
        2,
        r"order",
        files=POST,
        absent=("prior.json",),
        timeout=FAST,
    ),
    C(
        "export-prior-order-6",
        "export-prior post.nc --out prior.json --order 6",
        2,
        r"order",
        files=POST,
        absent=("prior.json",),
        timeout=FAST,
    ),
    C(
        "export-prior-order-negative",
        "export-prior post.nc --out prior.json --order -1",
        2,
        r"order",
        files=POST,
        absent=("prior.json",),
        timeout=FAST,
    ),
    C(
        "export-prior-order-not-int",
        "export-prior post.nc --out prior.json --order 2.5",
        2,
        r"order",
        files=POST,
        absent=("prior.json",),
        timeout=FAST,
    ),
    C(
        "export-prior-order-2",
        "export-prior post.nc --out prior.json --order 2",
        0,
        files=POST,
        json_files=("prior.json",),
    ),
    C(
        "export-prior-order-0",
        "export-prior post.nc --out prior.json --order 0",
        0,
        files=POST,
        json_files=("prior.json",),
    ),
    C(
        "export-prior-white-order-0",
        "export-prior w.nc --out prior.json --order 0",
        0,
        files={"w.nc": copy("white_posterior")},
        json_files=("prior.json",),
    ),
    C(
        "export-prior-white-order-3",
        "export-prior w.nc --out prior.json --order 3",
        2,  # white noise has no derivative: order 0 only
        files={"w.nc": copy("white_posterior")},
        absent=("*.part",),
    ),
    C(
        "export-prior-empty",
        "export-prior e.nc --out prior.json",
        2,
        r"e\.nc",
        files={"e.nc": EMPTY},
        timeout=FAST,
    ),
    C(
        "export-prior-truncated",
        "export-prior x.nc --out prior.json",
        2,
        r"x\.nc",
        files={"x.nc": truncated("posterior")},
        timeout=FAST,
    ),
    C(
        "export-prior-experiment",
        "export-prior x.nc --out prior.json",
        2,
        r"x\.nc",
        r"posterior",
        files={"x.nc": experiment()},
        timeout=FAST,
    ),
    C(
        "export-prior-csv",
        "export-prior x.csv --out prior.json",
        2,
        r"x\.csv",
        files={"x.csv": copy("csv")},
        timeout=FAST,
    ),
    C(
        "export-prior-json",
        "export-prior x.json --out prior.json",
        2,
        r"x\.json",
        files={"x.json": json_text('{"format": "bayes_jackal.prior/1"}')},
        timeout=FAST,
    ),
    C(
        "export-prior-missing",
        "export-prior nothere.nc --out prior.json",
        2,
        r"nothere\.nc",
        timeout=FAST,
    ),
]

REPORT_CASES = [
    C(
        "report-one-posterior",
        "report post.nc --out r.html --formats png",
        0,
        files=POST,
        exists=("r.html",),
    ),
    C(
        "report-one-bad-of-two",
        "report post.nc e.nc --out r.html --formats png",
        2,
        r"e\.nc",
        files={**POST, "e.nc": EMPTY},
        exists=("r.html",),
    ),
    C(
        "report-truncated-and-good",
        "report post.nc x.nc --out r.html --formats png",
        2,
        r"x\.nc",
        files={**POST, "x.nc": truncated("posterior")},
        exists=("r.html",),
    ),
    C(
        "report-experiment-as-posterior",
        "report x.nc --out r.html",
        2,
        r"x\.nc",
        files={"x.nc": experiment()},
        absent=("r.html", "r_figures"),  # issue 24, item 8: no empty folder
        timeout=FAST,
    ),
    C(
        "report-empty",
        "report e.nc --out r.html",
        2,
        r"e\.nc",
        files={"e.nc": EMPTY},
        absent=("r.html", "r_figures"),  # issue 24, item 8: no empty folder
        timeout=FAST,
    ),
    C(
        "report-empty-folder",
        "report posts --out r.html",
        2,
        r"posts",
        files={"posts": folder()},
        absent=("r.html",),
        timeout=FAST,
    ),
    C(
        "report-missing",
        "report nothere.nc --out r.html",
        2,
        r"nothere\.nc",
        absent=("r.html",),
        timeout=FAST,
    ),
    C(
        "report-formats-unknown",
        "report post.nc --out r.html --formats png,bmp",
        2,
        r"bmp",
        files=POST,
        absent=("r.html",),
        timeout=FAST,
    ),
]

# Item 9: several inputs, one bad: the good ones are written, exit 2. Pooled: named first.
ONE_BAD_CASES = [
    # Issue 24, item 12: a failed analyse left its empty output folder behind.
    C(
        "analyse-every-input-bad-leaves-no-folder",
        f"analyse nothere.bag e.csv --out deep/out {ANALYSE}",
        2,
        r"nothere\.bag: no such file",
        r"none of the 2 inputs could be used",
        files={"e.csv": EMPTY},
        absent=("deep", "deep/out"),
        timeout=FAST,
    ),
    C(
        "compare-every-input-bad-leaves-no-folder",
        f"compare e.csv --out cmp {COMPARE}",
        2,
        r"e\.csv",
        files={"e.csv": EMPTY},
        absent=("cmp",),
        timeout=FAST,
    ),
    C(
        "sample-one-empty-of-two",
        f"sample a.nc e.csv --out p.nc {SAMPLE}",
        2,
        r"e\.csv",
        files={"a.nc": experiment(), "e.csv": EMPTY},
        exists=("p.a.nc",),
    ),
    C(
        "sample-one-missing-of-two",
        f"sample a.nc nothere.nc --out p.nc {SAMPLE}",
        2,
        r"nothere\.nc",
        files=GOOD,
        exists=("p.a.nc",),
    ),
    C(
        "sample-json-one-bad",
        f"sample a.nc x.nc --out p.nc --json {SAMPLE}",
        2,
        r"x\.nc",
        files={"a.nc": experiment(), "x.nc": nc_scaled("yaw_rate", 1e300)},
        exists=("p.a.nc",),
    ),
    C(
        "compare-one-empty-of-two",
        f"compare a.nc e.csv --out cmp {COMPARE}",
        2,
        r"e\.csv",
        files={"a.nc": experiment(), "e.csv": EMPTY},
        exists=("cmp/a.white.nc",),
    ),
    C(
        "compare-json-one-bad",
        f"compare a.nc x.csv --json {COMPARE}",
        2,
        r"x\.csv",
        files={"a.nc": experiment(), "x.csv": csv_scaled("t", 1e3)},
    ),
    C(
        "residuals-one-empty-of-two",
        "residuals a.nc e.csv --json",
        2,
        r"e\.csv",
        files={"a.nc": experiment(), "e.csv": EMPTY},
    ),
    C(
        "residuals-one-nan-of-two",
        "residuals a.csv x.csv --json",
        2,
        r"x\.csv",
        files={"a.csv": copy("csv"), "x.csv": csv_cell("yaw_rate", np.inf)},
    ),
    C(
        "grid-one-empty-of-two",
        f"grid a.nc e.csv {GRID} --out g.nc",
        2,
        r"e\.csv",
        files={"a.nc": experiment(), "e.csv": EMPTY},
        absent=("g.nc",),  # one surface over all inputs: pooled, refused before any work
    ),
    C(
        "sample-pooled-one-bad",
        "sample a.nc b.nc e.csv --pooled --out p.nc",
        2,
        r"e\.csv",
        files={**GOOD2, "e.csv": EMPTY},
        absent=("p.nc", "p.chain.h5"),
        timeout=FAST,
    ),
    C(
        "sample-pooled-last-bad",
        "sample a.nc b.nc x.nc --pooled --out p.nc",
        2,
        r"x\.nc",
        "steady_window",
        files={**GOOD2, "x.nc": experiment(steady_window=[1.0])},
        absent=("p.nc", "p.chain.h5"),
        timeout=FAST,
    ),
    C(
        "compare-pooled-one-bad",
        "compare a.nc b.nc x.csv --pooled --out cmp",
        2,
        r"x\.csv",
        files={**GOOD2, "x.csv": csv_scaled("yaw_rate", 1e300)},
        absent=("cmp/*.nc",),
        timeout=FAST,
    ),
    C(
        "compare-pooled-two-bad-both-named",
        "compare x.csv e.csv a.nc --pooled",
        2,
        r"x\.csv",
        r"e\.csv",
        files={"a.nc": experiment(), "x.csv": csv_scaled("t", 1e9), "e.csv": EMPTY},
        timeout=FAST,
    ),
    C(
        "analyse-one-bad-of-two",
        f"analyse a.nc e.csv --out out {ANALYSE}",
        2,
        r"e\.csv",
        files={"a.nc": experiment(), "e.csv": EMPTY},
        exists=("out/report.html",),
        timeout=120,
    ),
]

# Item 8 and numeric flags: refused with exit 2 before any work.
FLAG_CASES = [
    C(f"{command}-{case_id}", argv, 2, *words, files=files, timeout=FAST)
    for command, case_id, argv, words, files in [
        ("simulate", "v1-negative", "simulate --out r --v1 -1", (r"v1",), {}),
        ("simulate", "seed-negative", "simulate --out r --v1 1 --v2 0 --seed -1", (r"seed",), {}),
        ("simulate", "width-negative", "simulate --out r --v1 1 --width -0.1", (r"width",), {}),
        ("simulate", "width-nan", "simulate --out r --v1 1 --width nan", (r"width",), {}),
        (
            "simulate",
            "sigma-c-nan",
            "simulate --out r --v1 1 --sigma-c nan 0 0",
            (r"sigma.c",),
            {},
        ),
        (
            "simulate",
            "sigma-n-negative",
            "simulate --out r --v1 1 --sigma-n -1 0 0",
            (r"sigma.n",),
            {},
        ),
        ("simulate", "d-lat-negative", "simulate --out r --v1 1 --d-lat -110", (r"d.lat",), {}),
        ("simulate", "d-lat-inf", "simulate --out r --v1 1 --d-lat inf", (r"d.lat",), {}),
        ("simulate", "d-long-1e300", "simulate --out r --v1 1 --d-long 1e300", (r"d.long",), {}),
        ("grid", "start-after-stop", "grid a.nc --d-lat 100 10 10", (r"d.lat",), GOOD),
        ("grid", "step-zero", "grid a.nc --d-lat 10 100 0", (r"d.lat",), GOOD),
        ("grid", "step-negative", "grid a.nc --d-long 10 100 -5", (r"d.long",), GOOD),
        ("grid", "step-nan", "grid a.nc --d-lat 10 100 nan", (r"d.lat",), GOOD),
        ("grid", "start-nan", "grid a.nc --d-long nan 100 10", (r"d.long",), GOOD),
        ("grid", "stop-inf", "grid a.nc --d-lat 10 inf 10", (r"d.lat",), GOOD),
        ("grid", "absurd-size", "grid a.nc --d-lat 1 1e9 1", (r"d.lat",), GOOD),
        ("grid", "damping-negative", "grid a.nc --d-lat -100 100 10", (r"d.lat",), GOOD),
        ("grid", "rate-zero", "grid a.csv --rate 0", (r"rate",), GOOD_CSV),
        ("grid", "rate-nan", "grid a.csv --rate nan", (r"rate",), GOOD_CSV),
        ("grid", "column-unknown-role", "grid a.csv --column gyro yaw_rate", (r"gyro",), GOOD_CSV),
        ("grid", "column-missing", "grid a.csv --column yaw_rate gyro_z", (r"gyro_z",), GOOD_CSV),
        ("residuals", "lags-zero", "residuals a.nc --lags 0", (r"lags",), GOOD),
        ("residuals", "lags-negative", "residuals a.nc --lags -3", (r"lags",), GOOD),
        ("residuals", "lags-too-many", "residuals a.nc --lags 100000", (r"lags",), GOOD),
        ("residuals", "d-lat-nan", "residuals a.nc --d-lat nan", (r"d.lat",), GOOD),
        ("residuals", "d-long-negative", "residuals a.nc --d-long -30", (r"d.long",), GOOD),
        ("residuals", "d-lat-inf", "residuals a.nc --d-lat inf", (r"d.lat",), GOOD),
        ("residuals", "rate-negative", "residuals a.csv --rate -72", (r"rate",), GOOD_CSV),
        ("residuals", "channels-unknown", "residuals a.nc --channels yaw,roll", (r"roll",), GOOD),
        (
            "sample",
            "max-steps-zero",
            "sample a.nc --out p.nc --max-steps 0",
            (r"max.steps",),
            GOOD,
        ),
        (
            "sample",
            "max-steps-negative",
            "sample a.nc --out p.nc --max-steps -5",
            (r"max.steps",),
            GOOD,
        ),
        ("sample", "walkers-negative", "sample a.nc --out p.nc --walkers -1", (r"walkers",), GOOD),
        ("sample", "walkers-one", "sample a.nc --out p.nc --walkers 1", (r"walkers",), GOOD),
        ("sample", "seed-negative", "sample a.nc --out p.nc --seed -1", (r"seed",), GOOD),
        (
            "sample",
            "prior-reversed",
            "sample a.nc --out p.nc --prior d_lat 1000 10",
            (r"d_lat",),
            GOOD,
        ),
        ("sample", "prior-nan", "sample a.nc --out p.nc --prior d_lat nan 10", (r"d_lat",), GOOD),
        (
            "sample",
            "prior-log-zero",
            "sample a.nc --out p.nc --prior sigma_h 0 1",
            (r"sigma_h",),
            GOOD,
        ),
        (
            "sample",
            "prior-unknown",
            "sample a.nc --out p.nc --prior d_latt 10 100",
            (r"d_latt",),
            GOOD,
        ),
        (
            "sample",
            "prior-not-number",
            "sample a.nc --out p.nc --prior d_lat ten 100",
            (r"d_lat",),
            GOOD,
        ),
        ("sample", "rate-inf", "sample a.csv --out p.nc --rate inf", (r"rate",), GOOD_CSV),
        (
            "sample",
            "channel-not-measured",
            "sample a.csv --out p.nc --channels vx",
            (r"vx",),
            {"a.csv": csv_columns(lambda h: [0, 1, 2, 3])},
        ),
        ("compare", "processes-zero", "compare a.nc --processes 0", (r"processes",), GOOD),
        ("compare", "processes-negative", "compare a.nc --processes -2", (r"processes",), GOOD),
        ("compare", "families-unknown", "compare a.nc --families white,pink", (r"pink",), GOOD),
        ("compare", "families-empty", "compare a.nc --families ,", (r"famil",), GOOD),
        ("compare", "max-steps-zero", "compare a.nc --max-steps 0", (r"max.steps",), GOOD),
        ("compare", "walkers-negative", "compare a.nc --walkers -8", (r"walkers",), GOOD),
        (
            "analyse",
            "processes-zero",
            "analyse a.nc --out out --processes 0",
            (r"processes",),
            GOOD,
        ),
        (
            "analyse",
            "max-steps-negative",
            "analyse a.nc --out out --max-steps -1",
            (r"max.steps",),
            GOOD,
        ),
        ("analyse", "window-reversed", "analyse a.nc --out out --window 30 5", (r"window",), GOOD),
        ("analyse", "max-gap-zero", "analyse a.nc --out out --max-gap 0", (r"max.gap",), GOOD),
    ]
]

# Item 8 and 10: robot profiles. Unknown keys and wrong types are refused, naming the key.
PROFILE_CASES = [
    C(
        f"profile-{case_id}",
        f"{command} --robot bad.toml",
        2,
        r"bad\.toml",
        *words,
        files={**GOOD, "bad.toml": builder},
        timeout=FAST,
    )
    for case_id, command, builder, words in [
        (
            "misspelt-prior",
            "residuals a.nc",
            profile(replace("d_lat = [10.0", "d_latt = [10.0")),
            (r"d_latt",),
        ),
        (
            "unknown-section",
            "residuals a.nc",
            profile(lambda t: t + "\n[prior]\nd_lat = [1, 2]\n"),
            (r"prior",),
        ),
        (
            "unknown-body-key",
            "grid a.nc",
            profile(replace("mass = 16.523", "mas = 16.523")),
            (r"mas\b",),
        ),
        (
            "topic-is-number",
            "residuals a.nc",
            profile(replace('imu = "/imu/data"', "imu = 42")),
            (r"imu",),
        ),
        (
            "mass-is-text",
            "residuals a.nc",
            profile(replace("mass = 16.523", 'mass = "heavy"')),
            (r"mass",),
        ),
        (
            "mass-negative",
            "grid a.nc",
            profile(replace("mass = 16.523", "mass = -16.5")),
            (r"mass",),
        ),
        (
            "mass-nan",
            "residuals a.nc",
            profile(replace("mass = 16.523", "mass = nan")),
            (r"mass",),
        ),
        ("rate-zero", "residuals a.nc", profile(replace("rate = 72.0", "rate = 0.0")), (r"rate",)),
        (
            "prior-reversed",
            "residuals a.nc",
            profile(replace("d_lat = [10.0, 1000.0]", "d_lat = [1000.0, 10.0]")),
            (r"d_lat",),
        ),
        (
            "prior-is-text",
            "residuals a.nc",
            profile(replace("d_lat = [10.0, 1000.0]", 'd_lat = "wide"')),
            (r"d_lat",),
        ),
        (
            "prior-three-numbers",
            "residuals a.nc",
            profile(replace("d_lat = [10.0, 1000.0]", "d_lat = [10.0, 500.0, 1000.0]")),
            (r"d_lat",),
        ),
        (
            "wheels-not-list",
            "residuals a.nc",
            profile(replace('right = ["front_right_wheel", "rear_right_wheel"]', "right = 3")),
            (r"right",),
        ),
        (
            "conversion-unknown",
            "residuals a.nc",
            profile(replace('conversion = "ros"', 'conversion = "magic"')),
            (r"conversion",),
        ),
        ("not-toml", "residuals a.nc", raw(b"mass: 16.5\n[[[\n"), (r"toml|parse|invalid",)),
        ("empty", "residuals a.nc", raw(b""), (r"mass|body|missing",)),
        ("binary", "grid a.nc", GARBAGE, ()),
        (
            "schema-version-99",
            "residuals a.nc",
            profile(replace("schema_version = 1", "schema_version = 99")),
            (r"schema",),
        ),
        (
            "simulate-misspelt",
            "simulate --out r --v1 1 --v2 0",
            profile(replace("wheel_radius = 0.098", "wheel_radios = 0.098")),
            (r"wheel_radi",),
        ),
    ]
] + [
    C(
        "profile-missing",
        "residuals a.nc --robot nothere.toml",
        2,
        r"nothere\.toml",
        files=GOOD,
        timeout=FAST,
    ),
    C(
        "profile-is-folder",
        "residuals a.nc --robot prof",
        2,
        r"prof",
        files={**GOOD, "prof": folder()},
        timeout=FAST,
    ),
]

# Item 8: garbage data under commands that once gave confident answers.
GARBAGE_CASES = [
    C(
        "grid-json-yaw-1e300",
        f"grid x.csv {GRID} --json",
        2,
        r"x\.csv",
        r"yaw_rate",
        files={"x.csv": csv_scaled("yaw_rate", 1e300)},
        timeout=FAST,
    ),
    C(
        "residuals-json-yaw-1e300",
        "residuals x.csv --json",
        2,
        r"x\.csv",
        r"yaw_rate",
        files={"x.csv": csv_scaled("yaw_rate", 1e300)},
        stdout_lacks=("Infinity", "NaN"),
        timeout=FAST,
    ),
    C(
        "residuals-json-yaw-1e150",
        "residuals x.nc --json",
        2,
        r"x\.nc",
        r"yaw_rate",
        files={"x.nc": nc_scaled("yaw_rate", 1e150)},
        timeout=FAST,
    ),
    C(
        "grid-wheels-1e200",
        f"grid x.nc {GRID}",
        2,
        r"x\.nc",
        r"omega_r",
        files={"x.nc": nc_scaled("omega_r", 1e200)},
        timeout=FAST,
    ),
    C(
        "grid-time-ms-nc",
        f"grid x.nc {GRID} --json",
        2,
        r"x\.nc",
        r"rate|sample time",
        files={"x.nc": nc_time(lambda t: t * 1e3)},
        timeout=FAST,
    ),
    C(
        "grid-time-ms-mat",
        f"grid x.mat {GRID}",
        2,
        r"x\.mat",
        r"rate|sample time",
        files={"x.mat": mat(lambda c: c | {"t": c["t"] * 1e3})},
        timeout=FAST,
    ),
    C(
        "residuals-time-us",
        "residuals x.csv",
        2,
        r"x\.csv",
        r"rate|sample time",
        files={"x.csv": csv_scaled("t", 1e6)},
        timeout=FAST,
    ),
    C(
        "grid-rate-disagrees",
        f"grid a.csv {GRID} --rate 100",
        2,
        r"a\.csv",
        r"rate",
        files=GOOD_CSV,
        timeout=FAST,
    ),
    C("residuals-json-valid", "residuals a.nc --json --channels yaw,vx,vy", 0, files=GOOD),
    C("grid-json-valid", f"grid a.nc {GRID} --json --method simulation", 0, files=GOOD),
    C(
        "simulate-json-valid",
        "simulate --out r --seed 2 --v1 1 --v2 0 --json",
        0,
        exists=("r/v1_01.nc",),
    ),
    C(
        "ingest-json-valid",
        "ingest a.bag --out exps --json",
        0,
        files={"a.bag": copy("bag")},
        exists=("exps/a.nc",),
    ),
    C(
        "sample-json-valid",
        f"sample a.nc --out p.nc --json {SAMPLE}",
        0,
        files=GOOD,
        exists=("p.nc",),
    ),
    C(
        "compare-json-valid",
        f"compare a.nc --json --out cmp {COMPARE}",
        0,
        files=GOOD,
        exists=("cmp/a.white.nc",),
        json_files=("cmp/a.compare.json",),
    ),
    C(
        "sample-csv-and-nc",
        f"sample a.csv b.nc --out p.nc {SAMPLE}",
        0,
        files={"a.csv": copy("csv"), "b.nc": experiment()},
        exists=("p.a.nc", "p.b.nc"),
    ),
    C("usage-no-command", "", 2, r"usage|command"),
    C("usage-unknown-command", "fly", 2, r"fly"),
    C("usage-missing-out", "sample a.nc", 2, r"--out", files=GOOD),
]

# Lock, signal and full-disk cases (items 3, 4, 5, 6).
HOLD = "--family white --channels yaw --walkers 32 --seed 1 --no-progress"
SPECIAL_CASES = [
    C(
        "lock-sample-same-out",
        "sample a.nc --out p.nc --walkers 32 --seed 1 --no-progress",
        2,
        r"lock|running|in use|busy",
        kind="lock",
        files=GOOD,
        trigger="p.chain.h5",
    ),
    C(
        "lock-compare-same-out",
        "compare a.nc --out cmp --families gaussian --walkers 32 --seed 1 --no-progress",
        2,
        r"lock|running|in use|busy",
        kind="lock",
        files=GOOD,
        trigger="cmp",
    ),
    C(
        "signal-sample-sigint-json",
        f"sample a.nc --out p.nc --json {HOLD} --max-steps 800",
        130,
        kind="signal",
        signum=signal.SIGINT,
        trigger="p.chain.h5",
        files=GOOD,
        rerun=(0, (r"resum",)),
    ),
    C(
        "signal-sample-sigterm",
        f"sample a.nc --out p.nc {HOLD} --max-steps 800",
        (130, 143),
        kind="signal",
        signum=signal.SIGTERM,
        trigger="p.chain.h5",
        files=GOOD,
        rerun=(0, (r"resum",)),
    ),
    C(
        "signal-sample-sigkill-resumes",
        f"sample a.nc --out p.nc {HOLD} --max-steps 800",
        -signal.SIGKILL,
        kind="signal",
        signum=signal.SIGKILL,
        trigger="p.chain.h5",
        files=GOOD,
        rerun=(0, (r"resum",)),
    ),
    C(
        "signal-compare-sigterm-keeps-family",
        f"compare a.nc --out cmp {COMPARE.replace('white', 'white,exponential,gaussian')} --json",
        (130, 143),
        kind="signal",
        signum=signal.SIGTERM,
        # The first family to finish (longest first), with two left to run (~2 s).
        trigger="cmp/a.exponential.nc",
        files=GOOD,
        exists=("cmp/a.exponential.nc",),
        rerun=(0, (r"reusing exponential from cmp/a\.exponential\.nc",)),
    ),
    C(
        "signal-sigint-during-imports",
        "residuals a.nc",
        130,
        kind="signal",
        signum=signal.SIGINT,
        delay=0.3,
        files=GOOD,
        script=True,
    ),
    C(
        "signal-sigterm-during-imports",
        "grid a.nc",
        (130, 143),
        kind="signal",
        signum=signal.SIGTERM,
        delay=0.3,
        files=GOOD,
    ),
    C(
        "signal-analyse-sigint-json",
        f"analyse a.nc --out out --json {ANALYSE}",
        130,
        kind="signal",
        signum=signal.SIGINT,
        trigger="out/experiments/a.nc",
        files=GOOD,
    ),
    C(
        "fsize-simulate",
        "simulate --out runs --seed 1 --v1 1 --v2 0",
        1,  # a write error: exit 1
        r"runs/v1_01\.nc",
        kind="fsize",
        limit=100_000,
        absent=("runs/v1_01.nc",),
    ),
    C(
        "fsize-sample-resumable",
        f"sample a.nc --out p.nc {SAMPLE}",
        1,  # a write error: exit 1
        r"p\.(chain\.h5|nc)",
        kind="fsize",
        limit=150_000,
        files=GOOD,
        rerun=(0, (r"resum",)),
    ),
    C(
        "fsize-grid-out",
        f"grid a.nc {GRID} --out g.nc",
        1,  # a write error: exit 1
        r"g\.nc",
        kind="fsize",
        limit=4_000,
        files=GOOD,
        absent=("g.nc",),
    ),
    C(
        "fsize-grid-plot",
        f"grid a.nc {GRID} --plot s.png",
        1,  # a write error: exit 1
        r"s\.png",
        kind="fsize",
        limit=4_000,
        files=GOOD,
        absent=("s.png",),
    ),
    C(
        "fsize-export-prior",
        "export-prior post.nc --out prior.json",
        1,  # a write error: exit 1
        r"prior\.json",
        kind="fsize",
        limit=600,
        files=POST,
        absent=("prior.json",),
    ),
    C(
        "fsize-report",
        "report post.nc --out r.html --formats png",
        1,  # a write error: exit 1
        r"r\.html|r_figures",
        kind="fsize",
        limit=20_000,
        files=POST,
        absent=("r.html",),
    ),
    C(
        "fsize-ingest",
        "ingest a.bag --out exps",
        1,  # a write error: exit 1
        r"exps/a\.nc",
        kind="fsize",
        limit=50_000,
        files={"a.bag": copy("bag")},
        absent=("exps/a.nc",),
    ),
    C(
        "tmpfs-sample-resumable",
        f"sample a.nc --out disk/p.nc {SAMPLE}",
        1,  # a write error: exit 1
        r"disk/p\.(chain\.h5|nc)",
        r"space|full",
        kind="tmpfs",
        limit=250_000,
        files=GOOD,
        rerun=(0, (r"resum",)),
    ),
    C(
        "tmpfs-simulate",
        "simulate --out disk/runs --seed 1 --v1 4 --v2 0",
        1,  # a write error: exit 1
        r"disk/runs",
        r"space|full",
        kind="tmpfs",
        limit=0,
    ),
]


# A lab on a shared server, its field recordings irreplaceable: what a hostile but
# realistic user tries next. Each row holds on the current code.
NOISE = "--families white --max-steps 200 --seed 1 --no-progress --processes 1"
PRIOR = {**GOOD, "prior.json": prior_file()}


def _bad_prior(edit: Callable[[dict], object]) -> dict[str, Builder]:
    return {**GOOD, "bad.json": prior_file(edit)}


def csv_encoded(encoding: str, edit: Callable[[str], str] = lambda text: text) -> Builder:
    """The simulated run's CSV text, ``edit`` applied, in another encoding (Excel's exports)."""

    def build(lib: Library, path: Path) -> None:
        path.write_bytes(edit(lib.csv.read_text()).encode(encoding))

    return build


FILTER_CASES = [
    # A prior.json that is JSON but not a prior: the format field is named.
    C(
        "filter-prior-is-json-list",
        "filter a.nc --prior list.json --out est.csv",
        2,
        r"list\.json",
        r"format",
        files={**GOOD, "list.json": json_text("[1, 2, 3]")},
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-empty-object",
        "filter a.nc --prior obj.json --out est.csv",
        2,
        r"obj\.json",
        r"format",
        files={**GOOD, "obj.json": json_text("{}")},
        absent=("est.csv",),
        timeout=FAST,
    ),
    # An empty prior file (a copy that failed half-way) is not JSON.
    C(
        "filter-prior-empty-file",
        "filter a.nc --prior e.json --out est.csv",
        2,
        r"e\.json",
        r"not JSON",
        files={**GOOD, "e.json": EMPTY},
        absent=("est.csv",),
        timeout=FAST,
    ),
    # A prior nested 200,000 deep: json's parser recursed out of its stack (exit 1).
    C(
        "filter-prior-nested-deep",
        "filter a.nc --prior deep.json --out est.csv",
        2,
        r"deep\.json",
        r"nests deeper than Python parses",
        files={**GOOD, "deep.json": json_text("[" * 200_000 + "]" * 200_000)},
        absent=("est.csv",),
        timeout=FAST,
    ),
    # The posterior given where its exported prior belongs.
    C(
        "filter-prior-is-a-posterior",
        "filter a.nc --prior post.nc --out est.csv",
        2,
        r"post\.nc",
        r"JSON",
        files={**GOOD, **POST},
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-missing",
        "filter a.nc --prior nothere.json --out est.csv",
        2,
        r"nothere\.json",
        r"no such file",
        files=GOOD,
        absent=("est.csv",),
        timeout=FAST,
    ),
    # A hand-edited prior: a field deleted, a family misspelt, a sign flipped, the rate halved.
    C(
        "filter-prior-without-damping",
        "filter a.nc --prior bad.json --out est.csv",
        2,
        r"bad\.json",
        r"damping\.mean",
        files=_bad_prior(lambda p: p.pop("damping")),
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-family-unknown",
        "filter a.nc --prior bad.json --out est.csv",
        2,
        r"bad\.json",
        r"noise\.family",
        r"'pink'",
        files=_bad_prior(lambda p: p["noise"].update(family="pink")),
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-noise-is-list",
        "filter a.nc --prior bad.json --out est.csv",
        2,
        r"bad\.json",
        r"noise\.channels",
        files=_bad_prior(lambda p: p.update(noise=[])),
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-damping-is-text",
        "filter a.nc --prior bad.json --out est.csv",
        2,
        r"bad\.json",
        r"damping\.mean",
        r"numbers",
        files=_bad_prior(lambda p: p["damping"].update(mean=["a", "b"])),
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-model-matrix-wrong-shape",
        "filter a.nc --prior bad.json --out est.csv",
        2,
        r"bad\.json",
        r"model\.Ad",
        r"3 x 3",
        files=_bad_prior(lambda p: p["model"].update(Ad=[1.0])),
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-dt-negative",
        "filter a.nc --prior bad.json --out est.csv",
        2,
        r"bad\.json",
        r"\bdt\b",
        r"-72 Hz",
        files=_bad_prior(lambda p: p.update(dt=-p["dt"])),
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-for-36-hz",
        "filter a.nc --prior bad.json --out est.csv",
        2,
        r"bad\.json",
        r"\bdt\b",
        r"36 Hz",
        r"72 Hz",
        files=_bad_prior(lambda p: p.update(dt=2 * p["dt"])),
        absent=("est.csv",),
        timeout=FAST,
    ),
    # Fields edited to the wrong type: each named with the file and its value, never a
    # ValueError, TypeError, ZeroDivisionError or AttributeError of the filters.
    *(
        C(
            f"filter-prior-{case_id}",
            "filter a.nc --prior bad.json --out est.csv",
            2,
            r"bad\.json",
            *words,
            files=_bad_prior(edit),
            absent=("est.csv",),
            timeout=FAST,
        )
        for case_id, edit, words in [
            (
                "dt-text",
                lambda p: p.update(dt="fast"),
                (r"\bdt: expected a positive number", "'fast'"),
            ),
            (
                "dt-null",
                lambda p: p.update(dt=None),
                (r"\bdt: expected a positive number", "None"),
            ),
            (
                "dt-zero",
                lambda p: p.update(dt=0),
                (r"\bdt: expected a positive number", r"got 0\b"),
            ),
            (
                "robot-is-list",
                lambda p: p.update(robot=[]),
                (r"\brobot: expected an object", r"\[\]"),
            ),
            (
                "robot-mass-text",
                lambda p: p["robot"].update(mass="heavy"),
                (r"robot\.mass: expected a positive number", "'heavy'"),
            ),
            # Item 2: a string was iterated letter by letter; an empty list wrote only t.
            (
                "channels-is-text",
                lambda p: p["noise"].update(channels="yaw"),
                (r"noise\.channels: expected a non-empty list of channel names", "'yaw'"),
            ),
            (
                "channels-empty",
                lambda p: p["noise"].update(channels=[]),
                (r"noise\.channels: expected a non-empty list of channel names", r"\[\]"),
            ),
            (
                "order-text",
                lambda p: p["generalised_coordinates"].update(order="two"),
                (r"generalised_coordinates\.order", "whole number", "'two'"),
            ),
            (
                "smoothness-text",
                lambda p: p["sensor_noise"].update(smoothness_seconds="x"),
                (r"sensor_noise\.smoothness_seconds", "positive number", "'x'"),
            ),
            (
                "draws-of-two-lengths",
                lambda p: p["draws"].update(d_lat=p["draws"]["d_lat"][:5]),
                (r"\bdraws: ", r"'d_lat': 5\b"),
            ),
        ]
    ),
    # Item 4: a named pipe as the prior blocked the read for ever.
    C(
        "filter-prior-is-fifo",
        "filter a.nc --prior pr.json --out est.csv",
        2,
        r"pr\.json: not a regular file \(a named pipe\)",
        files={**GOOD, "pr.json": fifo()},
        absent=("est.csv",),
        timeout=FAST,
    ),
    # Outputs: never an input (the data or the prior), a .csv, a file not a folder.
    C(
        "filter-out-is-input-csv",
        "filter a.csv --prior prior.json --out a.csv",
        2,
        r"a\.csv",
        r"input",
        files={**GOOD_CSV, "prior.json": prior_file()},
        timeout=FAST,
    ),
    C(
        "filter-out-is-the-prior",
        "filter a.nc --prior prior.json --out prior.json",
        2,
        r"prior\.json",
        r"input",
        files=PRIOR,
        timeout=FAST,
    ),
    C(
        "filter-out-wrong-suffix",
        "filter a.nc --prior prior.json --out est.json",
        2,
        r"est\.json",
        r"suffix|\.csv",
        files=PRIOR,
        absent=("est.json",),
        timeout=FAST,
    ),
    C(
        "filter-out-existing-folder",
        "filter a.nc --prior prior.json --out est.csv",
        2,
        r"est\.csv",
        r"folder",
        files={**PRIOR, "est.csv": folder()},
        timeout=FAST,
    ),
    # Flags refused by the parser, naming the flag and the value.
    C(
        "filter-filters-unknown",
        "filter a.nc --prior prior.json --out est.csv --filters kalman,particle",
        2,
        r"--filters",
        r"particle",
        files=PRIOR,
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-order-negative",
        "filter a.nc --prior prior.json --out est.csv --order -1",
        2,
        r"--order",
        r"-1",
        files=PRIOR,
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-lookahead-negative",
        "filter a.nc --prior prior.json --out est.csv --lookahead -1",
        2,
        r"--lookahead",
        r"-1",
        files=PRIOR,
        absent=("est.csv",),
        timeout=FAST,
    ),
    # An order whose precision is not finite: the allowed orders are said.
    C(
        "filter-order-99",
        "filter a.nc --prior prior.json --out est.csv --order 99",
        2,
        r"prior\.json",
        r"order 99",
        r"allowed",
        files=PRIOR,
        absent=("est.csv",),
        timeout=FAST,
    ),
    # Item 9 for filter: the good run's estimates are written, the bad one named, exit 2.
    C(
        "filter-one-empty-of-two",
        "filter a.nc e.csv --prior prior.json --out est.csv",
        2,
        r"e\.csv",
        files={**PRIOR, "e.csv": EMPTY},
        exists=("est.csv",),
    ),
    C(
        "filter-json-valid",
        "filter a.nc --prior prior.json --out est.csv --json",
        0,
        files=PRIOR,
        exists=("est.csv",),
    ),
]

NOISE_CASES = [
    # Bare noise series a bench recording can hold: each refused, naming file, column, value.
    C(
        "noise-constant-series",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv",
        r"gyro",
        r"constant",
        files={"x.csv": series(lambda t, x: (t, np.full_like(x, 0.3)))},
        timeout=FAST,
    ),
    C(
        "noise-single-sample",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv",
        r"gyro",
        r"\b1 samples?",
        files={"x.csv": series(lambda t, x: (t[:1], x[:1]))},
        timeout=FAST,
    ),
    # The logger's clock stepped back 1 s: a clock jump, with its line.
    C(
        "noise-clock-jump",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv",
        r"backwards",
        r"line \d+",
        files={"x.csv": series(lambda t, x: (np.where(t > 4.0, t - 1.0, t), x))},
        timeout=FAST,
    ),
    # Item 3: one stamp of 1e308 (here the last) overflowed the clock's fit: exit 1.
    C(
        "noise-stamp-1e308",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv: t: a clock jump at line \d+",
        r"t = 1e\+308 s",
        files={"x.csv": series(lambda t, x: (np.append(t[:-1], 1e308), x))},
        timeout=FAST,
    ),
    C(
        "noise-series-is-fifo",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv: not a regular file \(a named pipe\)",
        files={"x.csv": fifo()},
        timeout=FAST,
    ),
    C(
        "noise-all-nan",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv",
        r"gyro",
        r"nan",
        files={"x.csv": series(lambda t, x: (t, np.full_like(x, np.nan)))},
        timeout=FAST,
    ),
    C(
        "noise-inf-sample",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv",
        r"gyro",
        r"inf at line \d+",
        files={"x.csv": series(lambda t, x: (t, np.where(np.arange(len(x)) == 10, np.inf, x)))},
        timeout=FAST,
    ),
    C(
        "noise-values-1e308",
        f"noise x.csv --column gyro {NOISE}",
        2,
        r"x\.csv",
        r"gyro",
        r"rescale",
        files={"x.csv": series(lambda t, x: (t, x / np.abs(x).max() * 1e308))},
        timeout=FAST,
    ),
    C(
        "noise-column-missing",
        f"noise x.csv --column gyro_z {NOISE}",
        2,
        r"x\.csv",
        r"gyro_z",
        files={"x.csv": series()},
        timeout=FAST,
    ),
    C(
        "noise-no-time-column",
        f"noise x.csv {NOISE}",
        2,
        r"x\.csv",
        r"--rate",
        files={"x.csv": csv_columns(lambda h: [1])},
        timeout=FAST,
    ),
    # An experiment file is no bare series: the suffix is named.
    C(
        "noise-experiment-file",
        f"noise a.nc {NOISE}",
        2,
        r"a\.nc",
        r"\.nc",
        files=GOOD,
        timeout=FAST,
    ),
    C(
        "noise-topic-on-csv",
        f"noise x.csv --column gyro --topic /imu/data {NOISE}",
        2,
        r"x\.csv",
        r"topic",
        files={"x.csv": series()},
        timeout=FAST,
    ),
    C(
        "noise-prior-width-reversed",
        f"noise x.csv --column gyro {NOISE} --prior width 2 0.001",
        2,
        r"sigma_h",
        r"0\.001",
        files={"x.csv": series()},
        timeout=FAST,
    ),
    # Fewer steps than bridge sampling needs: refused before any series is read.
    C(
        "noise-max-steps-below-evidence",
        "noise x.csv --column gyro --families white --max-steps 5 --no-progress",
        2,
        r"max_steps",
        r"16",
        files={"x.csv": series()},
        timeout=FAST,
    ),
    C(
        "noise-families-unknown",
        "noise x.csv --column gyro --families white,pink",
        2,
        r"--families",
        r"pink",
        files={"x.csv": series()},
        timeout=FAST,
    ),
    C(
        "noise-out-existing-file",
        f"noise x.csv --column gyro --out taken {NOISE}",
        2,
        r"taken",
        r"file|folder",
        files={"x.csv": series(), "taken": raw(b"mine\n")},
        timeout=FAST,
    ),
    C(
        "noise-out-is-input",
        f"noise x.csv --column gyro --out x.csv {NOISE}",
        2,
        r"x\.csv",
        r"input",
        files={"x.csv": series()},
        timeout=FAST,
    ),
    # Two folders' series of one stem: the first is written, the second never replaces it.
    C(
        "noise-same-stem-two-folders",
        f"noise one/a.csv two/a.csv --column gyro --out out {NOISE}",
        2,
        r"two/a\.csv",
        r"rename",
        files={"one/a.csv": series(), "two/a.csv": series()},
        count={"out/*.noise.json": 1},
    ),
    # Item 9 for noise: the good series' files are written, the bad one named, exit 2.
    C(
        "noise-one-empty-of-two",
        f"noise a.csv e.csv --column gyro --out out --json {NOISE}",
        2,
        r"e\.csv",
        files={"a.csv": series(), "e.csv": EMPTY},
        exists=("out/a.noise.json",),
        json_files=("out/a.noise.json",),
    ),
]

# More robot profiles a lab edits by hand: each refused, naming the file and the key.
PROFILE_MORE_CASES = [
    C(
        f"profile-{case_id}",
        f"{command} --robot bad.toml",
        2,
        r"bad\.toml",
        *words,
        files={**GOOD, "bad.toml": profile(replace(old, new))},
        timeout=FAST,
    )
    for case_id, command, old, new, words in [
        (
            "yaw-inertia-negative",
            f"grid a.nc {GRID}",
            "yaw_inertia = 0.5485",
            "yaw_inertia = -0.5485",
            (r"yaw_inertia", r"-0\.5485"),
        ),
        (
            "half-track-zero",
            "residuals a.nc",
            "half_track = 0.2078",
            "half_track = 0.0",
            (r"half_track", r"\b0\.0\b"),
        ),
        (
            "half-wheelbase-inf",
            "residuals a.nc",
            "half_wheelbase = 0.131",
            "half_wheelbase = inf",
            (r"half_wheelbase", r"\binf\b"),
        ),
        (
            "wheel-radius-missing",
            "residuals a.nc",
            "wheel_radius = 0.098",
            "# wheel_radius = 0.098",
            (r"wheel_radius", r"missing"),
        ),
        # TOML's true is no number, though Python's bool is an int.
        ("mass-is-bool", "residuals a.nc", "mass = 16.523", "mass = true", (r"mass", r"True")),
        ("rate-is-text", "residuals a.nc", "rate = 72.0", 'rate = "72"', (r"rate", r"'72'")),
        (
            "multiplier-negative",
            "residuals a.nc",
            "wheel_separation_multiplier = 1.5",
            "wheel_separation_multiplier = -1.5",
            (r"wheel_separation_multiplier", r"-1\.5"),
        ),
        (
            "prior-from-zero",
            "residuals a.nc",
            "sigma_n = [1e-4, 1.0]",
            "sigma_n = [0.0, 1.0]",
            (r"sigma_n", r"0\.0, 1\.0"),
        ),
        (
            "schema-version-text",
            "residuals a.nc",
            "schema_version = 1",
            'schema_version = "1"',
            (r"schema_version", r"'1'"),
        ),
        (
            "topic-empty",
            "residuals a.nc",
            'imu = "/imu/data"',
            'imu = ""',
            (r"topics\.imu", r"empty"),
        ),
        (
            "section-capitalised",
            "residuals a.nc",
            "[sampling]",
            "[Sampling]",
            (r"Sampling",),
        ),
    ]
]

NEWLINE = "bad\nname.csv"

# File names and text a lab's own tools produce: odd names work; odd text is named.
FILE_CASES = [
    C(
        "grid-unicode-and-space-paths",
        f'grid "relevé 1.nc" {GRID} --out "sortie é/g ü.nc" --json',
        0,
        files={"relevé 1.nc": experiment()},
        exists=("sortie é/g ü.nc",),
    ),
    C(
        "grid-newline-in-paths",
        f'grid "a\nb.nc" {GRID} --out "g\nh.nc"',
        0,
        files={"a\nb.nc": experiment()},
        exists=("g\nh.nc",),
    ),
    C(
        "residuals-unicode-name-named",
        'residuals "relevé 3.csv"',
        2,
        r"relevé 3\.csv",
        r"empty",
        files={"relevé 3.csv": EMPTY},
        timeout=FAST,
    ),
    # A newline in a name is shown raw or escaped, the name whole either way.
    C(
        "residuals-newline-name-named",
        f'residuals "{NEWLINE}"',
        2,
        r"bad(\n|\\n|\?)name\.csv",
        r"empty",
        files={NEWLINE: EMPTY},
        timeout=FAST,
    ),
    # Item 4: a named pipe as an input blocked the read for ever; a FIFO is no recording.
    *(
        C(
            f"{argv.split()[0]}-input-is-fifo-{name.split('.')[-1]}",
            argv.format(name),
            2,
            rf"{re.escape(name)}: not a regular file \(a named pipe\)",
            files={**GOOD, name: fifo()},
            timeout=FAST,
        )
        for argv, name in [
            ("residuals {}", "x.csv"),
            ("residuals {}", "x.mat"),
            ("residuals {}", "x.nc"),
            (f"sample {{}} --out p.nc {SAMPLE}", "x.mcap"),
            ("ingest {} --out exps", "x.bag"),
            ("residuals a.nc --robot {}", "r.toml"),
            ("report {} --out r.html", "post.nc"),
        ]
    ),
    # Item 5: a CSV without its header row was "column '0' appears 3 times".
    C(
        "residuals-csv-no-header",
        "residuals x.csv",
        2,
        r"x\.csv: line 1 holds numbers",
        r"header row is missing",
        files={"x.csv": csv_text(lambda t: t.split("\n", 1)[1])},
        timeout=FAST,
    ),
    # Item 3: one stamp of 1e308 overflowed the clock's fit (exit 1) in every reader.
    *(
        C(
            f"{command}-csv-last-stamp-1e308",
            f"{command} x.csv{options}",
            2,
            r"x\.csv: t: a clock jump at line \d+",
            r"t = 1e\+308 s",
            files={"x.csv": csv_cell("t", 1e308, row=-1)},
            timeout=FAST,
        )
        for command, options in [("residuals", ""), ("grid", f" {GRID}")]
    ),
    # ... and one of 1e200 was said in 201 digits.
    C(
        "residuals-csv-stamp-1e200-compact",
        "residuals x.csv",
        2,
        r"x\.csv: t: a clock jump at line 102",
        r"t = 1e\+200 s",
        files={"x.csv": csv_cell("t", 1e200)},
        timeout=FAST,
    ),
    C(
        "residuals-csv-tabs",
        "residuals x.csv",
        2,
        r"x\.csv",
        r"column",
        files={"x.csv": csv_text(lambda t: t.replace(",", "\t"))},
        timeout=FAST,
    ),
    # Excel's "Unicode text" (UTF-16) and a Latin-1 header: an encoding error, named.
    C(
        "residuals-csv-utf16",
        "residuals x.csv",
        2,
        r"x\.csv",
        r"utf-8|decode|encoding",
        files={"x.csv": csv_encoded("utf-16")},
        timeout=FAST,
    ),
    C(
        "residuals-csv-latin1-header",
        "residuals x.csv",
        2,
        r"x\.csv",
        r"utf-8|decode|encoding",
        files={
            "x.csv": csv_encoded("latin-1", lambda t: t.replace("vy\n", "vy,température\n", 1))
        },
        timeout=FAST,
    ),
    C(
        "residuals-csv-nul-byte",
        "residuals x.csv",
        2,
        r"x\.csv",
        r"line \d+",
        files={"x.csv": csv_text(lambda t: t[:5000] + "\0" + t[5000:])},
        timeout=FAST,
    ),
    # A European export: semicolons between fields, decimal commas inside them.
    C(
        "residuals-csv-decimal-comma",
        "residuals x.csv",
        2,
        r"x\.csv",
        r"line \d+|column",
        files={"x.csv": csv_text(lambda t: t.replace(",", ";").replace(".", ","))},
        timeout=FAST,
    ),
    C(
        "residuals-csv-trailing-comment",
        "residuals x.csv",
        2,
        r"x\.csv",
        r"line \d+",
        files={"x.csv": csv_text(lambda t: t + "# end of log\n")},
        timeout=FAST,
    ),
    # What the csv module reads as the same table: quotes and spaces after the commas.
    C(
        "grid-accepts-csv-quoted",
        f"grid x.csv {GRID} --json",
        0,
        files={
            "x.csv": csv_text(
                lambda t: (
                    "\n".join(
                        ",".join(f'"{cell}"' for cell in line.split(","))
                        for line in t.splitlines()
                    )
                    + "\n"
                )
            )
        },
    ),
    C(
        "grid-accepts-csv-spaces-after-commas",
        f"grid x.csv {GRID} --json",
        0,
        files={"x.csv": csv_text(lambda t: t.replace(",", ", "))},
    ),
]

# Outputs and flags on a shared server: a link planted at the output is replaced,
# its target (another user's file) untouched; repeated names are refused.
SHARED_CASES = [
    C(
        "grid-out-is-symlink-to-theirs",
        f"grid a.nc {GRID} --out g.nc --plot s.png",
        0,
        files={
            **GOOD,
            "theirs/g.nc": raw(b"their surface\n"),
            "theirs/s.png": raw(b"their figure\n"),
            "g.nc": symlink("theirs/g.nc"),
            "s.png": symlink("theirs/s.png"),
        },
        exists=("g.nc", "s.png"),
    ),
    C(
        "export-prior-out-is-symlink-to-theirs",
        "export-prior post.nc --out prior.json",
        0,
        files={
            **POST,
            "theirs/prior.json": json_text('{"theirs": 1}'),
            "prior.json": symlink("theirs/prior.json"),
        },
        json_files=("prior.json",),
    ),
    C(
        "export-prior-out-parent-is-file",
        "export-prior post.nc --out notdir/prior.json",
        2,
        r"notdir",
        r"file",
        files={**POST, "notdir": raw(b"mine\n")},
        timeout=FAST,
    ),
    C(
        "report-out-parent-is-file",
        "report post.nc --out notdir/r.html",
        2,
        r"notdir",
        r"file",
        files={**POST, "notdir": raw(b"mine\n")},
        timeout=FAST,
    ),
    # A netCDF of someone else's tool is no posterior.
    C(
        "report-foreign-netcdf",
        "report x.nc --out r.html",
        2,
        r"x\.nc",
        r"posterior",
        files={"x.nc": nc_edit(lambda ds: ds[["yaw_rate"]].assign_attrs(format="theirs/1"))},
        absent=("r.html", "r_figures"),
        timeout=FAST,
    ),
    C(
        "export-prior-foreign-netcdf",
        "export-prior x.nc --out prior.json",
        2,
        r"x\.nc",
        r"posterior",
        files={"x.nc": nc_edit(lambda ds: ds[["yaw_rate"]].assign_attrs(format="theirs/1"))},
        absent=("prior.json",),
        timeout=FAST,
    ),
    C(
        "report-formats-empty",
        "report post.nc --out r.html --formats ,",
        2,
        r"--formats",
        files=POST,
        absent=("r.html",),
        timeout=FAST,
    ),
    C(
        "export-prior-sensor-smoothness-zero",
        "export-prior post.nc --out prior.json --sensor-smoothness 0",
        2,
        r"--sensor-smoothness",
        r"'0'",
        files=POST,
        absent=("prior.json",),
        timeout=FAST,
    ),
    C(
        "sample-channels-repeated",
        "sample a.nc --out p.nc --channels yaw,yaw",
        2,
        r"channels",
        r"'yaw', 'yaw'",
        files=GOOD,
        absent=("p.nc", "p.chain.h5"),
        timeout=FAST,
    ),
    C(
        "compare-families-repeated",
        "compare a.nc --out cmp --families white,white",
        2,
        r"families",
        r"'white', 'white'",
        files=GOOD,
        absent=("cmp/*.nc",),
        timeout=FAST,
    ),
    C(
        "analyse-families-unknown",
        "analyse a.nc --out out --families white,pink",
        2,
        r"--families",
        r"pink",
        files=GOOD,
        absent=("out/*",),
        timeout=FAST,
    ),
]


# ------------------------------------------------------------- issue 37

#: Short settings of population (its units sampled one at a time).
POP = (
    "--family white --channels yaw --max-steps 300 --walkers 32 --seed 1 --no-progress "
    "--processes 1"
)
#: The library run's provenance, recorded by another robot's profile.
HUSKY_RUN = json.dumps({"simulated": True, "robot": "husky"})


def groups(text: str) -> Builder:
    """A groups CSV of the experiments ``a``, ``b`` ... (``population --groups``)."""
    return raw(text.encode())


GROUPS = groups("run,group,speed\na,A,0.3\nb,B,0.5\n")


def provenance(**fields) -> Builder:
    """The simulated experiment with ``provenance`` = ``fields`` (a group, covariates)."""
    return experiment(provenance=json.dumps(fields))


def posterior_cell(variable: str, index: tuple[int, int], value: float) -> Builder:
    """The library's posterior with one draw of ``variable`` (chain, draw) set to ``value``."""

    def build(lib: Library, path: Path) -> None:
        import h5py

        shutil.copyfile(lib.posterior, path)
        with h5py.File(path, "r+") as stored:
            stored[f"posterior/{variable}"][index] = value

    return build


def prior_text(edit: Callable[[str], str]) -> Builder:
    """The exported prior's JSON text with ``edit(text) -> text`` applied."""

    def build(lib: Library, path: Path) -> None:
        path.write_text(edit(_exported_prior(lib).read_text()))

    return build


DEEP = 200_000
CAVEAT = r"the one-step minimum is not the damping's estimate"


def _population(case_id: str, files: dict, *words: str, options: str = "", **more) -> Case:
    """``population a.nc b.nc ...`` of ``files`` (a groups CSV ``g.csv`` if given)."""
    runs = " ".join(name for name in files if name.endswith(".nc"))
    table = " --groups g.csv" if "g.csv" in files else ""
    return C(
        case_id,
        f"population {runs}{table} --out pop {POP}{options}",
        more.pop("exit", 2),
        *words,
        files=files,
        **more,
    )


def _refused_groups(case_id: str, table: str, *words: str, verb: str = "population") -> Case:
    """A groups CSV ``table`` that ``population`` (or ``analyse``) refuses before any work."""
    files = {**GOOD2, "g.csv": groups(table)}
    if verb == "analyse":
        command = f"analyse a.nc b.nc --groups g.csv --out out {ANALYSE}"
        return C(case_id, command, 2, *words, files=files, absent=("out/*",), timeout=FAST)
    return _population(case_id, files, *words, absent=("pop/population.json", "pop/units/*"),
                       timeout=FAST)  # fmt: skip


# Issue 37's hostile cases: each fails on the code before issue 37 (c8b6858) and passes now.
ISSUE37_CASES = [
    # Item 1: an unquoted decimal comma (0,3) made a row longer than its header; speed read as 0.
    _refused_groups(
        "population-groups-decimal-comma",
        "run,group,speed\na,A,0,3\nb,B,0.5\n",
        r"g\.csv: row 2",
        r"4 cells under a header of 3",
        r"decimal comma",
    ),
    _refused_groups(
        "population-groups-decimal-comma-last-row",
        "run,group,speed\na,A,0.3\nb,B,0,5\n",
        r"g\.csv: row 3",
        r"4 cells under a header of 3",
    ),
    _refused_groups(
        "population-groups-decimal-comma-four-columns",
        "run,group,speed,slope\na,A,0.3,0\nb,B,0,5,0\n",
        r"g\.csv: row 3",
        r"5 cells under a header of 4",
    ),
    # analyse copied the runs into out/experiments before it read --groups: nothing now.
    _refused_groups(
        "analyse-groups-decimal-comma",
        "run,group,speed\na,A,0,3\nb,B,0.5\n",
        r"g\.csv: row 2",
        r"4 cells under a header of 3",
        verb="analyse",
    ),
    # Item 2: a header naming a column twice (the last one won), also once with a unit.
    _refused_groups(
        "population-groups-speed-twice",
        "run,group,speed,speed\na,A,0.3,0.4\nb,B,0.5,0.6\n",
        r"g\.csv: header",
        r"names 'speed' twice",
    ),
    _refused_groups(
        "population-groups-speed-and-speed-with-unit",
        "run,group,speed,Speed [m/s]\na,A,0.3,0.4\nb,B,0.5,0.6\n",
        r"g\.csv: header",
        r"names 'speed' twice",
    ),
    _refused_groups(
        "population-groups-group-twice",
        "run,group,group\na,A,B\nb,B,A\n",
        r"g\.csv: header",
        r"names 'group' twice",
    ),
    _refused_groups(
        "analyse-groups-speed-twice",
        "run,group,speed,speed\na,A,0.3,0.4\nb,B,0.5,0.6\n",
        r"g\.csv: header",
        r"names 'speed' twice",
        verb="analyse",
    ),
    # Item 3: speed [m/s] is speed (its slope was dropped in silence), and a speed
    # given for some runs only is said (covariate-incomplete), naming a run without.
    _population(
        "population-groups-speed-with-unit-is-speed",
        {**GOOD2, "g.csv": groups("run,group,speed [m/s]\na,A,0.3\nb,B,0.5\n")},
        r"speed dependence",
        r"pooled \+ slope",
        options=" --json",
        exit=0,
        json_files=("pop/population.json",),
    ),
    _population(
        "population-groups-speed-in-parentheses-is-the-covariate",
        {**GOOD2, "g.csv": groups("run,group,Speed (m/s)\na,A,0.3\nb,B,0.5\n")},
        r"speed dependence",
        options=" --covariate speed --json",
        exit=0,
        json_files=("pop/population.json",),
    ),
    _population(
        "population-groups-speed-missing-for-one-run",
        {**GOOD2, "g.csv": groups("run,group,speed\na,A,0.3\nb,B,\n")},
        r"1 of 2 runs have a speed \('b' has none\)",
        r"no state dependence is fitted",
        options=" --json",
        exit=0,
        json_files=("pop/population.json",),
    ),
    _population(
        "population-groups-speed-missing-for-one-of-three",
        {
            **GOOD2,
            "c.nc": experiment(),
            "g.csv": groups("run,group,speed\na,A,0.3\nb,A,0.5\nc,B,\n"),
        },
        r"2 of 3 runs have a speed \('c' has none\)",
        r"no state dependence is fitted",
        exit=0,
        exists=("pop/population.json",),
    ),
    # Item 4: speeds whose range overflows a float (numpy's overflow warning, exit 0).
    _population(
        "population-groups-speeds-1e308",
        {**GOOD2, "g.csv": groups("run,group,speed\na,A,1e308\nb,B,-1e308\n")},
        r"covariate",
        r"-1e\+308 \.\. 1e\+308 span more than a float holds",
        r"\A(?![\s\S]*(RuntimeWarning|overflow))",
        absent=("pop/population.json",),
    ),
    _population(
        "population-groups-speeds-1.7e308-covariate-speed",
        {**GOOD2, "g.csv": groups("run,group,speed\na,A,1.7e308\nb,B,-1.7e308\n")},
        r"covariate",
        r"span more than a float holds",
        r"\A(?![\s\S]*(RuntimeWarning|overflow))",
        options=" --covariate speed",
        absent=("pop/population.json",),
    ),
    _population(
        "population-provenance-speeds-1e308",
        {
            "a.nc": provenance(group="A", covariates={"speed": 1e308}),
            "b.nc": provenance(group="B", covariates={"speed": -1e308}),
        },
        r"covariate",
        r"span more than a float holds",
        r"\A(?![\s\S]*(RuntimeWarning|overflow))",
        absent=("pop/population.json",),
    ),
    # Item 5: a named pipe as --out was replaced by a regular file, exit 0.
    C(
        "sample-out-is-fifo",
        f"sample a.nc --out p.nc {SAMPLE}",
        2,
        r"--out p\.nc: is a named pipe, not a file",
        files={**GOOD, "p.nc": fifo()},
        absent=("p.chain.h5",),
        timeout=FAST,
    ),
    C(
        "filter-out-is-fifo",
        "filter a.nc --prior prior.json --out est.csv",
        2,
        r"--out est\.csv: is a named pipe, not a file",
        files={**PRIOR, "est.csv": fifo()},
        timeout=FAST,
    ),
    C(
        "export-prior-out-is-fifo",
        "export-prior post.nc --out prior.json",
        2,
        r"--out prior\.json: is a named pipe, not a file",
        files={**POST, "prior.json": fifo()},
        timeout=FAST,
    ),
    C(
        "report-out-is-fifo",
        "report post.nc --out r.html --formats png",
        2,
        r"--out r\.html: is a named pipe, not a file",
        files={**POST, "r.html": fifo()},
        absent=("r_figures",),
        timeout=FAST,
    ),
    C(
        "grid-out-is-fifo",
        f"grid a.nc {GRID} --out g.nc",
        2,
        r"--out g\.nc: is a named pipe, not a file",
        files={**GOOD, "g.nc": fifo()},
        timeout=FAST,
    ),
    # Item 6: population's own outputs were checked after its units were sampled.
    *(
        C(
            f"population-{case_id}",
            "population a.nc b.nc --groups g.csv --out pop --no-progress",
            2,
            words,
            files={**GOOD2, "g.csv": GROUPS, name: planted},
            absent=("pop/units/*",),
            timeout=FAST,
        )
        for case_id, name, planted, words in [
            ("units-is-a-file", "pop/units", raw(b"mine\n"), r"pop/units: is an existing file"),
            (
                "population-json-is-a-folder",
                "pop/population.json",
                folder(),
                r"pop/population\.json: is an existing folder",
            ),
            (
                "population-png-is-a-folder",
                "pop/population.png",
                folder(),
                r"pop/population\.png: is an existing folder",
            ),
            ("units-is-a-fifo", "pop/units", fifo(), r"pop/units: is an existing file"),
        ]
    ),
    # Item 9: a Husky's run read under the Jackal's profile (and the other way round)
    # was fitted as the profile's robot in silence.
    C(
        "grid-husky-run-under-jackal-profile",
        f"grid h.nc {GRID} --json",
        0,
        r"h\.nc: recorded as a 'husky' run, read with the 'jackal' profile",
        r"--robot husky",
        files={"h.nc": experiment(provenance=HUSKY_RUN)},
    ),
    C(
        "residuals-husky-run-under-jackal-profile",
        "residuals h.nc --json",
        0,
        r"h\.nc: recorded as a 'husky' run, read with the 'jackal' profile",
        r"--robot husky",
        files={"h.nc": experiment(provenance=HUSKY_RUN)},
    ),
    C(
        "residuals-jackal-run-under-husky-profile",
        "residuals a.nc --robot husky --json",
        0,
        r"a\.nc: recorded as a 'jackal' run, read with the 'husky' profile",
        r"--robot jackal",
        files=GOOD,
    ),
    C(
        "grid-jackal-csv-run-under-husky-profile",
        f"grid a.nc {GRID} --robot husky --json",
        0,
        r"a\.nc: recorded as a 'jackal' run, read with the 'husky' profile",
        files=GOOD,
    ),
    C(
        "sample-husky-run-under-jackal-profile",
        f"sample h.nc --out p.nc {SAMPLE}",
        0,
        r"h\.nc: recorded as a 'husky' run, read with the 'jackal' profile",
        files={"h.nc": experiment(provenance=HUSKY_RUN)},
        exists=("p.nc",),
    ),
    # Item 10: noise took stamps in ms as s (a 0.072 Hz series), or a 1000x rate.
    *(
        C(
            f"noise-stamps-{case_id}",
            f"noise x.{suffix} --column gyro {NOISE}",
            2,
            rf"x\.{suffix}: t: the stamps give {rate} Hz",
            r"outside the rates of sensor logs \(1-10000 Hz\)",
            hint,
            files={f"x.{suffix}": builder},
            absent=("*.noise.json",),
            timeout=FAST,
        )
        for case_id, suffix, rate, hint, builder in [
            ("in-ms", "csv", r"0\.072", r"milliseconds", series(lambda t, x: (t * 1e3, x))),
            ("in-us", "csv", r"7\.2e-05", r"microseconds", series(lambda t, x: (t * 1e6, x))),
            ("in-ks", "csv", r"72000", r"declare the rate", series(lambda t, x: (t / 1e3, x))),
            (
                "in-ms-mat",
                "mat",
                r"0\.072",
                r"milliseconds",
                mat(lambda c: {"t": c["t"] * 1e3, "gyro": c["yaw_rate"]}),
            ),
        ]
    ),
    # Item 11: a wheel radius of 1e-300 m (or one tenth of it) passed the profile check;
    # simulate then failed naming <memory>, not the profile.
    *(
        C(
            f"profile-wheel-radius-{case_id}",
            f"{command} --robot bad.toml",
            2,
            rf"bad\.toml: body\.wheel_radius: {re.escape(radius)} m is less than 0\.05 x the "
            r"half track",
            r"\A(?![\s\S]*<memory>)",
            files={
                **GOOD,
                "bad.toml": profile(replace("wheel_radius = 0.098", f"wheel_radius = {radius}")),
            },
            absent=("sim/*", "p.nc"),
            timeout=FAST,
        )
        for case_id, command, radius in [
            ("1e-300-residuals", "residuals a.nc", "1e-300"),
            ("1e-300-grid", f"grid a.nc {GRID}", "1e-300"),
            ("1e-300-simulate", "simulate --out sim --v1 1 --v2 0", "1e-300"),
            ("1e-300-sample", f"sample a.nc --out p.nc {SAMPLE}", "1e-300"),
            ("tenth-residuals", "residuals a.nc", "0.0098"),
            ("5mm-simulate", "simulate --out sim --v1 1 --v2 0", "0.005"),
        ]
    ),
    # Item 12: exit 1 with a bare exception for a prior nested 200,000 deep and for
    # covariates in a run's provenance that are not a mapping of numbers.
    # An experiment file's JSON attributes nested as deep: RecursionError, exit 1.
    *[
        C(
            f"residuals-{key}-nested-deep",
            "residuals dp.nc",
            2,
            r"dp\.nc",
            key,
            r"expected a JSON",
            files={
                "dp.nc": nc_edit(
                    lambda ds, key=key: ds.assign_attrs({key: "[" * DEEP + "]" * DEEP})
                )
            },
            timeout=FAST,
        )
        for key in ("provenance", "truth", "segments")
    ],
    C(
        "filter-prior-objects-nested-deep",
        "filter a.nc --prior deep.json --out est.csv",
        2,
        r"deep\.json",
        r"nests deeper than Python parses",
        files={**GOOD, "deep.json": json_text('{"a": ' * DEEP + "1" + "}" * DEEP)},
        absent=("est.csv",),
        timeout=FAST,
    ),
    C(
        "filter-prior-field-nested-deep",
        "filter a.nc --prior deep.json --out est.csv",
        2,
        r"deep\.json",
        r"nests deeper than Python parses",
        files={
            **GOOD,
            "deep.json": prior_text(
                lambda text: text.rstrip()[:-1] + ', "notes": ' + "[" * DEEP + "]" * DEEP + "}"
            ),
        },
        absent=("est.csv",),
        timeout=FAST,
    ),
    *(
        _population(
            f"population-provenance-covariates-{case_id}",
            {"a.nc": provenance(group="A", covariates=covariates), "b.nc": provenance(group="B")},
            rf"a\.nc: provenance\.covariates{field}: ",
            words,
            absent=("pop/population.json", "pop/units/*"),
            timeout=FAST,
        )
        for case_id, covariates, field, words in [
            ("a-list", [0.3], "", r"must map covariate names to numbers, got \[0\.3\]"),
            ("a-text", "speed=0.3", "", r"must map covariate names to numbers, got 'speed=0\.3'"),
            ("speed-text", {"speed": "fast"}, r"\.speed", r"must be a finite number, got 'fast'"),
            ("speed-null", {"speed": None}, r"\.speed", r"must be a finite number, got None"),
            ("speed-a-list", {"speed": [0.3]}, r"\.speed", r"must be a finite number"),
        ]
    ),
    # Item 13: messages that misled: a MATLAB text field "not in the file", a text
    # covariate "a run has no ...", a NaN draw named without its file.
    C(
        "noise-mat-text-field",
        f"noise x.mat --column gyro {NOISE}",
        2,
        r"x\.mat: gyro: variable 'gyro' holds text \(char\), not numbers",
        files={"x.mat": mat(lambda c: {"t": c["t"], "gyro": "not numbers"})},
        timeout=FAST,
    ),
    C(
        "noise-mat-text-field-beside-numbers",
        f"noise x.mat --column note {NOISE}",
        2,
        r"x\.mat: note: variable 'note' holds text \(char\), not numbers",
        files={"x.mat": mat(lambda c: {"t": c["t"], "gyro": c["yaw_rate"], "note": "bench"})},
        timeout=FAST,
    ),
    _population(
        "population-covariate-is-a-text-column",
        {**GOOD2, "g.csv": groups("run,group,surface,speed\na,A,grass,0.3\nb,B,tiles,0.5\n")},
        r"g\.csv: surface: the column 'surface' holds text, not numbers",
        options=" --covariate surface",
        absent=("pop/population.json", "pop/units/*"),
        timeout=FAST,
    ),
    _population(
        "population-covariate-is-the-group-column-text",
        {**GOOD2, "g.csv": groups("run,group,site\na,A,lab\nb,B,field\n")},
        r"g\.csv: site: the column 'site' holds text",
        options=" --covariate site",
        absent=("pop/population.json", "pop/units/*"),
        timeout=FAST,
    ),
    *(
        C(
            f"{command.split()[0]}-posterior-{case_id}",
            command,
            2,
            rf"post\.nc: posterior\.{variable}: the draw at chain {chain}, draw {draw} is {value}",
            files={"post.nc": posterior_cell(variable, (chain, draw), float(value))},
            absent=("prior.json", "r.html", "r_figures"),
            timeout=FAST,
        )
        for command in ("export-prior post.nc --out prior.json", "report post.nc --out r.html")
        for case_id, variable, chain, draw, value in [
            ("nan-draw", "d_long", 1, 5, "nan"),
            ("inf-draw", "sigma_h", 3, 7, "inf"),
        ]
    ),
    # Item 15: the one-step minimum read as the damping's estimate.
    C(
        "grid-says-the-minimum-is-not-the-estimate",
        f"grid a.nc {GRID} --json",
        0,
        CAVEAT,
        r"9-1-2",
        r"the posterior \(bayes-jackal sample\) is the estimate",
        files=GOOD,
    ),
    C(
        "grid-csv-minimum-on-the-high-edge-and-the-caveat",
        "grid a.csv --d-lat 10 30 10 --d-long 20 100 10 --json",
        0,
        CAVEAT,
        r"lies on the high edge of the d_lat grid",
        files=GOOD_CSV,
    ),
    C(
        "analyse-says-the-minimum-on-the-edge-is-not-the-estimate",
        f"analyse a.nc --out out {ANALYSE} --json",
        0,
        r"on the grid's edge: d_long low\); " + CAVEAT,
        files=GOOD,
    ),
    # Item 19: the console's jargon: a literal <family>.nc, +- 0.00, ess_tau, PSIS.
    C(
        "compare-out-names-the-files-it-wrote",
        f"compare a.nc --out cmp {COMPARE} --json",
        0,
        r"wrote a\.white\.nc and a\.compare\.json in cmp/",
        r"\A(?![\s\S]*<family>)",
        files=GOOD,
        exists=("cmp/a.white.nc",),
    ),
    C(
        "compare-two-runs-out-names-the-files-it-wrote",
        f"compare a.nc b.nc --out cmp {COMPARE}",
        0,
        files=GOOD2,
        stdout_lacks=("<family>",),
        exists=("cmp/a.white.nc", "cmp/b.white.nc"),
    ),
    C(
        "noise-evidence-error-to-two-digits",
        f"noise x.csv --column gyro {NOISE} --json",
        0,
        r"(?m)^white +-?[\d.]+ +0\.0*[1-9]\d",
        files={"x.csv": series()},
    ),
    C(
        "noise-two-series-evidence-error-to-two-digits",
        f"noise a.csv b.csv --column gyro --out out {NOISE} --json",
        0,
        r"(?m)^white +-?[\d.]+ +0\.0*[1-9]\d",
        r"\A(?![\s\S]*(\+- 0\.00\b| 0\.00 +0\.00))",
        files={"a.csv": series(), "b.csv": series(lambda t, x: (t, x[::-1].copy()))},
        json_files=("out/a.noise.json", "out/b.noise.json"),
    ),
    C(
        "sample-table-says-ess",
        f"sample a.nc --out p.nc {SAMPLE}",
        0,
        files=GOOD,
        stdout_lacks=("ess_tau",),
        exists=("p.nc",),
    ),
    C(
        "sample-json-convergence-line-in-words",
        f"sample a.nc --out p.nc {SAMPLE} --json",
        0,
        r"ess: effective draws, r_hat: the walkers' agreement",
        files=GOOD,
        exists=("p.nc",),
    ),
    C(
        "filter-says-why-the-first-samples-are-not-scored",
        "filter a.nc --prior prior.json --out est.csv --json",
        0,
        r"prediction errors scored from sample \d+ on \(the first start the filters\)",
        files=PRIOR,
        exists=("est.csv",),
    ),
    # Item 20: one speed per group: a slope and the groups' difference are one model.
    _population(
        "population-one-speed-per-group-confounded",
        {**GOOD2, "g.csv": groups("run,group,speed\na,slow,0.3\nb,fast,0.6\n")},
        r"a dependence on speed and a difference between the groups are one model here",
        r"cannot tell apart",
        options=" --json",
        exit=0,
        json_files=("pop/population.json",),
    ),
    _population(
        "population-provenance-one-speed-per-group-confounded",
        {
            "a.nc": provenance(group="slow", covariates={"speed": 0.3}),
            "b.nc": provenance(group="fast", covariates={"speed": 0.6}),
        },
        r"a dependence on speed and a difference between the groups are one model here",
        r"neither depends on speed nor differs between the groups",
        options=" --json",
        exit=0,
        json_files=("pop/population.json",),
    ),
    _population(
        "population-one-speed-per-group-of-two-runs-confounded",
        {
            **GOOD2,
            "c.nc": experiment(),
            "g.csv": groups("run,group,speed\na,slow,0.3\nb,slow,0.3\nc,fast,0.6\n"),
        },
        r"one model here",
        options=" --json",
        exit=0,
        json_files=("pop/population.json",),
    ),
]


CASES: list[Case] = [
    *_bad_experiment_cases(),
    *_accepted_cases(),
    *OUTPUT_CASES,
    *INGEST_CASES,
    *EXPORT_CASES,
    *REPORT_CASES,
    *ONE_BAD_CASES,
    *FLAG_CASES,
    *PROFILE_CASES,
    *GARBAGE_CASES,
    *SPECIAL_CASES,
    *FILTER_CASES,
    *NOISE_CASES,
    *PROFILE_MORE_CASES,
    *FILE_CASES,
    *SHARED_CASES,
    *ISSUE37_CASES,
]


def words_missing(case: Case, stderr: str, words=None) -> list[str]:
    return [w for w in (case.words if words is None else words) if not re.search(w, stderr, re.I)]
