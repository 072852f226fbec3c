"""Benchmark: the pose channels' cost against the derived-velocity model, on the demo's bags.

Run by hand: ``python benchmarks/bench_pose_model.py [--repeats N]``.

Issue 23 asks that ``sample`` on the demo's bags cost at most 1.5x what it
cost before the pose channels were modelled. The baseline is measured in
the same run: the same two bags, read the same way, with their poses
dropped, so that vx and vy are the reader's derived velocities under the
rate model (eq. 7-3, sigma_n): exactly the model of bayes_jackal before
issue 23. Each case is the whole ``sample`` (the MAP search, the chain to
convergence, the summary), default flags, seed 1; the chains' lengths are
printed, since a better-posed posterior can converge in fewer steps.

Also the cost of one likelihood evaluation per parameter set (a batch of
64, as emcee's half-ensembles of the default 44 walkers come close to) and
the peak resident memory of the process.
"""

from __future__ import annotations

import argparse
import dataclasses
import resource
import time
import warnings

import numpy as np

import bayes_jackal as bj
from bayes_jackal.bags import read_bag
from bayes_jackal.demo import demo_folder
from bayes_jackal.likelihood import ResidualLikelihood
from bayes_jackal.priors import Prior

ROBOT = bj.load_profile()


def demo_runs() -> list[bj.Experiment]:
    folder = demo_folder()
    return [read_bag(folder / name, ROBOT) for name in ("v1_01.bag", "v2_01.bag")]


def sample_once(runs: list[bj.Experiment]) -> tuple[float, dict]:
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # prior-boundary warnings of the derived model
        posterior = bj.sample(runs, seed=1, progress=False)
    seconds = time.perf_counter() - start
    return seconds, bj.summarize(posterior)


def per_set(runs: list[bj.Experiment]) -> float:
    """Seconds per parameter set of the fast engine, batches of 64 around the prior's centre."""
    likelihood = ResidualLikelihood(runs, ROBOT)
    prior = Prior.for_likelihood(likelihood, ROBOT)
    rng = np.random.default_rng(1)
    centre = np.sqrt(prior.low * prior.high)
    centre[:2] = (110.0, 30.0)
    theta = centre * np.exp(0.1 * rng.standard_normal((64, len(centre))))
    likelihood(theta)  # warm the cached Gram tensors
    start = time.perf_counter()
    for _ in range(20):
        likelihood(theta)
    return (time.perf_counter() - start) / (20 * 64)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1, help="samples of each case")
    args = parser.parse_args()
    poses = demo_runs()
    derived = [dataclasses.replace(run, pose=None) for run in poses]
    cases = {"derived velocities (before issue 23)": derived, "pose channels (now)": poses}
    seconds = {}
    for label, runs in cases.items():
        times = []
        for _ in range(args.repeats):
            elapsed, summary = sample_once(runs)
            times.append(elapsed)
        seconds[label] = min(times)
        print(
            f"{label:38s} sample {min(times):6.1f} s (best of {args.repeats}), "
            f"{summary['n_steps']} steps, converged={summary['converged']}, "
            f"{per_set(runs) * 1e6:6.0f} us per parameter set"
        )
    baseline, now = seconds.values()
    print(f"ratio now / before: {now / baseline:.2f} (issue 23: at most 1.5)")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory of the process: {peak:.0f} MB")


if __name__ == "__main__":
    main()
