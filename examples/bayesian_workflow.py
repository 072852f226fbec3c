"""The Bayesian workflow on your own bag: ingest, posterior, evidence, prior, report.

Run: ``python examples/bayesian_workflow.py [--bag YOUR.bag] [--quick] [--out DIR]``.

Without ``--bag`` it uses one of the demo's shipped bags (SIMULATED, truth
d_lat = 110, d_long = 30 N s/m). The same steps from the command line:

    bayes-jackal ingest YOUR.bag --out runs
    bayes-jackal compare runs/YOUR.nc --families white,gaussian --out posteriors
    bayes-jackal export-prior posteriors/YOUR.gaussian.nc --out prior.json
    bayes-jackal report posteriors --out report.html

``--quick`` caps the chains far below convergence (for the tests): the
numbers are then preliminary, and the report says so in red.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

from bayes_jackal import load_profile
from bayes_jackal.bags import read_bag
from bayes_jackal.comparison import compare_families
from bayes_jackal.demo import demo_folder
from bayes_jackal.experiment import write_netcdf
from bayes_jackal.export import export_prior, write_prior
from bayes_jackal.inference import ConvergenceWarning, SamplerSettings
from bayes_jackal.posterior import save_posterior, summarize
from bayes_jackal.report import write_report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bag", help="a ROS1 .bag or ROS2 .mcap/.db3 bag of steady circles")
    parser.add_argument("--robot", help="robot profile TOML (default: the Jackal)")
    parser.add_argument("--quick", action="store_true", help="short chains (not converged)")
    parser.add_argument("--out", default="workflow", help="output folder")
    args = parser.parse_args()
    out = Path(args.out)
    robot = load_profile(args.robot)
    bag = Path(args.bag) if args.bag else demo_folder() / "v2_01.bag"

    # 1. The bag becomes an experiment: IMU yaw rate, wheel speeds, mocap vx, vy.
    experiment = read_bag(bag, robot)
    write_netcdf(experiment, out / f"{experiment.name}.nc")
    start, stop = experiment.steady_window
    print(f"{bag.name}: {len(experiment.t)} samples, steady window {start:.2f}-{stop:.2f} s")

    # 2. Posterior and evidence of white and Gaussian-coloured noise.
    settings = SamplerSettings(max_steps=400, design_points=256) if args.quick else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore" if args.quick else "default", ConvergenceWarning)
        comparison = compare_families([experiment], robot, ("white", "gaussian"), settings, 1)
    print(comparison.verdict()[1])
    paths = {
        family: save_posterior(idata, out / f"{experiment.name}.{family}.nc")
        for family, idata in comparison.posteriors.items()
    }
    summary = summarize(comparison.posteriors["gaussian"])
    ratio = summary["ratio"]
    # One sigma_h per channel (sigma_h[yaw], ...) when the bag has vx and vy too.
    widths = ", ".join(f"{k} {v['mean']:.4f}" for k, v in summary.items() if k[:7] == "sigma_h")
    print(
        f"gaussian on {', '.join(summary['channels'])}: {widths} s, d_lat/d_long "
        f"[{ratio['hdi_3%']:.3f}, {ratio['hdi_97%']:.3f}] (94 % HDI), converged "
        f"{summary['converged']}"
    )

    # 3. The prior for an Active Inference (DEM) filter, and the report.
    prior = export_prior(comparison.posteriors["gaussian"], order=2, source=str(paths["gaussian"]))
    print(f"wrote {write_prior(prior, out / 'prior.json')}")
    print(f"wrote {write_report(list(paths.values()), out / 'report.html', formats=('png',))}")


if __name__ == "__main__":
    main()
