"""Benchmark: the state estimators' cost per sample on a 38 s and a 300 s run (issue 14).

Run by hand: ``python benchmarks/bench_filters.py [--durations 38 300] [--repeats 5]``.

Every filter runs from one exported prior: :func:`bayes_jackal.export_prior`
(order 2) of a posterior sampled with the default settings
(:func:`bayes_jackal.sample`, Gaussian family, channels yaw, vx and vy, seed 1)
on a simulated v1 run (``simulate_experiment(robot, 110, 30, "v1", rng=100)``);
the sampling time is printed apart. For each duration it simulates a
thesis-like run at 72 Hz (``simulate_experiment(robot, 110, 30, Series(0.3
m/s, 22.5 deg/s, duration), rng=1)``: Gaussian process noise of sigma_h =
0.047 s) and filters all three channels. It prints per filter

- the cost per sample [us] (the best of ``--repeats`` calls on the whole
  run, all channels, divided by its samples), and its ratio against the
  white ``kalman`` filter measured in the same run;
- the peak of the call's allocations [MB] (tracemalloc, which numpy reports to);
- the yaw-rate RMSE against the true states [rad/s] and the yaw channel's
  mean normalised innovation squared (NIS, 1 when the filter's variances
  are right), scored by :func:`bayes_jackal.score_estimates` from the same
  first sample for every row.

The filters: ``kalman`` (white process noise, the baseline) and
``kalman-coloured`` (the Gaussian family's shaping filter in the state),
each on the default steady path (the converged filter as an FFT convolution)
and on the step-by-step recursion (``step``); ``generalised`` (the D-step in
generalised coordinates) at the prior's embedding order p = 2 and at p = 1
and 3 (:func:`bayes_jackal.estimate_states`, ``order``). The process' peak
resident memory is printed at the end.
"""

from __future__ import annotations

import argparse
import resource
import time
import tracemalloc
import warnings

import numpy as np

import bayes_jackal as bj
from bayes_jackal.filters.kalman_filters import KALMAN_FILTERS
from bayes_jackal.io.simulate import Series

ROBOT = bj.load_profile()
#: The generalised filter's embedding orders; the prior's is the first.
ORDERS = (2, 1, 3)


def exported_prior() -> dict:
    """The order-2 prior of a posterior of all channels sampled on a simulated v1 run."""
    train = bj.simulate_experiment(ROBOT, 110.0, 30.0, "v1", rng=100)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", bj.ConvergenceWarning)  # reported by "converged"
        posterior = bj.sample([train], channels=["yaw", "vx", "vy"], seed=1)
    prior = bj.export_prior(posterior, order=ORDERS[0])
    print(
        f"prior: sampled {prior['noise']['channels']} on {prior['experiments']} in "
        f"{time.perf_counter() - start:.1f} s (converged: {prior['converged']}), "
        f"{prior['noise']['family']} family, order {prior['generalised_coordinates']['order']}"
    )
    return prior


def filter_calls(run, prior: dict) -> dict:
    """Per row label, a call running that filter on every channel of ``run``."""
    calls = {}
    for name, noise in KALMAN_FILTERS.items():
        for fast in (True, False):
            label = name if fast else f"{name} (step)"
            calls[label] = lambda noise=noise, fast=fast: bj.filters.kalman_filter(
                run, prior, noise=noise, fast=fast
            )
    for order in ORDERS:
        calls[f"generalised p={order}"] = lambda order=order: bj.estimate_states(
            run, prior, filters=["generalised"], order=order
        )["generalised"]
    return calls


def measure(call, repeats: int) -> tuple[dict, float, float]:
    """The call's estimates, its best time of ``repeats`` [s] and peak allocations [MB]."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    tracemalloc.start()
    estimates = call()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return estimates, min(times), peak / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--durations", type=float, nargs="+", default=[38.0, 300.0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    prior = exported_prior()
    for duration in args.durations:
        series = Series(0.3, float(np.deg2rad(22.5)), duration)
        run = bj.simulate_experiment(ROBOT, 110.0, 30.0, series, rng=1)
        print(f"\n{duration:g} s run: {len(run.t)} samples, 3 channels")
        print(
            f"{'filter':24s} {'us/sample':>10s} {'ratio':>7s} {'peak MB':>8s} "
            f"{'yaw RMSE':>10s} {'yaw NIS':>8s}"
        )
        results = {
            label: measure(call, args.repeats) for label, call in filter_calls(run, prior).items()
        }
        scores = bj.score_estimates(run, {label: r[0] for label, r in results.items()})
        baseline = results["kalman"][1]
        for label, (_, seconds, peak_mb) in results.items():
            score = scores[label]
            print(
                f"{label:24s} {1e6 * seconds / len(run.t):10.2f} {seconds / baseline:7.2f} "
                f"{peak_mb:8.2f} {score['state_rmse']['yaw']:10.5f} "
                f"{score['nis']['yaw']['mean']:8.3f}"
            )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak resident memory of the process: {peak:.0f} MB")


if __name__ == "__main__":
    main()
