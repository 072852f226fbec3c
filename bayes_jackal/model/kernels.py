"""Noise-filter families: unit-energy kernels that colour white noise (thesis ch. 7).

Each family is an impulse response h with one width parameter, sampled at
the data's sample time dt and normalised to unit energy, sum(h^2) = 1. White
noise of variance s^2 filtered by it keeps variance s^2 and has the kernel's
discrete self-correlation rho[l] = sum_j h[j] h[j + l] as autocorrelation:
the simulator's and the likelihood's, not its continuous limit
(docs/design.md §4).

Each family is a subclass of :class:`Family` holding all the package knows
about it, registered in :data:`FAMILIES`, the one list that everything else
reads (docs/families.md: adding a family). The families (thesis 7-4-1):

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
  a last tap of the fractional remainder (h continuous in w).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import numpy as np
import scipy.fft
import scipy.signal
import scipy.special

from .._runtime import InputError, as_rng

__all__ = [
    "FAMILIES",
    "Exponential",
    "Family",
    "Gaussian",
    "MovingAverage",
    "Triangular",
    "White",
    "bandwidth",
    "gaussian_kernel",
    "get_family",
]

#: The thesis truncates its Gaussian filter at +-3 sigma_h (ch. 7-3-1).
GAUSSIAN_TRUNCATION = 3.0


def _check_widths(width, name: str) -> np.ndarray:
    width = np.asarray(width, float)
    bad = ~(np.isfinite(width) & (width > 0))
    if bad.any():
        raise InputError(
            f"kernel width must be positive and finite, got {float(width[bad].flat[0])!r} s",
            field=name,
        )
    return width


class Family(abc.ABC):
    """A noise-filter family: everything the package knows about one kernel.

    A subclass sets the class attributes and :meth:`_taps`; the
    autocorrelation, PSD and generator follow from the taps, and a subclass
    overrides them where it has a closed form. The Active Inference export
    asks :attr:`max_order` and :meth:`autocorrelation_derivatives`. An
    instance registered in :data:`FAMILIES` is usable everywhere
    (docs/families.md shows how to add one).

    Attributes
    ----------
    name : str
        Key in :data:`FAMILIES` and on the command line.
    width_name : str or None
        Name of the width parameter [s] in the parameter layout and the
        posterior file; None for a family without one (white noise).
    description : str
        What the width means.
    max_order : int or None
        Highest embedding order P of generalised coordinates: the noise is
        P times mean-square differentiable, its autocorrelation has 2 P
        derivatives at lag 0. None: every order (only the condition number
        of the exported precision limits it).

    Examples
    --------
    The registered families, by name. Every kernel has unit energy, and its
    PSD integrates to the unit variance over (-1/(2 dt), 1/(2 dt)): here as
    the mean over a 1024-point frequency grid, exact for kernels shorter than
    512 taps.

    >>> import numpy as np
    >>> from bayes_jackal.model import FAMILIES
    >>> dt = 1 / 72
    >>> frequency = np.fft.fftfreq(1024, dt)
    >>> for name, family in FAMILIES.items():
    ...     energy = np.sum(family.taps(0.05, dt) ** 2)
    ...     variance = family.psd(0.05, dt, frequency).mean() / dt
    ...     print(f"{name:15} {family.width_name!s:8} {family.max_order!s:5} "
    ...           f"{energy:.12f} {variance:.12f}")
    white           None     0     1.000000000000 1.000000000000
    gaussian        sigma_h  None  1.000000000000 1.000000000000
    exponential     width    0     1.000000000000 1.000000000000
    triangular      width    1     1.000000000000 1.000000000000
    moving-average  width    0     1.000000000000 1.000000000000

    A new family is a subclass and a registry entry (docs/families.md).
    """

    name: ClassVar[str]
    width_name: ClassVar[str | None] = "width"
    description: ClassVar[str]
    max_order: ClassVar[int | None] = 0

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    @property
    def has_width(self) -> bool:
        """Whether the family has a width parameter."""
        return self.width_name is not None

    def widths(self, width: float | np.ndarray) -> np.ndarray:
        """``width`` [s] as a validated array; 1.0 for a family without a width.

        Raises
        ------
        InputError
            For a width that is not positive and finite, naming
            :attr:`width_name`.
        """
        return _check_widths(width if self.has_width else 1.0, self.width_name or "width")

    @abc.abstractmethod
    def _taps(self, width: np.ndarray, dt: float) -> np.ndarray:
        """Kernel taps of validated widths [s], any scale, shape (..., L), rows zero-padded."""

    def taps(self, width: float | np.ndarray, dt: float) -> np.ndarray:
        """Unit-energy kernel, shape (..., L); rows zero-padded to a common length.

        Parameters
        ----------
        width : float or ndarray, shape (...)
            Width [s]; ignored for ``white``.
        dt : float
            Sample time [s].
        """
        taps = self._taps(self.widths(width), dt)
        return taps / np.sqrt(np.sum(taps**2, axis=-1, keepdims=True))

    def autocorrelation(self, width: float | np.ndarray, dt: float, lags: int) -> np.ndarray:
        """Autocorrelation rho[0..lags-1] of white noise filtered by the kernel.

        Exact for the sampled kernel: its discrete self-correlation, exactly
        zero from each kernel's length on (for the banded factor). Vectorised.

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
        taps = self.taps(width, dt)
        size = scipy.fft.next_fast_len(2 * taps.shape[-1], real=True)
        full = scipy.fft.irfft(np.abs(scipy.fft.rfft(taps, size)) ** 2, size)
        out = np.zeros((*taps.shape[:-1], lags))
        kept = min(lags, taps.shape[-1])
        out[..., :kept] = full[..., :kept]
        # Each kernel's length, from its first nonzero tap to its last.
        length = bandwidth(taps) + bandwidth(taps[..., ::-1]) - taps.shape[-1]
        return np.where(np.arange(lags) < length[..., None], out, 0.0)

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
        kernel = self.taps(width, dt)
        white = as_rng(rng).standard_normal((n + len(kernel) - 1, *scale.shape))
        shaped_kernel = kernel.reshape(-1, *([1] * scale.ndim))
        return scale * scipy.signal.fftconvolve(white, shaped_kernel, mode="valid", axes=0)

    def check_order(self, order: int) -> None:
        """Refuse an embedding order the family's noise cannot give.

        Raises
        ------
        InputError
            For an order that is not an integer >= 0, or above :attr:`max_order`.
        """
        if not isinstance(order, (int, np.integer)) or order < 0:
            raise InputError(
                f"embedding order must be an integer >= 0, got {order!r}", field="order"
            )
        if self.max_order is not None and order > self.max_order:
            raise InputError(
                f"the {self.name} family's autocorrelation has no derivative of order "
                f"{2 * order} at lag 0 (its noise is not differentiable): generalised "
                f"coordinates exist up to order {self.max_order}, got {order}",
                field="order",
            )

    def autocorrelation_derivatives(self, width: np.ndarray, order: int) -> np.ndarray:
        """rho^(n)(0) for n = 0 .. 2 ``order`` of the continuous autocorrelation.

        The continuous-time autocorrelation is the one of which the sampled
        kernel's is the samples (exactly so as dt -> 0).

        Parameters
        ----------
        width : array_like
            Kernel width [s]; ignored for ``white``.
        order : int
            Embedding order P.

        Returns
        -------
        ndarray, shape (..., 2 P + 1)
            Derivatives [1/s^n]; the odd ones are zero (rho is even).

        Raises
        ------
        InputError
            When the family's noise is not P times differentiable.
        """
        self.check_order(order)
        n = np.arange(2 * order + 1)
        even = self._even_derivatives(np.asarray(width, float), n // 2)
        return np.where(n % 2 == 0, even, 0.0)

    def realisation(self, width: float | np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
        """Exact (T, g, c, d): v = taps * e is z[k+1] = T z[k] + g e[k], v[k] = c @ z[k] + d e[k];
        arrays broadcast over width. Here the taps' observable form: T = shift up, c = e_1."""
        taps = self.taps(width, dt)
        used = np.flatnonzero(np.abs(taps).reshape(-1, taps.shape[-1]).max(axis=0))
        h = taps[..., used[0] : used[-1] + 1]  # zero columns trimmed: a shift, the same noise
        n = h.shape[-1] - 1
        return np.eye(n, k=1), h[..., 1:], np.eye(n, 1).ravel(), h[..., 0]

    def _even_derivatives(self, width: np.ndarray, m: np.ndarray) -> np.ndarray:
        """rho^(2m)(0) [1/s^(2m)], shape (..., len(m)), for m <= :attr:`max_order`.

        Every autocorrelation has rho(0) = 1, all that a family of
        ``max_order = 0`` needs; a differentiable family overrides this.
        """
        return np.ones((*width.shape, len(m)))


class White(Family):
    """White noise: h = delta, no width.

    Examples
    --------
    The autocorrelation is a delta, the PSD flat at dt (unit variance):

    >>> import numpy as np
    >>> from bayes_jackal.model import White
    >>> White().taps(1.0, 0.01).tolist()
    [1.0]
    >>> White().autocorrelation(1.0, 0.01, 4).tolist()
    [1.0, 0.0, 0.0, 0.0]
    >>> White().psd(1.0, 0.01, np.array([0.0, 25.0, 50.0])).tolist()
    [0.01, 0.01, 0.01]
    """

    name = "white"
    width_name = None
    description = "white noise: no width"

    def _taps(self, width: np.ndarray, dt: float) -> np.ndarray:
        return np.ones((*width.shape, 1))

    def autocorrelation(self, width: float | np.ndarray, dt: float, lags: int) -> np.ndarray:
        return np.broadcast_to(np.arange(lags) == 0, (*np.shape(width), lags)).astype(float)


class Gaussian(Family):
    """The thesis' filter (eq. 7-5), truncated at +-3 sigma_h, edge taps weighted.

    Its continuous autocorrelation exp(-t^2 / (4 sigma_h^2)) is smooth, so
    every embedding order exists: rho^(2m)(0) = (-1)^m (2m)! / (m!
    (4 sigma_h^2)^m), e.g. rho''(0) = -1 / (2 sigma_h^2) and
    rho''''(0) = 3 / (4 sigma_h^4).

    Examples
    --------
    Where 3 sigma_h / dt is whole, the taps are eq. 7-5's exp(-t^2 /
    (2 sigma_h^2)), normalised; the derivatives at lag 0 are the closed forms
    above:

    >>> import numpy as np
    >>> from bayes_jackal.model import Gaussian
    >>> taps = Gaussian().taps(0.04, 0.01)  # 3 sigma_h / dt = 12
    >>> t = np.arange(-13, 14) * 0.01
    >>> h = np.exp(-(t**2) / (2 * 0.04**2)) * (np.abs(t) < 0.125)
    >>> bool(np.allclose(taps, h / np.linalg.norm(h)))
    True
    >>> Gaussian().autocorrelation_derivatives(0.05, 2).round(6).tolist()
    [1.0, 0.0, -200.0, 0.0, 120000.0]
    """

    name = "gaussian"
    width_name = "sigma_h"
    description = "sigma_h [s], the thesis' Gaussian filter (eq. 7-5)"
    max_order = None

    def _taps(self, width: np.ndarray, dt: float) -> np.ndarray:
        # Taps |k| <= K = floor(reach) in full, |k| = K + 1 times the fraction
        # reach - K: continuous in the width, eq. 7-5 itself where reach is whole.
        reach = (GAUSSIAN_TRUNCATION * width / dt)[..., None]
        k = np.arange(-int(reach.max()) - 1, int(reach.max()) + 2)
        weight = np.clip(reach + 1.0 - np.abs(k), 0.0, 1.0)
        return weight * np.exp(-((k * dt) ** 2) / (2.0 * width[..., None] ** 2))

    def _even_derivatives(self, width: np.ndarray, m: np.ndarray) -> np.ndarray:
        # eq. 7-5's kernel exp(-t^2 / (2 s^2)) has rho(t) = exp(-t^2 / (4 s^2)).
        log_size = scipy.special.gammaln(2 * m + 1) - scipy.special.gammaln(m + 1)
        return (-1.0) ** m * np.exp(log_size) / (4 * width[..., None] ** 2) ** m


class Exponential(Family):
    """First-order low-pass: AR(1) / Ornstein-Uhlenbeck, phi = exp(-dt / tau).

    rho[l] = phi^l and S(f) = dt (1 - phi^2) / |1 - phi exp(-i omega)|^2 in
    closed form, and the noise comes from the AR(1) recursion. The
    continuous autocorrelation exp(-|t| / tau) has a corner at 0: order 0.

    Examples
    --------
    The closed-form autocorrelation phi^l equals the self-correlation of the
    (truncated) taps that the base class would compute:

    >>> import numpy as np
    >>> from bayes_jackal.model import Exponential, Family
    >>> family, dt = Exponential(), 1 / 72
    >>> rho = family.autocorrelation(0.1, dt, 50)
    >>> bool(np.allclose(rho, Family.autocorrelation(family, 0.1, dt, 50), atol=1e-12))
    True
    >>> bool(np.isclose(rho[1], np.exp(-dt / 0.1)))
    True
    >>> noise = family.noise(0.1, dt, 20000, scale=0.01, rng=1)  # AR(1)
    >>> round(float(noise.std()), 3)
    0.01
    """

    name = "exponential"
    description = "time constant tau [s] of a first-order low-pass"

    def _phi(self, width: float | np.ndarray, dt: float) -> np.ndarray:
        return np.exp(-dt / self.widths(width))

    def _taps(self, width: np.ndarray, dt: float) -> np.ndarray:
        # The kernel is infinite: cut where the remaining energy is below 1e-16,
        # phi^(2 L) = 1e-16 for the slowest decay: L = ln(1e16) tau / (2 dt).
        length = int(np.ceil(np.log(1e16) * width.max() / (2 * dt))) + 1
        return np.exp(-dt / width)[..., None] ** np.arange(length)

    def realisation(self, width: float | np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
        """AR(1), exact in one state: z[k] = v[k-1], v[k] = phi z[k] + sqrt(1 - phi^2) e[k]."""
        phi = self._phi(width, dt)[..., None]
        return phi[..., None], np.sqrt(1.0 - phi**2), phi, np.sqrt(1.0 - phi[..., 0] ** 2)

    def autocorrelation(self, width: float | np.ndarray, dt: float, lags: int) -> np.ndarray:
        return self._phi(width, dt)[..., None] ** np.arange(lags)

    def psd(self, width: float | np.ndarray, dt: float, frequency: np.ndarray) -> np.ndarray:
        omega = 2.0 * np.pi * np.asarray(frequency, float) * dt
        phi = self._phi(width, dt)[..., None]
        return dt * (1.0 - phi**2) / np.abs(1.0 - phi * np.exp(-1j * omega)) ** 2

    def noise(
        self,
        width: float,
        dt: float,
        n: int,
        scale: float | np.ndarray = 1.0,
        rng: np.random.Generator | int | None = None,
    ) -> np.ndarray:
        scale = np.asarray(scale, float)
        phi = float(self._phi(width, dt))
        white = as_rng(rng).standard_normal((n, *scale.shape))
        # AR(1) started in its stationary distribution: x[0] = white[0].
        initial = phi * white[:1]
        filtered, _ = scipy.signal.lfilter(
            [np.sqrt(1.0 - phi**2)], [1.0, -phi], white[1:], axis=0, zi=initial
        )
        return scale * np.concatenate([white[:1], filtered])


class Triangular(Family):
    """h(t) ~ 1 - |t| / w for |t| < w; rho''(0) = -3 / w^2, so order 1.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.model import Triangular
    >>> taps = Triangular().taps(0.03, 0.01)  # 1 - |t| / w at t = -0.03 .. 0.03
    >>> (taps / taps.max()).round(4).tolist()
    [0.0, 0.3333, 0.6667, 1.0, 0.6667, 0.3333, 0.0]
    >>> Triangular().autocorrelation_derivatives(0.1, 1).round(6).tolist()
    [1.0, 0.0, -300.0]
    >>> try:
    ...     Triangular().check_order(2)
    ... except ValueError as error:
    ...     print(str(error).split(": ", 1)[1][:48])
    the triangular family's autocorrelation has no d
    """

    name = "triangular"
    description = "half-base w [s] of a triangular filter"
    max_order = 1

    def _taps(self, width: np.ndarray, dt: float) -> np.ndarray:
        reach = int(np.ceil(width.max() / dt))
        k = np.arange(-reach, reach + 1)
        return np.clip(1.0 - np.abs(k) * dt / width[..., None], 0.0, None)

    def _even_derivatives(self, width: np.ndarray, m: np.ndarray) -> np.ndarray:
        return np.where(m == 0, 1.0, -3.0 / width[..., None] ** 2)


class MovingAverage(Family):
    """Boxcar of duration w: floor(w / dt) unit taps and a fractional last tap.

    Examples
    --------
    A duration of 3.5 samples: three unit taps and a half one, normalised to
    unit energy:

    >>> import numpy as np
    >>> from bayes_jackal.model import MovingAverage
    >>> taps = MovingAverage().taps(0.035, 0.01)
    >>> (taps * np.sqrt(3.25)).round(12).tolist()
    [1.0, 1.0, 1.0, 0.5]
    """

    name = "moving-average"
    description = "duration w [s] of a boxcar filter"

    def _taps(self, width: np.ndarray, dt: float) -> np.ndarray:
        samples = np.maximum(width / dt, 1.0)[..., None]
        k = np.arange(int(np.ceil(samples.max())))
        return np.clip(samples - k, 0.0, 1.0)


#: The filter families, by name: the one registry that the command line,
#: the layout, the likelihood, the simulator, the export and the comparison read.
FAMILIES: dict[str, Family] = {
    family.name: family
    for family in (White(), Gaussian(), Exponential(), Triangular(), MovingAverage())
}


def get_family(name: str) -> Family:
    """The family called ``name``; an :class:`InputError` listing the known ones otherwise.

    Examples
    --------
    >>> from bayes_jackal.model import get_family
    >>> family = get_family("gaussian")
    >>> family, family.width_name, family.description
    (Gaussian(), 'sigma_h', "sigma_h [s], the thesis' Gaussian filter (eq. 7-5)")
    >>> try:
    ...     get_family("pink")
    ... except ValueError as error:
    ...     print(error)
    family: unknown noise family 'pink'; use one of
    ['white', 'gaussian', 'exponential', 'triangular', 'moving-average']
    """
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

    Examples
    --------
    With 3 sigma_h / dt = 12 the kernel is eq. 7-5 itself, 25 taps of unit
    energy:

    >>> import numpy as np
    >>> from bayes_jackal.model import gaussian_kernel
    >>> h = gaussian_kernel(0.04, 0.01)
    >>> len(h), round(float(np.sum(h**2)), 12)
    (25, 1.0)
    >>> g = np.exp(-((np.arange(-12, 13) * 0.01) ** 2) / (2 * 0.04**2))
    >>> bool(np.allclose(h, g / np.linalg.norm(g)))
    True
    """
    return np.trim_zeros(FAMILIES["gaussian"].taps(float(_check_widths(sigma_h, "sigma_h")), dt))


def bandwidth(acov: np.ndarray) -> np.ndarray:
    """Number of leading lags holding every nonzero autocovariance of each set, p + 1.

    Parameters
    ----------
    acov : ndarray, shape (..., n)
        Autocovariance at lags 0..n-1 of each batch member.

    Returns
    -------
    ndarray of int, shape (...)
        1 + the last lag at which each member's autocovariance is nonzero
        (at least 1).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.model import bandwidth
    >>> bandwidth(np.array([[2.0, 0.5, 0.0, 0.0], [1.0, 0.0, 0.1, 0.0], [1.0, 0.0, 0.0, 0.0]]))
    array([2, 3, 1])
    """
    nonzero = acov != 0
    last = acov.shape[-1] - np.argmax(nonzero[..., ::-1], axis=-1)
    return np.where(nonzero.any(axis=-1), last, 1)
