"""Benchmark: each noise family's ``sample`` time against the median family's (issue 25).

Run by hand: ``python benchmarks/bench_family_balance.py [--cases long,husky]
[--baseline REF | --no-baseline] [--workdir DIR]``.

Issue 25 asks that no family take more than 3 times the median family's time
on any input, widths at a prior bound included. Each family's ``sample``
(default flags, seed 1, one process) runs in a fresh process on:

- ``long``: the 300 s run at 72 Hz of ``bench_long_runs.make_run`` (yaw, vx,
  vy; Gaussian process noise of width 0.047 s);
- ``husky``: a Husky-like campaign, eight 48 s runs at 10 Hz pooled on the yaw
  channel, the whole record from rest (not steady), process noise 2.5 s
  wide: 2.5 times the kernel widths' 1 s prior bound, so every family's
  width piles at its bound and the damping against its floor.

It prints per family the wall and CPU time, peak memory, steps, and the
wall time over the median family's; then the same with the package at
``REF`` (default ``a59609c``, before issue 25) in a git worktree, run by the
same interpreter in the same run.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
from pathlib import Path

import numpy as np
from bench_long_runs import make_run
from timing import baseline_worktree, timed_sample, work_folder

import bayes_jackal as bj
from bayes_jackal.io.experiment import write_netcdf
from bayes_jackal.io.simulate import NoiseSettings, Series, simulate_experiment

FAMILIES = ("white", "exponential", "gaussian", "triangular", "moving-average")


def husky_runs(folder: Path) -> list[Path]:
    """Eight 48 s runs at 10 Hz, noise 2.5 s wide, as experiment files."""
    robot = dataclasses.replace(bj.load_profile(), rate=10.0)
    rng = np.random.default_rng(5)
    paths = []
    for index in range(8):
        run_ = simulate_experiment(
            robot, 110.0, 30.0, Series(0.4, 0.5, 48.0), NoiseSettings(width=2.5), rng=rng,
            name=f"husky{index}",
        )  # fmt: skip
        paths.append(write_netcdf(run_, folder / f"husky{index}.nc"))
    return paths


def families(source: Path, inputs: list[str], extra: list[str], out: Path) -> dict[str, dict]:
    """Each family's fresh ``sample`` of ``inputs``, timed."""
    results = {}
    for family in FAMILIES:
        results[family] = timed_sample(source, inputs, out / f"{family}.nc", *extra,
                                       "--family", family)  # fmt: skip
    return results


def report(label: str, results: dict[str, dict]) -> None:
    median = statistics.median(result["seconds"] for result in results.values())
    print(f"  {label} (median family {median:.1f} s):")
    for family, result in results.items():
        summary = result["summary"]
        ratio = result["seconds"] / median
        flag = "  > 3x the median" if ratio > 3 else ""
        print(
            f"    {family:<15s} {result['seconds']:6.1f} s wall {result['cpu']:6.1f} s CPU "
            f"{result['peak_mb']:5.0f} MB {summary['n_steps']:>6} steps "
            f"{ratio:4.1f}x median{flag}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="long,husky")
    parser.add_argument("--baseline", default="a59609c", help="git ref of the baseline")
    parser.add_argument("--no-baseline", action="store_true")
    parser.add_argument("--workdir", type=Path, default=None)
    args = parser.parse_args()
    folder = work_folder(args.workdir, "bench_families_")
    sources = {"this": Path(__file__).resolve().parents[1]}
    if not args.no_baseline:
        sources["baseline"] = baseline_worktree(folder, args.baseline)
    cases = {
        "long": ([str(make_run(folder, 300.0))], []),
        "husky": ([str(p) for p in husky_runs(folder)], ["--pooled", "--channels", "yaw"]),
    }
    for case in args.cases.split(","):
        inputs, extra = cases[case]
        print(f"{case}: {len(inputs)} file(s) {' '.join(extra)} (files in {folder})")
        for label, source in sources.items():
            out = folder / f"{case}-{label}"
            out.mkdir(exist_ok=True)
            report(label, families(source, inputs, extra, out))


if __name__ == "__main__":
    main()
