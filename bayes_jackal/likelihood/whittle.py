"""Debiased Whittle likelihood of stationary Gaussian series (Sykulski et al. 2019).

The periodogram pieces of the residual likelihood: cross-periodograms of the
regressors, the expected periodogram of an autocovariance, and the debiased
Whittle log-likelihood built from them (the ``whittle`` engine of
:class:`bayes_jackal.likelihood.ResidualLikelihood`, and the noise profile of
:mod:`bayes_jackal.inference.starts`). The exact engines live in
:mod:`bayes_jackal.likelihood.residual_likelihood`.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

__all__ = [
    "cross_periodogram",
    "debiased_whittle_loglike",
    "expected_periodogram",
    "frequency_weights",
]

_LOG_2PI = np.log(2.0 * np.pi)


def frequency_weights(n: int) -> np.ndarray:
    """Multiplicity of each rfft frequency among the n Fourier frequencies.

    Examples
    --------
    The rfft half counts each frequency but 0 (and n/2 for even n) twice; the
    weights add up to n:

    >>> from bayes_jackal.likelihood import frequency_weights
    >>> frequency_weights(6).tolist(), frequency_weights(5).tolist()
    ([1.0, 2.0, 2.0, 1.0], [1.0, 2.0, 2.0])
    """
    weights = np.full(n // 2 + 1, 2.0)
    weights[0] = 1.0
    if n % 2 == 0:
        weights[-1] = 1.0
    return weights


def expected_periodogram(acov: np.ndarray, length: int | None = None) -> np.ndarray:
    """E[I_j] = sum_|tau|<n (1 - |tau|/n) c_tau exp(-i w_j tau) at the rfft frequencies.

    Parameters
    ----------
    acov : ndarray, shape (B, L)
        Autocovariance at lags 0..L-1.
    length : int, optional
        Length n of the series (>= L), default L. With L < n the
        frequencies are those of L points, 2 pi j / L, and the lags from L
        on are taken as negligible.

    Returns
    -------
    ndarray, shape (B, L // 2 + 1)

    Examples
    --------
    E[I_j] = E|DFT(x)_j|^2 / n, the diagonal of F T F^H / n for the Toeplitz
    covariance T:

    >>> import numpy as np
    >>> import scipy.linalg
    >>> from bayes_jackal.likelihood import expected_periodogram
    >>> acov = 0.5 ** np.arange(6)  # AR(1), phi = 0.5
    >>> F = np.fft.rfft(np.eye(6), axis=0)  # rows: the DFT at the rfft frequencies
    >>> dense = np.real(np.diag(F @ scipy.linalg.toeplitz(acov) @ F.conj().T)) / 6
    >>> bool(np.allclose(expected_periodogram(acov[None]), dense))
    True
    """
    lags = acov.shape[-1]
    tapered = acov * (1.0 - np.arange(lags) / (length or lags))
    return 2.0 * scipy.fft.rfft(tapered, lags).real - tapered[..., :1]


def cross_periodogram(regressors: np.ndarray, size: int | None = None) -> np.ndarray:
    """Re(Z_j^* Z_j^T) of the regressors' DFT on ``size`` points, shape (size // 2 + 1, K, K).

    For any real coefficient vector c, |DFT(Z c)_j|^2 = c^T P_j c. The
    transform is zero-padded to ``size`` (default: the series' length n).

    Examples
    --------
    For any coefficients c, |DFT(Z c)_j|^2 = c' P_j c:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import cross_periodogram
    >>> rng = np.random.default_rng(1)
    >>> Z, c = rng.standard_normal((16, 4)), rng.standard_normal(4)
    >>> P = cross_periodogram(Z)
    >>> P.shape
    (9, 4, 4)
    >>> bool(np.allclose(P @ c @ c, np.abs(np.fft.rfft(Z @ c)) ** 2))
    True
    """
    spectra = scipy.fft.rfft(regressors, size, axis=0)
    return (spectra[:, :, None].conj() * spectra[:, None, :]).real


def debiased_whittle_loglike(
    acov: np.ndarray, periodogram: np.ndarray, count: int = 1
) -> np.ndarray:
    """Debiased Whittle log-likelihood of ``count`` series of length n.

    l = -1/2 sum_j [count log E[I_j] + I_j / E[I_j]] - count n/2 log(2 pi),
    over all n Fourier frequencies (folded onto the rfft half).

    Parameters
    ----------
    acov : ndarray, shape (B, n)
        Autocovariance of the model for each batch member.
    periodogram : ndarray, shape (B, n // 2 + 1)
        Sum of the ``count`` series' periodograms I_j.
    count : int
        Number of independent series summed in ``periodogram``.

    Returns
    -------
    ndarray, shape (B,)

    Examples
    --------
    For white noise the Whittle likelihood is exact (Parseval): it equals the
    series' Gaussian log-density.

    >>> import numpy as np
    >>> import scipy.stats
    >>> from bayes_jackal.likelihood import debiased_whittle_loglike
    >>> x = np.random.default_rng(1).standard_normal(16)
    >>> acov = np.zeros((1, 16))
    >>> acov[0, 0] = 2.0  # variance 2 at lag 0, nothing beyond
    >>> periodogram = np.abs(np.fft.rfft(x)) ** 2 / 16
    >>> value = debiased_whittle_loglike(acov, periodogram[None])
    >>> exact = scipy.stats.norm(scale=np.sqrt(2.0)).logpdf(x).sum()
    >>> bool(np.isclose(value[0], exact))
    True
    """
    n = acov.shape[-1]
    expected = expected_periodogram(acov)
    weights = frequency_weights(n)
    with np.errstate(invalid="ignore", divide="ignore"):
        terms = count * np.log(expected) + periodogram / expected
        loglike = -0.5 * (terms @ weights + count * n * _LOG_2PI)
    valid = np.all(expected > 0, axis=-1) & np.isfinite(loglike)
    return np.where(valid, loglike, -np.inf)
