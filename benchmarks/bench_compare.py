"""Benchmark: five noise families compared by evidence (issue 5 target).

Run by hand: ``python benchmarks/bench_compare.py [--nested]``.

- one thesis-like experiment (v1, ~2,700 samples, yaw channel, Gaussian
  noise of sigma_h = 0.047 s): five families sampled (one process per core,
  as ``compare`` does) and their evidence estimated by bridge sampling,
  target < 3 min on 2 cores;
- the baseline in the same process: the Gaussian family's posterior alone
  (what ``sample`` costs), so the ratio is the price of the comparison;
- ``--nested`` adds dynesty's nested-sampling evidence of the Gaussian family
  on the same data, the independent cross-check, with its cost.
"""

from __future__ import annotations

import argparse
import os
import time

from bayes_jackal import load_profile
from bayes_jackal.inference import FitOptions, ProcessExecutor
from bayes_jackal.inference.comparison import compare_families
from bayes_jackal.inference.evidence import nested_sampling
from bayes_jackal.inference.sampling import sample_posterior
from bayes_jackal.io.simulate import simulate_experiment
from bayes_jackal.likelihood.priors import Prior
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood

ROBOT = load_profile()


def timed(function):
    start = time.perf_counter()
    result = function()
    return result, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nested", action="store_true", help="also time nested sampling")
    args = parser.parse_args()
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", rng=1)
    print(f"one v1 experiment, {len(run.t)} samples, yaw channel")
    likelihood = ResidualLikelihood([run], ROBOT)
    _, baseline = timed(lambda: sample_posterior(likelihood, seed=1))
    print(f"baseline, the gaussian posterior alone: {baseline:6.1f} s")

    def report(family, evidence, _):
        print(f"  {family:15s} log Z = {evidence.log_evidence:10.2f} +- {evidence.error:.3f}")

    processes = os.cpu_count() or 1
    comparison, seconds = timed(
        lambda: compare_families(
            [run],
            FitOptions(robot=ROBOT, seed=1),
            executor=ProcessExecutor(processes),
            on_family=report,
        )
    )
    print(
        f"five families + bridge sampling on {processes} processes: {seconds:6.1f} s "
        "(target < 180 s), "
        f"{seconds / baseline:.1f}x the baseline; best {comparison.best}; "
        f"{comparison.verdict()[1]}"
    )
    if args.nested:
        prior = Prior.for_likelihood(likelihood, ROBOT)
        nested, seconds = timed(lambda: nested_sampling(likelihood, prior, rng=1))
        bridge = comparison.evidence["gaussian"]
        print(
            f"nested sampling, gaussian: {nested.log_evidence:.2f} +- {nested.error:.2f} "
            f"against bridge {bridge.log_evidence:.2f} +- {bridge.error:.3f}; "
            f"{seconds:6.1f} s, {seconds / baseline:.1f}x the baseline"
        )


if __name__ == "__main__":
    main()
