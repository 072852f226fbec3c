"""Benchmark: draw-averaged against plug-in noise parameters in every filter (issue 14).

Run by hand: ``python benchmarks/bench_averaged_prior.py [--tests 10]`` (about a minute).

Each filter of :data:`bayes_jackal.FILTERS` runs either with the noise
parameters at their posterior means (``plug-in``) or with its covariances
and precisions averaged over the prior's draws (``averaged``,
:func:`bayes_jackal.estimate_states`). Two Gaussian-family posteriors are
sampled with the default settings (seed 1) on one simulated v1 run
(``simulate_experiment(robot, 110, 30, "v1", rng=100)``) and exported at
order 2:

- ``wide``: the yaw channel alone, where the damping and with it the noise
  scale sigma_c are poorly pinned down;
- ``narrow``: the channels yaw, vx and vy, whose velocities pin the damping.

Their sampling times and the yaw noise parameters' posterior means and sds
are printed. The filters then run on ``--tests`` simulated v1 runs the
posteriors have not seen (seeds 1, 2, ..), and it prints per channel and
filter, as mean +- standard error over the runs,

- the state RMSE against the true states relative to the plug-in white
  ``kalman`` filter on the same run, for plug-in and averaged parameters;
- averaged / plug-in - 1 [%], the paired change from averaging (negative:
  averaging helps);
- the mean normalised innovation squared (NIS, 1 when the filter's
  variances are right) and the number of runs inside its 95 % chi-square
  band (:func:`bayes_jackal.score_estimates`, from the same first sample for
  every filter);

and the generalised filter's yaw RMSE relative to the augmented Kalman
filter (``kalman-coloured``).
"""

from __future__ import annotations

import argparse
import resource
import time
import warnings

import numpy as np

import bayes_jackal as bj

ROBOT = bj.load_profile()
#: The posteriors: name -> channels sampled.
POSTERIORS = {"wide": ["yaw"], "narrow": ["yaw", "vx", "vy"]}
PARAMETERS = ("plug-in", "averaged")
#: Seed of the run the posteriors are sampled on (the test runs' seeds start at 1).
TRAIN_SEED = 100
ORDER = 2


def sampled_prior(train: bj.Experiment, channels: list[str]) -> dict:
    """The order-2 prior of a Gaussian posterior of ``channels`` on ``train``; prints a summary."""
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", bj.ConvergenceWarning)  # reported by "converged"
        posterior = bj.sample([train], channels=channels, seed=1)
    seconds = time.perf_counter() - start
    prior = bj.export_prior(posterior, order=ORDER)
    damping = prior["damping"]
    print(
        f"sampled in {seconds:.1f} s (converged: {prior['converged']}, "
        f"{prior['draws']['count']} draws kept); d_lat {damping['d_lat']['mean']:.1f} "
        f"+- {damping['d_lat']['sd']:.1f}, d_long {damping['d_long']['mean']:.1f} "
        f"+- {damping['d_long']['sd']:.1f} N s/m (truth 110, 30)"
    )
    suffix = "[yaw]" if len(channels) > 1 else ""
    for name in ("sigma_h", "sigma_c", "sigma_n"):
        row = prior["noise"]["parameters"][name + suffix]
        print(
            f"  yaw {name}: mean {row['mean']:.4g}, sd {row['sd']:.3g} "
            f"({100 * row['sd'] / row['mean']:.1f} % of the mean)"
        )
    return prior


def run_scores(prior: dict, tests: list[bj.Experiment]) -> dict[str, list[dict]]:
    """Per parameters, the scores of every filter on each test run."""
    return {
        parameters: [
            bj.score_estimates(run, bj.estimate_states(run, prior, parameters=parameters))
            for run in tests
        ]
        for parameters in PARAMETERS
    }


def mean_se(values: np.ndarray, scale: float = 1.0) -> str:
    """``mean +- standard error`` of per-run values, times ``scale``."""
    values = scale * np.asarray(values)
    return f"{values.mean():.4f} +- {values.std(ddof=1) / np.sqrt(len(values)):.4f}"


def report(scores: dict[str, list[dict]], channel: str) -> None:
    """Print one channel's RMSE ratios, the paired change from averaging and the NIS."""

    def rmse(parameters: str, name: str) -> np.ndarray:
        return np.array([s[name]["state_rmse"][channel] for s in scores[parameters]])

    def nis(parameters: str, name: str) -> str:
        runs = [s[name]["nis"][channel] for s in scores[parameters]]
        inside = sum(r["consistent"] for r in runs)
        return f"{np.mean([r['mean'] for r in runs]):6.3f} ({inside}/{len(runs)})"

    base = rmse("plug-in", "kalman")
    print(
        f"\n{channel}: state RMSE / plug-in kalman's ({base.mean():.5f} on average), "
        f"mean +- se over {len(base)} runs; NIS mean (runs in band)"
    )
    print(
        f"{'filter':16s} {'plug-in':>17s} {'averaged':>17s} {'averaged/plug-in-1 [%]':>24s} "
        f"{'NIS plug-in':>14s} {'NIS averaged':>14s}"
    )
    for name in bj.FILTERS:
        plug, averaged = rmse("plug-in", name), rmse("averaged", name)
        print(
            f"{name:16s} {mean_se(plug / base):>17s} {mean_se(averaged / base):>17s} "
            f"{mean_se(averaged / plug - 1, 100.0):>24s} {nis('plug-in', name):>14s} "
            f"{nis('averaged', name):>14s}"
        )
    for parameters in PARAMETERS:
        ratio = rmse(parameters, "generalised") / rmse(parameters, "kalman-coloured")
        print(f"generalised / kalman-coloured, {parameters}: {mean_se(ratio)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=10, help="test runs (seeds 1..)")
    args = parser.parse_args()
    train = bj.simulate_experiment(ROBOT, 110.0, 30.0, "v1", rng=TRAIN_SEED)
    tests = [
        bj.simulate_experiment(ROBOT, 110.0, 30.0, "v1", rng=seed)
        for seed in range(1, args.tests + 1)
    ]
    print(
        f"posteriors on a simulated v1 run (seed {TRAIN_SEED}, {len(train.t)} samples), "
        f"filters on {len(tests)} others (seeds 1..{len(tests)}), generalised order {ORDER}"
    )
    for label, channels in POSTERIORS.items():
        print(f"\n=== {label} posterior: channels {channels} ===")
        prior = sampled_prior(train, channels)
        start = time.perf_counter()
        scores = run_scores(prior, tests)
        print(f"filters on the test runs: {time.perf_counter() - start:.1f} s")
        for channel in channels:
            report(scores, channel)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak resident memory of the process: {peak:.0f} MB")


if __name__ == "__main__":
    main()
