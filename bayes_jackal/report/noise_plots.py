"""Figures of a bare noise series against its families' posteriors (issue 15's report).

For a :class:`~bayes_jackal.noise.NoiseCharacterisation`:

- :func:`plot_noise_autocorrelation` and :func:`plot_noise_spectrum`: the
  series' sample autocorrelation and Welch PSD against the
  posterior-predictive bands of the best family and of white noise, for
  contrast (:func:`noise_predictive_bands`);
- :func:`plot_noise_widths`: every method's width on one axis in seconds
  (bins on the top axis): each family's posterior (mean and 94 % HDI),
  the classical least-squares widths for 1..10 lags and the thesis' fit.

A posterior-predictive replicate of the series is drawn from one posterior
draw: the family's coloured noise plus the white floor, as long as the
series, exactly from the covariance the likelihood scores
(:meth:`~bayes_jackal.likelihood.SeriesLikelihood.autocovariance`,
drawn by circulant embedding, :func:`bayes_jackal.posterior.stationary_series`).
The mean, which the likelihood integrates out, is left out: the
autocorrelation and the Welch PSD both remove it. At most
:data:`~bayes_jackal.posterior.PREDICTIVE_DRAWS` (200) evenly spaced draws
are used, as many as the report's other bands, made and reduced in chunks,
so nothing of size draws x samples is held for a long series. Built on
:class:`matplotlib.figure.Figure` without pyplot, as every figure of
:mod:`bayes_jackal.report.plots`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .._runtime import InputError, as_rng, thinned_indices
from ..likelihood import SeriesLikelihood
from ..noise import NoiseCharacterisation
from ..posterior import PREDICTIVE_DRAWS, sample_autocorrelation, spectrum, stationary_statistics
from ..thesis import THESIS_LAGS
from ._layout import DATA_COLOUR, MODEL_COLOUR, draw_band, new_axes
from .page import LAGS
from .predictive_plots import band_statistics

__all__ = [
    "noise_predictive_bands",
    "plot_noise_autocorrelation",
    "plot_noise_spectrum",
    "plot_noise_widths",
    "replicate_statistics",
]

#: The band of white noise, drawn for contrast.
WHITE_COLOUR = "tab:blue"


def replicate_statistics(
    result: NoiseCharacterisation,
    family: str,
    statistics: Mapping[str, Callable[[np.ndarray], np.ndarray]],
    *,
    count: int = PREDICTIVE_DRAWS,
    rng: np.random.Generator | int | None = None,
) -> dict[str, np.ndarray]:
    """Statistics of posterior-predictive replicates of the series under one family.

    One replicate per posterior draw (at most ``count``, evenly spaced): the
    family's coloured noise plus the white floor, as long as the series
    (module docstring), reduced chunk by chunk to ``statistics``.

    Parameters
    ----------
    result : NoiseCharacterisation
    family : str
        One of ``result.fits``.
    statistics : mapping of str to callable
        Each maps replicates of shape (B, n) [series units] to statistics of
        shape (B, ...).
    count : int
        Most draws used.
    rng : numpy.random.Generator, int or None

    Returns
    -------
    dict of str to ndarray
        Each statistic of every replicate, shape (B, ...), B <= ``count``.

    Raises
    ------
    InputError
        For a family that was not fitted.

    Examples
    --------
    A posterior of 100 draws at sigma_c = 1 and sigma_n = 0.5 (built, not
    sampled): the replicates' mean square is about 1.25, their variance
    (0.007 its standard error). The series' values set only its length here.

    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.report import replicate_statistics
    >>> from bayes_jackal.noise import NoiseSeries
    >>> values = np.random.default_rng(1).standard_normal(4000)
    >>> series = NoiseSeries(values=values, dt=0.01, name="imu")
    >>> fit = FamilyFit(family="gaussian", names=("sigma_h", "sigma_c", "sigma_n"), dt=0.01,
    ...                 draws=np.array([[0.03, 1.0, 0.5]] * 100), warnings=[],
    ...                 evidence=Evidence(0.0, 0.1, "bridge sampling"),
    ...                 diagnostics={"converged": True})
    >>> result = NoiseCharacterisation(series=series, fits={"gaussian": fit},
    ...                                acf_least_squares={}, thesis_fit=0.0)
    >>> square = {"square": lambda x: np.mean(x**2, axis=1)}
    >>> replicated = replicate_statistics(result, "gaussian", square, rng=1)["square"]
    >>> replicated.shape, round(float(replicated.mean()), 2)
    ((100,), 1.25)
    """
    if family not in result.fits:
        raise InputError(f"no fit of family {family!r}; fitted: {list(result.fits)}",
                         field="family")  # fmt: skip
    series = result.series
    draws = result.fits[family].draws
    theta = draws[thinned_indices(len(draws), count)]
    likelihood = SeriesLikelihood(values=series.values, dt=series.dt, family=family)
    n = len(series.values)
    return stationary_statistics(
        lambda part: likelihood.autocovariance(theta[part], n), len(theta), n, statistics, rng=rng
    )


def _band_families(result: NoiseCharacterisation) -> list[str]:
    """The best family, and white noise for contrast when it was fitted and is not the best."""
    contrast = ["white"] if "white" in result.fits and result.best != "white" else []
    return [result.best, *contrast]


def noise_predictive_bands(
    result: NoiseCharacterisation,
    *,
    families: Sequence[str] | None = None,
    lags: int = LAGS,
    count: int = PREDICTIVE_DRAWS,
    rng: np.random.Generator | int | None = 0,
) -> dict[str, dict[str, np.ndarray]]:
    """Each family's replicates' autocorrelation and Welch PSD, behind the bands of the figures.

    Parameters
    ----------
    result : NoiseCharacterisation
    families : sequence of str, optional
        By default the best family, and white noise when it was fitted.
    lags : int
        Largest lag of the autocorrelation.
    count : int
        Most draws per family.
    rng : numpy.random.Generator, int or None
        Each family draws from a stream spawned from it: same seed, same bands.

    Returns
    -------
    dict of str to dict
        Family -> ``acf``, shape (B, lags + 1), and ``psd``, shape (B, F)
        [(series units)^2 / Hz] (:func:`bayes_jackal.report.predictive_bands`'s).

    Examples
    --------
    A white-noise posterior built at the series' sd (not sampled):

    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.report import noise_predictive_bands
    >>> from bayes_jackal.noise import NoiseSeries
    >>> values = np.random.default_rng(1).standard_normal(600)
    >>> series = NoiseSeries(values=values, dt=0.01, name="imu")
    >>> white = FamilyFit(family="white", names=("sigma",), draws=np.ones((50, 1)), dt=0.01,
    ...                   evidence=Evidence(0.0, 0.1, "bridge sampling"),
    ...                   diagnostics={"converged": True}, warnings=[])
    >>> result = NoiseCharacterisation(series=series, fits={"white": white},
    ...                                acf_least_squares={}, thesis_fit=0.0)
    >>> bands = noise_predictive_bands(result, lags=10)
    >>> list(bands), bands["white"]["acf"].shape, bands["white"]["psd"].shape
    (['white'], (50, 11), (50, 129))
    """
    families = _band_families(result) if families is None else list(families)
    statistics = band_statistics(result.series.dt, lags)
    streams = as_rng(rng).spawn(len(families))
    return {
        family: replicate_statistics(result, family, statistics, count=count, rng=stream)
        for family, stream in zip(families, streams, strict=True)
    }


def _bands(
    result: NoiseCharacterisation, predictive: dict | None, rng, lags: int = LAGS
) -> dict[str, dict[str, np.ndarray]]:
    """``predictive`` when given, else :func:`noise_predictive_bands` drawn with ``rng``."""
    return predictive or noise_predictive_bands(result, lags=lags, rng=rng)


def _colour(result: NoiseCharacterisation, family: str) -> str:
    """The best family's band red, white noise's blue, any other family's grey."""
    if family == result.best:
        return MODEL_COLOUR
    return WHITE_COLOUR if family == "white" else "0.55"


def plot_noise_autocorrelation(
    result: NoiseCharacterisation,
    *,
    lags: int = LAGS,
    ax: Axes | None = None,
    predictive: dict[str, dict[str, np.ndarray]] | None = None,
    rng: np.random.Generator | int | None = 0,
) -> tuple[Figure, Axes]:
    """The series' sample autocorrelation against the families' predictive bands.

    Each band spans the central 94 % of the sample autocorrelations of the
    replicates (:func:`noise_predictive_bands`): the parameters' uncertainty
    and the estimate's sampling noise together; the line is their median.
    ``predictive`` passes the bands when already computed (of the same
    ``lags``); else they are drawn with ``rng``.

    Returns
    -------
    fig, ax

    Raises
    ------
    InputError
        When ``predictive`` holds the autocorrelation at other lags.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.report import plot_noise_autocorrelation
    >>> from bayes_jackal.noise import NoiseSeries
    >>> values = np.random.default_rng(1).standard_normal(600)
    >>> series = NoiseSeries(values=values, dt=0.01, name="imu")
    >>> white = FamilyFit(family="white", names=("sigma",), draws=np.ones((50, 1)), dt=0.01,
    ...                   evidence=Evidence(0.0, 0.1, "bridge sampling"),
    ...                   diagnostics={"converged": True}, warnings=[])
    >>> result = NoiseCharacterisation(series=series, fits={"white": white},
    ...                                acf_least_squares={}, thesis_fit=0.0)
    >>> fig, ax = plot_noise_autocorrelation(result, lags=10)
    >>> ax.get_title(), [text.get_text() for text in ax.get_legend().get_texts()]
    ('imu: autocorrelation', ['white (best), 94 %', 'imu'])
    """
    fig, ax = new_axes(ax, figsize=(6.0, 3.6))
    bands = _bands(result, predictive, rng, lags)
    lag = np.arange(lags + 1)
    for family, statistics in bands.items():
        acf = _checked(statistics, "acf", lags + 1, lambda k: f"lags 0..{k - 1}")
        draw_band(ax, lag, acf, color=_colour(result, family), label=_label(result, family))
    observed = sample_autocorrelation(result.series.values, lags)
    name = result.series.name
    ax.plot(lag, observed, "o-", color=DATA_COLOUR, ms=3, lw=0.8, label=name)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("lag [samples]")
    ax.set_ylabel("autocorrelation")
    ax.set_title(f"{name}: autocorrelation")
    ax.legend(fontsize="small", loc="upper right")  # "best" costs 0.3-0.6 s a figure
    return fig, ax


def _checked(
    statistics: dict[str, np.ndarray], key: str, length: int, what: Callable[[int], str]
) -> np.ndarray:
    """``statistics[key]``, refused unless its last axis has ``length`` values.

    ``what(k)`` says what ``k`` values are, e.g. "lags 0..k-1", in the error.
    """
    values = statistics[key]
    if values.shape[-1] != length:
        raise InputError(
            f"the predictive {_STATISTICS[key]} has {what(values.shape[-1])}, the figure "
            f"{what(length)}: drawn for another series or lag count",
            field="predictive",
        )
    return values


#: What each statistic of :func:`noise_predictive_bands` is, in errors.
_STATISTICS = {"acf": "autocorrelation", "psd": "spectrum"}


def _label(result: NoiseCharacterisation, family: str) -> str:
    return f"{family}{' (best)' if family == result.best else ''}, 94 %"


def plot_noise_spectrum(
    result: NoiseCharacterisation,
    *,
    ax: Axes | None = None,
    predictive: dict[str, dict[str, np.ndarray]] | None = None,
    rng: np.random.Generator | int | None = 0,
) -> tuple[Figure, Axes]:
    """The series' Welch PSD against the families' predictive bands.

    Each replicate's PSD is estimated exactly as the series'
    (:func:`bayes_jackal.posterior.spectrum`); ``predictive`` and
    ``rng`` as in :func:`plot_noise_autocorrelation`.

    Returns
    -------
    fig, ax

    Raises
    ------
    InputError
        When ``predictive`` holds spectra of another length than the series'.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.report import plot_noise_spectrum
    >>> from bayes_jackal.noise import NoiseSeries
    >>> values = np.random.default_rng(1).standard_normal(600)
    >>> series = NoiseSeries(values=values, dt=0.01, name="imu")
    >>> white = FamilyFit(family="white", names=("sigma",), draws=np.ones((50, 1)), dt=0.01,
    ...                   evidence=Evidence(0.0, 0.1, "bridge sampling"),
    ...                   diagnostics={"converged": True}, warnings=[])
    >>> result = NoiseCharacterisation(series=series, fits={"white": white},
    ...                                acf_least_squares={}, thesis_fit=0.0)
    >>> fig, ax = plot_noise_spectrum(result)
    >>> ax.get_title(), ax.get_xlabel(), ax.get_xscale()
    ('imu: spectrum', 'frequency [Hz]', 'log')
    """
    fig, ax = new_axes(ax, figsize=(6.0, 3.6))
    frequency, observed = spectrum(result.series.values, result.series.dt)
    for family, statistics in _bands(result, predictive, rng).items():
        psd = _checked(statistics, "psd", len(frequency), lambda k: f"{k} frequencies")
        draw_band(ax, frequency[1:], psd[:, 1:], color=_colour(result, family),
                  label=_label(result, family))  # fmt: skip
    name = result.series.name
    ax.loglog(frequency[1:], observed[1:], color=DATA_COLOUR, lw=0.8, label=name)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("PSD [(series unit)²/Hz]")
    ax.set_title(f"{name}: spectrum")
    ax.legend(fontsize="small", loc="lower left")  # where a spectrum rarely is
    return fig, ax


def plot_noise_widths(
    result: NoiseCharacterisation, *, ax: Axes | None = None
) -> tuple[Figure, Axes]:
    """Every method's width on one axis [s], with bins on the top axis.

    One row per method: each family with a width, its posterior mean (a
    marker) and 94 % HDI (a line), drawn apart because a skewed or two-armed
    posterior's mean can lie outside its HDI; the least-squares widths for
    1..10 lags; the thesis' fit. The axis is logarithmic: a posterior's
    interval can span decades. A least-squares width of 0 (no Gaussian fits
    the lags better than none) has no point, and its row says so. The
    families' widths are each their own kernel's (:mod:`bayes_jackal.model.kernels`),
    the classical ones a Gaussian's: alike in scale, not equal by definition.

    Returns
    -------
    fig, ax

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.report import plot_noise_widths
    >>> from bayes_jackal.noise import NoiseSeries
    >>> values = np.random.default_rng(1).standard_normal(600)
    >>> series = NoiseSeries(values=values, dt=0.01, name="imu")
    >>> draws = np.column_stack([np.linspace(0.02, 0.04, 50), np.ones(50), np.full(50, 0.3)])
    >>> fit = FamilyFit(family="gaussian", names=("sigma_h", "sigma_c", "sigma_n"), dt=0.01,
    ...                 draws=draws, diagnostics={"converged": True}, warnings=[],
    ...                 evidence=Evidence(0.0, 0.1, "bridge sampling"))
    >>> result = NoiseCharacterisation(series=series, fits={"gaussian": fit},
    ...                                acf_least_squares={1: 0.02, 2: 0.0}, thesis_fit=0.025)
    >>> fig, ax = plot_noise_widths(result)
    >>> for label in ax.get_yticklabels():
    ...     print(label.get_text())
    gaussian posterior (best)
    ACF least squares, 1 lag
    ACF least squares, 2 lags (none fits)
    thesis' fit (30 lags)
    >>> ax.get_xlabel(), ax.get_xscale()
    ('width [s]', 'log')
    """
    rows = _width_rows(result)
    fig, ax = new_axes(ax, figsize=(6.5, 1.2 + 0.28 * len(rows)))
    for kind, (marker, colour) in _WIDTH_STYLES.items():
        shown = [(i, value, low, high) for i, (k, _, value, low, high) in enumerate(rows)
                 if k == kind and value > 0]  # fmt: skip
        if shown:
            position, value, low, high = np.array(shown).T
            ax.hlines(position, low, high, color=colour, lw=1.5)
            ax.plot(value, position, marker, color=colour, linestyle="none")
    ax.set_yticks(range(len(rows)), [label for _, label, *_ in rows])
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xscale("log")
    ax.set_xlabel("width [s]")
    dt = result.series.dt
    bins = ax.secondary_xaxis("top", functions=(lambda s: s / dt, lambda b: b * dt))
    bins.set_xlabel("width [samples]")
    for axis in (ax.xaxis, bins.xaxis):
        axis.set_major_formatter(_number_format)
        axis.set_minor_formatter(lambda v, _: _number_format(v) if _mantissa(v) in (2, 5) else "")
    ax.set_title(f"{result.series.name}: the width by each method", fontsize="medium")
    ax.grid(axis="x", which="both", alpha=0.3)
    return fig, ax


#: Marker and colour of each kind of width in :func:`plot_noise_widths` (its rows name them).
_WIDTH_STYLES = {
    "best": ("o", MODEL_COLOUR),
    "posterior": ("o", "0.55"),
    "least squares": ("s", DATA_COLOUR),
    "thesis": ("D", WHITE_COLOUR),
}


def _number_format(value: float, _position=None) -> str:
    return f"{value:.3g}"


def _mantissa(value: float) -> int:
    """The leading digit of a positive tick value (2 for 0.02)."""
    return round(value / 10 ** np.floor(np.log10(value))) if value > 0 else 0


def _width_rows(result: NoiseCharacterisation) -> list[tuple[str, str, float, float, float]]:
    """Each method's width [s]: (kind, label, value, low, high), the interval a posterior's.

    The families with a width (kind ``best`` or ``posterior``: the mean and
    94 % HDI), the least-squares widths by lag count, the thesis' fit; a
    classical width is its own interval. A least-squares width of 0 (no
    Gaussian fits) is labelled so.
    """
    rows = []
    for family, fit in result.fits.items():
        width = fit.width()
        if width is not None:
            seconds = width["seconds"]
            best = family == result.best
            rows.append(("best" if best else "posterior",
                         f"{family} posterior{' (best)' if best else ''}", seconds["mean"],
                         seconds["hdi_3%"], seconds["hdi_97%"]))  # fmt: skip
    for count, value in result.acf_least_squares.items():
        label = f"ACF least squares, {count} lag{'s' if count > 1 else ''}"
        rows.append(("least squares", label + (" (none fits)" if value == 0 else ""), value,
                     value, value))  # fmt: skip
    fit = result.thesis_fit
    rows.append(("thesis", f"thesis' fit ({THESIS_LAGS} lags)", fit, fit, fit))
    return rows
