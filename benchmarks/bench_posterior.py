"""Benchmark: posterior sampling and the likelihood engines (issue 3 targets).

Run by hand: ``python benchmarks/bench_posterior.py [--skip-pooled]``.

- one thesis-like experiment (2,700 samples, yaw channel, Gaussian family)
  to a converged posterior: target < 30 s on 2 cores;
- 15 experiments (10 x v1, 5 x v2) pooled: target < 3 min;
- the cost of one likelihood evaluation (16 parameter sets, one emcee
  half-ensemble) per engine for N = 1e3, 1e4, 1e5 residuals, with the full
  Durbin-Levinson recursion ('exact') as the baseline in the same process.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.experiment import Experiment
from bayes_jackal.inference import SamplerSettings, sample_posterior
from bayes_jackal.kernels import FAMILIES
from bayes_jackal.likelihood import ResidualLikelihood
from bayes_jackal.posterior import summarize
from bayes_jackal.simulate import simulate_experiment, simulate_series

ROBOT = load_profile()
TRUTH = np.array([110.0, 30.0, 0.047, 0.01, 0.005])


def timed(function):
    start = time.perf_counter()
    result = function()
    return result, time.perf_counter() - start


def run_posterior(experiments, label: str) -> None:
    likelihood = ResidualLikelihood(experiments, ROBOT)
    idata, seconds = timed(lambda: sample_posterior(likelihood, SamplerSettings(), seed=1))
    summary = summarize(idata)
    tau = max(summary["autocorr_time"].values())
    ess = min(
        row["ess_autocorr"]
        for row in summary.values()
        if isinstance(row, dict) and "ess_autocorr" in row
    )
    print(
        f"{label}: {seconds:6.1f} s, {summary['n_steps']} steps "
        f"({summary['n_steps'] / tau:.0f} tau), converged={summary['converged']}, "
        f"min ESS {ess:.0f}, {likelihood.n_residuals} residuals"
    )


def noise_series(n: int, rng: np.random.Generator) -> Experiment:
    """A stationary experiment with n + 1 samples (steady window = all)."""
    dt = ROBOT.dt
    t = np.arange(n + 1) * dt
    yaw = 0.3 + FAMILIES["gaussian"].noise(0.047, dt, n + 1, 0.01, rng)
    omega = np.full(n + 1, 4.0)
    return Experiment(t, yaw + 0.005 * rng.standard_normal(n + 1), omega, omega - 1.0)


def engine_costs() -> None:
    rng = np.random.default_rng(0)
    theta = TRUTH * np.exp(0.05 * rng.standard_normal((16, 5)))
    print("\nlikelihood evaluation, 16 parameter sets (one emcee half-ensemble):")
    print(f"{'N':>8s} {'fast':>10s} {'whittle':>10s} {'exact':>10s} {'exact/fast':>11s}")
    for n in (1_000, 10_000, 100_000):
        experiment = noise_series(n, rng)
        costs = {}
        for engine in ("fast", "whittle", "exact"):
            likelihood = ResidualLikelihood([experiment], ROBOT, engine=engine, steady=False)
            batch = theta if engine != "exact" or n <= 10_000 else theta[:1]
            likelihood(batch[:2])
            repeats = 5 if engine != "exact" else 1
            start = time.perf_counter()
            for _ in range(repeats):
                likelihood(batch)
            seconds = (time.perf_counter() - start) / repeats
            costs[engine] = seconds * len(theta) / len(batch)
        print(
            f"{n:8d} {costs['fast'] * 1e3:8.1f}ms {costs['whittle'] * 1e3:8.1f}ms "
            f"{costs['exact'] * 1e3:8.0f}ms {costs['exact'] / costs['fast']:10.0f}x"
        )
    print("(exact at N = 1e5 timed on one parameter set and scaled to 16)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-pooled", action="store_true", help="skip the 15-run case")
    args = parser.parse_args()
    full = simulate_experiment(ROBOT, 110.0, 30.0, "v1", rng=1)
    one = full.window(full.t[0], full.t[2699])
    one = Experiment(
        one.t, one.yaw_rate, one.omega_r, one.omega_l, steady_window=full.steady_window
    )
    run_posterior([one], "1 experiment (2,700 samples), target < 30 s")
    if not args.skip_pooled:
        runs = simulate_series(ROBOT, 110.0, 30.0, {"v1": 10, "v2": 5}, rng=2)
        run_posterior(runs, "15 experiments pooled, target < 180 s")
    engine_costs()


if __name__ == "__main__":
    main()
