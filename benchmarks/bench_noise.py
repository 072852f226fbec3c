"""Benchmark: ``noise`` of the 5 families on one series against a baseline commit (issue 25).

Run by hand: ``python benchmarks/bench_noise.py [--samples 10000] [--processes 2]
[--series coloured|white|wide] [--baseline REF] [--repeats 1] [--workdir DIR]
[--no-families]``.

The series (dt = 0.01 s, written to a CSV file):

- ``coloured`` (default): Gaussian-coloured noise of width 3 samples and
  unit sd over a white floor of sd 0.3;
- ``white``: unit white noise, on which every coloured family's width is
  unidentified: its posterior reaches the prior's lower bound (below half
  a sample the noise is white too) and, with sigma_c -> 0, every width up
  to the upper bound;
- ``wide``: Gaussian-coloured noise of width 200 samples over a floor of
  sd 0.1, past the width prior's upper bound (a tenth of the record):
  long memory, where the exact likelihood's spectral grids cannot
  certify a set and the time-domain fallback runs.

Issue 25's target is on ``coloured`` with 10,000 samples on 2 cores: the
whole ``noise`` command under 15 s, and no family more than 3 times the
median family's time (on every series).

The command is ``bayes-jackal noise SERIES.csv --column value --processes P
--seed 1 --no-progress --json`` in a fresh process, once with this
checkout and once with the package at ``REF`` (default ``a16c102``, the
last commit before this benchmark's changes) checked out into a temporary
git worktree and run by the same interpreter (as ``bench_sample.py``); the
two alternate, ``--repeats`` times each, so that both see the same
machine. It prints each run's wall time, CPU time and the peak resident
memory of its largest process, then the median ratios baseline / this.

Then each family alone (:func:`bayes_jackal.noise.fit_family`,
default settings, seed 1), one after the other in one fresh process per
checkout: its wall and CPU time, chain steps, likelihood evaluations (rows
of parameter sets), log evidence and posterior; the largest family's time
over the median family's; and each family's log evidence and posterior
means under both, their difference in Monte Carlo errors (the bridge
sampling errors; sd / sqrt(ESS) of each mean, ESS from the chain's tau),
combined.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np
from timing import baseline_worktree, timed_console, work_folder

from bayes_jackal.model.kernels import FAMILIES, get_family

DT = 0.01  # [s]
#: Each family alone, timed, its likelihood's rows counted; prints one JSON object.
_FAMILIES = """
import json, sys, time
import numpy as np
import bayes_jackal
from bayes_jackal import series_likelihood
from bayes_jackal.noise.characterisation import fit_family
from bayes_jackal.noise.series import NoiseSeries

rows = [0]
evaluate = series_likelihood.SeriesLikelihood.__call__

def counted(self, theta):
    rows[0] += len(np.atleast_2d(theta))
    return evaluate(self, theta)

series_likelihood.SeriesLikelihood.__call__ = counted
values = np.loadtxt(sys.argv[1], delimiter=",", skiprows=1, usecols=1)
series = NoiseSeries(values=values, dt=float(sys.argv[2]), name="series")
out = {}
for family in sys.argv[3:]:
    rows[0], wall, cpu = 0, time.perf_counter(), time.process_time()
    fit = fit_family(series, family, seed=1)
    d = fit.diagnostics
    out[family] = {
        "seconds": time.perf_counter() - wall, "cpu": time.process_time() - cpu,
        "steps": d["n_steps"], "converged": bool(d["converged"]), "rows": rows[0],
        "log_z": fit.evidence.log_evidence, "log_z_error": fit.evidence.error,
        "parameters": {
            name: {"mean": float(column.mean()), "sd": float(column.std()),
                   "ess": d["ess_autocorr"][name]}
            for name, column in zip(fit.names, fit.draws.T)
        },
    }
print(json.dumps({"package": bayes_jackal.__file__, "families": out}))
"""


def series(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """The benchmark's series (module docstring)."""
    if kind == "coloured":
        return get_family("gaussian").noise(0.03, DT, n, rng=rng) + 0.3 * rng.standard_normal(n)
    if kind == "white":
        return rng.standard_normal(n)
    if kind == "wide":
        return get_family("gaussian").noise(2.0, DT, n, rng=rng) + 0.1 * rng.standard_normal(n)
    raise ValueError(kind)


def write_series(path: Path, values: np.ndarray) -> Path:
    """The series as a CSV file of columns t [s] and value."""
    t = DT * np.arange(len(values))
    np.savetxt(path, np.column_stack([t, values]), delimiter=",", header="t,value", comments="")
    return path


def command(source: Path, path: Path, processes: int) -> dict:
    """``bayes-jackal noise`` of ``path`` with the package in ``source``, timed."""
    arguments = ["noise", str(path), "--column", "value", "--processes", str(processes),
                 "--seed", "1", "--no-progress"]  # fmt: skip
    result = timed_console(source, arguments)
    (summary,) = result.pop("output")["series"].values()
    return {**result, "summary": summary}


