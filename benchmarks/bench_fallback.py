"""Benchmark: the ``fast`` engine's time-domain fallback, banded Cholesky against the recursion.

Run by hand: ``python benchmarks/bench_fallback.py [--sizes 2376 10000] [--sets 22]``.

For N residuals of a moving-average-coloured yaw rate (a 0.15 s boxcar,
sigma_c = 0.01 over a sensor floor 10x below it, 72 Hz: the setting whose
spectral nulls no spectral grid certifies, tests/test_evidence.py) and
parameter sets around the truth, it prints:

- ``fallback``: the time-domain density the ``fast`` engine now uses for
  sets no grid certifies (:func:`bayes_jackal.likelihood.fallback_loglike`:
  here the banded Cholesky factor, O(N p^2));
- ``recursion``: what it used before, the Durbin-Levinson recursion stopped
  at partial autocorrelations below 1e-13 (runs to ~N for these sets:
  O(N^2));

their ratio measured in the same run, how many of the sets reached the
fallback, the largest |fallback - recursion| over the sets [nats] and the
peak resident memory of the process.
"""

from __future__ import annotations

import argparse
import functools
import resource
import time

import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.likelihood.spectral import (
    evaluate_on_grids,
    spectral_loglike,
)
from bayes_jackal.likelihood.toeplitz import (
    FAST_TOLERANCE,
    fallback_loglike,
    toeplitz_loglike,
)
from bayes_jackal.model.kernels import FAMILIES
from bayes_jackal.model.physics import channel_coefficients

ROBOT = load_profile()
TRUTH = np.array([110.0, 30.0, 0.15, 0.01, 0.001])


def noise_run(n: int, rng: np.random.Generator) -> Experiment:
    """A stationary run with n residuals: the yaw rate about 0.3 rad/s, wheels near 4 rad/s."""
    dt = ROBOT.dt
    t = np.arange(n + 1) * dt
    yaw = 0.3 + FAMILIES["moving-average"].noise(TRUTH[2], dt, n + 1, TRUTH[3], rng)
    omega = 4.0 + 0.01 * rng.standard_normal(n + 1)
    return Experiment(t, yaw + TRUTH[4] * rng.standard_normal(n + 1), omega, omega - 1.0)


def timed(function, *args) -> tuple[np.ndarray, float]:
    """The value of one call and its seconds."""
    start = time.perf_counter()
    value = function(*args)
    return value, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2_376, 10_000])
    parser.add_argument("--sets", type=int, default=22)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    theta = TRUTH * np.exp(0.05 * rng.standard_normal((args.sets, len(TRUTH))))
    print(f"fallback of {args.sets} parameter sets, yaw channel, moving-average family")
    print(
        f"{'N':>8s} {'certified':>9s} {'fallback':>10s} {'recursion':>10s} "
        f"{'recursion/fallback':>19s} {'max|diff|':>10s}"
    )
    recursion = functools.partial(toeplitz_loglike, tol=FAST_TOLERANCE)
    for n in args.sizes:
        likelihood = ResidualLikelihood(
            [noise_run(n, rng)],
            ROBOT,
            family="moving-average",
            channels=("yaw",),
            steady=False,
        )
        block = likelihood.blocks[0]
        alpha, row = channel_coefficients(ROBOT, theta[:, 0], theta[:, 1], "yaw", block.dt)
        c = np.column_stack([np.ones(len(theta)), -alpha, -row])
        noise = np.column_stack([theta[:, 2:], alpha])
        pending = evaluate_on_grids(
            block,
            lambda rows, lags: likelihood._autocovariance(block, noise[rows], lags),  # noqa: B023
            c,
            spectral_loglike,
            np.empty(len(c)),
        )
        certified = len(c) - len(pending)
        new, new_seconds = timed(likelihood._recursion, block, noise, c, fallback_loglike)
        old, old_seconds = timed(likelihood._recursion, block, noise, c, recursion)
        print(
            f"{n:8d} {certified:9d} {new_seconds:9.2f}s {old_seconds:9.2f}s "
            f"{old_seconds / new_seconds:18.1f}x {np.max(np.abs(new - old)):10.1e}"
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak:.0f} MB")


if __name__ == "__main__":
    main()
