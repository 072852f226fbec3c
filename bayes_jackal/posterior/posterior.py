"""Posterior files: built from a chain, saved, loaded, read (docs/design.md §7).

A posterior is an arviz InferenceData (NetCDF on disk) with the groups
``posterior`` (the parameters, derived ``ratio``, ``Ad``, ``Bd``),
``sample_stats`` (``lp``, ``log_likelihood_total``), ``observed_data``
(the residuals at the posterior median) and ``constant_data`` (the measured
experiments). Its metadata (attributes of ``posterior``) and the names in
the data groups are owned by :mod:`bayes_jackal.posterior.file_format`;
:class:`Posterior` gives them typed (the robot, priors, parameter
layout, experiments, noise groups, convergence, and the results stored
later by :func:`store_comparison`, :func:`store_criticism` and
:func:`store_reweighting`). No other module parses them.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .._runtime import (
    CHANNELS,
    HDI_PROB,
    DataError,
    InputError,
    az,
    require_file,
    thinned_indices,
    write_hdf5,
)
from ..io import Experiment
from ..likelihood import MEASUREMENT_MODELS, ResidualLikelihood
from ..model import DAMPING, ParameterLayout, RobotProfile, discrete_matrices, get_family
from .file_format import (
    experiment_arrays,
    experiment_data,
    file_attributes,
    observed_data,
    posterior_metadata,
)
from .records import PosteriorMetadata

__all__ = [
    "Posterior",
    "build_inference_data",
    "load_posterior",
    "model_autocovariance",
    "noise_dimension",
    "save_posterior",
]


#: What a :class:`Posterior` reads from its groups once (dropped from its copies).
_CACHES = ("_metadata", "_experiments")


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
) -> Posterior:
    """The posterior of a sampled chain.

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
    layout = likelihood.layout
    noise, dims, noise_coords = _noise_variables(layout, draws)
    # The speed model's ratios (d at the top speed / at the bottom), beside d at v_ref.
    speed = layout.damping_bases[len(DAMPING) :]
    ratios = {base: draws[..., layout.column(base)] for base in speed}
    dt = likelihood.experiments[0].dt
    Ad, Bd = discrete_matrices(likelihood.robot, d_lat, d_long, dt)
    posterior = {
        "d_lat": d_lat,
        "d_long": d_long,
        **ratios,
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
    return Posterior.of(idata)


class Posterior(az.InferenceData):
    """A posterior: arviz's InferenceData of the draws, with its typed metadata.

    What :func:`bayes_jackal.sample` returns and :func:`load_posterior` reads:
    an InferenceData (arviz's functions take it as one) whose file
    attributes are read once, into :attr:`metadata`, and read again only
    when a result stored later (:func:`~bayes_jackal.posterior.file_format.store_comparison`,
    ``store_criticism``, ``store_reweighting``) changes them. Every function
    of the package that takes a posterior takes this, or any InferenceData
    of a bayes_jackal posterior, which it reads through :meth:`of`.

    Examples
    --------
    A posterior's robot, layout, experiments and draws. The 20-step chain is
    short on purpose:

    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> type(posterior).__name__, posterior.family, posterior.channels
    ('Posterior', 'white', ('yaw',))
    >>> posterior.robot.name, [run.name for run in posterior.experiments]
    ('jackal', ['v1'])
    >>> posterior.layout.names, posterior.noise_groups
    (('d_lat', 'd_long', 'sigma_c', 'sigma_n'), (('yaw', 'all'),))
    >>> draws, lp = posterior.draws()
    >>> draws.shape, lp.shape, posterior.thinned_draws(10).shape
    ((16, 32, 4), (16, 32), (10, 4))
    >>> posterior.truth["d_lat"], posterior.metadata.convergence.converged
    (110.0, False)
    """

    @classmethod
    def of(cls, idata: az.InferenceData) -> Posterior:
        """``idata`` itself if it is a :class:`Posterior`, else one sharing its groups.

        Raises
        ------
        InputError
            For an object that is not an InferenceData, or one without a
            ``posterior`` group.
        """
        if isinstance(idata, cls):
            return idata
        if not isinstance(idata, az.InferenceData) or "posterior" not in idata.groups():
            raise InputError(
                f"not a posterior: a {type(idata).__name__} without draws; give the "
                "InferenceData of bj.sample or bj.load_posterior",
                field="posterior",
            )
        groups = {group: idata[group] for group in idata.groups()}
        return cls(attrs=dict(idata.attrs) or None, **groups)

    def __getstate__(self) -> dict:
        """The state without what is read from it: a copy, a slice or a pickle reads anew."""
        return {key: value for key, value in vars(self).items() if key not in _CACHES}

    @property
    def metadata(self) -> PosteriorMetadata:
        """Everything the file says besides its draws (read once per change of its attributes)."""
        attrs = tuple(
            (key, value.tobytes() if isinstance(value, np.ndarray) else value)
            for key, value in self.posterior.attrs.items()
        )
        cached = self.__dict__.get("_metadata")
        if cached is None or cached[0] != attrs:
            cached = (attrs, posterior_metadata(self))
            self.__dict__["_metadata"] = cached
        return cached[1]

    @property
    def robot(self) -> RobotProfile:
        """The robot profile sampled with (:attr:`PosteriorMetadata.robot`)."""
        return self.metadata.robot

    @property
    def layout(self) -> ParameterLayout:
        """Parameter names, noise groups and columns."""
        return self.metadata.layout

    @property
    def family(self) -> str:
        """The noise family."""
        return self.metadata.family

    @property
    def channels(self) -> tuple[str, ...]:
        """The channels, in likelihood order."""
        return self.metadata.channels

    @property
    def noise_groups(self) -> tuple[tuple[str, str], ...]:
        """The (channel, experiment or ``"all"`` when pooled) of each noise group."""
        return self.layout.groups

    @property
    def truth(self) -> dict | None:
        """The shared truth of simulated experiments, when every one has it."""
        return self.metadata.truth

    @property
    def experiments(self) -> list[Experiment]:
        """The measured experiments sampled from, with their names and windows."""
        if "_experiments" not in self.__dict__:
            self.__dict__["_experiments"] = [
                Experiment(
                    **experiment_arrays(self, i),
                    name=record.name,
                    series=record.series,
                    steady_window=record.steady_window,
                    truth=record.truth,
                    provenance=record.provenance,
                    source=record.source or "<memory>",
                    segments=record.segments,
                )
                for i, record in enumerate(self.metadata.experiments)
            ]
        return list(self.__dict__["_experiments"])

    @property
    def variables(self) -> list[str]:
        """The sampled parameters' variable names (d_lat, d_long, then the noise)."""
        return [name for name in self.posterior.data_vars if name not in ("ratio", "Ad", "Bd")]

    def table(self, round_to: int | str = "none"):
        """The summary table arviz users know: one row per parameter and for the ratio.

        arviz's :func:`~arviz.summary` of every sampled parameter and the
        derived ``ratio`` d_lat/d_long: ``mean``, ``sd``, the 94 % HDI
        (``hdi_3%``, ``hdi_97%``), ``ess_bulk``, ``ess_tail``, ``r_hat``
        (walkers as chains: a secondary check), and ``ess_autocorr``, the
        effective draws from the integrated autocorrelation time, the
        primary one for emcee. :func:`bayes_jackal.summarize` is the same
        numbers as JSON, with the criticism.

        Parameters
        ----------
        round_to : int or "none"
            Decimals, as arviz's ``round_to``; by default unrounded (the
            noise sds are 1e-4 to 1e-2: decimals would lose them).

        Returns
        -------
        pandas.DataFrame

        Examples
        --------
        >>> import bayes_jackal as bj
        >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
        >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
        >>> table = posterior.table()
        >>> list(table.index)
        ['d_lat', 'd_long', 'sigma_c', 'sigma_n', 'ratio']
        >>> list(table.columns[:4]), table.columns[-1]
        (['mean', 'sd', 'hdi_3%', 'hdi_97%'], 'ess_autocorr')
        """
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            table = az.summary(self, var_names=[*self.variables, "ratio"], hdi_prob=HDI_PROB,
                               round_to=round_to, kind="all")  # fmt: skip
        ess = self.metadata.convergence.ess_autocorr
        table["ess_autocorr"] = [ess.get(label, np.nan) for label in table.index]
        return table

    def draws(self) -> tuple[np.ndarray, np.ndarray]:
        """The chain in parameter-vector order, and its log posterior.

        Returns
        -------
        draws : ndarray, shape (draws, walkers, P)
            Parameters in natural units, ordered as the layout's names
            (d_lat, d_long, then each noise group's).
        lp : ndarray, shape (draws, walkers)
            Log posterior in sampling coordinates (z = log theta).
        """
        layout = self.layout
        columns = []
        for base, group in zip(layout.bases, layout.column_groups, strict=True):
            variable = self.posterior[base]
            dimension, groups = noise_dimension(layout, base)
            if dimension is not None:
                variable = variable.isel({dimension: groups.index(group)})
            columns.append(variable.transpose("draw", "chain").values)
        lp = self.sample_stats["lp"].transpose("draw", "chain").values
        return np.stack(columns, axis=-1), lp

    def thinned_draws(self, count: int) -> np.ndarray:
        """At most ``count`` evenly spaced draws in natural units, shape (count, P)."""
        draws, _ = self.draws()
        draws = draws.reshape(-1, draws.shape[-1])
        return draws[thinned_indices(len(draws), count)]

    def likelihood(self) -> ResidualLikelihood:
        """The likelihood sampled with, rebuilt from the file.

        It prepares the likelihood's data (lagged sums, spectra): what needs
        only the parameters reads :attr:`metadata` instead.
        """
        metadata = self.metadata
        layout = metadata.layout
        return ResidualLikelihood(
            self.experiments,
            metadata.robot,
            family=layout.family,
            channels=layout.channels,
            shared_noise=layout.shared_noise,
            sensor=layout.sensor,
            engine=metadata.engine,
            steady=metadata.steady,
            shared_width=layout.shared_width,
            damping=layout.damping,
        )


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
        Of the posterior (:attr:`Posterior.metadata`).
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
    >>> from bayes_jackal.posterior import model_autocovariance
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> theta = posterior.thinned_draws(5)
    >>> acov = model_autocovariance(posterior.metadata, 0, "yaw", theta, 3)
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
        clock=(record.pose_clock or (1, 0.0)) if pose else (1, 0.0),
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


def load_posterior(path: str | Path) -> Posterior:
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
    _check_draws(idata.posterior, str(path))
    posterior = Posterior.of(idata)
    try:
        _ = posterior.metadata  # read now: a malformed file is refused here, naming it
    except DataError as exc:
        raise DataError(str(exc), source=str(path)) from None
    return posterior


def _check_draws(draws, source: str) -> None:
    """Refuse a posterior group with a draw that is not a finite number, naming where it is."""
    for name, variable in draws.data_vars.items():
        values = np.asarray(variable.values)
        if not np.issubdtype(values.dtype, np.number) or np.isfinite(values).all():
            continue
        index = np.unravel_index(np.flatnonzero(~np.isfinite(values))[0], values.shape)
        where = ", ".join(f"{dim} {i}" for dim, i in zip(variable.dims, index, strict=True))
        raise DataError(
            f"the draw at {where} is {values[index]} ({np.count_nonzero(~np.isfinite(values))} "
            "such): a posterior's draws are finite; the file is damaged or was not written "
            "by bayes_jackal",
            source=source,
            field=f"posterior.{name}",
        )
