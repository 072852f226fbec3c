"""Benchmark: posterior sampling and the likelihood engines (issue 3 targets).

Run by hand: ``python benchmarks/bench_posterior.py [--skip-pooled]``.

- one thesis-like experiment (2,700 samples, yaw channel, Gaussian family)
  to a converged posterior: target < 30 s on 2 cores;
- 15 experiments (10 x v1, 5 x v2) pooled: target < 3 min.

The engines' cost per evaluation against N: ``bench_engine.py``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.inference.chains import SamplerSettings
from bayes_jackal.inference.sampling import sample_posterior
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.io.simulate import simulate_experiment, simulate_series
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.posterior.summary import summarize

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


if __name__ == "__main__":
    main()
