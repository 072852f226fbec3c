"""Benchmark: the pose channels' cost against the derived-velocity model, on the demo's bags.

Run by hand: ``python benchmarks/bench_pose_model.py [--seeds N] [--repeats N]``.

Issue 23 asks that ``sample`` on the demo's bags cost at most 1.5x what it
cost before the pose channels were modelled. The baseline is measured in
the same run: the same two bags, read the same way, with their poses
dropped, so that vx and vy are the reader's derived velocities under the
rate model (eq. 7-3, sigma_n): exactly the model of bayes_jackal before
issue 23. Each case is the whole ``sample`` (the MAP search, the chain to
convergence, the summary), default flags, over seeds 1..N (default 3):
the chain stops when its autocorrelation time has settled, a random moment
(one seed's chain can be 1.5x another's), so the cost of ``sample`` is its
mean over seeds. The chains' lengths are printed, and the cost per step.

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
from bayes_jackal.io.bags import read_bag
from bayes_jackal.likelihood.priors import Prior
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.workflow.demo import demo_folder

ROBOT = bj.load_profile()


def demo_runs() -> list[bj.Experiment]:
    folder = demo_folder()
    return [read_bag(folder / name, ROBOT) for name in ("v1_01.bag", "v2_01.bag")]


def sample_once(runs: list[bj.Experiment], seed: int) -> tuple[float, dict]:
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # prior-boundary warnings of the derived model
        posterior = bj.sample(runs, seed=seed, progress=False)
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
    parser.add_argument("--seeds", type=int, default=3, help="chains of each case")
    parser.add_argument("--repeats", type=int, default=1, help="samples of each chain")
    args = parser.parse_args()
    poses = demo_runs()
    derived = [dataclasses.replace(run, pose=None) for run in poses]
    cases = {"derived velocities (before issue 23)": derived, "pose channels (now)": poses}
    seconds = {}
    for label, runs in cases.items():
        times, steps = [], []
        for seed in range(1, args.seeds + 1):
            best = min((sample_once(runs, seed) for _ in range(args.repeats)), key=lambda r: r[0])
            times.append(best[0])
            steps.append(best[1]["n_steps"])
            print(f"  {label}, seed {seed}: {best[0]:6.1f} s, {steps[-1]} steps", flush=True)
        seconds[label] = np.mean(times)
        print(
            f"{label:38s} sample {np.mean(times):6.1f} s (mean of {args.seeds} seeds, best of "
            f"{args.repeats}), {np.mean(steps):.0f} steps, "
            f"{1e3 * sum(times) / sum(steps):5.1f} ms per step, "
            f"{per_set(runs) * 1e6:6.0f} us per parameter set"
        )
    baseline, now = seconds.values()
    print(f"ratio now / before: {now / baseline:.2f} (issue 23: at most 1.5)")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory of the process: {peak:.0f} MB")


if __name__ == "__main__":
    main()
