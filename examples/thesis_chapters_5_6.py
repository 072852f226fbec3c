"""Reproduce the thesis step by step: eq. 6-7/6-8, table 6-1 and the ch. 5 grid.

Run: ``python examples/thesis_chapters_5_6.py [--quick] [--out DIR]``.

The thesis' own bags are not public, so the grid search runs on simulated
thesis-like experiments (10 x v1, 5 x v2) with known truth d_lat = 110,
d_long = 30 N s/m, the values the thesis found.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.io.simulate import simulate_series
from bayes_jackal.model.physics import (
    continuous_matrices,
    discrete_matrices,
    simulate,
    wheel_speeds,
)
from bayes_jackal.report.grid_plots import plot_grid
from bayes_jackal.thesis.gridsearch import damping_grid, grid_search


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 runs and a coarse grid")
    parser.add_argument("--out", default=".", help="folder for the figure")
    args = parser.parse_args()
    robot = load_profile()

    # Ch. 6: the continuous and discrete matrices at the thesis' optimum.
    A, B = continuous_matrices(robot, 110.0, 30.0)
    Ad, Bd = discrete_matrices(robot, 110.0, 30.0)
    np.set_printoptions(precision=4, suppress=True)
    print("A (eq. 6-7):\n", A, "\nB (eq. 6-8):\n", B)
    print("Ad (dt = 1/72 s; eq. 6-10 prints 0.9053, which is dt = 1/73):\n", Ad)
    print("Bd (eq. 6-11):\n", Bd)

    # Table 6-1: vx from rest under the v1 command, thesis input conversion.
    omega = wheel_speeds(robot, 0.3, np.deg2rad(22.5), conversion="thesis")
    inputs = np.tile(omega, (11, 1))
    for method in ("euler", "zoh"):
        row = simulate(robot, 110.0, 30.0, inputs, method=method)[:, 0]
        print(f"table 6-1 {method:5s}:", " ".join(f"{v:.4f}" for v in row))

    # Ch. 5: simulation-MSE grid over simulated experiments (eq. 5-1..5-3).
    counts = {"v1": 2, "v2": 1} if args.quick else {"v1": 10, "v2": 5}
    experiments = simulate_series(robot, 110.0, 30.0, counts, rng=2026)
    grid = damping_grid(10.0, 1000.0, 50.0 if args.quick else 10.0)
    result = grid_search(experiments, robot, grid, grid, method="simulation")
    for label, best in result.summary()["series"].items():
        print(f"series {label}: d_lat={best['d_lat']:g}, d_long={best['d_long']:g}")
    d_lat, d_long, mse = result.argmin()
    print(
        f"total (eq. 5-3): d_lat={d_lat:g}, d_long={d_long:g}, "
        f"ratio {d_lat / d_long:.3f}, MSE {mse:.4g}"
    )
    fig, _ = plot_grid(result)
    path = Path(args.out) / "thesis_fig_5_4.png"
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
