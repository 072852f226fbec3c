"""Noise kernels: unit-energy filters that colour white noise (thesis ch. 7).

A kernel h is sampled at the data's sample time dt and normalised to unit
energy, sum(h^2) = 1, so white noise of variance s^2 filtered by it keeps
variance s^2 and gets the autocorrelation of the kernel's discrete
self-correlation, rho[l] = sum_j h[j] h[j + l]. That discrete form (not its
continuous limit) is what the simulator and the likelihood share (DESIGN §4).
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from .errors import InputError

__all__ = ["as_rng", "autocorrelation", "coloured_noise", "gaussian_kernel"]

#: The thesis truncates its Gaussian filter at +-3 sigma_h (ch. 7-3-1).
GAUSSIAN_TRUNCATION = 3.0


def as_rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    """A ``numpy.random.Generator`` from a generator, a seed or None."""
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def gaussian_kernel(sigma_h: float, dt: float) -> np.ndarray:
    """The thesis' Gaussian filter (eq. 7-5), sampled and of unit energy.

    h(t) = sqrt(dt / (sigma_h sqrt(pi))) exp(-t^2 / (2 sigma_h^2)) at
    t = k dt, |t| <= 3 sigma_h. The analytic prefactor gives unit energy only
    for sigma_h >> dt; the taps are normalised to sum(h^2) = 1 exactly, so
    the kernel degrades to a single tap (white noise) for sigma_h << dt.

    Parameters
    ----------
    sigma_h : float
        Kernel width [s].
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (2 K + 1,)
        Taps for k = -K..K, K = floor(3 sigma_h / dt).
    """
    if not (np.isfinite(sigma_h) and sigma_h > 0):
        raise InputError(f"kernel width must be positive, got {sigma_h!r} s", field="sigma_h")
    half = int(np.floor(GAUSSIAN_TRUNCATION * sigma_h / dt))
    t = np.arange(-half, half + 1) * dt
    taps = np.exp(-(t**2) / (2.0 * sigma_h**2))
    return taps / np.sqrt(np.sum(taps**2))


def autocorrelation(kernel: np.ndarray, lags: int) -> np.ndarray:
    """Autocorrelation of white noise filtered by a unit-energy ``kernel``.

    Parameters
    ----------
    kernel : ndarray, shape (L,)
    lags : int
        Number of lags to return (0..lags-1).

    Returns
    -------
    ndarray, shape (lags,)
        rho[l] = sum_j h[j] h[j + l]; zero past the kernel length.
    """
    full = np.correlate(kernel, kernel, mode="full")[len(kernel) - 1 :]
    out = np.zeros(lags)
    out[: min(lags, len(full))] = full[:lags]
    return out


def coloured_noise(
    kernel: np.ndarray,
    n: int,
    scale: float | np.ndarray = 1.0,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """White Gaussian noise filtered by ``kernel``: stationary coloured noise.

    Parameters
    ----------
    kernel : ndarray, shape (L,)
        Unit-energy filter taps.
    n : int
        Number of samples.
    scale : float or ndarray, shape (C,)
        Standard deviation of the output, one per channel.
    rng : numpy.random.Generator, int or None

    Returns
    -------
    ndarray, shape (n,) or (n, C)
        ``n`` samples per channel (columns when ``scale`` is an array).
    """
    scale = np.asarray(scale, float)
    white = as_rng(rng).standard_normal((n + len(kernel) - 1, *scale.shape))
    shaped_kernel = kernel.reshape(-1, *([1] * scale.ndim))
    return scale * scipy.signal.fftconvolve(white, shaped_kernel, mode="valid", axes=0)
