"""Benchmark: ``sample`` on the thesis-like 38 s run against a baseline commit (issue 25).

Run by hand: ``python benchmarks/bench_sample.py [--baseline REF] [--repeats 3]
[--workdir DIR]``.

The run is ``bench_long_runs.make_run``'s 38 s at 72 Hz (truth d_lat 110,
d_long 30 N s/m, Gaussian process noise of sigma_h 0.047 s). The command is
``sample`` with default flags (yaw, vx and vy; Gaussian family; the ``fast``
engine) and one seed, in a fresh process each time: once with this checkout,
once with the package at ``REF`` (default ``a59609c``, the last commit before
issue 25's changes) checked out into a temporary git worktree and run by the
same interpreter. The two alternate, ``--repeats`` times each, so that both
see the same machine. It prints, per run, the wall time, the process' CPU
time, the peak resident memory, the chain's steps and whether it converged;
then the median ratios baseline / this of wall and CPU time (issue 25's
target: at least 4, and this under 10 s), and each parameter's posterior mean and 94 % HDI under
both, with the difference of the means in Monte Carlo standard errors
(sd / sqrt(ess_bulk) of each, combined).
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

from bench_long_runs import make_run
from timing import baseline_worktree, describe_sample, timed_sample, work_folder


def compare_posteriors(baseline: dict, current: dict) -> None:
    """Mean and 94 % HDI of each parameter under both, and the means' difference in MCSE."""
    print(f"{'parameter':<14s} {'baseline mean [HDI]':>34s} {'this mean [HDI]':>34s}  z")
    worst = 0.0
    for name, old in baseline.items():
        new = current.get(name)
        if not isinstance(old, dict) or not isinstance(new, dict) or "ess_bulk" not in old:
            continue
        error = (old["sd"] ** 2 / old["ess_bulk"] + new["sd"] ** 2 / new["ess_bulk"]) ** 0.5
        z = (new["mean"] - old["mean"]) / error
        worst = max(worst, abs(z))
        cells = [
            f"{row['mean']:.4g} [{row['hdi_3%']:.4g}, {row['hdi_97%']:.4g}]" for row in (old, new)
        ]
        print(f"{name:<14s} {cells[0]:>34s} {cells[1]:>34s} {z:5.1f}")
    print(f"largest |z|: {worst:.1f} (Monte Carlo error alone: ~N(0, 1) per parameter)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default="a59609c", help="git ref of the baseline")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workdir", type=Path, default=None)
    args = parser.parse_args()
    folder = work_folder(args.workdir, "bench_sample_")
    here = Path(__file__).resolve().parents[1]
    base = baseline_worktree(folder, args.baseline)
    path = make_run(folder, 38.0)
    print(f"sample of {path.name} (files in {folder}); baseline {args.baseline}")
    results: dict[str, list[dict]] = {"baseline": [], "this": []}
    for _ in range(args.repeats):
        for label, source in (("baseline", base), ("this", here)):
            result = timed_sample(source, [path], folder / f"{label}-posterior.nc")
            results[label].append(result)
            print(describe_sample(label, result))
    ratio = statistics.median(
        old["seconds"] / new["seconds"]
        for old, new in zip(results["baseline"], results["this"], strict=True)
    )
    cpu = statistics.median(
        old["cpu"] / new["cpu"]
        for old, new in zip(results["baseline"], results["this"], strict=True)
    )
    this = statistics.median(result["seconds"] for result in results["this"])
    print(
        f"median baseline / this: {ratio:.2f} wall, {cpu:.2f} CPU (target >= 4); "
        f"this: {this:.1f} s (target < 10)"
    )
    compare_posteriors(results["baseline"][0]["summary"], results["this"][0]["summary"])


if __name__ == "__main__":
    main()
