"""Statistics of a series: sample autocorrelation, its white-noise bounds, spectra, Ljung-Box.

Generic tools on any uniformly sampled series (vectorised over leading
axes), with the conventions of the thesis' MATLAB figures where it has one
(MATLAB's ``autocorr`` bounds, its single-sided amplitude spectrum). The
thesis' ch. 7 residual analysis (:mod:`bayes_jackal.thesis.residual_analysis`),
the figures (:mod:`bayes_jackal.report.plots`) and the model-criticism statistics
(:mod:`bayes_jackal.posterior.criticism_statistics`) use them.
"""

from __future__ import annotations

import numpy as np
import scipy.fft
import scipy.signal
import scipy.special
import scipy.stats

from .._runtime import InputError, positive_number

__all__ = [
    "MATLAB_LEVEL",
    "WELCH_SEGMENT",
    "autocorrelation_bounds",
    "check_lags",
    "ljung_box",
    "magnitude_spectrum",
    "sample_autocorrelation",
    "spectrum",
]

#: Confidence level of MATLAB's ``autocorr`` bounds: 2 standard errors
#: (``NumSTD = 2``), i.e. erf(sqrt(2)) = 0.9545.
MATLAB_LEVEL = float(scipy.special.erf(np.sqrt(2.0)))
#: Samples per Welch segment (3.6 s at 72 Hz: 0.28 Hz resolution).
WELCH_SEGMENT = 256


def check_lags(lags: int) -> int:
    """A number of autocorrelation lags: an integer >= 1 (a bool is refused).

    Parameters
    ----------
    lags : int
        Lags of an autocorrelation [samples].

    Returns
    -------
    int

    Raises
    ------
    InputError
        Naming ``lags`` and the value.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.posterior import check_lags
    >>> check_lags(np.int64(10))
    10
    >>> try:
    ...     check_lags(2.5)
    ... except ValueError as exc:
    ...     print(exc)
    lags: number of lags must be an integer >= 1, got 2.5
    """
    if isinstance(lags, bool) or not isinstance(lags, (int, np.integer)) or lags < 1:
        raise InputError(f"number of lags must be an integer >= 1, got {lags!r}", field="lags")
    return int(lags)


def _check_series(x, lags: int) -> np.ndarray:
    """A finite, non-constant series (..., n) with n >= lags + 1."""
    x = np.asarray(x, float)
    if x.ndim < 1 or x.shape[-1] < lags + 1:
        n = x.shape[-1] if x.ndim else 0
        raise InputError(
            f"{n} samples are too few for {lags} lags (at least {lags + 1} are needed)",
            field="lags",
        )
    if not np.isfinite(x).all():
        raise InputError("series holds non-finite values", field="x")
    if (np.ptp(x, axis=-1) == 0).any():
        raise InputError("series is constant: its autocorrelation is undefined", field="x")
    return x


def sample_autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    """Normalised sample autocorrelation r[0..lags] (r[0] = 1), by FFT.

    The biased estimator of the thesis' ``autocorr``: the mean is removed and
    every lag is divided by the same sum, r[k] = sum_t x_c[t] x_c[t+k] /
    sum_t x_c[t]^2. The FFT is zero-padded to at least n + lags points, so
    no circular wrap reaches the returned lags.

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Series, vectorised over leading axes.
    lags : int
        Largest lag, >= 1; n >= lags + 1.

    Returns
    -------
    ndarray, shape (..., lags + 1)

    Raises
    ------
    InputError
        For lags < 1, too short, non-finite or constant series.

    Examples
    --------
    For 1, 2, 3, 4 the centred series is -1.5, -0.5, 0.5, 1.5 (sum of squares
    5): r[1] = 1.25 / 5 and r[2] = -1.5 / 5.

    >>> import numpy as np
    >>> from bayes_jackal.posterior import sample_autocorrelation
    >>> r = sample_autocorrelation(np.array([1.0, 2.0, 3.0, 4.0]), 2)
    >>> np.allclose(r, [1.0, 0.25, -0.3])
    True
    """
    lags = check_lags(lags)
    x = _check_series(x, lags)
    centred = x - x.mean(axis=-1, keepdims=True)
    size = scipy.fft.next_fast_len(x.shape[-1] + lags, real=True)
    power = np.abs(scipy.fft.rfft(centred, size)) ** 2
    covariance = scipy.fft.irfft(power, size)[..., : lags + 1]
    return covariance / covariance[..., :1]


