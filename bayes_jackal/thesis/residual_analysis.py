"""The thesis' ch. 7 residual analysis: its look at the one-step noise, table 7-1.

The one-step residual w[k] = y[k+1] - Ad y[k] - Bd u[k] (eq. 7-3) of a
measured channel y is what the model leaves unexplained. The thesis reads
its colour from the magnitude spectrum and the sample autocorrelation with
white-noise confidence bounds (figs. 7-7..7-18), and fits the width sigma_h
of its Gaussian filter (eq. 7-5) by least squares between the residual's
autocorrelation and the filter's over the first 30 lags (eq. 7-6, table 7-1).
This module reproduces those steps, adds the Ljung-Box test as a number for
"is it white?", and uses the filter's exact autocorrelation (the sampled
kernel's self-correlation, :mod:`bayes_jackal.model.kernels`) instead of the
thesis' long simulated noise. The statistics of a series it reads
(autocorrelation, bounds, spectra, Ljung-Box) are generic and live in
:mod:`bayes_jackal.posterior.series_statistics`.

The fit ignores sensor noise, as the thesis does ("the measurement noise will
be ignored", ch. 7-2-2). A white sensor noise n adds n[k+1] - Ad n[k] to the
residual (docs/design.md §4): a spike at lag 0 and a negative lag-1 term that pull
the fitted sigma_h down. The Bayesian model accounts for it; this module
does not, by design.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from .._runtime import CHANNELS, RESIDUAL_CHANNELS, DataError, InputError, positive_number
from .._runtime import RESIDUAL_LAGS as LAGS
from ..io import CHANNEL_FIELDS, UNLABELLED, Experiment
from ..likelihood import channel_residuals, check_residual_window
from ..model import RobotProfile, get_family
from ..posterior import autocorrelation_bounds, check_lags, ljung_box, sample_autocorrelation

__all__ = [
    "FIRST_LAGS",
    "SIGMA_H_GRID",
    "analyse",
    "average_per_series",
    "fit_sigma_h",
    "sigma_h_table",
]

#: The thesis' sigma_h grid: 0.001..1 s in steps of 0.001 s (ch. 7-3-1).
#: Written as k / 1000 so that every value is the correctly rounded decimal.
SIGMA_H_GRID = np.arange(1, 1001) / 1000.0
SIGMA_H_GRID.setflags(write=False)
#: Autocorrelations (lags 1..FIRST_LAGS) reported by :func:`analyse`.
FIRST_LAGS = 5


def _gaussian_autocorrelation(grid: np.ndarray, dt: float, lags: int) -> np.ndarray:
    """Exact autocorrelation of the thesis' filter at lags 1..lags, shape (G, lags)."""
    return get_family("gaussian").autocorrelation(grid, dt, lags + 1)[..., 1:]


