"""Benchmark: the whole job against its essential chain (issue 39).

Run by hand: ``python benchmarks/bench_job.py [--workdir DIR]``.

Issue 39 asks that the demo and a two-run ``analyse`` take at most twice
the wall time of ``sample`` of the best family on the same runs, that the
report take at most 10 % of the demo, and that no family's chain be more
than 1.5x the best family's. Measured back to back, each in a fresh
process, on the demo's two shipped bags:

- the baseline: ``sample --pooled --family gaussian`` of the two bags
  (seed 2026, the demo's);
- ``demo``: its phases timed from the lines it writes as each starts
  (ingest, families, state estimation, report; the grids run beside the
  families' chains and the report's figures beside the state estimation,
  so neither is a phase of its own);
- ``analyse`` of the same two bags (seed 2026, default flags).

Each line gives the wall and CPU time (the command's and its workers') and
the peak resident memory of the largest process; then the ratios to the
baseline, each phase's share, and each family's chain length against the
best family's.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from timing import describe_sample, timed_console, work_folder

import bayes_jackal as bj
from bayes_jackal.workflow import demo_folder
from bayes_jackal.workflow.demo import DEMO_SEED

ROOT = Path(__file__).resolve().parents[1]
#: The line each phase starts with (the demo's and analyse's messages, stderr).
PHASES = {
    "posterior and evidence of": "families",
    "state estimation with": "state estimation",
    "writing the report": "report",
}


def timed_job(arguments: list[str], folder: Path) -> dict:
    """``bayes-jackal <arguments> --json`` in a fresh process: wall, CPU, peak memory, phases.

    The package is this checkout's (``PYTHONPATH``), as the baseline's. The
    last phase, the report, also holds the residual table written after it.
    """
    start = time.perf_counter()
    command = [sys.executable, "-m", "bayes_jackal.cli", *arguments, "--json", "--no-progress"]
    process = subprocess.Popen(
        command,
        cwd=folder,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    starts = {"ingest": 0.0}
    for line in process.stderr:
        for text, phase in PHASES.items():
            if line.lstrip().startswith(text) and phase not in starts:
                starts[phase] = time.perf_counter() - start
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    seconds = time.perf_counter() - start
    if process.returncode != 0:
        raise RuntimeError(f"{' '.join(arguments)} exited {process.returncode}")
    missing = [phase for phase in PHASES.values() if phase not in starts]
    if missing:  # a message reworded: its time would join the phase before
        raise RuntimeError(f"{' '.join(arguments)}: no line began the phases {missing}")
    usages = [usage]
    while True:  # the worker processes it left, adopted by this one: their CPU counts too
        try:
            usages.append(os.wait4(-1, 0)[2])
        except ChildProcessError:
            break
    cpu = sum(u.ru_utime + u.ru_stime for u in usages)
    ends = [*list(starts.values())[1:], seconds]  # a phase ends where the next starts
    phases = {name: end - begun for (name, begun), end in zip(starts.items(), ends, strict=True)}
    peak = max(u.ru_maxrss for u in usages) / 1024  # of the largest process [MB]
    return {"seconds": seconds, "cpu": cpu, "peak_mb": peak, "phases": phases}


def chain_steps(folder: Path) -> dict[str, int]:
    """Each family's chain length [steps], from the posteriors the job saved."""
    return {
        path.stem: int(bj.load_posterior(path).posterior.attrs["n_steps"])
        for path in sorted((folder / "posteriors").glob("*.nc"))
    }


def describe_job(label: str, job: dict, baseline: dict, steps: dict[str, int], best: str) -> None:
    print(
        f"{label:<10s} {job['seconds']:6.1f} s wall {job['cpu']:6.1f} s CPU "
        f"{job['peak_mb']:6.0f} MB  {job['seconds'] / baseline['seconds']:.2f}x the baseline "
        "(target <= 2)"
    )
    for phase, seconds in job["phases"].items():
        print(f"  {phase:<18s} {seconds:6.1f} s  {seconds / job['seconds']:5.1%}")
    ratios = ", ".join(f"{f} {n} ({n / steps[best]:.1f}x)" for f, n in steps.items())
    print(f"  chains: {ratios} (target <= 1.5x the best family's {steps[best]})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--workdir", type=Path, help="where the outputs go (default: a temp folder)"
    )
    args = parser.parse_args()
    folder = work_folder(args.workdir, "bench_job_")
    if ctypes.CDLL(None).prctl(36, 1, 0, 0, 0) != 0:  # PR_SET_CHILD_SUBREAPER (Linux)
        raise OSError("cannot become a child subreaper: the workers' CPU would not count")
    bags = [demo_folder() / "v1_01.bag", demo_folder() / "v2_01.bag"]
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"the demo's two bags; seed {DEMO_SEED}; load average {load}; outputs in {folder}")
    seed = ["--seed", str(DEMO_SEED)]
    sample = [
        "sample",
        *map(str, bags),
        "--out",
        str(folder / "sample.nc"),
        *seed,
        "--no-progress",
    ]
    baseline = timed_console(ROOT, [*sample, "--pooled", "--family", "gaussian"])
    baseline["summary"] = baseline.pop("output")
    print(describe_sample("baseline", baseline), "(sample --pooled --family gaussian)")
    demo = timed_job(["demo", "--out", str(folder / "demo")], folder)
    best = json.loads((folder / "demo" / "compare.json").read_text())["best"]
    describe_job("demo", demo, baseline, chain_steps(folder / "demo"), best)
    analyse = timed_job(
        ["analyse", *map(str, bags), "--out", str(folder / "analyse"), *seed], folder
    )
    best = json.loads((folder / "analyse" / "compare.json").read_text())["best"]
    describe_job("analyse", analyse, baseline, chain_steps(folder / "analyse"), best)


if __name__ == "__main__":
    main()
