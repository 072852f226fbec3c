"""Timing a whole command in a fresh process, and the baseline it is compared with.

:func:`timed_console` runs ``bayes-jackal`` with the package of a given
checkout and returns its wall and CPU time, with its worker processes', the
peak memory of the largest process and its JSON output;
:func:`timed_sample` times a fresh ``sample`` with it and
:func:`describe_sample` prints one line of it; :func:`baseline_worktree`
checks another commit out beside this one. Used by the benchmarks of this
folder.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

#: The timer's program: runs the command given after the package's folder
#: (put on PYTHONPATH) and prints [exit code, wall s, CPU s, peak RSS MB,
#: stdout]. It then reaps every process the command left (the worker
#: processes' fork server outlives it by a moment; a child subreaper
#: inherits it), so that their CPU counts too.
_TIMER = """
import ctypes, json, os, resource, subprocess, sys, time
if ctypes.CDLL(None).prctl(36, 1, 0, 0, 0) != 0:  # PR_SET_CHILD_SUBREAPER (Linux)
    raise OSError("cannot become a child subreaper: the workers' CPU would not count")
start = time.perf_counter()
done = subprocess.run(
    sys.argv[2:], stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONPATH=sys.argv[1])
)
seconds = time.perf_counter() - start
while True:
    try:
        os.wait()
    except ChildProcessError:
        break
usage = resource.getrusage(resource.RUSAGE_CHILDREN)
cpu, peak = usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024
print(json.dumps([done.returncode, seconds, cpu, peak, done.stdout]))
"""
_CONSOLE = "from bayes_jackal.cli import console; console()"


def baseline_worktree(folder: Path, ref: str) -> Path:
    """The package at ``ref`` checked out into ``folder/baseline`` (kept for reruns)."""
    base = folder / "baseline"
    if not base.exists():
        here = Path(__file__).resolve().parents[1]
        subprocess.run(
            ["git", "-C", str(here), "worktree", "add", "--detach", str(base), ref],
            check=True,
            capture_output=True,
        )
    return base


def timed_console(source: Path, arguments: list[str]) -> dict:
    """``bayes-jackal <arguments> --json`` with the package in ``source``, timed.

    Returns the wall and CPU time [s] of the command and its workers, the
    peak RSS [MB] of the largest of them and the JSON document it printed.
    """
    command = [sys.executable, "-c", _TIMER, str(source), sys.executable, "-c", _CONSOLE]
    # In ``source``: ``python -c`` puts the working directory before PYTHONPATH,
    # so from another checkout's root the "baseline" would be that checkout.
    timed = subprocess.run(
        [*command, *arguments, "--json"], capture_output=True, text=True, check=True, cwd=source
    )
    code, seconds, cpu, peak, output = json.loads(timed.stdout)
    if code != 0:
        raise RuntimeError(f"{source}: {' '.join(arguments)} exited {code}")
    return {"seconds": seconds, "cpu": cpu, "peak_mb": peak, "output": json.loads(output)}


def timed_sample(source: Path, inputs: list, out: Path, *options: str) -> dict:
    """A fresh ``sample`` of the files ``inputs`` (seed 1) to ``out``, no chain resumed; timed.

    :func:`timed_console`'s result, its JSON document as ``summary``.
    """
    for stale in out.parent.glob(f"{out.stem}.*"):
        stale.unlink()
    files = [str(path) for path in inputs]
    arguments = ["sample", *files, "--out", str(out), "--seed", "1", "--no-progress", *options]
    result = timed_console(source, arguments)
    return {**result, "summary": result.pop("output")}


def describe_sample(label: str, result: dict, width: int = 10) -> str:
    """One line of a :func:`timed_sample`: times, peak memory, chain length, convergence."""
    summary = result["summary"]
    return (
        f"{label:<{width}s} {result['seconds']:6.1f} s wall {result['cpu']:6.1f} s CPU "
        f"{result['peak_mb']:6.0f} MB  {summary['n_steps']:>6} steps "
        f"converged={summary['converged']}"
    )


def work_folder(workdir: Path | None, prefix: str) -> Path:
    """``workdir`` (``--workdir``), created if need be, or a new temporary folder."""
    folder = (workdir or Path(tempfile.mkdtemp(prefix=prefix))).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    return folder
