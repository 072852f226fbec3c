"""Benchmark: a 15-run campaign's population posterior on 2 cores (issue 27).

Run by hand: ``python benchmarks/bench_population.py [--processes 2]`` (about two minutes).

The campaign: 3 floors x 5 runs, simulated thesis-like v1 runs (38 s at
72 Hz; vx, vy and yaw rate; Gaussian-coloured process noise, the
simulator's default), the floors' dampings 0.8, 1 and 1.25 times
(110, 30) N s/m. Timed, with the default options otherwise (family
gaussian, every channel, seed 1):

- **baseline**: one pooled posterior of all 15 runs (``bj.sample``), what
  the package gave before: one damping for every floor;
- **population, shared noise** (the default): each floor's runs pooled into
  one unit, 3 units sampled on ``--processes`` processes, then stage 2;
- **population, noise per run** (``noise="per-experiment"``): 15 units of
  one run each.

Printed: the seconds of each and their ratio to the baseline measured in
this same process, the best structure and its verdict, and peak
resident memory (``resource.getrusage``: the largest of this process and
of its finished worker processes).
"""

from __future__ import annotations

import argparse
import resource
import time
import warnings

import bayes_jackal as bj
from bayes_jackal.inference.executors import ProcessExecutor

FLOORS = {"tiles": 0.8, "carpet": 1.0, "lino": 1.25}
RUNS_PER_FLOOR = 5


def campaign() -> list[bj.Experiment]:
    robot = bj.load_profile()
    runs = []
    for f, (label, factor) in enumerate(FLOORS.items()):
        for i in range(RUNS_PER_FLOOR):
            run = bj.simulate_experiment(
                robot, 110.0 * factor, 30.0 * factor, "v1", rng=100 * f + i, name=f"{label}_{i}"
            )
            run.provenance["group"] = label
            runs.append(run)
    return runs


def timed(label: str, work) -> tuple[float, object]:
    start = time.perf_counter()
    result = work()
    seconds = time.perf_counter() - start
    print(f"{label}: {seconds:.1f} s")
    return seconds, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args()
    runs = campaign()
    warnings.simplefilter("ignore", bj.ConvergenceWarning)  # kept in the results' warnings
    baseline, _ = timed(
        "baseline, one pooled posterior of 15 runs",
        lambda: bj.sample(runs, seed=1, progress=False),
    )
    for noise in ("shared", "per-experiment"):
        with ProcessExecutor(args.processes) as executor:
            seconds, result = timed(
                f"population, noise {noise}",
                lambda noise=noise, executor=executor: bj.population(
                    runs, noise=noise, seed=1, progress=False, executor=executor
                ),
            )
        print(
            f"  {len(result.hierarchy.units)} units, {seconds / baseline:.2f} x the baseline; "
            f"best {result.best}: {result.verdict()}"
        )
    peak = max(
        resource.getrusage(who).ru_maxrss
        for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
    )
    print(f"peak resident memory: {peak / 1024:.0f} MB")


if __name__ == "__main__":
    main()
