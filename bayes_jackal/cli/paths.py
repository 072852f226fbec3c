"""Each command's planned outputs and its inputs, from its arguments; checked before any work.

:func:`guarded` runs a command under the guarantees of
:mod:`bayes_jackal._runtime.output_safety`: outputs checked and their folders created before
any work, the inputs never replaced, and the command's main output (the
first one listed here) locked for the whole run.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from .._runtime import (
    Output,
    OutputLock,
    chain_path,
    check_outputs,
    each_input,
    protected,
    refuse,
    removed_if_empty,
    require_file,
)

if TYPE_CHECKING:  # this module stays light: outputs are checked before numpy loads
    from ..io import Experiment

#: Figure suffixes of ``grid --plot`` (matplotlib's formats the README names).
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def planned_outputs(args: argparse.Namespace) -> list[Output]:
    """What the command writes under the names the user gave; the main output first."""
    command, out = args.command, getattr(args, "out", None)
    if command == "population":  # its units' folder and files, checked before a unit runs
        folder = Path(out)
        inside = [Output(folder / name) for name in ("population.json", "population.png")]
        return [Output(folder, "folder"), Output(folder / "units", "folder"), *inside]
    if command in ("simulate", "ingest", "analyse", "demo") or (
        command in ("compare", "noise") and out
    ):
        return [Output(Path(out), "folder")]
    if command == "sample":
        path = Path(out)
        return [Output(path, suffixes=(".nc",)), Output(chain_path(path))]
    if command == "grid":
        files = [(args.out, (".nc",), "--out"), (args.plot, PLOT_SUFFIXES, "--plot")]
        return [Output(Path(p), "file", suffixes, flag) for p, suffixes, flag in files if p]
    if command == "export-prior":
        return [Output(Path(out), suffixes=(".json",))]
    if command == "filter":
        return [Output(Path(out), suffixes=(".csv",))]
    if command == "report":
        path = Path(out)
        return [
            Output(path, suffixes=(".html", ".htm")),
            Output(path.parent / f"{path.stem}_figures", "folder", create=False),
        ]
    return []  # residuals writes nothing


def command_inputs(args: argparse.Namespace) -> list[str]:
    """The files and folders the command reads: never to be replaced by an output."""
    robot = getattr(args, "robot", None)  # last: failures name the data first
    return [*_data_inputs(args), *([robot] if robot else [])]


def _data_inputs(args: argparse.Namespace) -> list[str]:
    """The logs, experiments, posteriors and tables the command reads (not the robot)."""
    inputs = [
        getattr(args, "posterior", None),
        getattr(args, "prior_file", None),
        getattr(args, "groups", None),
    ]
    for name in ("experiments", "posteriors", "bags", "inputs", "series"):
        inputs += getattr(args, name, None) or []
    return [given for given in inputs if given]


def refuse_absent_inputs(args: argparse.Namespace) -> None:
    """Refuse (DataError) a command none of whose data inputs can be read, before the imports.

    Each input is checked as its reader will first check it
    (:func:`~bayes_jackal._runtime.files.require_file`: no such file, a
    named pipe, a loop of links), with the reader's message: a mistyped
    path is told in a blink, not after the seconds numpy, scipy and the
    sampler take to load. Where some inputs pass, the command runs and
    names the others as it meets them (one bad file among many does not
    stop the others).
    """
    inputs = _data_inputs(args)
    _, failed = each_input(inputs, lambda given: require_file(given, given, folder=True))
    if inputs and len(failed) == len(inputs):
        refuse(failed, len(inputs))


def check_named_outputs(args: argparse.Namespace, paths: Iterable[Path]) -> None:
    """Check outputs named after the data (an experiment's name) like the planned ones.

    ``sample --out p.nc`` on several experiments writes ``p.<name>.nc``, and
    ``compare --out DIR`` writes ``DIR/<name>.<family>.nc``: known only once
    the inputs are read, and checked then, before the work they belong to.
    """
    check_outputs([Output(Path(path)) for path in paths], inputs=command_inputs(args))


def group_name(group: list[Experiment]) -> str:
    """What ``compare`` calls a group of experiments: its one experiment's name, or ``pooled``."""
    return "pooled" if len(group) > 1 else group[0].name


def family_files(folder: Path, name: str, families: Iterable[str]) -> dict[str, Path]:
    """Where ``compare --out`` keeps each family's posterior (and finds it on a rerun)."""
    return {family: folder / f"{name}.{family}.nc" for family in families}


def summary_file(folder: Path, name: str) -> Path:
    """Where ``compare --out`` writes the comparison of ``name``."""
    return folder / f"{name}.compare.json"


@contextlib.contextmanager
def guarded(args: argparse.Namespace) -> Iterator[None]:
    """Check the outputs, protect the inputs and lock the main output while the command runs.

    A folder the checks make for an output and the command leaves empty (it
    failed, or was refused, before writing) is removed.
    """
    outputs, inputs = planned_outputs(args), command_inputs(args)
    folders = [o.path if o.kind == "folder" else o.path.parent for o in outputs]
    with contextlib.ExitStack() as stack:
        stack.enter_context(removed_if_empty(folders))
        check_outputs(outputs, inputs=inputs)
        if outputs:
            main = outputs[0]
            stack.enter_context(OutputLock(main.path, folder=main.kind == "folder"))
        stack.enter_context(protected(inputs))
        refuse_absent_inputs(args)
        yield
