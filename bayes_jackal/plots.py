"""Figures. Every function takes an optional ``ax`` and returns ``(fig, ax)``.

Figures are built on :class:`matplotlib.figure.Figure` without pyplot, so
nothing here opens a window or depends on a display.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from ._files import atomic_path
from .criticism import criticise
from .errors import InputError
from .gridsearch import GridResult
from .physics import CHANNELS
from .posterior import (
    THESIS_RATIO,
    ExperimentRecord,
    observed_residuals,
    parameter_draws,
    posterior_experiments,
    posterior_layout,
    posterior_metadata,
    posterior_truth,
)
from .predictive import model_percentiles, predictive_statistics
from .series_statistics import autocorrelation_bounds, sample_autocorrelation, spectrum

__all__ = [
    "plot_autocorrelation",
    "plot_criticism",
    "plot_damping",
    "plot_grid",
    "plot_model_fit",
    "plot_residuals",
    "plot_sigma_h",
    "plot_spectrum",
    "plot_traces",
    "predictive_bands",
    "save_grid_plot",
]


def _figure(ax: Axes | None, **figure_options) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax
    fig = Figure(layout="constrained", **figure_options)
    return fig, fig.add_subplot()


def plot_grid(
    result: GridResult, surface: np.ndarray | None = None, ax: Axes | None = None
) -> tuple[Figure, Axes]:
    """MSE surface over (d_long, d_lat) with its minimum and ridge line.

    The ridge is the line d_lat = (d_lat / d_long at the minimum) x d_long,
    along which the yaw rate's steady state is constant (thesis fig. 5-4).

    Parameters
    ----------
    result : GridResult
    surface : ndarray, shape (L, M), optional
        One of ``result``'s surfaces; the total (eq. 5-3) by default.
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    fig, ax
    """
    fig, ax = _figure(ax, figsize=(6.0, 4.8))
    surface = result.mse if surface is None else surface
    floor = max(float(surface.min()), np.finfo(float).tiny)
    mesh = ax.pcolormesh(
        result.d_long, result.d_lat, np.maximum(surface, floor), shading="nearest", norm=LogNorm()
    )
    fig.colorbar(mesh, ax=ax, label=f"{result.method} MSE ({result.channel})")
    d_lat, d_long, mse = result.argmin(surface)
    ratio = d_lat / d_long
    ax.plot(result.d_long, ratio * result.d_long, "w--", lw=1, label=f"d_lat = {ratio:.3g} d_long")
    ax.plot(d_long, d_lat, "r*", ms=12, label=f"minimum ({d_lat:g}, {d_long:g}): {mse:.3g}")
    ax.set_xlim(result.d_long[0], result.d_long[-1])
    ax.set_ylim(result.d_lat[0], result.d_lat[-1])
    ax.set_xlabel("d_long [N s/m]")
    ax.set_ylabel("d_lat [N s/m]")
    ax.legend(loc="lower right", fontsize="small", facecolor="0.75")
    return fig, ax


def save_grid_plot(result: GridResult, path: str | Path, dpi: int = 120) -> Path:
    """Save :func:`plot_grid` of the total surface (png, svg, pdf by the suffix)."""
    fig, _ = plot_grid(result)
    path = Path(path)
    with atomic_path(path) as temporary:
        fig.savefig(temporary, dpi=dpi, format=path.suffix.lstrip(".").lower() or None)
    return path


#: Credible band drawn around posterior-predictive medians (the HDI mass).
BAND = (3.0, 97.0)
_UNITS = {"vx": "m/s", "vy": "m/s", "yaw": "rad/s"}
_DATA_COLOUR, _MODEL_COLOUR = "0.25", "tab:red"
#: Most points a curve over a whole run is drawn with. A longer series (past
#: ~55 s at 72 Hz) is drawn as its envelope: the min and max of each of
#: MAX_POINTS / 2 consecutive bins, filled, which at a figure's resolution
#: (a few hundred samples per pixel column for an hour) looks as the full
#: line would, at a fraction of the points.
MAX_POINTS = 4000


def _envelope(t: np.ndarray, low: np.ndarray, high: np.ndarray):
    """(t, low, high) binned to MAX_POINTS / 2 bins: each bin's centre, min of low, max of high."""
    edges = np.linspace(0, len(t), MAX_POINTS // 2 + 1).astype(int)
    centres = t[(edges[:-1] + edges[1:] - 1) // 2]
    return centres, np.minimum.reduceat(low, edges[:-1]), np.maximum.reduceat(high, edges[:-1])


def _curve(ax: Axes, t: np.ndarray, y: np.ndarray, *, color, lw: float, label=None) -> None:
    """A line of y(t), or its filled envelope past :data:`MAX_POINTS` samples."""
    if len(t) <= MAX_POINTS:
        ax.plot(t, y, color=color, lw=lw, label=label)
    else:
        ax.fill_between(*_envelope(t, y, y), color=color, lw=lw / 2, label=label)


def _band(ax: Axes, t: np.ndarray, low: np.ndarray, high: np.ndarray, **style) -> None:
    """A filled band low..high over t, enveloped past :data:`MAX_POINTS` samples."""
    ax.fill_between(*(_envelope(t, low, high) if len(t) > MAX_POINTS else (t, low, high)), **style)


def _figures(axes, rows: int, **figure_options) -> tuple[Figure, np.ndarray]:
    """A figure with ``rows`` stacked axes, or the figure of the given ones."""
    if axes is not None:
        axes = np.atleast_1d(axes)
        return axes[0].figure, axes
    fig = Figure(layout="constrained", **figure_options)
    return fig, np.atleast_1d(fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])


def _shade_window(ax: Axes, experiment) -> None:
    if experiment.steady_window is not None:
        ax.axvspan(*experiment.steady_window, color="tab:blue", alpha=0.07, lw=0)


def plot_model_fit(idata, index: int = 0, axes=None) -> tuple[Figure, np.ndarray]:
    """Measured vx, vy, yaw rate against the model at the posterior (thesis figs. 5-5, 5-13..5-16).

    The model runs without process noise from the measured initial state,
    driven by the measured wheel speeds; the band spans the central 94 % of
    50 posterior draws of the damping
    (:func:`bayes_jackal.predictive.model_percentiles`). The steady window
    is shaded. A run longer than :data:`MAX_POINTS` samples is drawn as
    envelopes: the measured series and the model's median as the min-max
    band of each of MAX_POINTS / 2 bins, the 94 % band from its lowest to its
    highest value in each bin.

    Parameters
    ----------
    idata : arviz.InferenceData
        A posterior written by ``bayes-jackal sample``.
    index : int
        Experiment of the posterior.
    axes : sequence of 3 matplotlib.axes.Axes, optional

    Returns
    -------
    fig, axes
    """
    experiment = posterior_experiments(idata)[index]
    t = experiment.t
    low, median, high = model_percentiles(idata, index, [BAND[0], 50.0, BAND[1]])
    fig, axes = _figures(axes, 3, figsize=(7.0, 6.0))
    for i, (ax, channel) in enumerate(zip(axes, CHANNELS, strict=True)):
        _shade_window(ax, experiment)
        if channel in experiment.channels:
            measured = experiment.channel(channel)
            _curve(ax, t, measured, color=_DATA_COLOUR, lw=0.6, label="measured")
        _band(ax, t, low[:, i], high[:, i], color=_MODEL_COLOUR, alpha=0.3)
        _curve(ax, t, median[:, i], color=_MODEL_COLOUR, lw=1.2, label="model (94 % band)")
        ax.set_ylabel(f"{channel} [{_UNITS[channel]}]")
    axes[0].legend(loc="lower right", fontsize="small")
    axes[0].set_title(f"{experiment.name}: model at the posterior against the data")
    axes[-1].set_xlabel("t [s]")
    return fig, axes


def plot_residuals(idata, index: int = 0, axes=None) -> tuple[Figure, np.ndarray]:
    """One-step residuals (eq. 7-3) at the posterior median, per channel (thesis figs. 7-1..7-6).

    Past :data:`MAX_POINTS` residuals each channel is drawn as its envelope
    (the min-max band of each of MAX_POINTS / 2 bins).

    Returns
    -------
    fig, axes
    """
    experiment = posterior_experiments(idata)[index]
    channels = _channels(idata)
    fig, axes = _figures(axes, len(channels), figsize=(7.0, 1.0 + 1.8 * len(channels)))
    for ax, channel in zip(axes, channels, strict=True):
        residuals = observed_residuals(idata, index, channel)
        start = experiment.steady_window[0] if experiment.steady_window else experiment.t[0]
        t = start + experiment.dt * np.arange(1, len(residuals) + 1)
        _curve(ax, t, residuals, color=_DATA_COLOUR, lw=0.6)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{channel} residual [{_UNITS[channel]}]")
    axes[0].set_title(f"{experiment.name}: one-step residuals (eq. 7-3)")
    axes[-1].set_xlabel("t [s]")
    return fig, axes


def _channels(idata) -> list[str]:
    return list(posterior_metadata(idata).channels)


def predictive_bands(
    idata, index: int = 0, channel: str = "yaw", *, lags: int = 30, rng=0
) -> dict[str, np.ndarray]:
    """Per-draw statistics behind the predictive bands of the ACF and PSD figures.

    For each of 200 posterior-predictive residual series
    (:func:`bayes_jackal.predictive.predictive_statistics`, made and reduced
    in chunks): its sample autocorrelation at lags 0..``lags`` and its Welch
    PSD estimated exactly as the data's (:func:`bayes_jackal.series_statistics.spectrum`),
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
    """
    dt = _experiment(idata, index).dt
    return predictive_statistics(
        idata,
        index,
        channel,
        {"acf": lambda x: sample_autocorrelation(x, lags), "psd": lambda x: spectrum(x, dt)[1]},
        rng=rng,
    )


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
    """
    fig, ax = _figure(ax, figsize=(6.0, 3.6))
    residuals = observed_residuals(idata, index, channel)
    predicted = (predictive or predictive_bands(idata, index, channel, lags=lags, rng=rng))["acf"]
    if predicted.shape[-1] != lags + 1:
        raise InputError(
            f"the predictive autocorrelation has lags 0..{predicted.shape[-1] - 1}, the "
            f"figure {lags}",
            field="predictive",
        )
    lag = np.arange(lags + 1)
    low, median, high = np.percentile(predicted, [BAND[0], 50.0, BAND[1]], axis=0)
    ax.fill_between(lag, low, high, color=_MODEL_COLOUR, alpha=0.3, label="fitted filter, 94 %")
    ax.plot(lag, median, color=_MODEL_COLOUR, lw=1)
    ax.plot(
        lag,
        sample_autocorrelation(residuals, lags),
        "o-",
        color=_DATA_COLOUR,
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
    """
    fig, ax = _figure(ax, figsize=(6.0, 3.6))
    dt = _experiment(idata, index).dt
    residuals = observed_residuals(idata, index, channel)
    frequency, observed = spectrum(residuals, dt)
    predicted = (predictive or predictive_bands(idata, index, channel, rng=rng))["psd"]
    low, median, high = np.percentile(predicted[:, 1:], [BAND[0], 50.0, BAND[1]], axis=0)
    ax.fill_between(
        frequency[1:], low, high, color=_MODEL_COLOUR, alpha=0.3, label="fitted filter, 94 %"
    )
    ax.loglog(frequency[1:], median, color=_MODEL_COLOUR, lw=1)
    ax.loglog(frequency[1:], observed[1:], color=_DATA_COLOUR, lw=0.8, label="residuals")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"PSD [({_UNITS[channel]})²/Hz]")
    ax.set_title(f"{_experiment(idata, index).name}: {channel} residual spectrum")
    ax.legend(fontsize="small")
    return fig, ax