def autocorrelation_bounds(n: int, level: float = 0.95) -> float:
    """White-noise confidence bound +-z / sqrt(n) of a sample autocorrelation.

    For white noise sqrt(n) r[k] is asymptotically N(0, 1) at every lag
    k >= 1, so r[k] lies within +-z / sqrt(n) with probability ``level``,
    z = Phi^-1((1 + level) / 2). MATLAB's ``autocorr`` (thesis figs.
    7-10..7-18) draws 2 standard errors, +-2 / sqrt(n): pass
    ``level=MATLAB_LEVEL`` for exactly that; 0.95 gives 1.96 / sqrt(n).

    Parameters
    ----------
    n : int
        Length of the series.
    level : float
        Two-sided confidence level, 0 < level < 1.

    Returns
    -------
    float
        The bound (its negative is the lower bound).

    Examples
    --------
    For 400 samples: 1.96 / 20 at 95 %, MATLAB's 2 / 20 at its level:

    >>> from bayes_jackal.posterior import MATLAB_LEVEL, autocorrelation_bounds
    >>> round(autocorrelation_bounds(400), 4)
    0.098
    >>> round(autocorrelation_bounds(400, MATLAB_LEVEL), 4)
    0.1
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"series length must be an integer >= 1, got {n!r}", field="n")
    if not 0.0 < level < 1.0:
        raise InputError(f"confidence level must be in (0, 1), got {level!r}", field="level")
    return float(scipy.stats.norm.ppf(0.5 + 0.5 * level) / np.sqrt(n))


def spectrum(
    x: np.ndarray, dt: float, segment: int = WELCH_SEGMENT
) -> tuple[np.ndarray, np.ndarray]:
    """One-sided power spectral density by Welch's method.

    ``scipy.signal.welch`` with a Hann window of ``min(segment, n)`` samples,
    50 % overlap, the mean of each segment removed (``detrend="constant"``),
    density scaling and a one-sided spectrum (bins other than 0 and Nyquist
    doubled), so that sum(psd) * df is about the variance of ``x``.

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Series [unit], vectorised over leading axes.
    dt : float
        Sample time [s].
    segment : int
        Samples per segment (256: 3.6 s and 0.28 Hz resolution at 72 Hz).

    Returns
    -------
    frequency : ndarray, shape (F,)
        [Hz], 0..1 / (2 dt).
    psd : ndarray, shape (..., F)
        [unit^2 / Hz].

    Examples
    --------
    White noise of sd 0.1 sampled at 72 Hz for 100 s: 129 bins up to the
    Nyquist frequency, and the density integrates to the variance:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import spectrum
    >>> x = 0.1 * np.random.default_rng(1).standard_normal(7200)
    >>> frequency, psd = spectrum(x, 1 / 72)
    >>> print(psd.shape, float(frequency[-1]))
    (129,) 36.0
    >>> print(round(float(np.sum(psd) * frequency[1]), 4), round(float(np.var(x)), 4))
    0.0099 0.0099
    """
    dt = positive_number(dt, name="dt", unit="s", required=True, what="the sample time")
    x = np.asarray(x, float)
    if isinstance(segment, bool) or not isinstance(segment, (int, np.integer)) or segment < 2:
        raise InputError(f"segment must be an integer >= 2, got {segment!r}", field="segment")
    if x.ndim < 1 or x.shape[-1] < 2:
        raise InputError(f"spectrum needs at least 2 samples, got shape {x.shape}", field="x")
    nperseg = min(int(segment), x.shape[-1])
    return scipy.signal.welch(
        x,
        fs=1.0 / dt,
        window="hann",
        nperseg=nperseg,
        noverlap=nperseg // 2,
        detrend="constant",
        return_onesided=True,
        scaling="density",
        axis=-1,
    )


def magnitude_spectrum(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided amplitude spectrum |FFT| (thesis figs. 7-7..7-9, 7-13..7-15).

    MATLAB's recipe: |X| / n of the whole series (no window, mean kept),
    bins other than 0 and Nyquist doubled, so that a sine of amplitude A at a
    bin frequency shows as A.

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Series [unit], vectorised over leading axes.
    dt : float
        Sample time [s].

    Returns
    -------
    frequency : ndarray, shape (n // 2 + 1,)
        [Hz].
    magnitude : ndarray, shape (..., n // 2 + 1)
        [unit].

    Examples
    --------
    A sine of amplitude 2 at 3.6 Hz on an offset of 0.5, 10 s at 72 Hz:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import magnitude_spectrum
    >>> t = np.arange(720) / 72
    >>> frequency, magnitude = magnitude_spectrum(0.5 + 2 * np.sin(2 * np.pi * 3.6 * t), 1 / 72)
    >>> peak = 1 + np.argmax(magnitude[1:])
    >>> print(float(frequency[peak]), *(round(float(magnitude[k]), 4) for k in (peak, 0)))
    3.6 2.0 0.5
    """
    dt = positive_number(dt, name="dt", unit="s", required=True, what="the sample time")
    x = np.asarray(x, float)
    if x.ndim < 1 or x.shape[-1] < 2:
        raise InputError(f"spectrum needs at least 2 samples, got shape {x.shape}", field="x")
    n = x.shape[-1]
    magnitude = np.abs(scipy.fft.rfft(x, axis=-1)) / n
    magnitude[..., 1 : (n + 1) // 2] *= 2.0  # the Nyquist bin (even n) has no mirror
    return scipy.fft.rfftfreq(n, dt), magnitude


def _ljung_box(r: np.ndarray, n: int, lags: int) -> tuple[np.ndarray, np.ndarray]:
    k = np.arange(1, lags + 1)
    statistic = n * (n + 2.0) * np.sum(r[..., 1 : lags + 1] ** 2 / (n - k), axis=-1)
    return statistic, scipy.stats.chi2.sf(statistic, lags)


def ljung_box(x: np.ndarray, lags: int) -> tuple[np.ndarray, np.ndarray]:
    """Ljung-Box portmanteau test of whiteness.

    Q = n (n + 2) sum_{k=1..h} r_k^2 / (n - k) with the sample
    autocorrelation r (:func:`sample_autocorrelation`), h = ``lags``; under
    white noise Q is asymptotically chi^2 with h degrees of freedom. (No
    degrees of freedom are removed for fitted parameters: d is fixed here.)

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Series, vectorised over leading axes.
    lags : int
        h >= 1; n >= h + 1.

    Returns
    -------
    Q : ndarray, shape (...)
    p_value : ndarray, shape (...)
        P(chi^2_h >= Q); small values reject whiteness.

    Examples
    --------
    White noise is not rejected; Gaussian-coloured noise (sigma_h = 0.047 s
    at 72 Hz, thesis ch. 7) is, by far:

    >>> import numpy as np
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.posterior import ljung_box
    >>> q, p = ljung_box(np.random.default_rng(1).standard_normal(1000), 10)
    >>> print(round(float(q), 2), round(float(p), 3))
    6.81 0.744
    >>> coloured = get_family("gaussian").noise(0.047, 1 / 72, 1000, rng=1)
    >>> q, p = ljung_box(coloured, 10)
    >>> print(round(float(q)), float(p) < 1e-100)
    3828 True
    """
    r = sample_autocorrelation(x, lags)
    return _ljung_box(r, np.shape(x)[-1], lags)
