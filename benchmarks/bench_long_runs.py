"""Benchmark: whole commands on long runs, time and peak memory (issue 12 targets).

Run by hand: ``python benchmarks/bench_long_runs.py [--cases ratio,hour,compare,khz]
[--seeds 1 2 3] [--workdir DIR]``.

Every case runs the real console script in a fresh process with default
flags (all three channels, Gaussian family, the ``fast`` engine), on runs
simulated here with known truth (d_lat 110, d_long 30 N s/m, Gaussian
process noise of sigma_h 0.047 s; ``simulate_experiment`` with a
``Series(0.3 m/s, 22.5 deg/s, duration)``), and prints its wall time, the
peak resident memory of its largest process, the chain's steps and whether
it converged:

- ``ratio``: ``sample`` on the thesis-like 38 s run (the baseline) and on a
  300 s run at 72 Hz, for each seed; the median ratio (target <= 1.5);
- ``hour``: ``sample`` on one hour at 72 Hz (259,200 samples): target under
  5 minutes and 2 GB, converged, the truth inside every 94 % HDI;
- ``compare``: ``compare`` of the five families on the 300 s run, one
  process per core: target under 3 minutes and 2 GB per process, converged;
- ``khz``: ``sample --family white --rate 1000`` on 16 s at 1 kHz
  (16,001 samples): target under 30 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import statistics
from pathlib import Path

import numpy as np
from timing import timed_console, work_folder

from bayes_jackal import load_profile
from bayes_jackal._runtime.files import chain_path
from bayes_jackal.io.experiment import write_netcdf
from bayes_jackal.io.simulate import Series, simulate_experiment
from bayes_jackal.posterior import Posterior
from bayes_jackal.posterior.posterior import load_posterior

ROBOT = load_profile()
TRUTH = {"d_lat": 110.0, "d_long": 30.0, "sigma_h": 0.047}
TRUTH_SD = {"sigma_c": (0.005, 0.005, 0.01), "sigma_n": (0.003, 0.003, 0.005)}


def make_run(folder: Path, seconds: float, rate: float = 72.0) -> Path:
    """A simulated run of ``seconds`` at ``rate`` Hz, written as NetCDF."""
    path = folder / f"run{seconds:g}s_{rate:g}hz.nc"
    if not path.exists():
        robot = dataclasses.replace(ROBOT, rate=rate)
        series = Series(0.3, float(np.deg2rad(22.5)), seconds)
        write_netcdf(simulate_experiment(robot, 110.0, 30.0, series, rng=1), path)
    return path


def run(arguments: list[str]) -> dict:
    """One command in a fresh process: its JSON output, time and CPU [s], peak RSS [MB]."""
    result = timed_console(Path(__file__).resolve().parents[1], arguments)
    return {**result, "summary": result.pop("output")}


def sample(path: Path, folder: Path, seed: int, *extra: str) -> dict:
    """``sample`` of one run with a seed (and extra flags) to a posterior in ``folder``.

    Adds the chain's largest integrated autocorrelation time [steps].
    """
    out = folder / f"{path.stem}.seed{seed}.nc"
    for old in (out, chain_path(out)):  # a stored chain would resume, not sample
        old.unlink(missing_ok=True)
    result = run(
        ["sample", str(path), "--out", str(out), "--seed", str(seed), "--no-progress", *extra]
    )
    tau = Posterior.of(load_posterior(out)).metadata.convergence.autocorr_time
    return result | {"tau": max(tau.values())}


def describe(label: str, result: dict) -> str:
    summary = result["summary"]
    tau = f" tau {result['tau']:.0f}" if "tau" in result else ""
    return (
        f"{label:<34s} {result['seconds']:7.1f} s {result['peak_mb']:7.0f} MB "
        f"{summary.get('n_steps', '-'):>6} steps{tau} converged={summary.get('converged')}"
    )


def truth_inside(summary: dict) -> list[str]:
    """Parameters whose 94 % HDI misses the simulated truth."""
    misses = []
    for name, row in summary.items():
        if not isinstance(row, dict) or "hdi_3%" not in row:
            continue
        base, _, channel = name.partition("[")
        channel = channel.rstrip("]")
        if base in TRUTH:
            truth = TRUTH[base]
        elif base in TRUTH_SD:
            truth = TRUTH_SD[base][("vx", "vy", "yaw").index(channel)]
        else:
            continue
        if not row["hdi_3%"] <= truth <= row["hdi_97%"]:
            misses.append(f"{name}: {truth} outside [{row['hdi_3%']:.5g}, {row['hdi_97%']:.5g}]")
    return misses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="ratio,hour,compare,khz")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--workdir", type=Path, default=None)
    args = parser.parse_args()
    cases = args.cases.split(",")
    folder = work_folder(args.workdir, "bench_long_")
    print(f"{'case':<34s} {'time':>9s} {'peak RSS':>10s}   (files in {folder})")
    if "ratio" in cases:
        ratios = []
        for seed in args.seeds:
            short = sample(make_run(folder, 38.0), folder, seed)
            long = sample(make_run(folder, 300.0), folder, seed)
            print(describe(f"sample 38 s, seed {seed}", short))
            print(describe(f"sample 300 s, seed {seed}", long))
            ratios.append(long["seconds"] / short["seconds"])
        print(
            f"300 s / 38 s: {', '.join(f'{r:.2f}' for r in ratios)}; median "
            f"{statistics.median(ratios):.2f} (target <= 1.5)"
        )
    if "hour" in cases:
        hour = sample(make_run(folder, 3600.0), folder, args.seeds[0])
        print(describe("sample 1 hour (259,200 samples)", hour))
        misses = truth_inside(hour["summary"])
        print("truth inside every 94 % HDI" if not misses else "; ".join(misses))
    if "compare" in cases:
        path = make_run(folder, 300.0)
        out = folder / "compare300"
        shutil.rmtree(out, ignore_errors=True)  # finished families would be reused
        result = run(
            [
                "compare",
                str(path),
                "--out",
                str(out),
                "--seed",
                str(args.seeds[0]),
                "--no-progress",
            ]
        )
        print(
            f"{'compare 5 families, 300 s':<34s} {result['seconds']:7.1f} s "
            f"{result['peak_mb']:7.0f} MB (largest process)"
        )
        for posterior in sorted(out.glob("*.nc")):
            convergence = Posterior.of(load_posterior(posterior)).metadata.convergence
            tau = max(convergence.autocorr_time.values())
            print(
                f"  {posterior.stem.split('.')[-1]:<14s} {convergence.n_steps:>6} steps "
                f"tau {tau:.0f} converged={convergence.converged}"
            )
    if "khz" in cases:
        path = make_run(folder, 16.0, rate=1000.0)
        result = sample(path, folder, args.seeds[0], "--family", "white", "--rate", "1000")
        print(describe("sample white, 16 s at 1 kHz", result))


if __name__ == "__main__":
    main()