def _experiment(idata, index: int) -> ExperimentRecord:
    """The stored description (name, dt, window, truth) of one experiment."""
    return posterior_metadata(idata).experiments[index]


def plot_traces(idata, axes=None) -> tuple[Figure, np.ndarray]:
    """Every walker's kept draws of every sampled parameter (after burn-in, thinned).

    Returns
    -------
    fig, axes
    """
    draws, _ = parameter_draws(idata)
    layout = posterior_layout(idata)
    names = layout.names
    fig, axes = _figures(axes, len(names), figsize=(7.0, 1.0 + 1.2 * len(names)))
    for ax, name, values, log in zip(
        axes, names, np.moveaxis(draws, -1, 0), layout.log_uniform, strict=True
    ):
        ax.plot(values, lw=0.4, alpha=0.5, rasterized=True)
        ax.set_ylabel(name, fontsize="small")
        if log:  # the noise parameters, log-uniform a priori
            ax.set_yscale("log")
    axes[0].set_title("walkers (kept draws)")
    axes[-1].set_xlabel("draw")
    return fig, axes


def plot_damping(idata, ax: Axes | None = None) -> tuple[Figure, Axes]:
    """Posterior draws of (d_long, d_lat) with the ridge and the thesis' ratio.

    Returns
    -------
    fig, ax
    """
    fig, ax = _figure(ax, figsize=(5.5, 4.5))
    d_lat = idata.posterior["d_lat"].values.ravel()
    d_long = idata.posterior["d_long"].values.ravel()
    ratio = float(np.median(d_lat / d_long))
    ax.plot(
        d_long,
        d_lat,
        ".",
        ms=2,
        alpha=0.3,
        color="tab:blue",
        label="posterior draws",
        rasterized=True,
    )
    span = np.array([d_long.min(), d_long.max()]) * np.array([0.9, 1.1])
    ax.plot(
        span, ratio * span, color=_MODEL_COLOUR, lw=1, label=f"ridge d_lat = {ratio:.3f} d_long"
    )
    ax.plot(span, THESIS_RATIO * span, "k--", lw=0.8, label="thesis 11/3")
    truth = posterior_truth(idata)
    if truth:
        ax.plot(truth["d_long"], truth["d_lat"], "k*", ms=12, label="truth (simulated)")
    ax.set_xlabel("d_long [N s/m]")
    ax.set_ylabel("d_lat [N s/m]")
    ax.legend(fontsize="small")
    return fig, ax