def families(source: Path, path: Path) -> dict:
    """Each family alone, one after the other, in a fresh process with ``source``'s package."""
    done = subprocess.run(
        [sys.executable, "-c", _FAMILIES, str(path), str(DT), *FAMILIES],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "PYTHONPATH": str(source)},
        cwd=path.parent,  # not a checkout (command's docstring)
    )
    result = json.loads(done.stdout.splitlines()[-1])
    if not Path(result["package"]).is_relative_to(source):
        raise RuntimeError(f"{result['package']} ran, not the package in {source}")
    return result["families"]


def family_table(label: str, fits: dict) -> None:
    """Each family's time, steps, rows and evidence; the largest time over the median's."""
    print(f"{label}: each family alone")
    for name, fit in fits.items():
        print(
            f"  {name:15s} {fit['seconds']:6.1f} s wall {fit['cpu']:6.1f} s CPU "
            f"{fit['steps']:5d} steps {fit['rows']:7d} rows converged {fit['converged']!s:5s} "
            f"log Z {fit['log_z']:.2f} +- {fit['log_z_error']:.3f}"
        )
    for unit in ("seconds", "cpu", "rows"):
        values = [fit[unit] for fit in fits.values()]
        print(f"  largest / median family ({unit}): {max(values) / statistics.median(values):.1f}")


def compare(baseline: dict, current: dict) -> None:
    """Log evidences and posterior means under both, their difference in Monte Carlo errors."""
    print(f"{'family':15s} {'parameter':10s} {'baseline':>12s} {'this':>12s}     z")
    worst = 0.0
    for name, old in baseline.items():
        new = current[name]
        error = np.hypot(old["log_z_error"], new["log_z_error"])
        z = (new["log_z"] - old["log_z"]) / error if error else 0.0
        rows = [("log Z", old["log_z"], new["log_z"], z)]
        for parameter, before in old["parameters"].items():
            after = new["parameters"][parameter]
            error = np.sqrt(before["sd"] ** 2 / before["ess"] + after["sd"] ** 2 / after["ess"])
            rows.append((parameter, before["mean"], after["mean"],
                         (after["mean"] - before["mean"]) / error))  # fmt: skip
        for parameter, before, after, z in rows:
            worst = max(worst, abs(z))
            print(f"{name:15s} {parameter:10s} {before:12.5g} {after:12.5g} {z:5.1f}")
    print(f"largest |z|: {worst:.1f} (Monte Carlo error alone: ~N(0, 1) each)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--series", choices=("coloured", "white", "wide"), default="coloured")
    parser.add_argument("--baseline", default="a16c102", help="git ref of the baseline")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--workdir", type=Path, default=None)
    parser.add_argument("--no-families", action="store_true", help="the command's runs only")
    args = parser.parse_args()
    folder = work_folder(args.workdir, "bench_noise_")
    here = Path(__file__).resolve().parents[1]
    base = baseline_worktree(folder, args.baseline)
    values = series(args.series, args.samples, np.random.default_rng(0))
    path = write_series(folder / f"{args.series}.csv", values)
    print(f"noise of {path} ({args.samples} samples, {args.processes} processes); "
          f"baseline {args.baseline}")  # fmt: skip
    runs: dict[str, list[dict]] = {"baseline": [], "this": []}
    for _ in range(args.repeats):
        for label, source in (("baseline", base), ("this", here)):
            run = command(source, path, args.processes)
            runs[label].append(run)
            print(f"{label:<10s} {run['seconds']:6.1f} s wall {run['cpu']:6.1f} s CPU "
                  f"{run['peak_mb']:6.0f} MB peak (largest process)")  # fmt: skip
    pairs = list(zip(runs["baseline"], runs["this"], strict=True))
    wall = statistics.median(old["seconds"] / new["seconds"] for old, new in pairs)
    cpu = statistics.median(old["cpu"] / new["cpu"] for old, new in pairs)
    this = statistics.median(run["seconds"] for run in runs["this"])
    print(f"median baseline / this: {wall:.2f} wall, {cpu:.2f} CPU; this: {this:.1f} s "
          f"(target < 15 s for 10,000 coloured samples on 2 cores)")  # fmt: skip
    for label, run in (("baseline", runs["baseline"][0]), ("this", runs["this"][0])):
        result = run["summary"]
        verdict = f"{result['verdict']} (best {result['best']})"
        print(f"{label:<10s} verdict: {verdict}")
    if args.no_families:
        return
    fits = {
        label: families(source, path) for label, source in (("baseline", base), ("this", here))
    }
    for label, each in fits.items():
        family_table(label, each)
    compare(fits["baseline"], fits["this"])


if __name__ == "__main__":
    main()
