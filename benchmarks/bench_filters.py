"""Benchmark: the state estimators' cost per sample on a 38 s and a 300 s run (issue 14).

Run by hand: ``python benchmarks/bench_filters.py [--durations 38 300] [--repeats 5]``.

For each duration it simulates a thesis-like run at 72 Hz
(``simulate_experiment(robot, 110, 30, Series(0.3 m/s, 22.5 deg/s,
duration), rng=1)``: Gaussian process noise of sigma_h = 0.047 s, channels
yaw, vx and vy) and filters all three channels with a prior holding the
simulation's truth (the filters' cost does not depend on where the prior
came from). It prints per filter

- the cost per sample [us] (the best of ``--repeats`` calls of
  :func:`bayes_jackal.kalman.kalman_filter` on the whole run, all channels,
  divided by its samples), and its ratio against the white ``kalman``
  filter measured in the same run;
- the peak of the call's allocations [MB] (tracemalloc, which numpy reports to);
- the yaw-rate RMSE against the true states [rad/s].

The filters: ``kalman`` (white process noise, the baseline) and
``kalman-coloured`` (the Gaussian family's 22-tap shift register in the
state), each on the default steady path (the converged filter as an FFT
convolution) and on the step-by-step recursion (``step``). The process' peak
resident memory is printed at the end.
"""

from __future__ import annotations

import argparse
import resource
import time
import tracemalloc

import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.kalman import FILTERS, kalman_filter
from bayes_jackal.physics import CHANNELS, discrete_matrices
from bayes_jackal.simulate import NoiseSettings, Series, simulate_experiment

ROBOT = load_profile()


def truth_prior() -> dict:
    """A prior holding the simulator's truth, with the fields the filters read."""
    Ad, Bd = discrete_matrices(ROBOT, 110.0, 30.0)
    noise = NoiseSettings()
    parameters = {}
    for i, c in enumerate(CHANNELS):
        parameters[f"sigma_h[{c}]"] = {"mean": noise.width}
        parameters[f"sigma_c[{c}]"] = {"mean": noise.sigma_c[i]}
        parameters[f"sigma_n[{c}]"] = {"mean": noise.sigma_n[i]}
    return {
        "format": "bayes_jackal.prior/1",
        "robot": {"name": ROBOT.name},
        "dt": ROBOT.dt,
        "damping": {"mean": [110.0, 30.0]},
        "model": {"Ad": Ad.tolist(), "Bd": Bd.tolist()},
        "noise": {
            "family": noise.family,
            "channels": list(CHANNELS),
            "sensor": "ma1",
            "parameters": parameters,
        },
    }


def measure(run, prior: dict, noise: str, fast: bool, repeats: int) -> dict:
    """Best time of ``repeats`` calls [s], peak allocations [MB] and the yaw RMSE."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        kalman_filter(run, prior, noise=noise, fast=fast)
        times.append(time.perf_counter() - start)
    tracemalloc.start()
    estimates = kalman_filter(run, prior, noise=noise, fast=fast)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    error = estimates["yaw"].mean - run.truth_arrays["yaw_state"]
    return {
        "seconds": min(times),
        "peak_mb": peak / 2**20,
        "rmse": float(np.sqrt(np.mean(error**2))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--durations", type=float, nargs="+", default=[38.0, 300.0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    prior = truth_prior()
    for duration in args.durations:
        series = Series(0.3, float(np.deg2rad(22.5)), duration)
        run = simulate_experiment(ROBOT, 110.0, 30.0, series, rng=1)
        print(f"\n{duration:g} s run: {len(run.t)} samples, 3 channels")
        print(f"{'filter':24s} {'us/sample':>10s} {'ratio':>7s} {'peak MB':>8s} {'yaw RMSE':>10s}")
        baseline = None
        for name, noise in FILTERS.items():
            for fast in (True, False):
                result = measure(run, prior, noise, fast, args.repeats)
                baseline = baseline or result["seconds"]
                label = name if fast else f"{name} (step)"
                print(
                    f"{label:24s} {1e6 * result['seconds'] / len(run.t):10.2f} "
                    f"{result['seconds'] / baseline:7.2f} {result['peak_mb']:8.2f} "
                    f"{result['rmse']:10.5f}"
                )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak resident memory of the process: {peak:.0f} MB")


if __name__ == "__main__":
    main()
