"""Posterior files: arviz InferenceData built from a chain, saved, loaded, summarised.

Layout of a posterior (NetCDF through arviz, groups):

- ``posterior``: ``d_lat``, ``d_long`` [N s/m]; the noise parameters
  (``sigma_h`` or ``width`` [s], ``sigma_c``, ``sigma_n`` [channel units];
  white noise with the diagonal sensor term has no ``sigma_n``, its
  ``sigma_c`` is the total sd), scalars when one noise group, else along
  ``noise_group``; derived
  ``ratio`` = d_lat / d_long, ``Ad`` (diagonal, along ``state``) and ``Bd``
  (``state`` x ``wheel``). Walkers are arviz chains.
- ``sample_stats``: ``lp`` (log posterior in sampling coordinates) and
  ``log_likelihood_total`` (the log-likelihood of each draw).
- ``observed_data``: ``residual_<channel>_<i>``, the one-step residuals of
  experiment i on its steady window at the posterior median of the damping.
- ``constant_data``: the measured experiments, ``<field>_<i>``.
- ``attrs`` of ``posterior``: format, model settings, priors, robot,
  experiments (each with its provenance: source file, time base and
  repairs) and convergence diagnostics (dicts as JSON strings).
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from . import __version__
from ._files import write_hdf5
from .errors import DataError
from .experiment import REQUIRED, Experiment
from .kernels import get_family
from .likelihood import ResidualLikelihood, residual_autocovariance
from .physics import CHANNELS, channel_coefficients, discrete_matrices
from .residuals import channel_residuals
from .robot import RobotProfile, load_profile

with warnings.catch_warnings():
    # arviz 0.2x announces its 1.x refactor on import (docs/design.md §4 pins arviz<1).
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

__all__ = [
    "FORMAT",
    "INTERVAL_FIELDS",
    "az",
    "build_inference_data",
    "interval",
    "load_posterior",
    "model_autocovariance",
    "parameter_draws",
    "parameter_variables",
    "posterior_experiments",
    "posterior_likelihood",
    "posterior_robot",
    "posterior_truth",
    "save_posterior",
    "summarize",
    "thinned_draws",
    "thinned_indices",
]

FORMAT = "bayes_jackal.posterior/1"
#: The thesis' ridge ratio d_lat / d_long (ch. 5-2-2).
THESIS_RATIO = 11.0 / 3.0
#: Credible mass of the reported highest-density intervals (arviz's default).
HDI_PROB = 0.94
_SUMMARY_FIELDS = ("mean", "sd", "hdi_3%", "hdi_97%", "ess_bulk", "ess_tail", "r_hat")
#: The fields of a summary row that describe the posterior itself.
INTERVAL_FIELDS = _SUMMARY_FIELDS[:4]


def _noise_variables(likelihood: ResidualLikelihood, draws: np.ndarray) -> tuple[dict, dict]:
    """Noise parameters as variables: scalars for one group, else along noise_group."""
    bases = likelihood.noise_parameter_names
    per_group = len(bases)
    groups = len(likelihood.noise_groups)
    variables, dims = {}, {}
    for i, base in enumerate(bases):
        columns = draws[..., 2 + i :: per_group][..., :groups]
        if groups == 1:
            variables[base] = columns[..., 0]
        else:
            variables[base] = columns
            dims[base] = ["noise_group"]
    return variables, dims


def build_inference_data(
    likelihood: ResidualLikelihood,
    prior,
    chain: np.ndarray,
    lp: np.ndarray,
    diagnostics: dict,
) -> az.InferenceData:
    """InferenceData of a sampled chain.

    Parameters
    ----------
    likelihood : ResidualLikelihood
    prior : Prior
        The priors the chain was sampled under (sampling coordinates).
    chain : ndarray, shape (draws, walkers, P)
        Kept draws in sampling coordinates.
    lp : ndarray, shape (draws, walkers)
        Their log posterior.
    diagnostics : dict
        Convergence diagnostics and settings, stored as attributes.
    """
    draws = np.swapaxes(prior.to_natural(chain), 0, 1)  # (walkers, draws, P)
    d_lat, d_long = draws[..., 0], draws[..., 1]
    noise, dims = _noise_variables(likelihood, draws)
    dt = likelihood.experiments[0].dt
    Ad, Bd = discrete_matrices(likelihood.robot, d_lat, d_long, dt)
    posterior = {
        "d_lat": d_lat,
        "d_long": d_long,
        **noise,
        "ratio": d_lat / d_long,
        "Ad": np.diagonal(Ad, axis1=-2, axis2=-1),
        "Bd": Bd,
    }
    dims |= {"Ad": ["state"], "Bd": ["state", "wheel"]}
    labels = [likelihood.group_label(c, e).strip("[]") or c for c, e in likelihood.noise_groups]
    coords = {"noise_group": labels, "state": list(CHANNELS), "wheel": ["right", "left"]}
    observed, constant = _data_groups(
        likelihood, float(np.median(d_lat)), float(np.median(d_long))
    )
    log_likelihood = np.swapaxes(lp - prior.log_density(chain), 0, 1)
    # C order, as a saved and loaded file (or a worker's pickled result) has
    # it: numpy's sums depend on the layout in the last bits, and a resumed
    # run must summarise to the same numbers as an uninterrupted one.
    posterior = {name: np.ascontiguousarray(values) for name, values in posterior.items()}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        # Walkers are chains; a short run may keep fewer draws than walkers,
        # which arviz flags as a possible transposition. The layout is right.
        warnings.filterwarnings("ignore", message="More chains", category=UserWarning)
        idata = az.from_dict(
            posterior=posterior,
            sample_stats={
                "lp": np.ascontiguousarray(np.swapaxes(lp, 0, 1)),
                "log_likelihood_total": np.ascontiguousarray(log_likelihood),
            },
            observed_data=observed,
            constant_data=constant,
            coords=coords,
            dims=dims
            | {name: [f"step_{name.rsplit('_', 1)[1]}"] for name in observed}
            | {name: [f"time_{name.rsplit('_', 1)[1]}"] for name in constant},
        )
    idata.posterior.attrs.update(_attributes(likelihood, prior, diagnostics))
    return idata


def _data_groups(likelihood: ResidualLikelihood, d_lat: float, d_long: float):
    """Residuals at (d_lat, d_long) and the measured experiments, keyed by index."""
    observed, constant = {}, {}
    for i, experiment in enumerate(likelihood.experiments):
        for channel in likelihood.channels:
            observed[f"residual_{channel}_{i}"] = channel_residuals(
                experiment, likelihood.robot, d_lat, d_long, channel, likelihood.steady
            )
        for key in (*REQUIRED, "vx", "vy"):
            values = getattr(experiment, key)
            if values is not None:
                constant[f"{key}_{i}"] = np.asarray(values)
    return observed, constant


#: Robot-profile fields a posterior keeps, enough to rebuild its model.
_ROBOT_CONSTANTS = (
    "name",
    "mass",
    "yaw_inertia",
    "half_wheelbase",
    "half_track",
    "wheel_radius",
    "wheel_separation",
    "wheel_separation_multiplier",
    "conversion",
    "rate",
    "source",
)


def _attributes(likelihood: ResidualLikelihood, prior, diagnostics: dict) -> dict:
    robot = likelihood.robot
    experiments = [
        {
            "name": e.name,
            "source": e.source,
            "series": e.series,
            "steady_window": e.steady_window,
            "dt": e.dt,
            "truth": e.truth,
            "provenance": e.provenance,
        }
        for e in likelihood.experiments
    ]
    values = {
        "format": FORMAT,
        "bayes_jackal_version": __version__,
        "family": likelihood.family,
        "channels": list(likelihood.channels),
        "shared_noise": likelihood.shared_noise,
        "sensor": likelihood.sensor,
        "engine": likelihood.engine,
        "steady": likelihood.steady,
        "parameter_names": list(prior.names),
        "prior": {
            name: {"low": lo, "high": hi, "kind": "log-uniform" if log else "uniform"}
            for name, lo, hi, log in zip(
                prior.names,
                prior.low.tolist(),
                prior.high.tolist(),
                prior.log_uniform,
                strict=True,
            )
        },
        "robot": {key: getattr(robot, key) for key in _ROBOT_CONSTANTS},
        "experiments": experiments,
        **diagnostics,
    }
    return {key: _attribute_value(value) for key, value in values.items()}


def _attribute_value(value):
    """NetCDF attributes hold strings and numbers: dicts, lists and None as JSON, bools as 0/1."""
    if isinstance(value, (dict, list, tuple)) or value is None:
        return json.dumps(value)
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    return value


def parameter_variables(idata: az.InferenceData) -> list[str]:
    """The sampled parameters' variable names (d_lat, d_long, then the noise)."""
    skip = {"ratio", "Ad", "Bd"}
    return [name for name in idata.posterior.data_vars if name not in skip]


