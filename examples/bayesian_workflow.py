"""The whole Bayesian workflow with ``import bayes_jackal as bj`` alone.

A log in; a posterior, its Active Inference prior, a report and the noise
families' evidence out.

Run: ``python examples/bayesian_workflow.py [--log YOUR.csv] [--quick] [--out DIR]``.

``--log`` takes any log the package reads: a CSV, MATLAB ``.mat`` or
experiment ``.nc`` file, or a ROS bag (``.bag``, ``.mcap``, ``.db3``).
Without it, the script first writes a CSV of a SIMULATED run (truth d_lat =
110, d_long = 30 N s/m, Gaussian process noise of sigma_h = 0.047 s) and
reads that. The same steps from the command line:

    bayes-jackal sample YOUR.csv --out posterior.nc --seed 1
    bayes-jackal export-prior posterior.nc --out prior.json
    bayes-jackal report posterior.nc --out report.html
    bayes-jackal compare YOUR.csv --families white,gaussian --seed 1

``--quick`` (for the tests) samples the yaw channel alone and caps every
chain at 200 steps, far below convergence: the numbers are then
preliminary, and the report says so in red. Real use takes the defaults
(every channel the log measures, up to 20000 steps), which take minutes.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import bayes_jackal as bj


def simulated_csv(robot: bj.RobotProfile, folder: Path) -> Path:
    """A CSV of one simulated thesis-like run (series v1: 0.3 m/s, 22.5 deg/s)."""
    run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1, name="v1_01")
    return bj.write_csv(run, folder / "v1_01.csv")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--log", help="your log: .csv, .mat, .nc, or a ROS .bag/.mcap/.db3 bag")
    parser.add_argument("--robot", help="robot profile TOML (default: the Jackal)")
    parser.add_argument("--quick", action="store_true", help="yaw only, short chains")
    parser.add_argument("--out", default="workflow", help="output folder")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    robot = bj.load_profile(args.robot)
    log = Path(args.log) if args.log else simulated_csv(robot, out)

    # 1. The log as an experiment.
    [run] = bj.load_experiments([log], robot=robot)
    print(f"{log.name}: {len(run.t)} samples at {1 / run.dt:.0f} Hz, channels {run.channels}")

    # The options shared by sample and compare: the defaults, or a quick look.
    quick = {"channels": ["yaw"], "max_steps": 200} if args.quick else {}
    options = {"seed": 1, "robot": robot, "progress": not args.quick, **quick}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore" if args.quick else "default", bj.ConvergenceWarning)

        # 2. The posterior of the damping and the Gaussian-filtered noise.
        posterior = bj.sample([run], family="gaussian", **options)
        summary = bj.summarize(posterior)
        print(
            f"d_lat {summary['d_lat']['mean']:.0f}, d_long {summary['d_long']['mean']:.0f} "
            f"N s/m, d_lat/d_long [{summary['ratio']['hdi_3%']:.2f}, "
            f"{summary['ratio']['hdi_97%']:.2f}] (94 % HDI), converged {summary['converged']}"
        )

        # 3. Its prior for an Active Inference (DEM) filter, embedding order 2.
        print(f"wrote {bj.write_prior(bj.export_prior(posterior), out / 'prior.json')}")

        # 4. The report of the posterior in memory (figures beside it).
        report = bj.write_report(posterior, out / "report.html", formats=("png",))
        print(f"wrote {report}")

        # 5. Is the noise coloured? White against Gaussian, by evidence.
        comparison = bj.compare([run], families=("white", "gaussian"), **options)
    print(f"best: {comparison.best}; {comparison.verdict()[1]}")


if __name__ == "__main__":
    main()
