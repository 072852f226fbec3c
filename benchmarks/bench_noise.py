"""Benchmark: characterising a noise series with every family on 2 processes (issue 15).

Run by hand: ``python benchmarks/bench_noise.py [--samples 10000] [--processes 2]``.

A series of N samples (Gaussian-coloured noise of width 3 samples, unit sd,
over a white floor of sd 0.3, dt = 0.01 s) is characterised by the 5
families (:func:`bayes_jackal.characterise_noise`, default sampler
settings) on a :class:`~bayes_jackal.executors.ProcessExecutor`. It prints
the wall time (target: under a minute for 10,000 samples on 2 cores), its
ratio to the baseline measured in the same run, the white family alone on
the same series in this process, each family's steps, convergence and
log evidence, and the peak resident memory of this process and of the
largest worker.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

import bayes_jackal as bj
from bayes_jackal.executors import ProcessExecutor
from bayes_jackal.kernels import get_family

DT = 0.01  # [s]
WIDTH = 0.03  # [s]: 3 samples
FLOOR = 0.3


def series(n: int, rng: np.random.Generator) -> np.ndarray:
    """Gaussian-coloured noise of width WIDTH and unit sd over a white floor of sd FLOOR."""
    return get_family("gaussian").noise(WIDTH, DT, n, rng=rng) + FLOOR * rng.standard_normal(n)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args()
    values = series(args.samples, np.random.default_rng(0))
    settings = None  # the command's defaults: NOISE_MAX_STEPS per chain
    start = time.perf_counter()
    bj.characterise_noise(values, dt=DT, families=["white"], settings=settings, seed=1)
    baseline = time.perf_counter() - start
    start = time.perf_counter()
    with ProcessExecutor(args.processes) as executor:
        result = bj.characterise_noise(values, dt=DT, settings=settings, seed=1,
                                       executor=executor)  # fmt: skip
    wall = time.perf_counter() - start
    print(f"{len(result.fits)} families, {args.samples} samples, {args.processes} processes")
    for name, fit in result.fits.items():
        d = fit.diagnostics
        print(f"  {name:15s} {d['n_steps']:6d} steps converged {d['converged']!s:5s} "
              f"log Z {fit.evidence.log_evidence:.1f} +- {fit.evidence.error:.2f}")  # fmt: skip
    print(f"verdict: {result.verdict()[1]}")
    print(f"wall time {wall:.1f} s (target < 60 s); the white family alone here "
          f"{baseline:.2f} s: ratio {wall / baseline:.0f}x")  # fmt: skip
    here = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    workers = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"peak resident memory: {here:.0f} MB here, {workers:.0f} MB in the largest worker")


if __name__ == "__main__":
    main()
