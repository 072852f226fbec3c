"""Posterior of the damping and the noise parameters, sampled with emcee (docs/design.md §4).

The run: the likelihood profiled over each noise group's parameters on a
design over the damping, local optimisations from the best profile points
to the maximum a posteriori (MAP), walkers drawn from the Laplace
approximation there, and the chain run to convergence by
:func:`bayes_jackal.inference.run_chain` (stored step by step in an HDF5 file;
a run started again with the same file and settings resumes where it
stopped). :class:`SamplerSettings` and :class:`BufferedHDFBackend` live in
:mod:`bayes_jackal.inference.chains` and are importable from here. The priors and
the log-posterior live in :mod:`bayes_jackal.likelihood.priors`, the MAP search and
the walkers' start in :mod:`bayes_jackal.inference.map_search`.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .._runtime import (
    DAMPING_MODEL,
    ENGINE,
    FAMILY,
    MAX_STEPS,
    NOISE,
    SENSOR,
    STEADY,
    WALKERS,
    check_interrupt,
)
from ..io import POSE_FIELDS, Experiment, as_experiments
from ..likelihood import LogPosterior, Prior, ResidualLikelihood
from ..model import RobotProfile
from ..posterior import Posterior, build_inference_data
from .chains import SamplerSettings, run_chain
from .map_search import damping_design, find_map, laplace_walkers
from .moves import Start
from .options import FitOptions

__all__ = ["run_identity", "sample", "sample_posterior"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)


#: Robot fields that do not change a chain: names and where the profile came from.
_ROBOT_LABELS = ("name", "source", "topics", "wheels")


def run_identity(
    likelihood: ResidualLikelihood,
    prior: Prior,
    walkers: int,
    seed,
    starts: np.ndarray | None = None,
) -> dict:
    """What defines a chain, part by part (JSON-ready; data and robot as hashes).

    Keys ``data``, ``robot``, ``family``, ``likelihood``, ``priors``,
    ``walkers`` and ``seed``, and ``starts`` where the MAP search was
    warm-started (:func:`sample_posterior`): a resumed or reused run must
    match on all.

    Examples
    --------
    What defines a chain; a resumed run must match it on every key:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import run_identity
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.likelihood import Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="white", channels=("yaw",))
    >>> identity = run_identity(likelihood, Prior.for_likelihood(likelihood, robot), 32, 1)
    >>> sorted(identity)
    ['data', 'family', 'likelihood', 'priors', 'robot', 'seed', 'walkers']
    >>> identity["family"], identity["likelihood"]["channels"], len(identity["data"])
    ('white', ['yaw'], 64)
    """
    data = hashlib.sha256()
    for experiment in likelihood.experiments:
        for values in (experiment.t, experiment.yaw_rate, experiment.omega_r, experiment.omega_l):
            data.update(np.ascontiguousarray(values).tobytes())
        for values in (experiment.vx, experiment.vy):
            if values is not None:
                data.update(np.ascontiguousarray(values).tobytes())
        if experiment.pose is not None:  # the pose channels' data
            for field in POSE_FIELDS:
                data.update(np.ascontiguousarray(getattr(experiment.pose, field)).tobytes())
        # The window the likelihood reads (``steady``): another window is other data.
        data.update(json.dumps(experiment.steady_window).encode())
    robot = {
        key: value for key, value in asdict(likelihood.robot).items() if key not in _ROBOT_LABELS
    }
    return {
        "data": data.hexdigest(),
        "robot": hashlib.sha256(json.dumps(robot, sort_keys=True).encode()).hexdigest(),
        "family": likelihood.family,
        "likelihood": {
            "channels": list(likelihood.channels),
            "shared_noise": likelihood.shared_noise,
            # only when set: chains written before the option still resume
            **({"shared_width": True} if likelihood.shared_width else {}),
            "sensor": likelihood.sensor,
            "engine": likelihood.engine,
            "steady": likelihood.steady,
        },
        "priors": {"low": prior.low.tolist(), "high": prior.high.tolist()},
        "walkers": walkers,
        "seed": seed,
        # only when given: chains started from the profile keep their identity
        **({} if starts is None else {"starts": np.asarray(starts, float).tolist()}),
    }


def _fingerprint(
    likelihood: ResidualLikelihood,
    prior: Prior,
    walkers: int,
    seed,
    starts: np.ndarray | None = None,
) -> str:
    """Hash of everything that defines a chain, to refuse resuming a different run."""
    identity = run_identity(likelihood, prior, walkers, seed, starts)
    return hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()


def sample_posterior(
    likelihood: ResidualLikelihood,
    settings: SamplerSettings | None = None,
    seed: int | None = None,
    chain_file: str | Path | None = None,
    prior_overrides: dict | None = None,
    starts: np.ndarray | None = None,
) -> Posterior:
    """Sample the posterior of a residual likelihood with emcee.

    Parameters
    ----------
    likelihood : ResidualLikelihood
        Experiments, channels, noise family, sensor model and engine.
    settings : SamplerSettings, optional
    seed : int, optional
        Seeds the design, the walkers and emcee's moves: same seed, same chain.
    chain_file : str or Path, optional
        HDF5 file of the chain; a run with the same file and settings resumes.
    prior_overrides : dict, optional
        (low, high) per base parameter name, over the profile's ranges.
    starts : ndarray, shape (S, P), optional
        Parameter values the MAP search climbs from instead of the profile
        likelihood's best points (:func:`~bayes_jackal.inference.find_map`):
        a warm start, e.g. the pooled posterior's best draws for the
        posterior without one of its runs.

    Returns
    -------
    arviz.InferenceData
        Groups ``posterior`` (parameters and derived ratio, Ad, Bd),
        ``sample_stats`` (lp, log_likelihood_total), ``observed_data`` (residuals at
        the posterior median), ``constant_data`` (the measured experiments);
        ``attrs`` hold convergence diagnostics and the settings.

    Examples
    --------
    The posterior of a white-noise model of one run's yaw rate. The 20-step
    chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import SamplerSettings, sample_posterior
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="white", channels=("yaw",))
    >>> posterior = sample_posterior(likelihood, SamplerSettings(max_steps=20), seed=1)
    >>> sorted(posterior.groups())
    ['constant_data', 'observed_data', 'posterior', 'sample_stats']
    >>> dict(posterior.posterior.sizes)
    {'chain': 32, 'draw': 16, 'state': 3, 'wheel': 2}
    """
    settings = settings or SamplerSettings()
    prior = Prior.for_likelihood(likelihood, likelihood.robot, prior_overrides)
    log_posterior = LogPosterior(likelihood, prior)

    def initial(rng: np.random.Generator, walkers: int) -> Start:
        started = time.perf_counter()
        _log.info(
            f"MAP search: the profile likelihood of each noise group on "
            f"{damping_design(settings.design_points)} damping points, then local searches"
            if starts is None
            else f"MAP search: local searches from {len(starts)} given points (a warm start)"
        )
        centre = find_map(log_posterior, rng, settings.design_points, starts)
        check_interrupt()  # a signal swallowed in the search (scipy's Cython code)
        _log.info(
            f"MAP found in {time.perf_counter() - started:.0f} s; the walkers start around it"
        )
        return laplace_walkers(log_posterior, centre, walkers, rng)

    chain = run_chain(
        log_posterior,
        initial,
        settings=settings,
        seed=seed,
        fingerprint=_fingerprint(
            likelihood, prior, settings.n_walkers(len(prior.names)), seed, starts
        ),
        chain_file=chain_file,
    )
    return build_inference_data(
        likelihood, prior, chain.samples, chain.log_prob, chain.diagnostics
    )


def sample(
    experiments: Experiment | Sequence[Experiment],
    *,
    family: str = FAMILY,
    channels: Sequence[str] | None = None,
    noise: str = NOISE,
    sensor: str = SENSOR,
    engine: str = ENGINE,
    steady: bool = STEADY,
    damping: str = DAMPING_MODEL,
    seed: int | None = None,
    max_steps: int = MAX_STEPS,
    walkers: int = WALKERS,
    priors: Mapping[str, tuple[float, float]] | None = None,
    robot: RobotProfile | str | Path | None = None,
    chain_file: str | Path | None = None,
    progress: bool = True,
) -> Posterior:
    """The posterior of the damping and the noise, sampled with emcee (``bayes-jackal sample``).

    The same likelihood, sampler settings and seed as ``bayes-jackal sample
    --pooled`` with the same options, so the same chain.

    Parameters
    ----------
    experiments : Experiment or sequence of them
        Several are pooled into one posterior: one damping (d_lat, d_long)
        for all.
    family : str
        Process-noise family, a key of :data:`bayes_jackal.FAMILIES`
        (``--family``; :data:`FAMILY`).
    channels : sequence of {"yaw", "vx", "vy"}, optional
        By default every channel all experiments measure (``--channels``).
    noise : {"shared", "per-experiment", "one-width"}
        Pooled experiments' noise parameters (``--noise``; :data:`NOISE`):
        "one-width" shares them too, with one width for every channel.
    sensor : {"ma1", "diagonal"}
        Sensor-noise footprint (``--sensor-noise``; :data:`SENSOR`).
    engine : {"fast", "exact", "whittle"}
        Likelihood engine (``--engine``; :data:`ENGINE`).
    steady : bool
        Each experiment's steady window only, as the thesis (``--steady``);
        by default every sample: transients are data the model covers.
    damping : {"constant", "speed"}
        One damping, or one that depends on each segment's speed through
        the speed ratios ``speed_ratio_lat``, ``speed_ratio_long``
        (``--damping speed``; :class:`bayes_jackal.likelihood.ResidualLikelihood`).
    seed : int, optional
        Same seed, same chain (``--seed``).
    max_steps : int
        Step cap of the chain (``--max-steps``; :data:`MAX_STEPS`). A chain
        that reaches it before converging warns
        (:class:`~bayes_jackal.inference.ConvergenceWarning`).
    walkers : int
        Ensemble size; 0: max(32, 4 x parameters) (``--walkers``).
    priors : mapping of str to (float, float), optional
        (low, high) ranges over the profile's, e.g. ``{"d_lat": (10, 2000)}``
        [N s/m; s for ``sigma_h``/``width``; rad/s or m/s for ``sigma_c``,
        ``sigma_n``] (``--prior``).
    robot : RobotProfile, str or Path, optional
        A profile or its TOML file; the Jackal's by default (``--robot``).
    chain_file : str or Path, optional
        HDF5 file of the chain: a run with the same file and options resumes
        it (``sample`` keeps it beside the posterior as ``*.chain.h5``).
    progress : bool
        Show the chain's progress on stderr (by default: a bar on a terminal, a
        line every 10 s elsewhere, with the steps the chain expects to need and
        the time left); False for silence.

    Returns
    -------
    arviz.InferenceData
        As :func:`bayes_jackal.inference.sample_posterior`; save it with
        :func:`bayes_jackal.save_posterior`.

    Raises
    ------
    InputError
        Naming an unknown family, channel, noise sharing, sensor model,
        engine or prior, or a bad count.
    DataError
        For a channel an experiment does not measure.

    Examples
    --------
    A quick chain of 20 steps, far from converged (a ConvergenceWarning);
    real use takes the default step cap:

    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> sorted(posterior.posterior.data_vars)[:4]
    ['Ad', 'Bd', 'd_lat', 'd_long']
    >>> summary = bj.summarize(posterior)
    >>> summary["family"], summary["channels"], summary["converged"]
    ('white', ['yaw'], False)
    """
    fit = FitOptions.of_keywords(locals())  # the keywords above, as they were given
    likelihood = fit.likelihood_options.likelihood(as_experiments(experiments), fit.robot, family)
    return sample_posterior(
        likelihood,
        fit.settings,
        seed=fit.seed,
        chain_file=chain_file,
        prior_overrides=fit.prior_overrides,
    )
