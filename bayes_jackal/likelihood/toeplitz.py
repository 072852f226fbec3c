"""Exact Gaussian log-densities of series under a Toeplitz covariance, in the time domain.

:func:`toeplitz_loglike` is the Durbin-Levinson recursion, O(n^2): the
``exact`` engines' reference. :func:`banded_toeplitz_loglike` is the
banded Cholesky factorisation, O(n p^2), and :func:`fallback_loglike`
chooses between them for the ``fast`` engines' fallback.

Every noise family but the exponential has a kernel of finite length, so
the autocovariance of the one-step residual (:mod:`bayes_jackal.likelihood.residual_likelihood`)
and of a bare noise series (:mod:`bayes_jackal.likelihood.series_likelihood`) vanishes
beyond some lag p: its Toeplitz covariance T (n x n, first row
r_0, ..., r_p, 0, ..., 0) is banded, and so is its Cholesky factor,

    T = L L',   L lower triangular, L[i, j] = 0 for i - j > p,

computed by LAPACK's banded Cholesky (dpbtrf, O(n p^2), backward stable;
T is positive definite iff it succeeds). With z = L^-1 x (the banded
triangular solve dtbtrs, O(n p) per series),

    log N(x; 0, T) = -1/2 (2 sum_k log L[k, k] + |z|^2 + n log 2 pi),

exact: no truncation, every row of the factor is computed. The
Durbin-Levinson recursion costs O(n^2) instead, as the predictor of a
moving-average process does not end. This is the ``fast`` engines'
fallback for the parameter sets no spectral grid certifies
(:func:`fallback_loglike`): a moving-average kernel's spectral nulls,
barely lifted by a white floor, make its spectral factor converge slowly,
but its band stays p + 1 lags wide.
"""

from __future__ import annotations

import numpy as np
import scipy.fft
import scipy.linalg

from ..model import bandwidth

__all__ = [
    "FALLBACK_BAND",
    "FAST_TOLERANCE",
    "SCAN_WORK",
    "banded_loglike",
    "banded_toeplitz_loglike",
    "fallback_loglike",
    "toeplitz_loglike",
]

_LOG_2PI = np.log(2.0 * np.pi)
#: Consecutive negligible partial autocorrelations that end the recursion.
_QUIET_STEPS = 16
#: Threshold of a negligible partial autocorrelation in the fallback recursion:
#: the error grows with tol and n (measured on 2 x 5,000 moving-average
#: residuals: 2.3e-6 nats at 1e-10, 1e-8 at 1e-12, 8e-10 at 1e-13).
FAST_TOLERANCE = 1e-13
#: The fallback (:func:`fallback_loglike`) takes the banded factor for bands
#: of p + 1 <= FALLBACK_BAND sqrt(n) lags (n samples), the recursion beyond.
FALLBACK_BAND = 4
#: A scan's fallback takes the banded factor only where it costs little as
#: well: n (p + 1)^2 <= SCAN_WORK (measured, one thread: 15 ms a set at
#: n = 10,000 and p + 1 = 100, 1.3 ms at n = 1,000 and 31, 2.4 ms at 126);
#: a set cost flat in the record's length.
SCAN_WORK = 1e8


