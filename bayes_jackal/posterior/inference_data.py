"""Posterior files: built from a chain, saved, loaded, read (docs/design.md §7).

A posterior is an arviz InferenceData (NetCDF on disk) with the groups
``posterior`` (the parameters, derived ``ratio``, ``Ad``, ``Bd``),
``sample_stats`` (``lp``, ``log_likelihood_total``), ``observed_data``
(the residuals at the posterior median) and ``constant_data`` (the measured
experiments). Its metadata (attributes of ``posterior``) and the names in
the data groups are owned by :mod:`bayes_jackal.posterior.file_format` (re-exported):
:func:`posterior_metadata` gives them typed (the robot, priors, parameter
layout, experiments, noise groups, convergence, and the results stored
later by :func:`store_comparison`, :func:`store_criticism` and
:func:`store_reweighting`). No other module parses them.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .._runtime.arviz_quiet import az
from .._runtime.chunks import thinned_indices
from .._runtime.defaults import CHANNELS
from .._runtime.errors import DataError
from .._runtime.files import require_file, write_hdf5
from ..io.experiment import Experiment
from ..likelihood.measurements import MEASUREMENT_MODELS
from ..likelihood.residual_likelihood import ResidualLikelihood
from ..model.kernels import get_family
from ..model.parameters import ParameterLayout
from ..model.physics import discrete_matrices
from ..model.robot import RobotProfile
from .file_format import (
    experiment_arrays,
    experiment_data,
    file_attributes,
    observed_data,
    posterior_layout,
    posterior_metadata,
)
from .records import PosteriorMetadata

__all__ = [
    "build_inference_data",
    "load_posterior",
    "model_autocovariance",
    "noise_dimension",
    "parameter_draws",
    "parameter_variables",
    "posterior_experiments",
    "posterior_likelihood",
    "posterior_robot",
    "posterior_truth",
    "save_posterior",
    "thinned_draws",
]


def _noise_variables(layout: ParameterLayout, draws: np.ndarray) -> tuple[dict, dict, dict]:
    """Noise parameters as variables, with their dims and coordinates.

    A parameter one column serves (one group, or a shared width) is a
    scalar; one that every group has is indexed by ``noise_group``; one that
    some groups have (``sigma_n`` of the rate channels, ``sigma_p`` of the
    pose channels) by a dimension of its own, ``<base>_group``
    (:func:`noise_dimension`).
    """
    variables, dims, coords = {}, {}, {}
    for base in layout.noise_bases:
        dimension, groups = noise_dimension(layout, base)
        columns = list(dict.fromkeys(layout.column(base, g) for g in groups))
        if dimension is None:
            variables[base] = draws[..., columns[0]]
            continue
        variables[base] = draws[..., columns]
        dims[base] = [dimension]
        coords[dimension] = [layout.labels[g] for g in groups]
    return variables, dims, coords


def noise_dimension(layout: ParameterLayout, base: str) -> tuple[str | None, tuple[int, ...]]:
    """The posterior file's dimension of noise parameter ``base``, and the groups along it.

    None for a scalar (one column serves every group that has it: a single
    group, or a shared width); ``noise_group`` where every group has it;
    ``<base>_group`` where only some do (``sigma_p_group`` for the pose
    channels' ``sigma_p``).

    Examples
    --------
    >>> from bayes_jackal.model import ParameterLayout
    >>> from bayes_jackal.posterior import noise_dimension
    >>> layout = ParameterLayout(
    ...     "gaussian", "ma1", ("yaw", "vx", "vy"), ("v1",), True, pose_channels=("vx", "vy")
    ... )
    >>> noise_dimension(layout, "sigma_h"), noise_dimension(layout, "sigma_p")
    (('noise_group', (0, 1, 2)), ('sigma_p_group', (1, 2)))
    """
    groups = layout.groups_of(base)
    names = layout.names_of(base)
    if names == (base,):
        return None, groups
    every = len(groups) == len(layout.groups)
    return ("noise_group" if every else f"{base}_group"), groups


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

    Examples
    --------
    A posterior from draws made elsewhere, here 20 draws of 8 walkers scattered
    about the truth in the sampling coordinates (log theta), with their log
    posterior:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.posterior import build_inference_data
    >>> from bayes_jackal.likelihood import LogPosterior, Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="white", channels=("yaw",))
    >>> prior = Prior.for_likelihood(likelihood, robot)
    >>> rng = np.random.default_rng(1)
    >>> chain = np.log([110.0, 30.0, 0.01, 0.005]) + 0.01 * rng.normal(size=(20, 8, 4))
    >>> lp = LogPosterior(likelihood, prior)(chain.reshape(-1, 4)).reshape(20, 8)
    >>> diagnostics = {"converged": False, "n_steps": 20, "autocorr_time": {}, "ess_autocorr": {}}
    >>> posterior = build_inference_data(likelihood, prior, chain, lp, diagnostics)
    >>> dict(posterior.posterior.sizes)
    {'chain': 8, 'draw': 20, 'state': 3, 'wheel': 2}
    >>> round(float(posterior.posterior["ratio"].mean()), 1)
    3.7
    """
    draws = np.swapaxes(prior.to_natural(chain), 0, 1)  # (walkers, draws, P)
    d_lat, d_long = draws[..., 0], draws[..., 1]
    noise, dims, noise_coords = _noise_variables(likelihood.layout, draws)
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
    coords = noise_coords | {"state": list(CHANNELS), "wheel": ["right", "left"]}
    observed, observed_dims = observed_data(
        likelihood, float(np.median(d_lat)), float(np.median(d_long))
    )
    constant, constant_dims = experiment_data(likelihood.experiments)
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
            dims=dims | observed_dims | constant_dims,
        )
    idata.posterior.attrs.update(file_attributes(likelihood, prior, diagnostics))
    return idata


