"""Benchmark: a campaign of many runs x families, serial, on local processes, on Dask (issue 12).

Run by hand (needs the extra ``cluster``: ``pip install -e '.[cluster]'``)::

    python benchmarks/bench_campaign.py                      # 20 runs x 5 families
    python benchmarks/bench_campaign.py --runs 2 --families white,exponential --max-steps 200

Each run is a simulated thesis-like v1 experiment (38 s at 72 Hz, yaw
channel, its own noise seed); each is compared over the families, the
whole campaign submitted at once, one task per (run, family)
(:func:`bayes_jackal.inference.compare_groups`), so that every worker
stays busy until the last tasks. Three ways, in this order, on the same
campaign and seed:

- serial: every task in this process, one after the other (the baseline;
  with ``--serial-runs K`` on the first K runs only, its runs per minute
  measured on those: the full serial campaign takes as long as the other
  two together);
- local processes: one per core (``compare``'s default);
- a local Dask cluster of ``--workers`` worker processes, one thread each,
  on 127.0.0.1 (what ``--scheduler`` reaches on a real cluster).

Printed: seconds and runs per minute of each, the ratio of runs per minute
against serial measured in the same process, whether the log evidences
agree exactly with serial's (on the runs serial did), and peak resident
memory (``resource.getrusage``, the largest of this process and of its
finished children; the children's figure covers the workers once they
exit).
"""

from __future__ import annotations

import argparse
import os
import resource
import time
import warnings

from bayes_jackal import load_profile
from bayes_jackal.inference import FitOptions
from bayes_jackal.inference.chains import SamplerSettings
from bayes_jackal.inference.comparison import compare_groups
from bayes_jackal.inference.executors import (
    DaskExecutor,
    Executor,
    ProcessExecutor,
    SerialExecutor,
)
from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
from bayes_jackal.io.simulate import simulate_experiment
from bayes_jackal.likelihood import LikelihoodOptions
from bayes_jackal.model.kernels import FAMILIES

ROBOT = load_profile()


def campaign(runs, families, settings, seed, executor: Executor) -> tuple[float, dict]:
    """Seconds to compare every run, and each run's log evidences by family [nats]."""
    evidences = {}
    start = time.perf_counter()
    with executor, warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # short caps do not converge
        for name, comparison in compare_groups(
            {run.name: [run] for run in runs},
            FitOptions(
                robot=ROBOT,
                likelihood_options=LikelihoodOptions(channels=("yaw",)),
                settings=settings,
                seed=seed,
            ),
            families=families,
            executor=executor,
        ):
            evidences[name] = {f: e.log_evidence for f, e in comparison.evidence.items()}
    return time.perf_counter() - start, evidences


def peak_memory() -> str:
    """Peak resident memory of this process and of its largest finished child [MB]."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return f"peak RSS {own:.0f} MB here, {children:.0f} MB largest finished child"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="experiments (20)")
    parser.add_argument(
        "--families",
        default=",".join(FAMILIES),
        help=f"comma-separated families ({','.join(FAMILIES)})",
    )
    parser.add_argument("--max-steps", type=int, default=20_000, help="step cap (20000)")
    parser.add_argument("--workers", type=int, default=2, help="Dask workers (2)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--serial-runs", type=int, default=0, help="serial baseline on the first K runs (all)"
    )
    args = parser.parse_args()
    from distributed import LocalCluster  # the extra `cluster`

    families = tuple(args.families.split(","))
    settings = SamplerSettings(max_steps=args.max_steps, progress=False)
    runs = [
        simulate_experiment(
            ROBOT, 110.0, 30.0, "v1", rng=[args.seed, index], name=f"v1_{index:02d}"
        )
        for index in range(args.runs)
    ]
    print(
        f"campaign: {len(runs)} runs x {len(families)} families ({', '.join(families)}), "
        f"{len(runs[0].t)} samples each, yaw, max {args.max_steps} steps, seed {args.seed}"
    )
    serial_runs = runs[: args.serial_runs or len(runs)]
    serial, reference = campaign(serial_runs, families, settings, args.seed, SerialExecutor())
    processes = os.cpu_count() or 1
    rows = [(f"serial, this process ({len(serial_runs)} runs)", serial, reference)]
    local = campaign(runs, families, settings, args.seed, ProcessExecutor(processes))
    rows.append((f"local processes ({processes})", *local))
    with LocalCluster(
        n_workers=args.workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",  # None would still listen on 0.0.0.0:8787
    ) as cluster:
        clustered = campaign(runs, families, settings, args.seed, DaskExecutor(cluster))
    rows.append((f"Dask LocalCluster ({args.workers} workers)", *clustered))
    serial_rate = 60 * len(serial_runs) / serial
    for label, seconds, evidences in rows:
        rate = 60 * len(evidences) / seconds
        same = all(evidences[name] == reference[name] for name in reference)
        print(
            f"{label:40s} {seconds:8.1f} s  {rate:7.2f} runs/min  "
            f"{rate / serial_rate:5.2f}x serial  same log Z as serial: {same}"
        )
    print(peak_memory())


if __name__ == "__main__":
    main()