def _fit(r: np.ndarray, dt: float, lags: int, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    model = _gaussian_autocorrelation(grid, dt, lags)
    # eq. 7-6: MSE between the autocorrelations over lags 1..l, for every grid point
    mse = np.mean((r[..., None, 1 : lags + 1] - model) ** 2, axis=-1)
    return grid[np.argmin(mse, axis=-1)], mse


def _check_grid(grid) -> np.ndarray:
    if grid is None:
        return SIGMA_H_GRID
    grid = np.asarray(grid, float)
    if grid.ndim != 1 or grid.size == 0:
        raise InputError(
            f"sigma_h grid must be a non-empty 1-D array, got shape {grid.shape}", field="grid"
        )
    bad = ~(np.isfinite(grid) & (grid > 0))
    if bad.any():
        raise InputError(
            f"sigma_h grid values must be positive and finite, got {float(grid[bad][0])!r} s",
            field="grid",
        )
    return grid


def fit_sigma_h(
    x: np.ndarray, dt: float, lags: int = LAGS, grid: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The thesis' sigma_h: least squares between autocorrelations (eq. 7-6).

    MSE(sigma_h) = (1/l) sum_{k=1..l} (r_k - rho_k(sigma_h))^2 between the
    sample autocorrelation r of ``x`` and the autocorrelation rho of white
    noise through the Gaussian filter of eq. 7-5 (truncated at +-3 sigma_h),
    minimised over a grid. rho is the sampled kernel's exact discrete
    self-correlation, computed for the whole grid at once; the thesis used
    the autocorrelation of a long simulated filtered noise instead. Below
    sigma_h ~ dt / 3 the sampled kernel is one tap (white noise), so the
    smallest grid values tie and the first of them is returned.

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Residuals, vectorised over leading axes.
    dt : float
        Sample time [s].
    lags : int
        l, the number of lags fitted (30 in the thesis); n >= l + 1.
    grid : ndarray, shape (G,), optional
        sigma_h values [s]; :data:`SIGMA_H_GRID` (0.001..1 s by 0.001 s)
        when omitted.

    Returns
    -------
    sigma_h : ndarray, shape (...)
        Grid value of least MSE [s].
    mse_curve : ndarray, shape (..., G)
        MSE at every grid value [dimensionless].

    Examples
    --------
    Noise through the Gaussian filter of width 0.047 s (the thesis' value),
    at the Jackal's 72 Hz: the fit finds the width on the grid.

    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.thesis import fit_sigma_h
    >>> x = get_family("gaussian").noise(0.047, 1 / 72, 20000, rng=1)
    >>> sigma_h, mse = fit_sigma_h(x, 1 / 72)
    >>> print(float(sigma_h), mse.shape)
    0.047 (1000,)
    """
    dt = positive_number(dt, name="dt", unit="s", required=True, what="the sample time")
    grid = _check_grid(grid)
    r = sample_autocorrelation(x, lags)
    return _fit(r, dt, lags, grid)


def average_per_series(values: dict[str, float], series: dict[str, str | None]) -> dict:
    """Average per-experiment values per series and over all (thesis table 7-1).

    Parameters
    ----------
    values : dict of str to float
        One value per experiment name.
    series : dict of str to (str or None)
        Series label per experiment name; experiments without a label form
        the series ``"unlabelled"`` (as in the grid search).

    Returns
    -------
    dict
        ``series``: label -> mean over its experiments; ``members``: label ->
        experiment names; ``all``: the mean over every experiment (not the
        mean of the series means: the thesis' 10 x v1 + 5 x v2 weigh 2 : 1).

    Examples
    --------
    The overall mean weighs every experiment, not every series:

    >>> from bayes_jackal.thesis import average_per_series
    >>> table = average_per_series(
    ...     {"a": 0.050, "b": 0.040, "c": 0.045}, {"a": "v1", "b": "v2", "c": "v2"}
    ... )
    >>> {label: round(value, 4) for label, value in table["series"].items()}
    {'v1': 0.05, 'v2': 0.0425}
    >>> table["members"], round(table["all"], 4)
    ({'v1': ['a'], 'v2': ['b', 'c']}, 0.045)
    """
    if not values:
        raise InputError("no experiments given", field="experiments")
    members: dict[str, list[str]] = {}
    for name in values:
        members.setdefault(series.get(name) or UNLABELLED, []).append(name)
    return {
        "series": {
            label: float(np.mean([values[n] for n in names])) for label, names in members.items()
        },
        "members": members,
        "all": float(np.mean(list(values.values()))),
    }


def _window_residuals(
    experiment: Experiment,
    robot: RobotProfile,
    d_lat: float,
    d_long: float,
    channel: str,
    lags: int,
) -> tuple[np.ndarray, float]:
    """Steady-window residuals of one channel, checked for the analysis; and dt [s].

    The thesis' analysis is of measured states (eq. 7-3): a channel recorded
    as poses is analysed on the velocity derived from them, as the thesis'
    own motion-capture data were (its pose residual is mostly pose noise).
    """
    if experiment.measurement(channel) == "pose":
        experiment = dataclasses.replace(experiment, pose=None)
    check_residual_window(
        experiment, channel, lags + 1, steady=True, reason=f" for {lags} lags", field="lags"
    )
    residuals = channel_residuals(experiment, robot, d_lat, d_long, channel, steady=True)
    if np.ptp(residuals) == 0:
        raise DataError(
            f"the residuals of channel {channel!r} are constant ({residuals[0]:g}); "
            "the model explains the window exactly and there is no noise to analyse",
            source=experiment.source,
            field=CHANNEL_FIELDS[channel],
        )
    return residuals, experiment.steady().dt


def _check_experiments(experiments: Sequence[Experiment]) -> None:
    if not experiments:
        raise InputError("no experiments given", field="experiments")
    names = [e.name for e in experiments]
    duplicated = sorted({n for n in names if names.count(n) > 1})
    if duplicated:
        raise InputError(f"experiment names are not unique: {duplicated}", field="name")


def sigma_h_table(
    experiments: Sequence[Experiment],
    robot: RobotProfile,
    d_lat: float,
    d_long: float,
    lags: int = LAGS,
) -> dict:
    """Thesis table 7-1: sigma_h of the yaw-rate residuals, per series and over all.

    Each experiment's steady-state yaw residuals get their own fit
    (:func:`fit_sigma_h` on the default grid); the fits are averaged per
    series and over all experiments (:func:`average_per_series`). The thesis
    found 0.051 s (v1), 0.041 s (v2) and 0.047 s (all 15 experiments).

    Parameters
    ----------
    experiments : sequence of Experiment
        Unique names; experiments without a series label form series ``"unlabelled"``.
    robot : RobotProfile
    d_lat, d_long : float
        Damping of the model [N s/m] (the thesis: 110, 30).
    lags : int
        Lags fitted (30).

    Returns
    -------
    dict
        ``experiments``: name -> sigma_h [s]; ``series``, ``members``, ``all``
        as :func:`average_per_series`; ``lags``.

    Raises
    ------
    DataError
        When a steady-state window is shorter than lags + 2 samples, or the
        yaw rate is constant in it (naming the file).
    InputError
        For lags < 1, no experiments or duplicate names.

    Examples
    --------
    One simulated run of each series (truth sigma_h = 0.047 s); the white
    sensor noise, which the thesis' fit ignores, pulls the fits low:

    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.thesis import sigma_h_table
    >>> from bayes_jackal.io import simulate_series
    >>> robot = load_profile()
    >>> runs = simulate_series(robot, 110.0, 30.0, {"v1": 1, "v2": 1}, rng=1)
    >>> table = sigma_h_table(runs, robot, 110.0, 30.0)
    >>> table["experiments"], table["all"]
    ({'v1_01': 0.032, 'v2_01': 0.038}, 0.035)
    """
    lags = check_lags(lags)
    _check_experiments(experiments)
    values = {}
    for experiment in experiments:
        residuals, dt = _window_residuals(experiment, robot, d_lat, d_long, "yaw", lags)
        values[experiment.name] = float(fit_sigma_h(residuals, dt, lags)[0])
    series = {e.name: e.series for e in experiments}
    return {"experiments": values, **average_per_series(values, series), "lags": lags}


def _summary(residuals: np.ndarray, dt: float, lags: int) -> dict:
    """JSON-ready statistics of one residual series."""
    n = residuals.shape[-1]
    r = sample_autocorrelation(residuals, lags)
    statistic, p_value = ljung_box(residuals, lags)
    sigma_h, _ = _fit(r, dt, lags, SIGMA_H_GRID)
    return {
        "n": int(n),
        "mean": float(np.mean(residuals)),
        "sd": float(np.std(residuals, ddof=1)),
        "ljung_box_q": float(statistic),
        "ljung_box_p": float(p_value),
        "autocorrelation": r[1 : min(FIRST_LAGS, lags) + 1].tolist(),
        "bound": autocorrelation_bounds(n),
        "sigma_h": float(sigma_h),
    }


def _check_channels(channels: Sequence[str]) -> list[str]:
    channels = [channels] if isinstance(channels, str) else list(channels)
    unknown = [c for c in channels if c not in CHANNELS]
    if not channels or unknown:
        raise InputError(
            f"unknown or no channel(s) {unknown or channels!r}; use some of {list(CHANNELS)}",
            field="channels",
        )
    return list(dict.fromkeys(channels))


def analyse(
    experiments: Sequence[Experiment],
    robot: RobotProfile,
    d_lat: float,
    d_long: float,
    channels: Sequence[str] = RESIDUAL_CHANNELS,
    lags: int = LAGS,
) -> dict:
    """Residual analysis of thesis ch. 7 for several experiments (JSON-ready).

    For every experiment and channel, on the steady-state window: the number
    of residuals ``n``, their ``mean`` and ``sd`` (ddof 1) [channel unit],
    the Ljung-Box statistic ``ljung_box_q`` and ``ljung_box_p`` at ``lags``,
    the ``autocorrelation`` at lags 1..5, the 95 % white-noise ``bound``
    1.96 / sqrt(n), and the fitted Gaussian-filter width ``sigma_h`` [s]
    (eq. 7-6). Then the thesis' table 7-1 from the yaw channel. vx, vy
    recorded as poses are analysed on the velocities derived from them, as
    the thesis did (``derived`` is True): a smoother's, whose sigma_h is
    wider than the robot's noise (docs/design.md §2.2; the posterior models
    the poses).

    Parameters
    ----------
    experiments : sequence of Experiment
    robot : RobotProfile
    d_lat, d_long : float
        Damping of the model [N s/m].
    channels : sequence of {"yaw", "vx", "vy"}
    lags : int
        Lags of the Ljung-Box test and of the sigma_h fit (30).

    Returns
    -------
    dict
        ``experiments``: name -> channel -> the fields above; ``sigma_h``:
        series label -> mean sigma_h [s] of the yaw channel, plus ``all``
        (the mean over every experiment, which wins over an unlabelled
        series of the same name); ``series``: label -> experiment names;
        ``d_lat``, ``d_long``, ``lags``, ``channels``.

    Raises
    ------
    DataError
        When a steady-state window is shorter than lags + 2 samples, or a
        channel is missing or constant in it (naming the file).
    InputError
        For lags < 1, unknown channels, bad damping, no or duplicate names.

    Examples
    --------
    One simulated v1 run at the true damping: its yaw-rate and vx residuals
    are far from white (Ljung-Box p = 0), coloured by the Gaussian filter.

    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.thesis import analyse
    >>> from bayes_jackal.io import simulate_experiment
    >>> robot = load_profile()
    >>> run = simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> result = analyse([run], robot, 110.0, 30.0, channels=("yaw", "vx"))
    >>> yaw = result["experiments"]["v1"]["yaw"]
    >>> print(yaw["n"], round(yaw["sd"], 4), yaw["ljung_box_p"], round(yaw["bound"], 4))
    2376 0.0119 0.0 0.0402
    >>> result["sigma_h"]
    {'v1': 0.04, 'all': 0.04}
    """
    lags = check_lags(lags)
    channels = _check_channels(channels)
    _check_experiments(experiments)
    rows = {
        e.name: {
            c: _summary(*_window_residuals(e, robot, d_lat, d_long, c, lags), lags)
            | {"derived": e.measurement(c) == "pose"}
            for c in channels
        }
        for e in experiments
    }
    if "yaw" in channels:
        values = {name: row["yaw"]["sigma_h"] for name, row in rows.items()}
        table = average_per_series(values, {e.name: e.series for e in experiments})
    else:
        table = sigma_h_table(experiments, robot, d_lat, d_long, lags)
    return {
        "d_lat": float(d_lat),
        "d_long": float(d_long),
        "lags": lags,
        "channels": channels,
        "experiments": rows,
        "sigma_h": {**table["series"], "all": table["all"]},
        "series": table["members"],
    }
