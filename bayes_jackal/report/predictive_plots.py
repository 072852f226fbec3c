"""Figures of the residuals' colour against the fitted filter's posterior-predictive band.

The residual autocorrelation (:func:`plot_autocorrelation`) and spectrum
(:func:`plot_spectrum`), each with the band of 200 posterior-predictive
residual series (:func:`predictive_bands`, which both can share). Built on
:class:`matplotlib.figure.Figure` without pyplot, as every figure of
:mod:`bayes_jackal.report.plots` (which exports these too).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .._runtime import InputError
from ..posterior import (
    ExperimentRecord,
    Posterior,
    autocorrelation_bounds,
    observed_residuals,
    predictive_statistics,
    sample_autocorrelation,
    spectrum,
)
from ._layout import DATA_COLOUR, MODEL_COLOUR, UNITS, draw_band, new_axes

__all__ = ["band_statistics", "plot_autocorrelation", "plot_spectrum", "predictive_bands"]


def predictive_bands(
    idata, index: int = 0, channel: str = "yaw", *, lags: int = 30, rng=0
) -> dict[str, np.ndarray]:
    """Per-draw statistics behind the predictive bands of the ACF and PSD figures.

    For each of 200 posterior-predictive residual series
    (:func:`bayes_jackal.posterior.predictive_statistics`, made and reduced
    in chunks): its sample autocorrelation at lags 0..``lags`` and its Welch
    PSD estimated exactly as the data's (:func:`bayes_jackal.posterior.spectrum`),
    for :func:`plot_autocorrelation` and :func:`plot_spectrum`.

    Parameters
    ----------
    idata : arviz.InferenceData
    index : int
        Experiment of the posterior.
    channel : {"yaw", "vx", "vy"}
    lags : int
        Largest lag of the autocorrelation.
    rng : numpy.random.Generator, int or None

    Returns
    -------
    dict
        ``acf``, shape (200, lags + 1), and ``psd``, shape (200, F)
        [(channel unit)^2 / Hz].

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import predictive_bands
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> bands = predictive_bands(posterior, 0, "yaw", lags=10, rng=0)
    >>> bands["acf"].shape, bands["psd"].shape[0]
    ((200, 11), 200)
    >>> bool((bands["acf"][:, 0] == 1.0).all())  # each series' lag 0
    True
    """
    dt = _experiment(idata, index).dt
    return predictive_statistics(idata, index, channel, band_statistics(dt, lags), rng=rng)


def band_statistics(dt: float, lags: int) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
    """What a predictive band is made of: each series' ``acf`` at lags 0..lags and Welch ``psd``.

    Shared by :func:`predictive_bands` and :mod:`bayes_jackal.report.noise_plots`:
    the replicates are estimated exactly as the data are
    (:func:`~bayes_jackal.posterior.sample_autocorrelation`,
    :func:`~bayes_jackal.posterior.spectrum`).

    Parameters
    ----------
    dt : float
        Sample time of the series [s].
    lags : int
        Largest lag of the autocorrelation [samples].

    Returns
    -------
    dict of str to callable
        ``acf`` and ``psd``: each maps series of shape (B, n) [unit] to the
        autocorrelation, shape (B, lags + 1), or the PSD, shape (B, F)
        [unit^2 / Hz].

    Examples
    --------
    Two white-noise series of 1000 samples at 100 Hz: the autocorrelation
    is 1 at lag 0, and the PSD of unit variance is about 2 dt = 0.02 /Hz.

    >>> import numpy as np
    >>> from bayes_jackal.report import band_statistics
    >>> series = np.random.default_rng(1).standard_normal((2, 1000))
    >>> statistics = band_statistics(0.01, 5)
    >>> acf, psd = statistics["acf"](series), statistics["psd"](series)
    >>> acf.shape, acf[:, 0].tolist(), psd.shape, round(float(psd[:, 1:-1].mean()), 2)
    ((2, 6), [1.0, 1.0], (2, 129), 0.02)
    """
    return {"acf": lambda x: sample_autocorrelation(x, lags), "psd": lambda x: spectrum(x, dt)[1]}


def plot_autocorrelation(
    idata,
    index: int = 0,
    channel: str = "yaw",
    lags: int = 30,
    ax: Axes | None = None,
    rng=0,
    predictive: dict[str, np.ndarray] | None = None,
) -> tuple[Figure, Axes]:
    """Residual autocorrelation with its white-noise bounds and the fitted filter's band.

    Thesis figs. 7-12, 7-22..7-24 with the posterior added: the band spans
    the central 94 % of the sample autocorrelations of 200 posterior-predictive
    residual series (:func:`predictive_bands`), so it holds both the
    parameter uncertainty and the sampling noise of an autocorrelation
    estimate. Bounds: +-1.96 / sqrt(n). ``predictive`` passes
    :func:`predictive_bands` of the same ``lags`` when already computed
    (:func:`plot_spectrum` uses the same); else they are drawn with ``rng``.

    Returns
    -------
    fig, ax

    Raises
    ------
    InputError
        When ``predictive`` holds the autocorrelation at other lags.

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_autocorrelation
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, ax = plot_autocorrelation(posterior, 0, "yaw", lags=10)
    >>> ax.get_title()
    'v1: yaw residual autocorrelation'
    >>> [text.get_text() for text in ax.get_legend().get_texts()]
    ['fitted filter, 94 %', 'residuals', 'white-noise 95 % bounds']
    """
    fig, ax = new_axes(ax, figsize=(6.0, 3.6))
    residuals = observed_residuals(idata, index, channel)
    predicted = (predictive or predictive_bands(idata, index, channel, lags=lags, rng=rng))["acf"]
    if predicted.shape[-1] != lags + 1:
        raise InputError(
            f"the predictive autocorrelation has lags 0..{predicted.shape[-1] - 1}, the "
            f"figure {lags}",
            field="predictive",
        )
    lag = np.arange(lags + 1)
    draw_band(ax, lag, predicted, color=MODEL_COLOUR, label="fitted filter, 94 %")
    ax.plot(
        lag,
        sample_autocorrelation(residuals, lags),
        "o-",
        color=DATA_COLOUR,
        ms=3,
        lw=0.8,
        label="residuals",
    )
    bound = autocorrelation_bounds(len(residuals))
    ax.axhspan(-bound, bound, color="tab:blue", alpha=0.12, label="white-noise 95 % bounds")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("lag [samples]")
    ax.set_ylabel("autocorrelation")
    ax.set_title(f"{_experiment(idata, index).name}: {channel} residual autocorrelation")
    ax.legend(fontsize="small")
    return fig, ax


def plot_spectrum(
    idata,
    index: int = 0,
    channel: str = "yaw",
    ax: Axes | None = None,
    rng=0,
    predictive: dict[str, np.ndarray] | None = None,
) -> tuple[Figure, Axes]:
    """Welch PSD of the residuals against the fitted filter's (thesis figs. 7-7..7-9).

    The band spans the central 94 % of the Welch estimates of 200
    posterior-predictive residual series, estimated exactly as the data's
    (:func:`predictive_bands`; ``predictive`` and ``rng`` as in
    :func:`plot_autocorrelation`).

    Returns
    -------
    fig, ax

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_spectrum
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, ax = plot_spectrum(posterior, 0, "yaw")
    >>> ax.get_title(), ax.get_xlabel(), ax.get_xscale()
    ('v1: yaw residual spectrum', 'frequency [Hz]', 'log')
    """
    fig, ax = new_axes(ax, figsize=(6.0, 3.6))
    dt = _experiment(idata, index).dt
    residuals = observed_residuals(idata, index, channel)
    frequency, observed = spectrum(residuals, dt)
    predicted = (predictive or predictive_bands(idata, index, channel, rng=rng))["psd"]
    draw_band(ax, frequency[1:], predicted[:, 1:], color=MODEL_COLOUR, label="fitted filter, 94 %")
    ax.loglog(frequency[1:], observed[1:], color=DATA_COLOUR, lw=0.8, label="residuals")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"PSD [({UNITS[channel]})²/Hz]")
    ax.set_title(f"{_experiment(idata, index).name}: {channel} residual spectrum")
    ax.legend(fontsize="small")
    return fig, ax


def _experiment(idata, index: int) -> ExperimentRecord:
    """The stored description (name, dt, window, truth) of one experiment."""
    return Posterior.of(idata).metadata.experiments[index]
