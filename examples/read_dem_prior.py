"""Read an exported Active Inference prior as a DEM user would, with json and numpy only.

Run: ``python examples/read_dem_prior.py [--prior prior.json] [--quick] [--out DIR]``.

Without ``--prior`` the script first makes one: it simulates a thesis-like
run, samples its posterior and exports the prior (``bayes-jackal sample`` and
``bayes-jackal export-prior`` do the same from the command line). The
reading half uses nothing from bayes_jackal: the file is the interface.

A DEM filter (Friston 2008; Meera & Wisse 2020 for a robot) works on
generalised coordinates x~ = (x, x', ..., x^(P)). With the derivative
operator D (a shift between the blocks), the linear model
dx/dt = A x + B u + w becomes D x~ = (I kron A) x~ + (I kron B) u~ + w~,
and the prior precision of w~ is the file's ``precision`` matrix.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def make_prior(out: Path, quick: bool) -> Path:
    """Simulate one run, sample its posterior and export the prior."""
    import warnings

    from bayes_jackal import load_profile
    from bayes_jackal.export import export_prior, write_prior
    from bayes_jackal.inference import ConvergenceWarning, SamplerSettings, sample_posterior
    from bayes_jackal.likelihood import ResidualLikelihood
    from bayes_jackal.simulate import simulate_experiment

    robot = load_profile()
    run = simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    likelihood = ResidualLikelihood([run], robot, channels=("yaw", "vx"))
    settings = SamplerSettings(max_steps=300, design_points=256) if quick else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore" if quick else "default", ConvergenceWarning)
        posterior = sample_posterior(likelihood, settings, seed=1)
    return write_prior(export_prior(posterior, order=2), out / "prior.json")


def generalised_model(prior: dict) -> dict[str, np.ndarray]:
    """The DEM matrices of the exported model, on the channels that were fitted."""
    states = prior["states"]
    coordinates = prior["generalised_coordinates"]
    channels = coordinates["channels"]
    index = [states.index(c) for c in channels]
    A = np.asarray(prior["model"]["A"])[np.ix_(index, index)]
    B = np.asarray(prior["model"]["B"])[index]
    size = coordinates["order"] + 1
    # D shifts each derivative block up by one: (x, x', x'') -> (x', x'', 0).
    D = np.kron(np.eye(size, k=1), np.eye(len(channels)))
    return {
        "D": D,
        "A": np.kron(np.eye(size), A),
        "B": np.kron(np.eye(size), B),
        "Pi_w": np.asarray(coordinates["precision"]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prior", help="a prior.json from bayes-jackal export-prior")
    parser.add_argument("--quick", action="store_true", help="a short chain for the demo prior")
    parser.add_argument("--out", default=".", help="folder for the made prior")
    args = parser.parse_args()
    path = Path(args.prior) if args.prior else make_prior(Path(args.out), args.quick)

    prior = json.loads(path.read_text())
    if prior["format"] != "bayes_jackal.prior/1":
        raise SystemExit(f"{path}: not a bayes_jackal prior ({prior['format']!r})")
    if not prior["converged"]:
        print(f"note: {path} comes from a chain that did not converge")
    model = generalised_model(prior)
    coordinates = prior["generalised_coordinates"]
    channels, order = coordinates["channels"], coordinates["order"]
    np.set_printoptions(precision=4, suppress=False, linewidth=110)
    print(f"{prior['noise']['family']} noise on {channels}, order {order}, dt {prior['dt']:.5f} s")
    print("d_lat, d_long mean [N s/m]:", np.round(prior["damping"]["mean"], 2))
    print("their covariance:\n", np.asarray(prior["damping"]["covariance"]))
    print(
        "shift D, generalised A~ and Pi_w are",
        model["D"].shape,
        model["A"].shape,
        model["Pi_w"].shape,
    )
    smallest = np.linalg.eigvalsh(model["Pi_w"]).min()
    if not smallest > 0:
        raise SystemExit(f"{path}: the precision is not positive definite ({smallest:.3g})")
    print(f"Pi_w is positive definite: smallest eigenvalue {smallest:.4g}")

    # The closed form at the posterior-mean widths, for the Gaussian family:
    # V = [[1, 0, -k], [0, k, 0], [-k, 0, 3 k^2]] with k = 1 / (2 sigma_h^2).
    # The file's Pi_w averages over draws; the gap is what the uncertainty adds.
    if prior["noise"]["family"] == "gaussian" and order == 2:
        parameters = prior["noise"]["parameters"]
        blocks = np.zeros_like(model["Pi_w"])
        for c, channel in enumerate(channels):
            label = "sigma_h" if len(channels) == 1 else f"sigma_h[{channel}]"
            k = 1 / (2 * parameters[label]["mean"] ** 2)
            V = np.array([[1, 0, -k], [0, k, 0], [-k, 0, 3 * k**2]])
            unit = np.zeros((len(channels), len(channels)))
            unit[c, c] = 1 / prior["noise"]["process_sd_continuous"][channel]["mean"] ** 2
            blocks += np.kron(np.linalg.inv(V), unit)
        gap = np.linalg.norm(model["Pi_w"] - blocks) / np.linalg.norm(blocks)
        print(f"Pi_w against the closed form at the posterior means: {gap:.2%} apart")

    draws = prior["draws"]
    ratio = np.asarray(draws["d_lat"]) / np.asarray(draws["d_long"])
    print(
        f"{draws['count']} draws; d_lat/d_long {ratio.mean():.3f} +- {ratio.std():.3f} "
        f"(thesis {11 / 3:.3f}); e-folding time of the yaw rate "
        f"{-1 / prior['model']['A'][2][2] * 1e3:.1f} ms"
    )


if __name__ == "__main__":
    main()
