"""Figures. Every function takes an optional ``ax`` and returns ``(fig, ax)``.

Figures are built on :class:`matplotlib.figure.Figure` without pyplot, so
nothing here opens a window or depends on a display. This module draws a
posterior: the model against the data, the residuals, walker traces, the
damping and sigma_h, and the model criticism. It also exports the figures
of :mod:`bayes_jackal.report.grid_plots` (grid-search surfaces) and
:mod:`bayes_jackal.report.predictive_plots` (the residuals' autocorrelation and
spectrum against the fitted filter's band).
"""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from .._runtime import CHANNELS
from ..likelihood import residual_times
from ..model import DAMPING
from ..posterior import THESIS_RATIO, Posterior, criticise, model_percentiles, observed_residuals
from ._layout import BAND, DATA_COLOUR, DATA_LABELS, MODEL_COLOUR, UNITS, new_axes

__all__ = [
    "plot_criticism",
    "plot_damping",
    "plot_model_fit",
    "plot_residuals",
    "plot_sigma_h",
    "plot_traces",
]

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
    (:func:`bayes_jackal.posterior.model_percentiles`). The steady window
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

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_model_fit
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, axes = plot_model_fit(posterior)
    >>> [ax.get_ylabel() for ax in axes]
    ['vx [m/s]', 'vy [m/s]', 'yaw [rad/s]']
    >>> axes[0].get_title()
    'v1: model at the posterior against the data'
    """
    experiment = Posterior.of(idata).experiments[index]
    t = experiment.t
    low, median, high = model_percentiles(idata, index, [BAND[0], 50.0, BAND[1]])
    fig, axes = _figures(axes, 3, figsize=(7.0, 6.0))
    for i, (ax, channel) in enumerate(zip(axes, CHANNELS, strict=True)):
        _shade_window(ax, experiment)
        if channel in experiment.channels:
            label = DATA_LABELS[experiment.measurement(channel)]
            _curve(ax, t, experiment.channel(channel), color=DATA_COLOUR, lw=0.6, label=label)
        _band(ax, t, low[:, i], high[:, i], color=MODEL_COLOUR, alpha=0.3)
        _curve(ax, t, median[:, i], color=MODEL_COLOUR, lw=1.2, label="model (94 % band)")
        ax.set_ylabel(f"{channel} [{UNITS[channel]}]")
    axes[0].legend(loc="lower right", fontsize="small")
    axes[0].set_title(f"{experiment.name}: model at the posterior against the data")
    axes[-1].set_xlabel("t [s]")
    return fig, axes


def plot_residuals(idata, index: int = 0, axes=None) -> tuple[Figure, np.ndarray]:
    """One-step residuals at the posterior median, per channel (thesis figs. 7-1..7-6).

    Eq. 7-3's for a measured state, a pose channel's those of its pose
    increments (:mod:`bayes_jackal.likelihood.measurements`), in the same unit.

    Past :data:`MAX_POINTS` residuals each channel is drawn as its envelope
    (the min-max band of each of MAX_POINTS / 2 bins).

    Returns
    -------
    fig, axes

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_residuals
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, axes = plot_residuals(posterior)
    >>> len(axes), axes[0].get_ylabel()  # one channel sampled: one axes
    (1, 'yaw residual [rad/s]')
    """
    posterior = Posterior.of(idata)
    experiment = posterior.experiments[index]
    channels = _channels(idata)
    fig, axes = _figures(axes, len(channels), figsize=(7.0, 1.0 + 1.8 * len(channels)))
    for ax, channel in zip(axes, channels, strict=True):
        residuals = observed_residuals(idata, index, channel)
        t = residual_times(experiment, channel, posterior.metadata.steady)
        _curve(ax, t, residuals, color=DATA_COLOUR, lw=0.6)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{channel} residual [{UNITS[channel]}]")
    axes[0].set_title(f"{experiment.name}: one-step residuals")
    axes[-1].set_xlabel("t [s]")
    return fig, axes


def _channels(idata) -> list[str]:
    return list(Posterior.of(idata).metadata.channels)


def plot_traces(idata, axes=None) -> tuple[Figure, np.ndarray]:
    """Every walker's kept draws of every sampled parameter (after burn-in, thinned).

    Returns
    -------
    fig, axes

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_traces
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, axes = plot_traces(posterior)
    >>> [ax.get_ylabel() for ax in axes], axes[-1].get_yscale()
    (['d_lat', 'd_long', 'sigma_c', 'sigma_n'], 'log')
    """
    posterior = Posterior.of(idata)
    draws, _ = posterior.draws()
    layout = posterior.layout
    names = layout.names
    fig, axes = _figures(axes, len(names), figsize=(7.0, 1.0 + 1.2 * len(names)))
    for ax, name, values, base in zip(
        axes, names, np.moveaxis(draws, -1, 0), layout.bases, strict=True
    ):
        ax.add_collection(_walker_lines(values))
        ax.set_ylabel(name, fontsize="small")
        if base not in DAMPING:  # the noise parameters, spanning decades
            ax.set_yscale("log")
        ax.autoscale_view()
    axes[0].set_title("walkers (kept draws)")
    axes[-1].set_xlabel("draw")
    return fig, axes


def _walker_lines(values: np.ndarray) -> LineCollection:
    """One line per walker (column of ``values``, against the draw), in the colour cycle.

    One collection draws in half the time of a line per walker (the demo's
    traces: 484 lines).
    """
    draws = np.broadcast_to(np.arange(len(values))[:, None], values.shape)
    cycle = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    return LineCollection(
        np.stack([draws, values], axis=-1).swapaxes(0, 1),
        colors=[cycle[walker % len(cycle)] for walker in range(values.shape[1])],
        linewidths=0.4,
        alpha=0.5,
        rasterized=True,
    )


def plot_damping(idata, ax: Axes | None = None) -> tuple[Figure, Axes]:
    """Posterior draws of (d_long, d_lat) with the ridge and the thesis' ratio.

    Returns
    -------
    fig, ax

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_damping
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, ax = plot_damping(posterior)
    >>> ax.get_xlabel(), ax.get_ylabel()
    ('d_long [N s/m]', 'd_lat [N s/m]')
    >>> [text.get_text() for text in ax.get_legend().get_texts()][1:]
    ['ridge d_lat = 3.6... d_long', 'thesis 11/3', 'truth (simulated)']
    """
    fig, ax = new_axes(ax, figsize=(5.5, 4.5))
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
        span, ratio * span, color=MODEL_COLOUR, lw=1, label=f"ridge d_lat = {ratio:.3f} d_long"
    )
    ax.plot(span, THESIS_RATIO * span, "k--", lw=0.8, label="thesis 11/3")
    truth = Posterior.of(idata).truth
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

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_sigma_h
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="gaussian", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, ax = plot_sigma_h(posterior)
    >>> [text.get_text() for text in ax.get_legend().get_texts()]
    ['posterior', 'thesis v1: 0.051 s', 'thesis v2: 0.041 s', 'thesis all 15: 0.047 s',
     'truth (simulated)']
    """
    fig, ax = new_axes(ax, figsize=(6.0, 3.4))
    variable = idata.posterior["sigma_h"]
    groups = variable["noise_group"].values if "noise_group" in variable.dims else [None]
    for group in groups:
        values = (variable if group is None else variable.sel(noise_group=group)).values.ravel()
        ax.hist(values, bins=60, density=True, alpha=0.6, label=f"posterior {group or ''}".strip())
    for (label, value), style in zip(THESIS_SIGMA_H.items(), (":", "-.", "--"), strict=True):
        ax.axvline(value, color="k", ls=style, lw=1, label=f"thesis {label}: {value} s")
    truth = Posterior.of(idata).truth
    if truth and truth.get("sigma_h"):
        ax.axvline(truth["sigma_h"], color=MODEL_COLOUR, lw=1.5, label="truth (simulated)")
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
    :func:`bayes_jackal.posterior.criticise`'s.

    Parameters
    ----------
    axes : ndarray of Axes, shape (channels, 2), optional

    Returns
    -------
    fig, axes

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_criticism
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> fig, axes = plot_criticism(posterior)
    >>> axes.shape, [ax.get_title() for ax in axes[0]]  # a row per channel
    ((1, 2), ['residual-input cross-correlation (99 % band)',
     'posterior-predictive p-values of the residual ACF'])
    >>> [text.get_text() for text in axes[0, 0].get_legend().get_texts()]
    ['v1', 'wheel-speed sum', 'wheel-speed difference', '99 % band per lag',
     'warning level, all lags']
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
        right.axhspan(0.0, tail, color=MODEL_COLOUR, alpha=0.2)
        right.axhspan(1.0 - tail, 1.0, color=MODEL_COLOUR, alpha=0.2)
        right.set_ylim(-0.02, 1.02)
        right.set_ylabel("p-value")
    axes[0, 0].set_title("residual-input cross-correlation (99 % band)", fontsize="medium")
    axes[0, 1].set_title("posterior-predictive p-values of the residual ACF", fontsize="medium")
    axes[-1, 0].set_xlabel("lag k [samples] (input leads for k > 0)")
    _criticism_legends(axes[0], list(criticism["residual_input"]), list(test["z"]))
    return fig, axes


def _criticism_legends(row: np.ndarray, experiments: list[str], inputs: list[str]) -> None:
    """:func:`plot_criticism`'s legends on its first row: colours, line styles and zones."""
    runs = [Line2D([], [], color=f"C{n % 10}", label=name) for n, name in enumerate(experiments)]
    styles = [
        Line2D([], [], color="k", ls=style, lw=0.9, label=f"wheel-speed {name}")
        for name, style in zip(inputs, ("-", ":"), strict=False)
    ]
    left = [
        *runs,
        *styles,
        Patch(color="tab:blue", alpha=0.12, label="99 % band per lag"),
        Line2D([], [], color="k", ls="--", lw=0.8, label="warning level, all lags"),
    ]
    row[0].legend(handles=left, fontsize="x-small", loc="upper right", ncols=2)
    flagged = Patch(color=MODEL_COLOUR, alpha=0.2, label="flagged (Bonferroni tails)")
    right = [Line2D([], [], ls="", marker="o", color=h.get_color(), label=h.get_label())
             for h in runs]  # fmt: skip
    row[1].legend(handles=[*right, flagged], fontsize="x-small", loc="center right")
