"""Benchmark: a 10-minute command-step sequence against the 38 s thesis run (issue 36).

Run by hand: ``python benchmarks/bench_lab_logs.py [--repeats 3] [--workdir DIR]``.

Issue 36 asks that a 10-minute step sequence at 20 Hz sample in at most
twice the time of the 38 s three-channel run, and that the likelihood's
cost per evaluation stay flat in the run's length. Both runs are measured
here, in the same session, alternating ``--repeats`` times:

- the baseline: ``sample`` of ``bench_long_runs.make_run``'s 38 s at 72 Hz
  (yaw, vx, vy as rates; Gaussian family; default flags), in a fresh process;
- the step sequence: ``sample --robot husky`` of a DRIVE-like table of
  ``tests/lab_simulator.py`` (100 random (v, omega) steps of 6 s at 20 Hz,
  the wheel encoders at 4 Hz held on the rows, lidar-ICP poses at 5 Hz with
  2 cm of noise in rows of their own), its columns mapped with ``--column``
  as a user maps them, default flags otherwise.

It prints each command's wall and CPU time, peak resident memory and chain
length, and the median ratio step sequence / baseline (target <= 2). Then
the cost of one evaluation of the default likelihood (44 parameter sets,
emcee's ensemble, around the truth) on step sequences of 1, 2.5, 5 and 10
minutes, its ratio 10 min / 1 min (flat: about 1), and beside it the cost
of ``--damping speed``, whose banded engine grows with the run.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from bench_long_runs import make_run
from timing import describe_sample, timed_sample, work_folder

import bayes_jackal as bj
from bayes_jackal.likelihood import Prior, ResidualLikelihood

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import lab_simulator as lab  # the tests' independent simulator

#: Length of one command step of the DRIVE protocol [s].
STEP = 6.0
#: Parameter sets per evaluation: emcee's ensemble of the default walkers.
SETS = 44


def drive_run(folder: Path, minutes: float) -> Path:
    """A DRIVE-like step sequence of ``minutes`` (ICP at its own stamps), written once."""
    path = folder / f"drive_{minutes:g}min.csv"
    if not path.exists():
        lab.write_drive_run(path, kind="steps", icp_layout="sparse",
                            n_steps=round(60 * minutes / STEP), rng=36)  # fmt: skip
    return path


def true_centre(likelihood: ResidualLikelihood, prior: Prior) -> np.ndarray:
    """The DRIVE-like run's truth in the likelihood's parameter order (natural units).

    The kernel width sets the banded engine's band, so the noise is the
    simulated one: sigma_h, each channel's sigma_c, the ICP's 2 cm
    (``write_drive_run``'s ``icp_sd``) as sigma_p; the speed ratios at 1 and
    the yaw sensor sd at its prior's geometric mean.
    """
    layout, drive = likelihood.layout, lab.HUSKY_DRIVE
    known = {base: drive[base] for base in ("d_lat", "d_long", "sigma_h")} | {"sigma_p": 0.02}
    sigma_c = dict(zip(("yaw", "vx", "vy"), drive["sigma_c"], strict=True))
    centre = np.sqrt(prior.low * prior.high)
    for column, (base, group) in enumerate(zip(layout.bases, layout.column_groups, strict=True)):
        if base == "sigma_c":
            centre[column] = sigma_c[layout.groups[group][0]]
        elif base in known:
            centre[column] = known[base]
    return centre


def per_evaluation(path: Path, damping: str) -> tuple[float, int]:
    """Seconds per evaluation of :data:`SETS` parameter sets near the truth, and the samples."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the held encoders, said and replaced
        experiments = bj.load_experiments([path], robot="husky", columns=lab.DRIVE_ALL_ROLES)
    robot = bj.load_profile("husky")
    likelihood = ResidualLikelihood(experiments, robot, damping=damping)
    prior = Prior.for_likelihood(likelihood, robot)
    centre = true_centre(likelihood, prior)
    theta = centre * np.exp(0.05 * np.random.default_rng(1).standard_normal((SETS, centre.size)))
    likelihood(theta)  # the cached patterns and Gram tensors
    repeats = 20
    start = time.perf_counter()
    for _ in range(repeats):
        likelihood(theta)
    return (time.perf_counter() - start) / repeats, sum(e.t.size for e in experiments)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workdir", type=Path, default=None)
    args = parser.parse_args()
    folder = work_folder(args.workdir, "bench_lab_logs_")
    here = Path(__file__).resolve().parents[1]
    baseline, steps = make_run(folder, 38.0), drive_run(folder, 10.0)
    columns = [
        word for role, name in lab.DRIVE_ALL_ROLES.items() for word in ("--column", role, name)
    ]
    print(f"sample of {baseline.name} and {steps.name} (files in {folder})")
    results: dict[str, list[dict]] = {"38 s thesis run": [], "10 min of steps": []}
    for _ in range(args.repeats):
        for label, (path, options) in zip(
            results, ((baseline, ()), (steps, ("--robot", "husky", *columns))), strict=True
        ):
            out = folder / f"{path.stem}-posterior.nc"
            result = timed_sample(here, [path], out, *options)
            results[label].append(result)
            print(describe_sample(label, result, width=16), flush=True)
    ratio = statistics.median(
        new["seconds"] / old["seconds"] for old, new in zip(*results.values(), strict=True)
    )
    print(f"median 10 min of steps / 38 s run: {ratio:.2f} wall (target <= 2)")
    print(f"ms per evaluation of {SETS} parameter sets:")
    costs = {}
    for minutes in (1.0, 2.5, 5.0, 10.0):
        path = drive_run(folder, minutes)
        constant, samples = per_evaluation(path, "constant")
        speed, _ = per_evaluation(path, "speed")
        costs[minutes] = (constant, speed)
        print(
            f"  {minutes:4g} min ({samples:6d} samples): constant damping "
            f"{1e3 * constant:7.1f} ms, --damping speed {1e3 * speed:7.1f} ms",
            flush=True,
        )
    flat = costs[10.0][0] / costs[1.0][0]
    grows = costs[10.0][1] / costs[1.0][1]
    print(f"10 min / 1 min: constant {flat:.2f} (flat: ~1), speed {grows:.2f} (the samples: 10)")


if __name__ == "__main__":
    main()