def parameter_variables(idata: az.InferenceData) -> list[str]:
    """The sampled parameters' variable names (d_lat, d_long, then the noise).

    Examples
    --------
    The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import parameter_variables
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> parameter_variables(posterior)
    ['d_lat', 'd_long', 'sigma_c', 'sigma_n']
    """
    skip = {"ratio", "Ad", "Bd"}
    return [name for name in idata.posterior.data_vars if name not in skip]


def parameter_draws(idata: az.InferenceData) -> tuple[np.ndarray, np.ndarray]:
    """The chain of a posterior in parameter-vector order, and its log posterior.

    Returns
    -------
    draws : ndarray, shape (draws, walkers, P)
        Parameters in natural units, ordered as the layout's names
        (:func:`posterior_layout`: d_lat, d_long, then each noise group's).
    lp : ndarray, shape (draws, walkers)
        Log posterior in sampling coordinates (z = log theta).

    Examples
    --------
    The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import parameter_draws
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> draws, lp = parameter_draws(posterior)
    >>> draws.shape, lp.shape  # (draws, walkers, P): d_lat, d_long, sigma_c, sigma_n
    ((17, 32, 4), (17, 32))
    """
    posterior = idata.posterior
    layout = posterior_layout(idata)
    columns = []
    for base, group in zip(layout.bases, layout.column_groups, strict=True):
        variable = posterior[base]
        dimension, groups = noise_dimension(layout, base)
        if dimension is not None:
            variable = variable.isel({dimension: groups.index(group)})
        columns.append(variable.transpose("draw", "chain").values)
    return np.stack(columns, axis=-1), idata.sample_stats["lp"].transpose("draw", "chain").values


def posterior_truth(idata: az.InferenceData) -> dict | None:
    """The shared truth of simulated experiments, when every one has it.

    Examples
    --------
    The simulator's truth, kept in the posterior of a simulated run. The
    20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import posterior_truth
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> truth = posterior_truth(posterior)
    >>> truth["d_lat"], truth["d_long"], truth["family"], truth["sigma_h"]
    (110.0, 30.0, 'gaussian', 0.047)
    """
    return posterior_metadata(idata).truth


def posterior_robot(idata: az.InferenceData) -> RobotProfile:
    """The robot profile a posterior was sampled with (:attr:`PosteriorMetadata.robot`).

    Rebuilt from the file alone. Files written before the whole profile was
    stored (bayes_jackal 0.1.0 before docs/design.md §7) keep the body
    constants only; their priors, topics and wheel joints are then the
    installed default profile's, which do not enter the model.

    Examples
    --------
    The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import posterior_robot
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> robot = posterior_robot(posterior)
    >>> robot.name, robot.rate, robot == bj.load_profile()
    ('jackal', 72.0, True)
    """
    return posterior_metadata(idata).robot


def posterior_experiments(idata: az.InferenceData) -> list[Experiment]:
    """The measured experiments a posterior was sampled from, with names and windows.

    Examples
    --------
    The 20-step chain is short on purpose:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import posterior_experiments
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> [stored] = posterior_experiments(posterior)
    >>> stored.name, stored.channels, stored.steady_window
    ('v1', ('vx', 'vy', 'yaw'), (3.0, 36.0))
    >>> np.array_equal(stored.yaw_rate, run.yaw_rate)
    True
    """
    experiments = []
    for i, record in enumerate(posterior_metadata(idata).experiments):
        experiments.append(
            Experiment(
                **experiment_arrays(idata, i),
                name=record.name,
                series=record.series,
                steady_window=record.steady_window,
                truth=record.truth,
                provenance=record.provenance,
                source=record.source or "<memory>",
            )
        )
    return experiments


