"""Posterior-predictive series and model states of a posterior, in bounded memory.

Each posterior draw carries a series as long as the run: a replicated
residual series (:func:`predictive_series`, :func:`predictive_statistics`)
or the model's states (:func:`model_percentiles`). For an hour at 72 Hz
(259,200 samples) and 200 draws those would be 400 MB per array, and the
circulant embedding of the replicated series several times that. So the
draws are made and reduced in chunks of at most :data:`CHUNK_SAMPLES`
draws x samples, and only the small per-draw
statistics (autocorrelation at a few lags, spectra, percentiles) are kept.
:func:`stationary_series` and :func:`stationary_statistics` do the same
for any stationary Gaussian series given its autocovariance (a bare noise
series' replicates, :mod:`bayes_jackal.report.noise_plots`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence

import numpy as np

from .._runtime import as_rng, az, chunks
from ..likelihood import sample_stationary
from ..model import simulate
from .file_format import observed_residuals
from .posterior import Posterior, model_autocovariance
from .records import PosteriorMetadata

__all__ = [
    "CHUNK_SAMPLES",
    "model_percentiles",
    "predictive_series",
    "predictive_statistics",
    "stationary_series",
    "stationary_statistics",
]

#: Samples held at once where each posterior draw carries a series of a
#: whole run (replicated residuals, model states): a chunk of draws holds at
#: most this many draws x samples, ~3 MB per array.
CHUNK_SAMPLES = 400_000


def _model(
    metadata: PosteriorMetadata, index: int, channel: str, theta: np.ndarray, n: int
) -> Callable[[slice], np.ndarray]:
    """``autocovariance`` of :func:`stationary_series`: the residuals of draws of ``theta``."""
    return lambda part: model_autocovariance(metadata, index, channel, theta[part], n)


def predictive_series(
    metadata: PosteriorMetadata,
    index: int,
    channel: str,
    theta: np.ndarray,
    n: int,
    rng: np.random.Generator | int | None = None,
) -> Iterator[tuple[slice, np.ndarray]]:
    """Posterior-predictive residual series of one experiment and channel, chunk by chunk.

    For each draw of ``theta``, one series of ``n`` samples drawn exactly
    from the model's residual covariance
    (:func:`bayes_jackal.likelihood.sample_stationary`). Series i comes from
    the i-th of ``len(theta)`` generators spawned from ``rng``, so every
    series is the same whatever the chunks.

    Parameters
    ----------
    metadata : PosteriorMetadata
        Of the posterior (:attr:`bayes_jackal.posterior.Posterior.metadata`).
    index : int
        Experiment index.
    channel : {"yaw", "vx", "vy"}
    theta : ndarray, shape (B, P)
        Parameter vectors in natural units.
    n : int
        Samples per series.
    rng : numpy.random.Generator, int or None

    Yields
    ------
    part : slice
        The chunk's draws in ``theta``.
    series : ndarray, shape (len(part), n)
        Their series [channel unit].

    Examples
    --------
    Four replicated yaw-rate residual series of 100 samples,
    one per posterior draw, in one chunk. The 20-step chain is short on
    purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import Posterior
    >>> from bayes_jackal.posterior import predictive_series
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> metadata, theta = posterior.metadata, posterior.thinned_draws(4)
    >>> chunks = predictive_series(metadata, 0, "yaw", theta, 100, rng=1)
    >>> [(part, series.shape) for part, series in chunks]
    [(slice(0, 4, None), (4, 100))]
    """
    yield from stationary_series(
        _model(metadata, index, channel, theta, n), len(theta), n, rng=rng
    )


def predictive_statistics(
    idata: az.InferenceData,
    index: int,
    channel: str,
    statistics: Mapping[str, Callable[[np.ndarray], np.ndarray]],
    *,
    count: int = 200,
    rng: np.random.Generator | int | None = None,
) -> dict[str, np.ndarray]:
    """Statistics of posterior-predictive one-step residuals of one experiment and channel.

    For each of ``count`` posterior draws, one series as long as the observed
    residuals (:func:`predictive_series`): what the fitted noise filter says
    the residuals should look like. The series are made and reduced chunk by
    chunk, so only the statistics of all draws are held at once, never the
    draws x samples of the series.

    Parameters
    ----------
    idata : arviz.InferenceData
    index : int
        Experiment index.
    channel : {"yaw", "vx", "vy"}
    statistics : mapping of str to callable
        Each maps series of shape (B, n) to statistics of shape (B, ...).
    count : int
        Posterior draws (evenly spaced, :func:`thinned_draws`).
    rng : numpy.random.Generator, int or None

    Returns
    -------
    dict of str to ndarray
        Each statistic of every draw, shape (count, ...), under its key.

    Examples
    --------
    The sd of 20 replicated yaw-rate residual series, against the observed
    residuals' sd. The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import observed_residuals
    >>> from bayes_jackal.posterior import predictive_statistics
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> sd = {"sd": lambda series: series.std(axis=1)}
    >>> replicated = predictive_statistics(posterior, 0, "yaw", sd, count=20, rng=1)["sd"]
    >>> observed = observed_residuals(posterior, 0, "yaw").std()
    >>> replicated.shape, round(float(replicated.mean() / observed), 1)
    ((20,), 1.0)
    """
    posterior = Posterior.of(idata)
    metadata = posterior.metadata
    theta = posterior.thinned_draws(count)
    n = observed_residuals(idata, index, channel).size
    return stationary_statistics(
        _model(metadata, index, channel, theta, n),
        len(theta),
        n,
        statistics,
        rng=rng,
    )


def stationary_series(
    autocovariance: Callable[[slice], np.ndarray],
    count: int,
    n: int,
    *,
    rng: np.random.Generator | int | None = None,
) -> Iterator[tuple[slice, np.ndarray]]:
    """Stationary Gaussian series of given autocovariances, chunk by chunk.

    Series i of ``count`` is drawn exactly from its autocovariance
    (:func:`bayes_jackal.likelihood.sample_stationary`) with the i-th of
    ``count`` generators spawned from ``rng``, so every series is the same
    whatever the chunks; a chunk holds at most :data:`CHUNK_SAMPLES`
    series x samples.

    Parameters
    ----------
    autocovariance : callable
        ``autocovariance(part)``: the autocovariances at lags 0..n-1 of the
        series in the slice ``part`` of 0..count-1, shape (len(part), n).
    count : int
        Number of series.
    n : int
        Samples per series.
    rng : numpy.random.Generator, int or None

    Yields
    ------
    part : slice
    series : ndarray, shape (len(part), n)

    Examples
    --------
    Three AR(1) series (phi = 0.5, unit variance) of 2000 samples:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import stationary_series
    >>> acov = np.tile(0.5 ** np.arange(2000), (3, 1))
    >>> chunks = stationary_series(lambda part: acov[part], 3, 2000, rng=1)
    >>> [(part, series.shape) for part, series in chunks]
    [(slice(0, 3, None), (3, 2000))]
    """
    generators = as_rng(rng).spawn(count)
    for part in chunks(count, n, budget=CHUNK_SAMPLES):
        acov = autocovariance(part)
        yield (
            part,
            np.concatenate(
                [sample_stationary(row, g) for row, g in zip(acov, generators[part], strict=True)]
            ),
        )


def stationary_statistics(
    autocovariance: Callable[[slice], np.ndarray],
    count: int,
    n: int,
    statistics: Mapping[str, Callable[[np.ndarray], np.ndarray]],
    *,
    rng: np.random.Generator | int | None = None,
) -> dict[str, np.ndarray]:
    """Statistics of the series of :func:`stationary_series`, reduced chunk by chunk.

    Only the statistics of all series are held at once, never the series.

    Parameters
    ----------
    autocovariance, count, n, rng
        As :func:`stationary_series`.
    statistics : mapping of str to callable
        Each maps series of shape (B, n) to statistics of shape (B, ...).

    Returns
    -------
    dict of str to ndarray
        Each statistic of every series, shape (count, ...), under its key.

    Examples
    --------
    The mean square of 400 AR(1) series (phi = 0.5, unit variance) of 500
    samples, against the variance 1:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import stationary_statistics
    >>> acov = np.tile(0.5 ** np.arange(500), (400, 1))
    >>> square = {"square": lambda series: np.mean(series**2, axis=1)}
    >>> result = stationary_statistics(lambda p: acov[p], 400, 500, square, rng=1)
    >>> result["square"].shape, round(float(result["square"].mean()), 2)
    ((400,), 1.0)
    """
    reduced = [
        {name: function(series) for name, function in statistics.items()}
        for _, series in stationary_series(autocovariance, count, n, rng=rng)
    ]
    return {name: np.concatenate([chunk[name] for chunk in reduced]) for name in statistics}


def model_percentiles(
    idata: az.InferenceData, index: int, percentiles: Sequence[float], *, count: int = 50
) -> np.ndarray:
    """Percentiles over ``count`` posterior draws of the damping of the model's states.

    The deterministic model (no process noise) driven by the measured wheel
    speeds from the measured initial state, as in thesis figs. 5-5,
    5-13..5-16. It runs over consecutive time segments of the experiment,
    each from the last state of the one before, with at most
    :data:`CHUNK_SAMPLES` draws x samples per segment: the states of all
    draws over the whole run are never held at once.

    Parameters
    ----------
    idata : arviz.InferenceData
    index : int
        Experiment index.
    percentiles : sequence of float
        In [0, 100].
    count : int
        Posterior draws (evenly spaced, :func:`thinned_draws`).

    Returns
    -------
    ndarray, shape (len(percentiles), N, 3)
        Percentiles of (vx, vy, yaw rate) [m/s, m/s, rad/s] at each sample.

    Examples
    --------
    The 5th, 50th and 95th percentiles of the model's states over 10 posterior
    draws; in the steady window the median yaw rate meets the measured one
    [rad/s]. The 20-step chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import model_percentiles
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> states = model_percentiles(posterior, 0, [5, 50, 95], count=10)
    >>> states.shape  # (percentiles, samples, (vx, vy, yaw rate))
    (3, 2737, 3)
    >>> steady = (run.t >= 3.0) & (run.t <= 36.0)
    >>> round(float(states[1, steady, 2].mean()), 2), round(float(run.yaw_rate[steady].mean()), 2)
    (0.22, 0.21)
    """
    posterior = Posterior.of(idata)
    experiment = posterior.experiments[index]
    robot = posterior.metadata.robot
    theta = posterior.thinned_draws(count)
    x0 = [0.0 if v is None else v[0] for v in (experiment.vx, experiment.vy)]
    state = np.array([*x0, experiment.yaw_rate[0]])
    inputs = experiment.inputs
    step = max(1, CHUNK_SAMPLES // len(theta) - 1)
    parts = []
    for start in range(0, len(inputs) - 1, step):
        # Samples start..start + step; the last one starts the next segment.
        segment = inputs[start : start + step + 1]
        states = simulate(robot, theta[:, 0], theta[:, 1], segment, state, dt=experiment.dt)
        state = states[:, -1]
        parts.append(np.percentile(states[:, : len(segment) - 1], percentiles, axis=0))
    last = np.percentile(state, percentiles, axis=0)[:, None]
    return np.concatenate([*parts, last], axis=1)