#: Thesis table 7-1: sigma_h of the yaw residuals [s].
THESIS_SIGMA_H = {"v1": 0.051, "v2": 0.041, "all 15": 0.047}


def plot_sigma_h(idata, ax: Axes | None = None) -> tuple[Figure, Axes]:
    """Posterior of the Gaussian filter width sigma_h beside the thesis' table 7-1.

    Returns
    -------
    fig, ax
    """
    fig, ax = _figure(ax, figsize=(6.0, 3.4))
    variable = idata.posterior["sigma_h"]
    groups = variable["noise_group"].values if "noise_group" in variable.dims else [None]
    for group in groups:
        values = (variable if group is None else variable.sel(noise_group=group)).values.ravel()
        ax.hist(values, bins=60, density=True, alpha=0.6, label=f"posterior {group or ''}".strip())
    for (label, value), style in zip(THESIS_SIGMA_H.items(), (":", "-.", "--"), strict=True):
        ax.axvline(value, color="k", ls=style, lw=1, label=f"thesis {label}: {value} s")
    truth = posterior_truth(idata)
    if truth and truth.get("sigma_h"):
        ax.axvline(truth["sigma_h"], color=_MODEL_COLOUR, lw=1.5, label="truth (simulated)")
    ax.set_xlabel("sigma_h [s]")
    ax.set_ylabel("density")
    ax.legend(fontsize="small")
    return fig, ax


