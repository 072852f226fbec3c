"""Exact Toeplitz log-density of residual series at a cost flat in their length.

The ``fast`` engine of :class:`bayes_jackal.likelihood.ResidualLikelihood`
(docs/design.md §4). The residual series of one channel is x = Z c, linear
in c with the regressors Z (n, K) (K = 4 for a rate channel, c = (1,
-alpha, -beta_r, -beta_l); 6 for a pose channel,
:mod:`bayes_jackal.likelihood.measurements`). Its
Gaussian log-density under the Toeplitz covariance T_n of an autocovariance
needs

- log det T_n = n c_0 + sum_k k c_k^2, with c_k the cepstrum of the
  spectrum (strong Szego theorem; the remainder falls exponentially in n),
- x' T_n^-1 x = (|L(a)' x|^2 - |L(a~)' x|^2) / v (Gohberg-Semencul), with a
  the innovations predictor exp(-sum_{k>0} c_k z^-k) and v = exp(c_0)
  (Kolmogorov) once the predictor has converged within the series.

Both come from the spectrum alone. Once the cepstrum has decayed, a spectral
grid of L points much shorter than the series gives them exactly, so the
spectral factor costs O(L log L) whatever n is. The quadratic form's main
term |L(a)' x|^2, the energy of the full convolution of a (m significant
taps) with the series, is sum_{|l|<m} r_a(l) R_x(l): the predictor's
autocorrelation against the series' lagged sums R_x(l) = c' G(l) c, with G
the lagged Gram tensor of the regressors, computed once
(:class:`ResidualBlock`). The boundary terms involve the first and last m
samples only. So one evaluation costs O(L log L + E m log m) per
parameter set (E series in a block), after a one-off O(n log n) pass over
the data; a set not certified on a grid pays for that grid too, at most
doubling its cost (the grids double).

Each parameter set is evaluated on the first grid of :data:`SHORT_GRIDS`
where its spectral factor converged (cepstrum below 1e-10 and autocovariance
below 1e-13 of its variance over the grid's last half); otherwise on a grid
of at least 2n points, where the autocovariance is represented exactly; the
caller falls back to the time domain
(:func:`bayes_jackal.likelihood.fallback_loglike`) where even that has not
converged (long memory, spectral nulls): :func:`evaluate_on_grids` is that loop, shared by
the engines. The factor depends on the autocovariance only, so
:func:`spectral_forms` gives the quadratic forms of several coefficient
vectors from one factorisation (the bare series of
:mod:`bayes_jackal.likelihood.series_likelihood` needs three).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.fft

from .._runtime import chunks
from .whittle import cross_periodogram

__all__ = [
    "CHUNK_ELEMENTS",
    "SHORT_GRIDS",
    "ResidualBlock",
    "evaluate_on_grids",
    "spectral_forms",
    "spectral_loglike",
]

#: Spectral grids tried before the full one (>= 2n points), in this order.
#: Doubling bounds the work on grids too short for a set by the work on the
#: one that certifies it; 2^17 points hold an autocovariance of ~65,000 lags
#: (an exponential kernel of 1 s decays to 1e-13 in ~2,200 lags at 72 Hz).
SHORT_GRIDS = tuple(2**k for k in range(9, 18))
#: Largest cepstral term over a grid's last half accepted as converged.
CEPSTRUM_TOLERANCE = 1e-10
#: Largest autocovariance over the last half of a short grid's lags
#: (size/4 to size/2), relative to the variance, accepted as negligible
#: beyond them. The autocovariances of the families decay at least
#: geometrically (or end), so the lags dropped past size/2 are far smaller
#: still; measured against ``exact``: within 2e-8 nats on 1e5 residuals.
ACOV_TOLERANCE = 1e-13
#: A set's predictor taps past its last one above this are dropped.
PREDICTOR_TOLERANCE = 1e-14
#: Segment spectra kept per block (:meth:`ResidualBlock.edge_spectra`): the
#: predictor lengths m of a chain's nearby sets take a few values.
_EDGE_SPECTRA_KEPT = 8
#: Elements of the largest work array of one chunk of parameter sets
#: (2^22 doubles: 32 MiB).
CHUNK_ELEMENTS = 2**22
_LOG_2PI = np.log(2.0 * np.pi)


@dataclass(frozen=True)
class ResidualBlock:
    """Residual series of one channel with one noise setting and one length.

    Holds the regressors Z of E series, each (n, K), how they were recorded
    (:attr:`measurement`, a key of
    :data:`bayes_jackal.likelihood.MEASUREMENT_MODELS`, and the poses
    averaged per sample, :attr:`samples`), and what the engines
    derive from them once (:attr:`clock`: the series is every m samples
    of the experiment's clock at one phase, a pose channel's own clock;
    :meth:`bayes_jackal.likelihood.Measurement.clock`): the Whittle cross-periodogram and, for the
    ``fast`` engine, the series' means and the lagged Gram tensor of their
    deviations. Splitting off the means keeps the lagged sums accurate:
    the transforms' rounding is relative to the deviations' energy, not
    to the large means of the wheel speeds and the steady yaw rate.

    Examples
    --------
    One run's yaw regressors: the residuals of a coefficient vector, and the
    lagged sums R(l) = sum_i x[i] x[i+l] from the Gram tensor, computed once:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import residual_regressors
    >>> from bayes_jackal.likelihood import ResidualBlock
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v1", rng=1)
    >>> block = ResidualBlock("yaw", 0, run.dt, residual_regressors(run, "yaw")[None])
    >>> block.count, block.n, block.grids()[:3]
    (1, 2736, [512, 1024, 2048])
    >>> c = np.array([[1.0, -0.72, -0.01, 0.01]])
    >>> x = block.residuals(c)[0, 0]
    >>> direct = [x[: len(x) - lag] @ x[lag:] for lag in range(3)]
    >>> bool(np.allclose(block.lagged_sums(c, 3)[0], direct))
    True
    """

    channel: str
    noise_group: int
    dt: float
    regressors: np.ndarray = field(repr=False)
    measurement: str = "rate"
    samples: int = 1
    clock: tuple[int, float] = (1, 0.0)

    @property
    def count(self) -> int:
        """Number of series E."""
        return self.regressors.shape[0]

    @property
    def n(self) -> int:
        """Length of each series."""
        return self.regressors.shape[1]

    @property
    def width(self) -> int:
        """K, the regressors of each sample."""
        return self.regressors.shape[2]

    @property
    def size(self) -> int:
        """The full spectral grid: zero padding to >= 2n points."""
        return scipy.fft.next_fast_len(2 * self.n, real=True)

    def grids(self) -> list[int]:
        """Spectral grids to try, shortest first; the last is :attr:`size`."""
        return [size for size in SHORT_GRIDS if size < self.size] + [self.size]

    def residuals(self, coefficients: np.ndarray) -> np.ndarray:
        """Residual series Z c of every parameter set, shape (B, E, n)."""
        return np.einsum("enk,bk->ben", self.regressors, coefficients)

    @cached_property
    def periodogram(self) -> np.ndarray:
        """Cross-periodogram on the n Fourier frequencies / n, summed over the series, (F, K^2)."""
        spectra = sum(cross_periodogram(z) for z in self.regressors) / self.n
        return spectra.reshape(-1, self.width**2)

    @cached_property
    def means(self) -> np.ndarray:
        """Each series' regressor means mu_e, shape (E, K)."""
        return self.regressors.mean(axis=1)

    def _deviations(self) -> np.ndarray:
        """D_e = Z_e - mu_e, shape (E, n, K) (not kept: each use is once)."""
        return self.regressors - self.means[:, None, :]

    @cached_property
    def _lag_basis(self) -> np.ndarray:
        """[G_D(l), S(l)] for l = 0..n-1, shape (n, K^2 + E K), contiguous.

        G_D(l) = sum_e sum_i D_e[i] D_e[i+l]' (symmetrised), the deviations'
        lagged Gram tensor (D_e = Z_e - mu_e), from their cross-periodogram on
        >= 2n points, so the lags are not circular; S_e(l) = sum_{i<n-l} D_e[i]
        + sum_{i>=l} D_e[i], their edge sums: as the deviations sum to zero,
        -(sum of the first l) - (sum of the last l).
        """
        deviations = self._deviations()
        spectra = sum(cross_periodogram(d, self.size) for d in deviations)
        spectra = spectra.reshape(-1, self.width**2)
        gram = scipy.fft.irfft(spectra, self.size, axis=0)[: self.n]
        zero = np.zeros((self.count, 1, self.width))
        head = np.concatenate([zero, np.cumsum(deviations[:, :-1], axis=1)], axis=1)
        tail = np.concatenate([zero, np.cumsum(deviations[:, :0:-1], axis=1)], axis=1)
        edges = -(head + tail).transpose(1, 0, 2).reshape(self.n, -1)
        return np.ascontiguousarray(np.concatenate([gram, edges], axis=1))

    def lagged_sums(self, coefficients: np.ndarray, lags: int) -> np.ndarray:
        """R(l) = sum_e sum_i x_e[i] x_e[i+l] of x = Z c for l < ``lags``, shape (B, lags).

        With x = m_e + d (m_e = mu_e' c the series' mean):
        R(l) = (n - l) sum_e m_e^2 + sum_e m_e c' S_e(l) + c' G_D(l) c, with the
        deviations' edge sums S and lagged Gram tensor G_D (:attr:`_lag_basis`):
        one product of (c c', m_e c) with them.
        """
        batch = len(coefficients)
        mean = coefficients @ self.means.T  # (B, E)
        features = np.concatenate(
            [
                (coefficients[:, :, None] * coefficients[:, None, :]).reshape(batch, -1),
                (mean[:, :, None] * coefficients[:, None, :]).reshape(batch, -1),
            ],
            axis=1,
        )
        level = (self.n - np.arange(lags)) * np.sum(mean**2, axis=-1, keepdims=True)
        return level + features @ self._lag_basis[:lags].T

    def edge_spectra(self, m: int, length: int) -> np.ndarray:
        """Spectra on ``length`` points of each series' first m regressors and last m reversed.

        Shape (2E, length // 2 + 1, K); the last few (m, length) are kept.
        """
        key = (m, length)
        cache = self._edge_spectra
        if key not in cache:
            if len(cache) >= _EDGE_SPECTRA_KEPT:
                cache.pop(next(iter(cache)))
            segments = np.concatenate(
                [self.regressors[:, :m], self.regressors[:, self.n - m :][:, ::-1]], axis=0
            )
            cache[key] = scipy.fft.rfft(segments, length, axis=1)
        return cache[key]

    @cached_property
    def _edge_spectra(self) -> dict[tuple[int, int], np.ndarray]:
        return {}


