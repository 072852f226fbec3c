"""Benchmark: how soon ``bayes-jackal`` refuses what it cannot do (issue 39).

Run by hand: ``python benchmarks/bench_refusals.py [--repeats 7]``.

Issue 39 asks that a refusal (a busy ``--out``, a bad flag, a missing file)
take under 0.5 s of wall time on a quiet machine. Each case runs the
console script (``python -m bayes_jackal.cli``, this checkout's package) in
a fresh process, ``--repeats`` times; the median wall time, the CPU time and
the peak resident memory are printed with the ratio to the baseline measured
in the same run: the imports a refusal would wait for if it came after them
(``import bayes_jackal.cli.commands``: numpy, scipy, arviz, the sampler).
``--version`` is the floor, an interpreter's start-up and the package's
name. Each refusal must also exit 2 (bad input).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bayes_jackal._runtime import OutputLock

ROOT = Path(__file__).resolve().parents[1]
#: The budget of a refusal [s] (issue 39).
BUDGET = 0.5


def timed(command: list[str]) -> tuple[int, float, float, float]:
    """``command`` in a fresh process: exit code, wall [s], CPU [s], peak RSS [MB]."""
    start = time.perf_counter()
    process = subprocess.Popen(
        command,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    cpu = usage.ru_utime + usage.ru_stime
    return os.waitstatus_to_exitcode(status), seconds, cpu, usage.ru_maxrss / 1024


def median_of(command: list[str], repeats: int, expected: int) -> dict:
    """The median wall and CPU time and the largest peak memory of ``repeats`` runs."""
    runs = [timed(command) for _ in range(repeats)]
    codes = {code for code, *_ in runs}
    if codes != {expected}:
        raise RuntimeError(f"{' '.join(command)} exited {sorted(codes)}, not {expected}")
    return {
        "seconds": statistics.median(run[1] for run in runs),
        "cpu": statistics.median(run[2] for run in runs),
        "peak_mb": max(run[3] for run in runs),
    }


def cases(folder: Path) -> dict[str, tuple[list[str], bool, int]]:
    """Each case: its command, whether ``--out`` is held meanwhile, its expected exit code."""
    run = folder / "run.nc"
    run.write_bytes(b"")  # never read: the refusals come first
    console = [sys.executable, "-m", "bayes_jackal.cli"]
    return {
        "imports (baseline)": (
            [sys.executable, "-c", "import bayes_jackal.cli.commands"],
            False,
            0,
        ),
        "--version (floor)": ([*console, "--version"], False, 0),
        "bad flag": ([*console, "sample", str(run), "--no-such-flag"], False, 2),
        "missing file": (
            [*console, "sample", str(folder / "absent.bag"), "--out", str(folder / "p.nc")],
            False,
            2,
        ),
        "busy --out": ([*console, "sample", str(run), "--out", str(folder / BUSY)], True, 2),
    }


#: The output another run holds in the busy case (its lock taken here, as a run's).
BUSY = "busy.nc"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    repeats = parser.parse_args().repeats
    print(f"load average at start: {os.getloadavg()[0]:.2f}; {repeats} runs each, median")
    with tempfile.TemporaryDirectory() as folder:
        measured = {}
        for label, (command, held, expected) in cases(Path(folder)).items():
            if held:
                with OutputLock(Path(folder) / BUSY):
                    measured[label] = median_of(command, repeats, expected)
            else:
                measured[label] = median_of(command, repeats, expected)
    baseline = measured["imports (baseline)"]["seconds"]
    for label, result in measured.items():
        verdict = (
            "" if label.endswith(")") else ("  ok" if result["seconds"] < BUDGET else "  SLOW")
        )
        print(
            f"{label:<20s} {result['seconds']:6.3f} s wall {result['cpu']:6.3f} s CPU "
            f"{result['peak_mb']:5.0f} MB  {result['seconds'] / baseline:5.2f}x the imports"
            f"{verdict}"
        )
    print(f"budget {BUDGET} s; load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