def toeplitz_loglike(acov: np.ndarray, x: np.ndarray, tol: float | None = None) -> np.ndarray:
    """Gaussian log-density of series with Toeplitz covariance (Durbin-Levinson).

    The log-determinant is the sum of the log prediction-error variances,
    the quadratic form the sum of the squared standardised innovations of
    the order-k predictors. The recursion over the order k is sequential;
    every step is vectorised over the batch.

    With ``tol`` the recursion stops once 16 consecutive partial
    autocorrelations of every batch member are below ``tol``; the rest of
    each series is then predicted by that converged predictor (an FFT
    convolution). The error grows with tol and n (the innovations' errors
    are of order tol times the predictor's size); ``tol = 1e-13`` is exact
    to ~1e-9 nats on 10,000 residuals while the recursion runs a few
    hundred steps instead of n. A process whose partial autocorrelations do
    not die out runs the full recursion.

    Parameters
    ----------
    acov : ndarray, shape (B, n)
        Autocovariance at lags 0..n-1 of each batch member.
    x : ndarray, shape (B, E, n)
        E series per batch member, all with that member's covariance.
    tol : float, optional
        Convergence threshold of the partial autocorrelations; None runs
        the full O(n^2) recursion.

    Returns
    -------
    ndarray, shape (B, E)
        log N(x; 0, T(acov)); -inf where T(acov) is not positive definite.

    Examples
    --------
    Against the dense Gaussian density with covariance toeplitz(acov):

    >>> import numpy as np
    >>> import scipy.linalg
    >>> import scipy.stats
    >>> from bayes_jackal.likelihood import toeplitz_loglike
    >>> acov = 0.5 ** np.arange(8)[None]  # one batch member
    >>> x = np.random.default_rng(1).standard_normal((1, 3, 8))  # three series
    >>> dense = scipy.stats.multivariate_normal(cov=scipy.linalg.toeplitz(acov[0]))
    >>> bool(np.allclose(toeplitz_loglike(acov, x), dense.logpdf(x[0])))
    True
    """
    batch, n = acov.shape
    phi = np.zeros((batch, n))
    variances = np.empty((batch, n))
    innovations = np.empty(x.shape)
    variances[:, 0] = acov[:, 0]
    innovations[..., 0] = x[..., 0]
    variance = acov[:, 0].copy()
    order, quiet = n, 0
    with np.errstate(invalid="ignore", divide="ignore"):
        for k in range(1, n):
            previous = phi[:, : k - 1]
            kappa = acov[:, k] - np.einsum("bj,bj->b", previous, acov[:, k - 1 : 0 : -1])
            kappa /= variance
            phi[:, : k - 1] = previous - kappa[:, None] * previous[:, ::-1]
            phi[:, k - 1] = kappa
            variance = variance * (1.0 - kappa**2)
            variances[:, k] = variance
            prediction = np.einsum("bj,bej->be", phi[:, :k], x[..., k - 1 :: -1])
            innovations[..., k] = x[..., k] - prediction
            if tol is not None:
                quiet = quiet + 1 if np.max(np.abs(kappa)) < tol else 0
                if quiet == _QUIET_STEPS:
                    order = k + 1
                    break
        if order < n:
            filter_ = np.concatenate([np.ones((batch, 1)), -phi[:, : order - 1]], axis=1)
            size = scipy.fft.next_fast_len(n + order, real=True)
            spectrum = scipy.fft.rfft(x, size) * scipy.fft.rfft(filter_, size)[:, None, :]
            innovations[..., order:] = scipy.fft.irfft(spectrum, size)[..., order:n]
            variances[:, order:] = variance[:, None]
        quadratic = np.sum(innovations**2 / variances[:, None, :], axis=-1)
        log_det = np.sum(np.log(variances), axis=-1)
    loglike = -0.5 * (log_det[:, None] + quadratic + n * _LOG_2PI)
    return np.where(np.isfinite(loglike), loglike, -np.inf)


