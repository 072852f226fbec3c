"""Benchmark: the 1000 x 1000 one-step grid (thesis ch. 9-1-2) against a per-pair loop.

Run by hand: ``python benchmarks/bench_onestep_grid.py``. Target (issue 2):
the full grid, d_lat and d_long from 1 to 1000 in steps of 1, on one
2,700-sample experiment in under 0.2 s on 2 cores. The baseline is what the
thesis did: discretise with ``c2d`` for every pair and compute the residuals;
a random sample of pairs is timed and extrapolated to the 10^6 pairs.
"""

from __future__ import annotations

import argparse
import time

import control
import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.io.simulate import simulate_experiment
from bayes_jackal.model.physics import continuous_matrices, one_step_residuals
from bayes_jackal.thesis.gridsearch import damping_grid, grid_search

SAMPLES = 2700


def per_pair_mse(experiment, robot, d_lat: float, d_long: float) -> float:
    """One grid point the straightforward way: c2d, residuals, mean square."""
    A, B = continuous_matrices(robot, d_lat, d_long)
    system = control.c2d(control.ss(A, B, np.eye(3), np.zeros((3, 2))), experiment.dt)
    residuals = one_step_residuals(system.A, system.B, experiment.states(), experiment.inputs)
    return float(np.mean(residuals[:, 2] ** 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs of the grid (best)")
    parser.add_argument("--pairs", type=int, default=300, help="pairs timed for the baseline")
    args = parser.parse_args()

    robot = load_profile()
    full = simulate_experiment(robot, 110.0, 30.0, "v1", rng=0)
    experiment = full.window(full.t[0], full.t[SAMPLES - 1])
    grid = damping_grid(1.0, 1000.0, 1.0)

    grid_search([experiment], robot, grid, grid)  # warm-up (imports, allocation)
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        result = grid_search([experiment], robot, grid, grid, method="onestep")
        times.append(time.perf_counter() - start)
    fast = min(times)

    rng = np.random.default_rng(1)
    pairs = rng.choice(grid, size=(args.pairs, 2))
    start = time.perf_counter()
    sampled = [per_pair_mse(experiment, robot, lat, long) for lat, long in pairs]
    per_pair = (time.perf_counter() - start) / args.pairs
    baseline = per_pair * grid.size**2

    # The two must agree where they were both evaluated.
    index = np.searchsorted(grid, pairs)
    np.testing.assert_allclose(result.mse[index[:, 0], index[:, 1]], sampled, rtol=1e-8)

    print(f"experiment: {len(experiment.t)} samples; grid: {grid.size} x {grid.size} pairs")
    print(f"vectorised one-step grid (best of {args.repeats}): {fast * 1e3:8.1f} ms")
    print(
        f"per-pair c2d loop: {per_pair * 1e6:8.1f} us/pair x {grid.size**2} pairs "
        f"= {baseline:8.1f} s (extrapolated from {args.pairs} pairs)"
    )
    print(f"ratio (loop / vectorised): {baseline / fast:,.0f}x")
    print(f"target: full grid < 200 ms -> {'met' if fast < 0.2 else 'NOT met'}")
    print(f"argmin: d_lat={result.argmin()[0]:g}, d_long={result.argmin()[1]:g}")


if __name__ == "__main__":
    main()