def spectral_forms(
    acov: np.ndarray, block: ResidualBlock, coefficients: np.ndarray, size: int
) -> tuple[np.ndarray, np.ndarray]:
    """log det T_n and the quadratic forms of several coefficient vectors, from one factorisation.

    The spectral factor (the log-determinant and the predictor) depends on
    the autocovariance only, so J coefficient vectors per parameter set
    share it: x' T_n^-1 x of x = Z c_j for each j at the cost of one extra
    lagged-sum contraction and boundary correlation each.

    Parameters
    ----------
    acov : ndarray, shape (B, min(n, size // 2 + 1))
        Autocovariance at lags 0, 1, ... (as :func:`spectral_loglike`).
    block : ResidualBlock
        E series of length n.
    coefficients : ndarray, shape (B, J, K)
        J coefficient vectors c_j of each parameter set.
    size : int
        Spectral grid: one of ``block.grids()``.

    Returns
    -------
    forms : ndarray, shape (B, 1 + J)
        Column 0: log det T_n of one series [nats]; column 1 + j: x' T_n^-1 x
        of x = Z c_j, summed over the block's series. Meaningful where
        ``converged``.
    converged : ndarray of bool, shape (B,)
        As :func:`spectral_loglike`.

    Examples
    --------
    White noise of variance 4: log det = n log 4 and x' T^-1 x = |x|^2 / 4,
    here for x = y and x = 2 y:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import ResidualBlock, spectral_forms
    >>> y = np.random.default_rng(1).standard_normal(100)
    >>> regressors = np.zeros((1, 100, 4))
    >>> regressors[0, :, 0] = y
    >>> block = ResidualBlock("series", 0, 0.01, regressors)
    >>> acov = np.zeros((1, 100))
    >>> acov[0, 0] = 4.0
    >>> c = np.array([[[1.0, 0, 0, 0], [2.0, 0, 0, 0]]])
    >>> forms, converged = spectral_forms(acov, block, c, block.size)
    >>> expected = [100 * np.log(4.0), y @ y / 4, y @ y]
    >>> bool(converged[0]), bool(np.allclose(forms[0], expected))
    (True, True)
    """
    batch, lags = acov.shape
    n, half = block.n, size // 2
    symmetric = np.zeros((batch, size))
    symmetric[:, :lags] = acov
    symmetric[:, size - lags + 1 :] = acov[:, :0:-1]
    spectrum = scipy.fft.rfft(symmetric).real
    positive = np.all(spectrum > 0, axis=-1)
    cepstrum = scipy.fft.irfft(np.log(np.where(positive[:, None], spectrum, 1.0)), size)
    causal = np.zeros((batch, size))
    causal[:, 1:half] = cepstrum[:, 1:half]
    predictor = np.exp(-scipy.fft.rfft(causal))
    log_v = cepstrum[:, 0]
    log_det = n * log_v + np.sum(np.arange(1, half) * cepstrum[:, 1:half] ** 2, axis=-1)
    tail = min(n, half) // 2
    converged = positive & (np.abs(cepstrum[:, tail:half]).max(axis=-1) < CEPSTRUM_TOLERANCE)
    if lags < n:
        beyond = np.abs(acov[:, lags // 2 :]).max(axis=-1)
        converged &= beyond <= ACOV_TOLERANCE * acov[:, 0]
    # The predictor's taps down to 1e-14, each set its own (a_0 = 1).
    a = scipy.fft.irfft(predictor, size)[:, : min(n, half)]
    significant = np.abs(a) > PREDICTOR_TOLERANCE
    last = a.shape[1] - 1 - np.argmax(significant[:, ::-1], axis=1)
    m = max(2, int(last[converged].max()) + 1) if converged.any() else 2
    taps = np.where(np.arange(m) <= last[:, None], a[:, :m], 0.0)
    length = 2 * scipy.fft.next_fast_len(m, real=True)  # even, >= 2m
    taps_spectrum = scipy.fft.rfft(taps, length)
    # |L(a)'x|^2 summed over the series: the full convolution's energy,
    # sum_{|l|<m} r_a(l) R(l), less the boundary terms.
    predictor_acf = scipy.fft.irfft(np.abs(taps_spectrum) ** 2, length)[:, :m]
    weights = np.full(m, 2.0)
    weights[0] = 1.0
    forms = coefficients.shape[1]
    sums = block.lagged_sums(coefficients.reshape(-1, block.width), m).reshape(batch, forms, m)
    full = np.sum(predictor_acf[:, None, :] * sums * weights, axis=-1)
    boundary = _boundary_energy(taps_spectrum, m, block, coefficients)
    quadratic = (full - boundary) / np.exp(log_v)[:, None]
    return np.column_stack([log_det, quadratic]), converged


def spectral_loglike(
    acov: np.ndarray, block: ResidualBlock, coefficients: np.ndarray, size: int
) -> tuple[np.ndarray, np.ndarray]:
    """Exact Toeplitz Gaussian log-density of a block's residuals from a spectral grid.

    Parameters
    ----------
    acov : ndarray, shape (B, min(n, size // 2 + 1))
        Autocovariance at lags 0, 1, ...: on a short grid (size < 2n) up to
        lag size / 2, on the full grid (size >= 2n) every lag of the series.
    block : ResidualBlock
        E series of length n.
    coefficients : ndarray, shape (B, K)
        c of each parameter set: the residuals are Z c.
    size : int
        Spectral grid: one of ``block.grids()``.

    Returns
    -------
    loglike : ndarray, shape (B,)
        Summed over the block's series; meaningful where ``converged``.
    converged : ndarray of bool, shape (B,)
        Whether this grid certifies the value: positive spectrum, cepstrum
        decayed over the grid's last half (within the series on the full
        grid) and, on a short grid, the autocovariance too.

    Examples
    --------
    On the full grid the value is the exact Toeplitz density of
    :func:`bayes_jackal.likelihood.toeplitz_loglike`:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.likelihood import residual_autocovariance, toeplitz_loglike
    >>> from bayes_jackal.likelihood import residual_regressors
    >>> from bayes_jackal.likelihood import ResidualBlock, spectral_loglike
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v1", rng=1)
    >>> block = ResidualBlock("yaw", 0, run.dt, residual_regressors(run, "yaw")[None])
    >>> c = np.array([[1.0, -0.72, -0.01, 0.01]])
    >>> one = np.ones(1)
    >>> acov = residual_autocovariance(
    ...     get_family("gaussian"), 0.047 * one, 0.01 * one, 0.005 * one, 0.72 * one,
    ...     run.dt, block.n,
    ... )
    >>> value, converged = spectral_loglike(acov, block, c, block.size)
    >>> exact = toeplitz_loglike(acov, block.residuals(c))[:, 0]
    >>> bool(converged[0]), bool(abs(value[0] - exact[0]) < 1e-6)
    (True, True)
    """
    forms, converged = spectral_forms(acov, block, coefficients[:, None, :], size)
    log_det, quadratic = forms[:, 0], forms[:, 1]
    loglike = -0.5 * (block.count * log_det + quadratic + block.count * block.n * _LOG_2PI)
    return loglike, converged


def evaluate_on_grids(
    block: ResidualBlock,
    autocovariance: Callable[[np.ndarray, int], np.ndarray],
    coefficients: np.ndarray,
    evaluate: Callable[..., tuple[np.ndarray, np.ndarray]],
    out: np.ndarray,
) -> np.ndarray:
    """Evaluate each parameter set on the first of ``block.grids()`` that certifies it.

    The grid loop of the ``fast`` engines, in chunks of sets whose work
    arrays stay within :data:`CHUNK_ELEMENTS`.

    Parameters
    ----------
    block : ResidualBlock
    autocovariance : callable
        ``autocovariance(rows, lags)``: the autocovariance at lags
        0..lags-1 of the sets indexed by the integer array ``rows``, shape
        (len(rows), lags).
    coefficients : ndarray, shape (B, K) or (B, J, K)
        The sets' coefficient vectors, as ``evaluate`` takes them.
    evaluate : callable
        :func:`spectral_loglike` or :func:`spectral_forms`:
        ``evaluate(acov, block, coefficients, size) -> (values, converged)``.
    out : ndarray, shape (B, ...)
        Receives each certified set's values (in place); the others are
        left as they were.

    Returns
    -------
    ndarray of int
        The sets no grid certifies (long memory), for the caller's fallback.

    Examples
    --------
    A white series of variance 2 is certified on the first grid:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import ResidualBlock, evaluate_on_grids, spectral_loglike
    >>> regressors = np.zeros((1, 50, 4))
    >>> regressors[0, :, 0] = 1.0
    >>> block = ResidualBlock("series", 0, 0.01, regressors)
    >>> def white(rows, lags):
    ...     return 2.0 * (np.arange(lags) == 0) * np.ones((len(rows), 1))
    >>> out = np.full(1, -np.inf)
    >>> c = np.array([[1.0, 0, 0, 0]])
    >>> evaluate_on_grids(block, white, c, spectral_loglike, out).tolist()
    []
    >>> expected = -0.5 * (50 * np.log(2.0) + 50 / 2.0 + 50 * np.log(2 * np.pi))
    >>> bool(np.isclose(out[0], expected))
    True
    """
    pending = np.arange(len(coefficients))
    forms = int(np.prod(coefficients.shape[1:-1]))
    for size in block.grids():
        if not len(pending):
            break
        lags = min(block.n, size // 2 + 1)
        certified = []
        # Per set: the grid's arrays, and the boundary's (J x 2E, ~2m <= size).
        per_set = size * (1 + 2 * block.count * forms)
        for rows in chunks(len(pending), per_set, budget=CHUNK_ELEMENTS):
            chunk = pending[rows]
            acov = autocovariance(chunk, lags)
            values, converged = evaluate(acov, block, coefficients[chunk], size)
            out[chunk[converged]] = values[converged]
            certified.append(converged)
        pending = pending[~np.concatenate(certified)]
    return pending


def _boundary_energy(
    taps_spectrum: np.ndarray, m: int, block: ResidualBlock, coefficients: np.ndarray
) -> np.ndarray:
    """The convolution's tail plus |L(a~)' x|^2, summed over the block's series, shape (B, J).

    The tail sum_{k>=r} a_k x_{k-r} and the rows of L(a~)' x are both lag-r
    correlations of the m taps a (r = 1..m-1, from their spectrum on
    >= 2m points) with the first m samples and with the reversed last m
    samples of each series, for each of the J coefficient vectors (B, J, K):
    the segments' spectra are the regressors' (:meth:`ResidualBlock.edge_spectra`)
    times c.
    """
    batch, forms, width = coefficients.shape
    length = 2 * (taps_spectrum.shape[1] - 1)  # even
    spectra = block.edge_spectra(m, length) @ coefficients.reshape(-1, width).T  # (2E, F, BJ)
    spectra = spectra.transpose(2, 0, 1).reshape(batch, forms, -1, spectra.shape[1])
    correlation = scipy.fft.irfft(taps_spectrum[:, None, None, :] * spectra.conj(), length)
    return np.sum(correlation[..., 1:m] ** 2, axis=(2, 3))
