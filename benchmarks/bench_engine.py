"""Benchmark: the likelihood engines' cost per evaluation against the run's length (issue 12).

Run by hand: ``python benchmarks/bench_engine.py [--sizes 1000 10000 100000]``.

For N residuals of a Gaussian-coloured yaw rate (sigma_h = 0.047 s, 72 Hz)
and 22 parameter sets around the truth (one emcee half-ensemble of the
11-parameter, three-channel model; here one channel), it prints per engine
the cost of one evaluation:

- ``fast``: the default, the spectral factor on a short grid and the lagged
  Gram tensor computed once (target: flat in N);
- ``full grid``: the same formula on a grid of >= 2N points, what the
  ``fast`` engine was before issue 12 (O(N log N));
- ``exact``: the full Durbin-Levinson recursion, O(N^2), the reference
  (above 10,000 residuals timed on 2 sets and scaled to 22),

the ratios against ``fast`` at the smallest N, measured in the same run, the
largest |fast - exact| over the sets [nats] (target 1e-6), the one-off setup
(the Gram tensor) and the peak resident memory of the process.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.likelihood.spectral import spectral_loglike
from bayes_jackal.model.kernels import FAMILIES
from bayes_jackal.model.physics import channel_coefficients

ROBOT = load_profile()
TRUTH = np.array([110.0, 30.0, 0.047, 0.01, 0.005])
SETS = 22


def noise_run(n: int, rng: np.random.Generator) -> Experiment:
    """A stationary run with n residuals: the yaw rate about 0.3 rad/s, wheels near 4 rad/s."""
    dt = ROBOT.dt
    t = np.arange(n + 1) * dt
    yaw = 0.3 + FAMILIES["gaussian"].noise(0.047, dt, n + 1, 0.01, rng)
    omega = 4.0 + 0.01 * rng.standard_normal(n + 1)
    return Experiment(t, yaw + 0.005 * rng.standard_normal(n + 1), omega, omega - 1.0)


def per_call(function, *args, repeats: int) -> float:
    """Seconds per call, after a warm-up call when repeated."""
    if repeats > 1:
        function(*args)
    start = time.perf_counter()
    for _ in range(repeats):
        function(*args)
    return (time.perf_counter() - start) / repeats


def full_grid(likelihood: ResidualLikelihood, theta: np.ndarray):
    """The pre-issue-12 ``fast`` path: the same formula on the >= 2N-point grid."""
    block = likelihood.blocks[0]
    alpha, row = channel_coefficients(ROBOT, theta[:, 0], theta[:, 1], "yaw", block.dt)
    c = np.column_stack([np.ones(len(theta)), -alpha, -row])
    noise = np.column_stack([theta[:, 2:], alpha])

    def evaluate():
        acov = likelihood._autocovariance(block, noise, block.n)
        return spectral_loglike(acov, block, c, block.size)

    return evaluate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1_000, 10_000, 100_000])
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    theta = TRUTH * np.exp(0.05 * rng.standard_normal((SETS, len(TRUTH))))
    print(f"one evaluation of {SETS} parameter sets, yaw channel, Gaussian family")
    print(
        f"{'N':>8s} {'setup':>8s} {'fast':>9s} {'full grid':>10s} {'exact':>10s} "
        f"{'fast/fast@N0':>13s} {'exact/fast':>11s} {'max|fast-exact|':>16s}"
    )
    baseline = None
    for n in args.sizes:
        run = noise_run(n, rng)
        start = time.perf_counter()
        fast = ResidualLikelihood([run], ROBOT, channels=("yaw",), steady=False)
        fast(theta[:1])
        setup = time.perf_counter() - start
        exact = ResidualLikelihood([run], ROBOT, channels=("yaw",), steady=False, engine="exact")
        checked = theta if n <= 10_000 else theta[:2]
        start = time.perf_counter()
        reference = exact(checked)
        exact_seconds = (time.perf_counter() - start) * SETS / len(checked)
        error = np.max(np.abs(fast(checked) - reference))
        fast_seconds = per_call(fast, theta, repeats=20)
        grid_seconds = per_call(full_grid(fast, theta), repeats=5)
        baseline = baseline or fast_seconds
        print(
            f"{n:8d} {setup:7.2f}s {fast_seconds * 1e3:7.2f}ms {grid_seconds * 1e3:8.1f}ms "
            f"{exact_seconds:9.2f}s {fast_seconds / baseline:12.2f}x "
            f"{exact_seconds / fast_seconds:10.0f}x {error:16.1e}"
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak:.0f} MB")


if __name__ == "__main__":
    main()