def banded_toeplitz_loglike(acov: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Gaussian log-density of series under a banded Toeplitz covariance (banded Cholesky).

    The module docstring gives the equations: LAPACK's dpbtrf and dtbtrs
    for each batch member, O(n p^2) each, p + 1 its own :func:`bandwidth`.

    Parameters
    ----------
    acov : ndarray, shape (B, p + 1)
        Autocovariance at lags 0..p of each batch member; zero beyond lag
        p (:func:`bandwidth` gives p + 1). p + 1 may exceed n: the lags
        past n - 1 are then unused.
    x : ndarray, shape (B, E, n)
        E series per batch member, all with that member's covariance.

    Returns
    -------
    ndarray, shape (B, E)
        log N(x; 0, T) [nats]; -inf where T is not positive definite or
        not finite.

    Examples
    --------
    A moving-average autocovariance over 30 samples against the dense
    density of the Toeplitz matrix:

    >>> import numpy as np
    >>> import scipy.linalg
    >>> import scipy.stats
    >>> from bayes_jackal.likelihood import banded_toeplitz_loglike
    >>> acov = np.array([[3.0, 2.0, 1.0]])  # a 3-tap boxcar's
    >>> x = np.random.default_rng(1).standard_normal((1, 2, 30))
    >>> row = np.zeros(30)
    >>> row[:3] = acov[0]
    >>> dense = scipy.stats.multivariate_normal(cov=scipy.linalg.toeplitz(row))
    >>> bool(np.allclose(banded_toeplitz_loglike(acov, x), dense.logpdf(x[0])))
    True
    """
    n = x.shape[-1]
    widths = np.minimum(bandwidth(acov), n)
    loglike = np.full(x.shape[:2], -np.inf)
    for member, (row, width) in enumerate(zip(acov, widths, strict=True)):
        # Lower band storage: band[j, i] = T[i + j, i] = r_j (entries past n unused).
        band = np.repeat(row[:width, None], n, axis=1)
        loglike[member] = banded_loglike(band[None], x[member][None])[0]
    return loglike


def banded_loglike(band: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Gaussian log-density of x under banded covariances (LAPACK's dpbtrf and dtbtrs).

    Parameters
    ----------
    band : ndarray, shape (B, p + 1, n)
        Each member's covariance in lower band storage: ``band[b, o, j]`` =
        Cov(x_{j+o}, x_j) (entries past n unused).
    x : ndarray, shape (B, n) or (B, E, n)
        One series (or E) per member.

    Returns
    -------
    ndarray, shape (B,) or (B, E)
        [nats]; -inf where a covariance is not positive definite or finite.

    Examples
    --------
    Against the dense density of a tridiagonal covariance:

    >>> import numpy as np
    >>> import scipy.stats
    >>> from bayes_jackal.likelihood import banded_loglike
    >>> diagonal, off = np.full(5, 2.0), np.full(4, 0.5)
    >>> dense = np.diag(diagonal) + np.diag(off, 1) + np.diag(off, -1)
    >>> band = np.stack([diagonal, np.append(off, 0.0)])[None]
    >>> x = np.random.default_rng(1).standard_normal((1, 5))
    >>> bool(np.isclose(banded_loglike(band, x)[0],
    ...                 scipy.stats.multivariate_normal(cov=dense).logpdf(x[0])))
    True
    """
    series = x if x.ndim == 3 else x[:, None, :]
    n = series.shape[-1]
    loglike = np.full(series.shape[:2], -np.inf)
    for member, (rows, values) in enumerate(zip(band, series, strict=True)):
        if not np.isfinite(rows).all():
            continue
        factor, info = scipy.linalg.lapack.dpbtrf(rows, lower=1)
        if info != 0:  # not positive definite
            continue
        z, _ = scipy.linalg.lapack.dtbtrs(factor, values.T, uplo="L")
        log_det = 2.0 * np.sum(np.log(factor[0]))
        loglike[member] = -0.5 * (log_det + np.sum(z**2, axis=0) + n * _LOG_2PI)
    loglike = np.where(np.isnan(loglike), -np.inf, loglike)
    return loglike if x.ndim == 3 else loglike[:, 0]


def fallback_loglike(acov: np.ndarray, x: np.ndarray, *, recursion: bool = True) -> np.ndarray:
    """The ``fast`` engines' time-domain fallback: the banded Cholesky, else a stopped recursion.

    Each set whose autocovariance ends within p + 1 <= 4 sqrt(n) lags
    (:func:`bandwidth`, :data:`FALLBACK_BAND`; every family but the
    exponential, at widths short against the record) takes
    :func:`banded_toeplitz_loglike`, exact in O(n p^2); the others
    :func:`toeplitz_loglike` stopped at :data:`FAST_TOLERANCE`, whose sets
    here (those no spectral grid certifies) run to order ~n: O(n^2).
    Measured on 2,376 residuals (one thread, 11 sets): the banded factor
    0.3 ms a set for a band of 11 lags, 3.7 ms for 131 and 9.2 ms for 305
    (p + 1 = 6.3 sqrt(n)), the recursion 12 ms; 4 sqrt(n) keeps a margin.

    Parameters
    ----------
    acov : ndarray, shape (B, n)
        Autocovariance at lags 0..n-1 of each batch member.
    x : ndarray, shape (B, E, n)
        E series per batch member.
    recursion : bool
        True: as above, every set evaluated. False: the cheap fallback of
        the MAP search's scans, which evaluate many sets over the whole
        prior: only the bands whose factor also costs little
        (:data:`SCAN_WORK`: n (p + 1)^2 <= 1e8, ~15 ms a set) are
        evaluated, the other sets are -inf (the recursion would cost 67 ms
        a set at n = 4,000, 320 ms at 10,000).

    Returns
    -------
    ndarray, shape (B, E)
        log N(x; 0, T(acov)) [nats]; -inf where T(acov) is not positive
        definite.

    Examples
    --------
    Both branches against the full recursion, for a banded and an AR(1)
    autocovariance; a scan takes the band only:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import fallback_loglike, toeplitz_loglike
    >>> x = np.random.default_rng(1).standard_normal((2, 1, 64))
    >>> acov = np.array([[2.0, 0.5, 0.25] + [0.0] * 61, 0.5 ** np.arange(64)])
    >>> bool(np.allclose(fallback_loglike(acov, x), toeplitz_loglike(acov, x)))
    True
    >>> scan = fallback_loglike(acov, x, recursion=False)[:, 0]
    >>> bool(np.isclose(scan[0], toeplitz_loglike(acov, x)[0, 0])), bool(np.isneginf(scan[1]))
    (True, True)
    """
    n = acov.shape[-1]
    squared = bandwidth(acov) ** 2
    banded = squared <= FALLBACK_BAND**2 * n
    if not recursion:
        banded &= n * squared <= SCAN_WORK
    loglike = np.full(x.shape[:2], -np.inf)
    if banded.any():
        loglike[banded] = banded_toeplitz_loglike(acov[banded], x[banded])
    if recursion and not banded.all():
        loglike[~banded] = toeplitz_loglike(acov[~banded], x[~banded], FAST_TOLERANCE)
    return loglike