def posterior_likelihood(idata: az.InferenceData) -> ResidualLikelihood:
    """The likelihood a posterior was sampled with, rebuilt from its file.

    It prepares the likelihood's data (lagged sums, spectra): what needs
    only the parameters reads :func:`posterior_metadata` instead.

    Examples
    --------
    The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import posterior_likelihood
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> likelihood = posterior_likelihood(posterior)
    >>> likelihood.family, likelihood.channels, likelihood.engine
    ('white', ('yaw',), 'fast')
    """
    metadata = posterior_metadata(idata)
    layout = metadata.layout
    return ResidualLikelihood(
        posterior_experiments(idata),
        metadata.robot,
        family=layout.family,
        channels=layout.channels,
        shared_noise=layout.shared_noise,
        sensor=layout.sensor,
        engine=metadata.engine,
        steady=metadata.steady,
        shared_width=layout.shared_width,
    )


def thinned_draws(idata: az.InferenceData, count: int) -> np.ndarray:
    """At most ``count`` evenly spaced posterior draws in natural units, shape (count, P).

    Examples
    --------
    The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import thinned_draws
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> thinned_draws(posterior, 10).shape  # 10 of the kept draws, 4 parameters
    (10, 4)
    """
    draws, _ = parameter_draws(idata)
    draws = draws.reshape(-1, draws.shape[-1])
    return draws[thinned_indices(len(draws), count)]


def model_autocovariance(
    metadata: PosteriorMetadata,
    index: int,
    channel: str,
    theta: np.ndarray,
    n: int,
) -> np.ndarray:
    """The model's autocovariance of one experiment's one-step residuals in one channel.

    Parameters
    ----------
    metadata : PosteriorMetadata
        Of the posterior (:func:`posterior_metadata`).
    index : int
        Experiment index.
    channel : {"yaw", "vx", "vy"}
    theta : ndarray, shape (B, P)
        Parameter vectors in natural units (the layout's order).
    n : int
        Number of lags.

    Returns
    -------
    ndarray, shape (B, n)
        Autocovariance at lags 0..n-1 [channel unit squared].

    Examples
    --------
    The model's autocovariance of the yaw-rate residuals at 5 posterior draws.
    White process noise plus the MA(1) footprint of the sensor noise reach lag
    1, no further. The 20-step chain is short on purpose:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import model_autocovariance, posterior_metadata, thinned_draws
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> theta = thinned_draws(posterior, 5)
    >>> acov = model_autocovariance(posterior_metadata(posterior), 0, "yaw", theta, 3)
    >>> acov.shape, bool(np.all(acov[:, 1] < 0)), np.allclose(acov[:, 2], 0)
    ((5, 3), True, True)
    """
    record = metadata.experiments[index]
    layout = metadata.layout
    noise = layout.noise_parameters(theta, layout.group(channel, record.name))
    pose = channel in layout.pose_channels
    measurement = MEASUREMENT_MODELS["pose" if pose else "rate"]
    _, alpha = measurement.coefficients(
        metadata.robot, theta[:, 0], theta[:, 1], channel, record.dt
    )
    return measurement.autocovariance(
        get_family(layout.family),
        *noise,
        alpha,
        record.dt,
        n,
        sensor=layout.sensor,
        samples=record.pose_samples,
    )


def save_posterior(idata: az.InferenceData, path: str | Path) -> Path:
    """Write a posterior as NetCDF, atomically.

    Examples
    --------
    A posterior saved and read back. The 20-step chain is short on purpose:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = bj.save_posterior(posterior, Path(folder) / "posterior.nc")
    ...     loaded = bj.load_posterior(path)
    >>> path.name, loaded.posterior.equals(posterior.posterior)
    ('posterior.nc', True)
    """
    return write_hdf5(idata, path)


def load_posterior(path: str | Path) -> az.InferenceData:
    """Read a posterior written by :func:`save_posterior`, its attributes checked.

    Raises
    ------
    DataError
        When the file is missing, unreadable, not a bayes_jackal posterior,
        of a format this version does not read (naming it), or its
        attributes are malformed; the message names the file.

    Examples
    --------
    A posterior saved and read back; a file that is not one is refused. The
    20-step chain is short on purpose:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     loaded = bj.load_posterior(bj.save_posterior(posterior, Path(folder) / "p.nc"))
    ...     try:
    ...         bj.load_posterior(Path(folder) / "missing.nc")
    ...     except bj.DataError as error:
    ...         print(str(error).endswith("missing.nc: no such file"))
    True
    >>> bj.summarize(loaded)["family"]
    'white'
    """
    path = Path(path)
    require_file(path, str(path))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            idata = az.from_netcdf(str(path))
    except (OSError, ValueError, KeyError) as exc:
        raise DataError(f"not a readable posterior file ({exc})", source=str(path)) from None
    if getattr(idata, "posterior", None) is None:
        raise DataError(
            "not a bayes_jackal posterior (no posterior group; posteriors are written by "
            "`bayes-jackal sample` and `compare --out`)",
            source=str(path),
        )
    try:
        posterior_metadata(idata)
    except DataError as exc:
        raise DataError(str(exc), source=str(path)) from None
    return idata
