"""Noise-filter families: unit-energy kernels that colour white noise (thesis ch. 7).

Each family is an impulse response h with one width parameter, sampled at
the data's sample time dt and normalised to unit energy, sum(h^2) = 1. White
noise of variance s^2 filtered by it keeps variance s^2 and has the
autocorrelation of the kernel's discrete self-correlation,
rho[l] = sum_j h[j] h[j + l]. That discrete form, not its continuous limit,
is what the simulator and the likelihood share (docs/design.md §4).

Families (thesis 7-4-1):

- ``white``: h = delta; no width.
- ``gaussian``: the thesis' filter (eq. 7-5), h(t) ~ exp(-t^2 / (2 sigma_h^2))
  at t = k dt, truncated at |t| <= 3 sigma_h; width sigma_h [s]. With
  K = floor(3 sigma_h / dt), the taps |k| <= K are whole and the two at
  |k| = K + 1 are weighted by the fraction 3 sigma_h / dt - K, so that h
  varies continuously with sigma_h (a hard truncation makes the likelihood
  jump by nats whenever a tap enters) and is exactly the thesis' filter
  wherever 3 sigma_h / dt is whole.
- ``exponential``: first-order low-pass, AR(1) / Ornstein-Uhlenbeck,
  rho[l] = phi^l with phi = exp(-dt / tau); width tau [s].
- ``triangular``: h(t) ~ 1 - |t| / w for |t| < w; width w [s] (half-base).
- ``moving-average``: boxcar of duration w [s]: floor(w / dt) unit taps and
  a last tap of the fractional remainder, so that h varies continuously
  with w.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.signal

from .errors import InputError

__all__ = [
    "FAMILIES",
    "Family",
    "as_rng",
    "gaussian_kernel",
    "get_family",
]

#: The thesis truncates its Gaussian filter at +-3 sigma_h (ch. 7-3-1).
GAUSSIAN_TRUNCATION = 3.0


def as_rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    """A ``numpy.random.Generator`` from a generator, a seed or None."""
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def _check_widths(width, name: str) -> np.ndarray:
    width = np.asarray(width, float)
    bad = ~(np.isfinite(width) & (width > 0))
    if bad.any():
        raise InputError(
            f"kernel width must be positive and finite, got {float(width[bad].flat[0])!r} s",
            field=name,
        )
    return width


def _gaussian_taps(width: np.ndarray, dt: float) -> np.ndarray:
    # Taps |k| <= K = floor(reach) in full, |k| = K + 1 times the fraction
    # reach - K: continuous in the width, eq. 7-5 itself where reach is whole.
    reach = (GAUSSIAN_TRUNCATION * width / dt)[..., None]
    k = np.arange(-int(reach.max()) - 1, int(reach.max()) + 2)
    weight = np.clip(reach + 1.0 - np.abs(k), 0.0, 1.0)
    return weight * np.exp(-((k * dt) ** 2) / (2.0 * width[..., None] ** 2))


def _triangular_taps(width: np.ndarray, dt: float) -> np.ndarray:
    reach = int(np.ceil(width.max() / dt))
    k = np.arange(-reach, reach + 1)
    return np.clip(1.0 - np.abs(k) * dt / width[..., None], 0.0, None)


def _moving_average_taps(width: np.ndarray, dt: float) -> np.ndarray:
    samples = np.maximum(width / dt, 1.0)[..., None]
    k = np.arange(int(np.ceil(samples.max())))
    return np.clip(samples - k, 0.0, 1.0)


def _white_taps(width: np.ndarray, dt: float) -> np.ndarray:
    return np.ones((*width.shape, 1))


@dataclass(frozen=True)
class Family:
    """A noise-filter family.

    Attributes
    ----------
    name : str
        ``white``, ``gaussian``, ``exponential``, ``triangular`` or
        ``moving-average``.
    width_name : str or None
        Name of the width parameter (``sigma_h`` for the Gaussian, ``width``
        otherwise); None for white noise, which has none.
    description : str
        What the width means.
    """

    name: str
    width_name: str | None
    description: str

    @property
    def has_width(self) -> bool:
        """Whether the family has a width parameter."""
        return self.width_name is not None

    def taps(self, width: float | np.ndarray, dt: float) -> np.ndarray:
        """Unit-energy kernel, shape (..., L); rows zero-padded to a common length.

        The exponential family's kernel is infinite; its taps are cut where
        the remaining energy is below 1e-16.

        Parameters
        ----------
        width : float or ndarray, shape (...)
            Width [s]; ignored for ``white``.
        dt : float
            Sample time [s].
        """
        width = _check_widths(width if self.has_width else 1.0, self.width_name or "width")
        if self.name == "exponential":
            phi = np.exp(-dt / width)[..., None]
            # phi^(2 L) = 1e-16 for the slowest decay: L = ln(1e16) tau / (2 dt).
            length = int(np.ceil(np.log(1e16) * width.max() / (2 * dt))) + 1
            taps = phi ** np.arange(length)
        else:
            taps = _TAPS[self.name](width, dt)
        return taps / np.sqrt(np.sum(taps**2, axis=-1, keepdims=True))

    def autocorrelation(self, width: float | np.ndarray, dt: float, lags: int) -> np.ndarray:
        """Autocorrelation rho[0..lags-1] of white noise filtered by the kernel.

        Exact for the sampled kernel: its discrete self-correlation, or
        phi^l for the exponential family. Vectorised over ``width``.

        Parameters
        ----------
        width : float or ndarray, shape (...)
            Width [s]; ignored for ``white``.
        dt : float
            Sample time [s].
        lags : int
            Number of lags.

        Returns
        -------
        ndarray, shape (..., lags)
        """
        if self.name == "white":
            return np.broadcast_to(np.arange(lags) == 0, (*np.shape(width), lags)).astype(float)
        if self.name == "exponential":
            width = _check_widths(width, self.width_name)
            return np.exp(-dt / width)[..., None] ** np.arange(lags)
        taps = self.taps(width, dt)
        size = scipy.fft.next_fast_len(2 * taps.shape[-1], real=True)
        full = scipy.fft.irfft(np.abs(scipy.fft.rfft(taps, size)) ** 2, size)
        out = np.zeros((*taps.shape[:-1], lags))
        kept = min(lags, taps.shape[-1])
        out[..., :kept] = full[..., :kept]
        return out

    def psd(self, width: float | np.ndarray, dt: float, frequency: np.ndarray) -> np.ndarray:
        """Two-sided power spectral density of unit-variance filtered noise [1/Hz].

        S(f) = dt |H(f)|^2 with H the kernel's discrete-time Fourier
        transform, so that the integral of S over [-1/(2 dt), 1/(2 dt)] is 1.

        Parameters
        ----------
        width : float or ndarray, shape (...)
        dt : float
            Sample time [s].
        frequency : ndarray, shape (F,)
            Frequencies [Hz].

        Returns
        -------
        ndarray, shape (..., F)
        """
        omega = 2.0 * np.pi * np.asarray(frequency, float) * dt
        if self.name == "exponential":
            phi = np.exp(-dt / _check_widths(width, self.width_name))[..., None]
            return dt * (1.0 - phi**2) / np.abs(1.0 - phi * np.exp(-1j * omega)) ** 2
        taps = self.taps(width, dt)
        phases = np.exp(-1j * np.outer(np.arange(taps.shape[-1]), omega))
        return dt * np.abs(taps @ phases) ** 2

    def noise(
        self,
        width: float,
        dt: float,
        n: int,
        scale: float | np.ndarray = 1.0,
        rng: np.random.Generator | int | None = None,
    ) -> np.ndarray:
        """Stationary coloured noise: white Gaussian noise through the kernel.

        Parameters
        ----------
        width : float
            Width [s]; ignored for ``white``.
        dt : float
            Sample time [s].
        n : int
            Number of samples.
        scale : float or ndarray, shape (C,)
            Standard deviation of the output, one per channel (column).
        rng : numpy.random.Generator, int or None

        Returns
        -------
        ndarray, shape (n,) or (n, C)
        """
        scale = np.asarray(scale, float)
        if self.name != "exponential":
            return _coloured_noise(self.taps(width, dt), n, scale, rng)
        phi = float(np.exp(-dt / _check_widths(width, self.width_name)))
        white = as_rng(rng).standard_normal((n, *scale.shape))
        # AR(1) started in its stationary distribution: x[0] = white[0].
        initial = phi * white[:1]
        filtered, _ = scipy.signal.lfilter(
            [np.sqrt(1.0 - phi**2)], [1.0, -phi], white[1:], axis=0, zi=initial
        )
        return scale * np.concatenate([white[:1], filtered])


_TAPS = {
    "white": _white_taps,
    "gaussian": _gaussian_taps,
    "triangular": _triangular_taps,
    "moving-average": _moving_average_taps,
}

#: The filter families, by name.
FAMILIES = {
    family.name: family
    for family in (
        Family("white", None, "white noise: no width"),
        Family("gaussian", "sigma_h", "sigma_h [s], the thesis' Gaussian filter (eq. 7-5)"),
        Family("exponential", "width", "time constant tau [s] of a first-order low-pass"),
        Family("triangular", "width", "half-base w [s] of a triangular filter"),
        Family("moving-average", "width", "duration w [s] of a boxcar filter"),
    )
}


def get_family(name: str) -> Family:
    """The family called ``name``; an :class:`InputError` listing the known ones otherwise."""
    if name not in FAMILIES:
        raise InputError(
            f"unknown noise family {name!r}; use one of {list(FAMILIES)}", field="family"
        )
    return FAMILIES[name]


def gaussian_kernel(sigma_h: float, dt: float) -> np.ndarray:
    """The thesis' Gaussian filter (eq. 7-5), sampled and of unit energy.

    h(t) = sqrt(dt / (sigma_h sqrt(pi))) exp(-t^2 / (2 sigma_h^2)) at
    t = k dt, |t| <= 3 sigma_h. The analytic prefactor gives unit energy only
    for sigma_h >> dt; the taps are normalised to sum(h^2) = 1 exactly, so
    the kernel degrades to a single tap (white noise) for sigma_h << dt.

    With K = floor(3 sigma_h / dt) and f = 3 sigma_h / dt - K, the taps
    |k| <= K are eq. 7-5's and the two edge taps |k| = K + 1 are eq. 7-5's
    times f (before normalisation), as the moving-average family weights
    its last tap. So the kernel is continuous in sigma_h: a tap enters at
    zero height rather than at exp(-4.5) ~ 1.1 % of the peak. Where
    3 sigma_h / dt is whole, f = 0 and the kernel is the thesis' filter
    itself; elsewhere the edge taps are below 1.1 % f of the peak.

    Parameters
    ----------
    sigma_h : float
        Kernel width [s].
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (2 K + 1,) or (2 K + 3,)
        Taps for k = -K..K, and the edge taps k = +-(K + 1) where they are
        non-zero (f > 0, and no underflow for sigma_h << dt).
    """
    return np.trim_zeros(FAMILIES["gaussian"].taps(float(_check_widths(sigma_h, "sigma_h")), dt))


def _coloured_noise(
    kernel: np.ndarray, n: int, scale: np.ndarray, rng: np.random.Generator | int | None
) -> np.ndarray:
    """``n`` samples of white Gaussian noise filtered by ``kernel``, times ``scale``."""
    white = as_rng(rng).standard_normal((n + len(kernel) - 1, *scale.shape))
    shaped_kernel = kernel.reshape(-1, *([1] * scale.ndim))
    return scale * scipy.signal.fftconvolve(white, shaped_kernel, mode="valid", axes=0)
