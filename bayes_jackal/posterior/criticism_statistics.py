"""Array-level statistics behind the model-criticism checks.

Pure functions of numpy arrays, no posterior: the posterior draws' density
at a prior bound (:func:`boundary_density`), the residual-input
cross-correlation and its band (:func:`cross_correlation`,
:func:`cross_correlation_sd`, :func:`simultaneous_threshold`), the
posterior-predictive autocorrelation statistics, their p-values and the
multiple-testing rule that flags them (:func:`acf_statistics`,
:func:`predictive_p_values`, :func:`predictive_flags`), and how far a window
is from steady cornering (:func:`steadiness`). :mod:`bayes_jackal.posterior.criticism`
applies them to a posterior; each of its checks returns a :class:`Check`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.fft
import scipy.stats

from .._runtime import InputError, az
from ..io import STEADY_YAW_FLOOR, STEADY_YAW_TOLERANCE, steady_smoothing
from .series_statistics import ljung_box, sample_autocorrelation

__all__ = [
    "Check",
    "acf_statistics",
    "boundary_density",
    "cross_correlation",
    "cross_correlation_sd",
    "predictive_flags",
    "predictive_p_values",
    "prior_shift",
    "simultaneous_threshold",
    "steadiness",
]


@dataclass
class Check:
    """The result of one check: JSON-ready numbers and warnings.

    Attributes
    ----------
    numbers : dict
    warnings : list of dict
        Each with ``kind`` and ``message`` and the fields that locate it.

    Examples
    --------
    Every check of :mod:`bayes_jackal.posterior.criticism` returns one; a check that
    found nothing to warn about has no warnings:

    >>> from bayes_jackal.posterior import Check
    >>> check = Check({"v1": {"duration": 33.0}})
    >>> check.numbers["v1"]["duration"], check.warnings
    (33.0, [])
    """

    numbers: dict = field(default_factory=dict)
    warnings: list[dict] = field(default_factory=list)


def boundary_density(
    values: np.ndarray, low: float, high: float, *, log: bool, prob: float, strip: float
) -> tuple[float, float]:
    """The draws' density next to each prior bound relative to their density over the HDI.

    In the prior's coordinate x (log theta for a log-uniform prior, theta for
    a uniform one), with the ``prob`` HDI (arviz's) of width w: the fraction
    of draws within ``strip`` w of a bound, divided by that strip's width,
    over ``prob`` / w. About 1 when the posterior runs flat into the bound,
    more when it peaks there, ~0 when it stays clear of it.

    Parameters
    ----------
    values : ndarray
        Posterior draws in natural units, inside [low, high].
    low, high : float
        The prior's bounds (natural units).
    log : bool
        Whether the prior is log-uniform.
    prob : float
        Mass of the HDI.
    strip : float
        Strip width as a fraction of the HDI's width.

    Returns
    -------
    (float, float)
        Density ratio at the lower and at the upper bound.

    Examples
    --------
    Draws spread evenly up to both bounds, draws well inside them, and
    draws piled against the lower bound (a half-normal at 0):

    >>> import numpy as np
    >>> from bayes_jackal.posterior import boundary_density
    >>> rng = np.random.default_rng(1)
    >>> options = dict(log=False, prob=0.94, strip=0.1)
    >>> for draws in (
    ...     rng.uniform(0.0, 1.0, 4000),
    ...     rng.normal(0.5, 0.05, 4000),
    ...     np.abs(rng.normal(0.0, 0.1, 4000)),
    ... ):
    ...     print([round(ratio, 2) for ratio in boundary_density(draws, 0.0, 1.0, **options)])
    [1.02, 1.03]
    [0.0, 0.0]
    [1.59, 0.0]
    """
    transform = np.log if log else np.asarray
    x, lo, hi = transform(np.asarray(values, float).ravel()), transform(low), transform(high)
    start, stop = az.hdi(x, hdi_prob=prob)
    # A posterior narrower than rounding: the strip is at least 1e-9 of the range.
    width = max(strip * (stop - start), 1e-9 * (hi - lo))
    mean_density = prob / (width / strip)
    return (
        float(np.mean(x <= lo + width) / width / mean_density),
        float(np.mean(x >= hi - width) / width / mean_density),
    )


def prior_shift(values: np.ndarray, log_weights: np.ndarray) -> float:
    """How far another prior moves a posterior: the shift of its mean, in posterior sds.

    The draws ``values`` (of one coordinate) reweighted by the ratio of the
    other prior's density to the one they were drawn under, ``exp(log_weights)``
    up to a constant (importance sampling): (weighted mean - mean) / sd. For
    a normal posterior of sd s reweighted by exp(x) the shift is s, so a
    posterior well inside its data (s small) hardly moves, and one the
    prior shapes moves by a good part of its width.

    Examples
    --------
    Normal draws of sd 0.1 and 1 reweighted by exp(x): shifts of 0.1 and 1 sd:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import prior_shift
    >>> x = np.random.default_rng(1).standard_normal(100_000)
    >>> round(prior_shift(0.1 * x, 0.1 * x), 2), round(prior_shift(x, x), 1)
    (0.1, 1.0)
    """
    values = np.asarray(values, float).ravel()
    spread = np.std(values)
    if spread == 0:  # draws all alike (a stuck chain): nothing to move
        return 0.0
    weights = np.exp(log_weights - np.max(log_weights)).ravel()
    shifted = np.sum(weights * values) / np.sum(weights)
    return float((shifted - np.mean(values)) / spread)


# --- residual-input cross-correlation -------------------------------------------------


def _check_lags(lags: int, n: int) -> int:
    if isinstance(lags, bool) or not isinstance(lags, (int, np.integer)) or not 0 <= lags < n:
        raise InputError(f"lags must be an integer in 0..{n - 1}, got {lags!r}", field="lags")
    return int(lags)


def cross_correlation(x: np.ndarray, y: np.ndarray, lags: int) -> np.ndarray:
    """Sample cross-correlation r_xy(k) at lags k = -L..L, by FFT.

    r_xy(k) = sum_t x_c[t + k] y_c[t] / sqrt(sum x_c^2 sum y_c^2) with the
    centred series x_c, y_c (MATLAB ``resid``: x the residual, y the input;
    k > 0 pairs the residual with earlier inputs).

    Parameters
    ----------
    x, y : ndarray, shape (..., n)
        Series, broadcast together over leading axes; neither constant.
    lags : int
        L, 0 <= L < n.

    Returns
    -------
    ndarray, shape (..., 2 L + 1)
        r_xy(-L..L).

    Examples
    --------
    A series against itself delayed by 3 samples peaks at k = 3:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import cross_correlation
    >>> x = np.random.default_rng(1).normal(size=500)
    >>> y = np.roll(x, -3)  # y[t] = x[t + 3]
    >>> r = cross_correlation(x, y, 5)
    >>> r.shape, int(np.argmax(r)) - 5, round(float(r.max()), 3)
    ((11,), 3, 0.998)
    """
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    n = x.shape[-1]
    lags = _check_lags(lags, n)
    xc = x - x.mean(axis=-1, keepdims=True)
    yc = y - y.mean(axis=-1, keepdims=True)
    scale = np.sqrt(np.sum(xc**2, axis=-1) * np.sum(yc**2, axis=-1))
    if not (scale > 0).all():
        raise InputError("a series is constant: its cross-correlation is undefined", field="x")
    size = scipy.fft.next_fast_len(n + lags, real=True)
    cross = scipy.fft.irfft(scipy.fft.rfft(xc, size) * np.conj(scipy.fft.rfft(yc, size)), size)
    ordered = np.concatenate([cross[..., size - lags :], cross[..., : lags + 1]], axis=-1)
    return ordered / scale[..., None]


def cross_correlation_sd(autocorrelation: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Standard error of r_xy(k) when x, with autocorrelation rho_x, is independent of y.

    Bartlett's formula, conditional on y: var r_xy(k) = (1/n) sum_j
    rho_x(j) r_y(j) over |j| < n, with the sample autocorrelation r_y of
    y. At k = 0 it is exactly y_c' R_x y_c / (n y_c' y_c) with the
    correlation matrix R_x of x (taking sum x_c^2 as its expectation). With
    white x it is 1/n, the plain +-z / sqrt(n) band; coloured series (both
    smooth) widen it.

    Parameters
    ----------
    autocorrelation : ndarray, shape (..., m)
        rho_x at lags 0..m-1 (rho_x(0) = 1); lags from n on are unused.
    y : ndarray, shape (..., n)
        The other series, not constant.

    Returns
    -------
    ndarray, shape (...)

    Examples
    --------
    White x gives the plain 1 / sqrt(n); an AR(1) x with rho(j) = 0.9^j
    against a smooth input widens the band about fourfold:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import cross_correlation_sd
    >>> u = np.sin(np.arange(500) / 20)
    >>> bool(np.isclose(cross_correlation_sd(np.array([1.0, 0.0]), u), 1 / np.sqrt(500)))
    True
    >>> round(float(cross_correlation_sd(0.9 ** np.arange(50), u) * np.sqrt(500)), 2)
    3.96
    """
    y = np.asarray(y, float)
    n = y.shape[-1]
    rho = np.asarray(autocorrelation, float)[..., :n]
    r_y = sample_autocorrelation(y, rho.shape[-1] - 1)
    products = rho * r_y
    variance = (2.0 * products.sum(axis=-1) - products[..., 0]) / n
    return np.sqrt(variance)


def simultaneous_threshold(count: int, *, level: float) -> float:
    """|z| that ``count`` standard-normal statistics all stay below with probability >= level.

    Bonferroni: Phi^-1(1 - (1 - level) / (2 count)). It holds whatever their
    correlation, so the family-wise false-alarm rate is at most 1 - level
    (much less for the strongly correlated lags of a smooth input).

    Examples
    --------
    One statistic at 95 % is the familiar 1.96; the residual-input test's
    2 inputs x 51 lags at 99 % need |z| < 3.9:

    >>> from bayes_jackal.posterior import simultaneous_threshold
    >>> round(simultaneous_threshold(1, level=0.95), 3), round(
    ...     simultaneous_threshold(2 * 51, level=0.99), 2
    ... )
    (1.96, 3.9)
    """
    return float(scipy.stats.norm.isf((1.0 - level) / (2.0 * count)))


# --- posterior-predictive autocorrelation ------------------------------------------


def acf_statistics(x: np.ndarray, *, lags: tuple[int, ...], portmanteau: int) -> np.ndarray:
    """Autocorrelation at ``lags`` and the Ljung-Box Q over lags 1..``portmanteau``.

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Series, n > max(lags, portmanteau).

    Returns
    -------
    ndarray, shape (..., len(lags) + 1)

    Examples
    --------
    White noise: autocorrelations near 0 and Q near its chi-squared(10)
    mean of 10:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import acf_statistics
    >>> x = np.random.default_rng(1).normal(size=1000)
    >>> [round(float(s), 3) for s in acf_statistics(x, lags=(1, 2), portmanteau=10)]
    [-0.018, -0.026, 6.807]
    """
    r = sample_autocorrelation(x, max(max(lags), portmanteau))
    q, _ = ljung_box(x, portmanteau)
    return np.concatenate([r[..., list(lags)], q[..., None]], axis=-1)


def predictive_p_values(observed: np.ndarray, replicated: np.ndarray) -> np.ndarray:
    """Posterior-predictive p-values: the fraction of draws with T(rep) >= T(obs).

    Parameters
    ----------
    observed, replicated : ndarray, shape (draws, S)
        Statistics of the data and of a replicated series at each posterior
        draw (realised discrepancies: the observed residuals depend on the
        draw's damping).

    Returns
    -------
    ndarray, shape (S,)

    Examples
    --------
    Two statistics at four draws: the first is exceeded by half of the
    replicated series, the second by all of them:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import predictive_p_values
    >>> observed = np.array([[0.1, 5.0]] * 4)
    >>> replicated = np.array([[0.0, 9.0], [0.2, 8.0], [0.3, 7.0], [0.05, 6.0]])
    >>> predictive_p_values(observed, replicated).tolist()
    [0.5, 1.0]
    """
    return np.mean(np.asarray(replicated) >= np.asarray(observed), axis=0)


def predictive_flags(p_values: np.ndarray, draws: int, *, alarm: float) -> np.ndarray:
    """Which of S posterior-predictive p-values (from ``draws`` draws each) are extreme.

    Bonferroni over both tails of the S statistics: each tail is tested at
    ``alarm`` / (2 S), so the family-wise false-alarm rate is at most
    ``alarm`` whatever the statistics' correlation. A p-value from D draws
    resolves only steps of 1/D, so the test uses the Monte Carlo p-value
    (k + 1) / (D + 1) of the tail, k the replicated statistics at least as
    extreme as the observed one (Davison & Hinkley 1997, eq. 4.11): its
    tail rate under the model is floor(tail (D + 1)) / (D + 1) <= tail even
    for an exact p-value. Posterior-predictive p-values are conservative
    (Meng 1994), so the rate is lower still. With fewer than
    1 / tail - 1 draws nothing can be flagged.

    Parameters
    ----------
    p_values : ndarray, shape (S,)
        Fractions of replicated statistics >= the observed one
        (:func:`predictive_p_values`).
    draws : int
        D, the draws behind each p-value.
    alarm : float
        Family-wise false-alarm level.

    Returns
    -------
    ndarray of bool, shape (S,)

    Examples
    --------
    Both extremes are flagged with 200 draws; with 20 draws nothing can be
    (1 / 21 is above the tail level 0.05 / 6):

    >>> import numpy as np
    >>> from bayes_jackal.posterior import predictive_flags
    >>> p_values = np.array([0.0, 0.5, 1.0])
    >>> predictive_flags(p_values, 200, alarm=0.05).tolist()
    [True, False, True]
    >>> predictive_flags(p_values, 20, alarm=0.05).tolist()
    [False, False, False]
    """
    p = np.asarray(p_values, float)
    count = np.rint(np.minimum(p, 1.0 - p) * draws)
    return (count + 1.0) / (draws + 1.0) <= alarm / (2.0 * p.size)


# --- steadiness ----------------------------------------------------------------------


def steadiness(
    t: np.ndarray, yaw_rate: np.ndarray, inputs: np.ndarray
) -> tuple[float | None, float]:
    """How far a window is from steady cornering, by the rule of ``experiment.detect_steady``.

    Both signals are first smoothed as there
    (:func:`bayes_jackal.io.steady_smoothing`).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times [s].
    yaw_rate : ndarray, shape (N,)
        [rad/s].
    inputs : ndarray, shape (N, 2)
        Wheel speeds [rad/s].

    Returns
    -------
    input_deviation : float or None
        Largest |smoothed wheel speed - its median| over the window, relative
        to the larger median wheel speed; steady when <=
        ``STEADY_INPUT_TOLERANCE``. None when the median wheel speeds are
        both zero (the wheels stand still: no cornering to be steady in).
    yaw_drift : float
        Change of the least-squares line through the smoothed yaw rate over
        the window, relative to max(|median yaw rate|, ``STEADY_YAW_FLOOR`` /
        ``STEADY_YAW_TOLERANCE``); steady when <= ``STEADY_YAW_TOLERANCE``.
        (Process noise makes the yaw rate wander; its trend is what settles.)

    Examples
    --------
    Constant wheel speeds (12 and 6 rad/s) with a constant yaw rate, then
    with a yaw rate ramping from 0.4 to 1.2 rad/s over the 20 s window
    (a drift of 100 % of its median):

    >>> import numpy as np
    >>> from bayes_jackal.posterior import steadiness
    >>> t = np.arange(0.0, 20.0, 1 / 72)
    >>> inputs = np.tile([12.0, 6.0], (t.size, 1))
    >>> deviation, drift = steadiness(t, np.full(t.size, 0.8), inputs)
    >>> deviation, round(drift, 6)
    (0.0, 0.0)
    >>> deviation, drift = steadiness(t, 0.4 + 0.04 * t, inputs)
    >>> deviation, round(drift, 3)
    (0.0, 1.0)
    """
    t = np.asarray(t, float)
    u, r = steady_smoothing(t, yaw_rate, inputs)
    level = np.median(u, axis=0)
    scale = np.abs(level).max()
    input_deviation = float(np.abs(u - level).max() / scale) if scale > 0 else None
    slope = np.polyfit(t - t.mean(), r, 1)[0]
    reference = max(abs(float(np.median(r))), STEADY_YAW_FLOOR / STEADY_YAW_TOLERANCE)
    return input_deviation, float(abs(slope) * (t[-1] - t[0]) / reference)
