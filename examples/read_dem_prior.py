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

The second half maps the file onto the parameters of three consumers
(docs/active_inference.md): SPM's ``spm_DEM`` and dempy (model per time bin),
k-cybulski/dem's ``DEMInput`` (seconds), and a Jackal Active Inference filter
(``sigma_w``, ``s_w``, ``sigma_z``, ``s_z``, ``mean_u``, ``mean_y``), and
writes them to ``consumers.json`` in ``--out``.
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
    from bayes_jackal.dem.export import export_prior, write_prior
    from bayes_jackal.inference.chains import SamplerSettings
    from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
    from bayes_jackal.inference.sampling import sample_posterior
    from bayes_jackal.io.simulate import simulate_experiment
    from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood

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


def gaussian_temporal_covariance(order: int, s: float) -> np.ndarray:
    """V[i, j] = (-1)^i rho^(i+j)(0) of rho(t) = exp(-t^2 / (4 s^2)), as spm_DEM_R builds it."""
    # rho^(2m)(0) = (-1)^m (2m - 1)!! / (2 s^2)^m; odd derivatives vanish.
    even = np.array([np.prod(np.arange(1, 2 * m, 2)) for m in range(order + 1)], float)
    rho = np.zeros(2 * order + 1)
    rho[::2] = (-1.0) ** np.arange(order + 1) * even / (2 * s**2) ** np.arange(order + 1)
    i, j = np.indices((order + 1, order + 1))
    return (-1.0) ** i * rho[i + j]


def consumer_parameters(prior: dict) -> dict[str, dict]:
    """The prior under the names SPM/dempy, k-cybulski/dem and a Jackal AI filter use."""
    coordinates, noise = prior["generalised_coordinates"], prior["noise"]
    channels = coordinates["channels"]
    log_precision, sensor = prior["log_precision"], prior["sensor_noise"]
    smoothness, point = prior["smoothness"], prior["operating_point"]["pooled"]
    damping = prior["damping"]
    process_bins = [coordinates["process_sd_bins"][c]["mean"] for c in channels]
    # SPM / dempy: the model per time bin (E.dt = 1): f = (A dt) x + (B dt) v,
    # state noise W + sum_c exp(gE_c) R_c with R_c = e_c e_c', sensor noise
    # V + sum_c exp(hE_c) Q_c; smoothness sw, sv in bins; P = (d_lat, d_long).
    spm = {
        "pE": damping["mean"],
        "pC": damping["covariance"],
        "gE": log_precision["process_bins"]["mean"],
        "gC": log_precision["process_bins"]["covariance"],
        "hE": None if sensor is None else log_precision["sensor"]["mean"],
        "hC": None if sensor is None else log_precision["sensor"]["covariance"],
        "sw": smoothness["shared_bins"],
        "sv": None if sensor is None else sensor["smoothness_bins"],
        "process_sd_per_bin": process_bins,
    }
    # k-cybulski/dem: time in seconds; one temporal precision for w and z.
    shared = smoothness["shared_seconds"]
    dem = {
        "dt": prior["dt"],
        "p": coordinates["order"],
        "m_x": len(channels),
        "omega_w": np.diag(
            [1 / noise["process_sd_continuous"][c]["mean"] ** 2 for c in channels]
        ).tolist(),
        "omega_z": None if sensor is None else np.diag(sensor["precision_per_channel"]).tolist(),
        "noise_autocorr_inv": None
        if shared is None
        else np.linalg.inv(gaussian_temporal_covariance(coordinates["order"], shared)).tolist(),
        "eta_theta": damping["mean"],
        "p_theta": np.linalg.inv(damping["covariance"]).tolist(),
    }
    # A Jackal Active Inference filter of one channel (yaw), in seconds.
    yaw = channels.index("yaw") if "yaw" in channels else 0
    jackal = {
        "channel": channels[yaw],
        "sigma_w": noise["process_sd_continuous"][channels[yaw]]["mean"],
        "s_w": None
        if shared is None
        else smoothness["channels"][channels[yaw]]["seconds"]["mean"],
        "sigma_z": None if sensor is None else sensor["sd"][channels[yaw]]["mean"],
        "s_z": None if sensor is None else sensor["smoothness_seconds"],
        "mean_u": point["u"],
        "mean_y": point["y"][prior["states"].index(channels[yaw])],
    }
    return {"spm_dempy": spm, "k_cybulski_dem": dem, "jackal_filter": jackal}


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

    consumers = consumer_parameters(prior)
    jackal = consumers["jackal_filter"]
    sw = consumers["spm_dempy"]["sw"]
    smooth = "none (the noise has no derivative)" if sw is None else f"{sw:.3f} bins"
    print(f"SPM/dempy per bin: sw = {smooth}, gE = {np.round(consumers['spm_dempy']['gE'], 2)}")
    print("Jackal filter:", {k: v for k, v in jackal.items() if k not in ("mean_u", "mean_y")})
    print(
        f"operating point: u0 = {np.round(jackal['mean_u'], 3)} rad/s, y0 = {jackal['mean_y']:.4f}"
    )
    if jackal["s_w"] is not None:
        # The filter's plug-in PI_w = inv(V(s_w)) / sigma_w^2 against the file's
        # block of that channel, the draws' mean precision: the gap is the uncertainty.
        n = len(channels)
        block = model["Pi_w"][channels.index(jackal["channel"]) :: n][
            :, channels.index(jackal["channel"]) :: n
        ]
        plug_in = np.linalg.inv(gaussian_temporal_covariance(order, jackal["s_w"]))
        plug_in /= jackal["sigma_w"] ** 2
        gap = np.linalg.norm(block - plug_in) / np.linalg.norm(block)
        print(f"Jackal PI_w (plug-in) against the draws' mean precision: {gap:.2%} apart")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "consumers.json").write_text(json.dumps(consumers, indent=1))

    draws = prior["draws"]
    ratio = np.asarray(draws["d_lat"]) / np.asarray(draws["d_long"])
    print(
        f"{draws['count']} draws; d_lat/d_long {ratio.mean():.3f} +- {ratio.std():.3f} "
        f"(thesis {11 / 3:.3f}); e-folding time of the yaw rate "
        f"{-1 / prior['model']['A'][2][2] * 1e3:.1f} ms"
    )


if __name__ == "__main__":
    main()