def plot_criticism(idata, axes=None) -> tuple[Figure, np.ndarray]:
    """Model criticism: the residual-input test and the residual-ACF p-values.

    One row per channel. Left: MATLAB ``resid``'s independence test, the
    cross-correlation of each experiment's residuals with the wheel-speed
    sum (solid) and difference (dotted) in units of its standard error,
    z(k) = r(k) / sd, with the per-lag 99 % band (+-2.58) and the level of
    the warning over all lags (dashed). Right: the posterior-predictive
    p-values of the residual autocorrelation statistics per experiment; the
    shaded zones (each tail's Bonferroni level, 0.005 for 5 statistics) hold
    the flagged ones. The numbers are
    :func:`bayes_jackal.criticism.criticise`'s.

    Parameters
    ----------
    axes : ndarray of Axes, shape (channels, 2), optional

    Returns
    -------
    fig, axes
    """
    criticism = criticise(idata)["criticism"]
    channels = _channels(idata)
    if axes is None:
        fig = Figure(layout="constrained", figsize=(9.0, 2.6 * len(channels) + 0.4))
        axes = fig.subplots(len(channels), 2, squeeze=False)
    else:
        axes = np.asarray(axes).reshape(len(channels), 2)
        fig = axes[0, 0].figure
    for row, channel in zip(axes, channels, strict=True):
        left, right = row
        for number, rows in enumerate(criticism["residual_input"].values()):
            test = rows[channel]
            lag = np.arange(-test["lags"], test["lags"] + 1)
            for z, style in zip(test["z"].values(), ("-", ":"), strict=False):
                left.plot(lag, z, style, color=f"C{number % 10}", lw=0.9)
            left.axhline(test["threshold"], color="k", ls="--", lw=0.8)
            left.axhline(-test["threshold"], color="k", ls="--", lw=0.8)
        left.axhspan(-test["band"], test["band"], color="tab:blue", alpha=0.12)
        left.set_ylabel(f"{channel}: z(k)")
        tests = criticism["predictive_acf"]
        for number, rows in enumerate(tests.values()):
            values = rows[channel]
            right.plot(values["statistics"], values["p_values"], "o", color=f"C{number % 10}")
        tail = values["tail_level"]
        right.axhspan(0.0, tail, color=_MODEL_COLOUR, alpha=0.2)
        right.axhspan(1.0 - tail, 1.0, color=_MODEL_COLOUR, alpha=0.2)
        right.set_ylim(-0.02, 1.02)
        right.set_ylabel("p-value")
    axes[0, 0].set_title("residual-input cross-correlation (99 % band)", fontsize="medium")
    axes[0, 1].set_title("posterior-predictive p-values of the residual ACF", fontsize="medium")
    axes[-1, 0].set_xlabel("lag k [samples] (input leads for k > 0)")
    return fig, axes