def parameter_draws(idata: az.InferenceData) -> tuple[np.ndarray, np.ndarray]:
    """The chain of a posterior in parameter-vector order, and its log posterior.

    Returns
    -------
    draws : ndarray, shape (draws, walkers, P)
        Parameters in natural units, ordered as the ``parameter_names``
        attribute (d_lat, d_long, then each noise group's parameters).
    lp : ndarray, shape (draws, walkers)
        Log posterior in sampling coordinates (z = log theta).
    """
    posterior = idata.posterior
    names = json.loads(posterior.attrs["parameter_names"])
    bases = [name.split("[")[0] for name in names]
    per_group = len(dict.fromkeys(bases[2:]))
    columns = []
    for j, base in enumerate(bases):
        variable = posterior[base]
        if "noise_group" in variable.dims:
            variable = variable.isel(noise_group=(j - 2) // per_group)
        columns.append(variable.transpose("draw", "chain").values)
    return np.stack(columns, axis=-1), idata.sample_stats["lp"].transpose("draw", "chain").values


def interval(row: dict) -> dict:
    """Mean, sd and 94 % HDI of a :func:`summarize` row."""
    return {key: row[key] for key in INTERVAL_FIELDS}


def posterior_truth(idata: az.InferenceData) -> dict | None:
    """The shared truth of simulated experiments, when every one has it."""
    truths = [e.get("truth") for e in json.loads(idata.posterior.attrs["experiments"])]
    return truths[0] if truths and all(truths) else None


def posterior_robot(idata: az.InferenceData) -> RobotProfile:
    """The robot profile a posterior was sampled with (its constants, validated)."""
    stored = json.loads(idata.posterior.attrs["robot"])
    return load_profile().replace(**{k: v for k, v in stored.items() if k in _ROBOT_CONSTANTS})


def posterior_experiments(idata: az.InferenceData) -> list[Experiment]:
    """The measured experiments a posterior was sampled from, with names and windows."""
    data = idata.constant_data
    experiments = []
    for i, meta in enumerate(json.loads(idata.posterior.attrs["experiments"])):
        arrays = {
            key: data[f"{key}_{i}"].values
            for key in (*REQUIRED, "vx", "vy")
            if f"{key}_{i}" in data
        }
        window = meta.get("steady_window")
        experiments.append(
            Experiment(
                **arrays,
                name=meta["name"],
                series=meta.get("series"),
                steady_window=None if window is None else tuple(window),
                truth=meta.get("truth"),
                provenance=meta.get("provenance") or {},
                source=meta.get("source") or "<memory>",
            )
        )
    return experiments


def posterior_likelihood(idata: az.InferenceData) -> ResidualLikelihood:
    """The likelihood a posterior was sampled with, rebuilt from its file."""
    attrs = idata.posterior.attrs
    return ResidualLikelihood(
        posterior_experiments(idata),
        posterior_robot(idata),
        family=str(attrs["family"]),
        channels=tuple(json.loads(attrs["channels"])),
        shared_noise=bool(attrs["shared_noise"]),
        sensor=str(attrs["sensor"]),
        engine=str(attrs["engine"]),
        steady=bool(attrs["steady"]),
    )


def thinned_indices(count: int, limit: int) -> np.ndarray:
    """Evenly spaced indices of at most ``limit`` out of ``count`` draws."""
    return np.unique(np.linspace(0, count - 1, min(count, limit)).astype(int))


def thinned_draws(idata: az.InferenceData, count: int) -> np.ndarray:
    """At most ``count`` evenly spaced posterior draws in natural units, shape (count, P)."""
    draws, _ = parameter_draws(idata)
    draws = draws.reshape(-1, draws.shape[-1])
    return draws[thinned_indices(len(draws), count)]


def model_autocovariance(
    likelihood: ResidualLikelihood, index: int, channel: str, theta: np.ndarray, n: int
) -> np.ndarray:
    """The model's autocovariance of one experiment's one-step residuals in one channel.

    Parameters
    ----------
    likelihood : ResidualLikelihood
        As rebuilt by :func:`posterior_likelihood`.
    index : int
        Experiment index.
    channel : {"yaw", "vx", "vy"}
    theta : ndarray, shape (B, P)
        Parameter vectors in natural units (``parameter_names`` order).
    n : int
        Number of lags.

    Returns
    -------
    ndarray, shape (B, n)
        Autocovariance at lags 0..n-1 [channel unit squared].
    """
    experiment = likelihood.experiments[index]
    key = (channel, "all" if likelihood.shared_noise else experiment.name)
    width, sigma_c, sigma_n = likelihood.noise_parameters(
        theta, likelihood.noise_groups.index(key)
    )
    alpha, _ = channel_coefficients(
        likelihood.robot, theta[:, 0], theta[:, 1], channel, experiment.dt
    )
    return residual_autocovariance(
        get_family(likelihood.family),
        width,
        sigma_c,
        sigma_n,
        alpha,
        experiment.dt,
        n,
        likelihood.sensor,
    )


def save_posterior(idata: az.InferenceData, path: str | Path) -> Path:
    """Write a posterior as NetCDF, atomically."""
    return write_hdf5(idata, path)


def load_posterior(path: str | Path) -> az.InferenceData:
    """Read a posterior written by :func:`save_posterior`.

    Raises
    ------
    DataError
        When the file is missing, unreadable, or not a bayes_jackal posterior.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError("no such file", source=str(path))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            idata = az.from_netcdf(str(path))
    except (OSError, ValueError, KeyError) as exc:
        raise DataError(f"not a readable posterior file ({exc})", source=str(path)) from None
    posterior = getattr(idata, "posterior", None)
    if posterior is None or posterior.attrs.get("format") != FORMAT:
        raise DataError(
            "not a bayes_jackal posterior (written by `bayes-jackal sample`)", source=str(path)
        )
    return idata


def summarize(idata: az.InferenceData) -> dict:
    """JSON-ready summary of a posterior (docs/design.md §6 ``sample --json``).

    One key per parameter and for the derived ``ratio``, each with arviz's
    ``mean``, ``sd``, ``hdi_3%``, ``hdi_97%``, ``ess_bulk``, ``ess_tail``,
    ``r_hat`` (walkers as chains: a secondary check only) and
    ``ess_autocorr``, the ESS implied by the integrated autocorrelation time
    (the primary one for emcee); plus ``corr_d_lat_d_long``,
    ``autocorr_time``, ``n_steps``, ``converged``, and under ``ratio`` the
    thesis' 3 2/3. ``warnings`` lists the model-criticism warnings (dicts
    with ``kind`` and ``message``) and ``criticism`` their numbers
    (:func:`bayes_jackal.criticism.criticise`).
    """
    from .criticism import criticise  # criticism builds on this module

    attrs = idata.posterior.attrs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        table = az.summary(
            idata,
            var_names=[*parameter_variables(idata), "ratio"],
            hdi_prob=HDI_PROB,
            round_to="none",
        )
    ess_autocorr = json.loads(attrs["ess_autocorr"])
    summary: dict = {}
    for label, row in table.iterrows():
        summary[label] = {key: float(row[key]) for key in _SUMMARY_FIELDS}
        if label in ess_autocorr:
            summary[label]["ess_autocorr"] = ess_autocorr[label]
    posterior = idata.posterior
    d_lat, d_long = posterior["d_lat"].values.ravel(), posterior["d_long"].values.ravel()
    summary["ratio"]["thesis"] = THESIS_RATIO
    summary["corr_d_lat_d_long"] = float(np.corrcoef(d_lat, d_long)[0, 1])
    summary["autocorr_time"] = json.loads(attrs["autocorr_time"])
    summary["n_steps"] = int(attrs["n_steps"])
    summary["converged"] = bool(attrs["converged"])
    summary["family"] = str(attrs["family"])
    summary["channels"] = json.loads(attrs["channels"])
    return summary | criticise(idata)
