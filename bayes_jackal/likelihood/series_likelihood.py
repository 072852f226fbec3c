"""Likelihood of a bare noise series: a constant mean, coloured noise and a white floor.

A series y_k (k = 0..n-1, sample time dt) of a sensor standing still, or a
model's residual, is modelled (issue 15) as

    y = mu 1 + w + e,

with mu a constant mean, w coloured noise of a registered family
(:mod:`bayes_jackal.model.kernels`: sd ``sigma_c``, the family's width [s]) and e
a white floor of sd ``sigma_n``. Its covariance is Toeplitz, with the
autocovariance sigma_c^2 rho(l; width) + sigma_n^2 [l = 0]: the one-step
residual's of the robot model with alpha = 0
(:func:`bayes_jackal.likelihood.residual_autocovariance`; the ``ma1`` and
``diagonal`` sensor terms coincide there). White noise plus a white floor
has one variance, which two sds would split along a flat ridge: the white
family has one parameter, ``sigma``, the total sd.

The mean is integrated out under a flat prior. With T the covariance and
1 the ones vector,

    log L = -1/2 [y'T^-1 y - (1'T^-1 y)^2 / (1'T^-1 1) + log det T
                  + log(1'T^-1 1) + (n - 1) log 2 pi].

The flat prior is improper: this is the marginal density with the prior's
density set to 1 per series unit. That constant is the same for every
family, so Bayes factors between families of one series do not depend on
it. The GLS mean (1'T^-1 y) / (1'T^-1 1) is :meth:`SeriesLikelihood.gls_mean`.

The value needs three quadratic forms, x'T^-1 x for x = y, 1 and y + 1
(whence 1'T^-1 y), and log det T. They are computed on the series centred
on its sample mean: the marginal likelihood does not depend on a constant
added to the series, and centring keeps a large mean from cancelling
digits in y'T^-1 y - (1'T^-1 y)^2 / (1'T^-1 1). Two engines give them:

- ``exact``: the Durbin-Levinson recursion over all n orders, O(n^2)
  (:func:`bayes_jackal.likelihood.toeplitz_loglike` on x = 0, y, 1, y + 1:
  the density of x = 0 is -1/2 (log det T + n log 2 pi)). The reference.
- ``fast`` (default): the spectral engine (:mod:`bayes_jackal.likelihood.spectral`)
  with the regressors Z = [y, 1, 0, 0] and the forms' coefficient vectors
  e1, e2 and e1 + e2, from one spectral factorisation per parameter set
  (:func:`~bayes_jackal.likelihood.spectral_forms`) at a cost flat in n. Sets
  no grid certifies fall back to the time domain
  (:func:`~bayes_jackal.likelihood.fallback_loglike`: the banded Cholesky
  factor, or the recursion stopped at converged partial
  autocorrelations), as :class:`~bayes_jackal.likelihood.ResidualLikelihood`
  does; the exponential family's take its tridiagonal form instead, below.

The exponential family is an AR(1) process, phi = exp(-dt / tau), whose
correlation matrix Phi (Phi_ij = phi^|i-j|) has a tridiagonal inverse,
Phi^-1 = K / a with a = 1 - phi^2 and K = tridiag(-phi; 1, 1 + phi^2, ...,
1 + phi^2, 1; -phi). With T = sigma_c^2 Phi + sigma_n^2 I and the
tridiagonal N = a sigma_c^2 I + sigma_n^2 K = a Phi^-1 T,

    T^-1 x = N^-1 K x,    log det T = log det N - log a,

O(n) per set by LAPACK's tridiagonal factorisation (dpttrf, dpttrs), exact
(:meth:`SeriesLikelihood._tridiagonal_forms`). Its long time constants
(tau of tens of samples and more under a weak coloured part, on white
noise) are those no spectral grid certifies: the recursion cost them 15 ms
a set on 1,000 samples, and 0.3 s on 10,000.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property, partial

import numpy as np
import scipy.linalg

from .._runtime import FAMILY, SERIES_ENGINES, DataError, InputError, chunks, positive_number
from ..io import check_finite, numeric_array
from ..model import Exponential, Family, get_family
from .measurements import residual_autocovariance
from .spectral import CHUNK_ELEMENTS, ResidualBlock, evaluate_on_grids, spectral_forms
from .toeplitz import fallback_loglike, toeplitz_loglike

__all__ = [
    "MIN_LIKELIHOOD_SAMPLES",
    "SERIES_SPREAD",
    "WHITE_SD",
    "SeriesLikelihood",
    "check_length",
    "check_series",
]

#: Fewest samples of a series: four parameters (the mean, the width, two
#: sds) and a dozen degrees of freedom beyond them.
MIN_LIKELIHOOD_SAMPLES = 16
#: The white family's one parameter: the total sd [series units].
WHITE_SD = "sigma"
#: Coefficient vectors of the quadratic forms over Z = [y, 1, 0, 0]: x = y, 1, y + 1.
_FORMS = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]])
_LOG_2PI = np.log(2.0 * np.pi)


@dataclass(frozen=True, kw_only=True, eq=False)
class SeriesLikelihood:
    """Log-likelihood of one noise series, its mean integrated out (module docstring).

    Parameters
    ----------
    values : array_like, shape (n,)
        The series [series units]: finite, not constant, n >= :data:`MIN_LIKELIHOOD_SAMPLES`.
        Kept as a read-only float copy.
    dt : float
        Sample time [s], > 0.
    family : str
        Noise family (:data:`bayes_jackal.model.FAMILIES`).
    engine : {"fast", "exact"}
        ``fast`` (spectral, cost flat in n) or ``exact`` (the O(n^2)
        recursion, the reference).
    fallback : bool
        ``fast`` only: sets no spectral grid certifies (widths comparable
        with the record: long memory) take the time-domain fallback
        (:func:`~bayes_jackal.likelihood.fallback_loglike`); without, only
        those whose banded factor is cheap do and the rest are -inf (the
        MAP search's scan over a wide prior, where a long-memory set costs
        ~0.5 s).

    Raises
    ------
    DataError
        For non-finite, constant or too few values (field ``values``).
    InputError
        For a ``dt`` that is not positive and finite, or an unknown
        ``family`` or ``engine`` (naming the field).

    Examples
    --------
    A Gaussian-coloured series of width 5 samples about a mean of 5, with a
    white floor: the true width is likelier than a narrower one, the
    engines agree, and the GLS mean is within two of its sds (0.21 here,
    (1'T^-1 1)^-1/2) of the true mean.

    >>> import numpy as np
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.likelihood import SeriesLikelihood
    >>> rng = np.random.default_rng(1)
    >>> noise = get_family("gaussian").noise(0.05, 0.01, 400, rng=rng)
    >>> values = 5.0 + noise + 0.1 * rng.standard_normal(400)
    >>> likelihood = SeriesLikelihood(values=values, dt=0.01, family="gaussian")
    >>> likelihood.names
    ('sigma_h', 'sigma_c', 'sigma_n')
    >>> theta = np.array([[0.05, 1.0, 0.1], [0.02, 1.0, 0.1]])
    >>> loglike = likelihood(theta)
    >>> bool(loglike[0] > loglike[1])
    True
    >>> exact = SeriesLikelihood(values=values, dt=0.01, family="gaussian", engine="exact")
    >>> bool(np.allclose(loglike, exact(theta), rtol=0, atol=1e-8))
    True
    >>> round(float(likelihood.gls_mean(theta)[0]), 2)
    4.63
    >>> SeriesLikelihood(values=values, dt=0.01, family="white").names
    ('sigma',)
    """

    values: np.ndarray
    dt: float
    family: str = FAMILY
    engine: str = "fast"
    fallback: bool = True

    def __post_init__(self) -> None:
        values, dt = check_series(self.values, self.dt)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "dt", dt)
        get_family(self.family)  # an InputError naming the known families
        if self.engine not in SERIES_ENGINES:
            raise InputError(
                f"unknown engine {self.engine!r}; use one of {SERIES_ENGINES}", field="engine"
            )

    @property
    def _family(self) -> Family:
        return get_family(self.family)

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self.values)

    @property
    def width_name(self) -> str | None:
        """The family's width parameter [s] (``sigma_h`` or ``width``); None for white noise."""
        return self._family.width_name

    @property
    def names(self) -> tuple[str, ...]:
        """Names in vector order: the width, ``sigma_c``, ``sigma_n``; white: ``sigma``."""
        if self.width_name is None:
            return (WHITE_SD,)
        return (self.width_name, "sigma_c", "sigma_n")

    @cached_property
    def centre(self) -> float:
        """The sample mean the forms are computed about [series units]."""
        return float(np.mean(self.values))

    @cached_property
    def block(self) -> ResidualBlock:
        """The spectral engine's block: regressors [y - centre, 1, 0, 0], one series."""
        regressors = np.zeros((1, self.n, 4))
        regressors[0, :, 0] = self.values - self.centre
        regressors[0, :, 1] = 1.0
        return ResidualBlock("series", 0, self.dt, regressors)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Log-likelihood of each parameter vector, the mean integrated out [nats].

        Parameters
        ----------
        theta : ndarray, shape (B, k) or (k,)
            Parameter vectors in natural units, ordered as :attr:`names`:
            the width [s] and the sds [series units].

        Returns
        -------
        ndarray, shape (B,)
            -inf where the covariance is not positive definite.
        """
        log_det, yy, ones, cross = self._forms(theta)
        with np.errstate(invalid="ignore", divide="ignore"):
            quadratic = yy - cross**2 / ones
            loglike = -0.5 * (quadratic + log_det + np.log(ones) + (self.n - 1) * _LOG_2PI)
        return np.where(np.isfinite(loglike), loglike, -np.inf)

    def gls_mean(self, theta: np.ndarray) -> np.ndarray:
        """The generalised least-squares mean (1'T^-1 y) / (1'T^-1 1) [series units].

        The posterior mean of mu under the flat prior, given the noise
        parameters; its posterior sd is (1'T^-1 1)^-1/2.

        Parameters
        ----------
        theta : ndarray, shape (B, k) or (k,)
            As :meth:`__call__`.

        Returns
        -------
        ndarray, shape (B,)
        """
        _, _, ones, cross = self._forms(theta)
        return self.centre + cross / ones

    def autocovariance(self, theta: np.ndarray, lags: int) -> np.ndarray:
        """The noise's autocovariance at lags 0..lags-1 [(series units)^2].

        sigma_c^2 rho(l; width) + sigma_n^2 [l = 0], rho the family's
        autocorrelation (:meth:`bayes_jackal.model.Family.autocorrelation`);
        white noise: sigma^2 [l = 0]. The covariance this likelihood scores.

        Parameters
        ----------
        theta : ndarray, shape (B, k) or (k,)
            As :meth:`__call__`.
        lags : int

        Returns
        -------
        ndarray, shape (B, lags)
        """
        return self._autocovariance(self._noise(theta), lags)

    def _forms(self, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """log det T, y'T^-1 y, 1'T^-1 1 and 1'T^-1 y of the centred series, each (B,)."""
        noise = self._noise(theta)
        if self.engine == "exact":
            forms = self._recursion(noise)
        else:
            forms = np.full((noise.shape[1], 4), np.nan)
            coefficients = np.broadcast_to(_FORMS, (noise.shape[1], *_FORMS.shape))

            def autocovariance(rows: np.ndarray, lags: int) -> np.ndarray:
                return self._autocovariance(noise[:, rows], lags)

            pending = evaluate_on_grids(
                self.block, autocovariance, coefficients, spectral_forms, forms
            )
            if len(pending) and isinstance(self._family, Exponential):
                forms[pending] = self._tridiagonal_forms(noise[:, pending])
            elif len(pending):
                density = partial(fallback_loglike, recursion=self.fallback)
                forms[pending] = self._recursion(noise[:, pending], density)
        log_det, yy, ones, both = forms.T
        return log_det, yy, ones, 0.5 * (both - yy - ones)

    def _noise(self, theta: np.ndarray) -> np.ndarray:
        """(width [s], sigma_c, sigma_n) of each set, shape (3, B); white: (1, sigma, 0)."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.ndim != 2 or theta.shape[1] != len(self.names):
            raise InputError(
                f"parameter vectors must have shape (B, {len(self.names)}) for "
                f"{self.names}, got {theta.shape}",
                field="theta",
            )
        if self.width_name is None:
            ones = np.ones(len(theta))
            return np.stack([ones, theta[:, 0], 0.0 * ones])
        return theta.T

    def _autocovariance(self, noise: np.ndarray, lags: int) -> np.ndarray:
        """Autocovariance at lags 0..lags-1 of (width, sigma_c, sigma_n) columns, (B, lags)."""
        alpha = np.zeros(noise.shape[1])
        return residual_autocovariance(self._family, *noise, alpha, self.dt, lags, "diagonal")

    def _tridiagonal_forms(self, noise: np.ndarray) -> np.ndarray:
        """log det T and x'T^-1 x of x = y, 1, y + 1 for the exponential family, shape (B, 4).

        The tridiagonal form of the module docstring, exact in O(n) per set;
        NaN where N is not positive definite. K x is computed as
        (1 - phi)^2 x - phi (second difference of x), its ends as
        (1 - phi) x - phi (first difference): no cancellation as phi -> 1.
        """
        width, sigma_c, sigma_n = noise
        y = self.block.regressors[0, :, 0]
        x = np.column_stack([y, np.ones(self.n), y + 1.0])
        second = np.zeros_like(x)
        second[1:-1] = x[:-2] - 2.0 * x[1:-1] + x[2:]
        second[[0, -1]] = x[[1, -2]] - x[[0, -1]]
        ends = np.zeros((self.n, 1))
        ends[[0, -1]] = 1.0
        q = -np.expm1(-self.dt / width)  # 1 - phi, accurate for long tau
        phi, a = 1.0 - q, q * (2.0 - q)  # a = 1 - phi^2
        forms = np.full((len(q), 4), np.nan)
        for row, (p, c, w, step, scale) in enumerate(
            zip(phi, sigma_c**2, sigma_n**2, q, a, strict=True)
        ):
            gain = np.where(ends[:, 0] > 0, step, step * step)
            kx = gain[:, None] * x - p * second
            diagonal = scale * c + w * (gain + 2.0 * p - p * ends[:, 0])
            d, e, info = scipy.linalg.lapack.dpttrf(diagonal, np.full(self.n - 1, -w * p))
            if info != 0:
                continue
            solved, info = scipy.linalg.lapack.dpttrs(d, e, kx)
            if info != 0:
                continue
            forms[row, 0] = np.sum(np.log(d)) - np.log(scale)
            forms[row, 1:] = np.sum(x * solved, axis=0)
        return forms

    def _recursion(
        self,
        noise: np.ndarray,
        density: Callable[[np.ndarray, np.ndarray], np.ndarray] = toeplitz_loglike,
    ) -> np.ndarray:
        """log det T and x'T^-1 x of x = y, 1, y + 1 from a time-domain density, shape (B, 4).

        ``density``: :func:`~bayes_jackal.likelihood.toeplitz_loglike`, the
        full recursion (the ``exact`` engine), or the ``fast`` engine's
        :func:`~bayes_jackal.likelihood.fallback_loglike`.
        """
        n = self.n
        y = self.block.regressors[0, :, 0]
        series = np.stack([np.zeros(n), y, np.ones(n), y + 1.0])
        forms = np.empty((noise.shape[1], 4))
        for rows in chunks(noise.shape[1], 7 * n, budget=CHUNK_ELEMENTS):
            acov = self._autocovariance(noise[:, rows], n)
            loglike = density(acov, np.broadcast_to(series, (len(acov), 4, n)))
            with np.errstate(invalid="ignore"):
                forms[rows, 0] = -2.0 * loglike[:, 0] - n * _LOG_2PI
                forms[rows, 1:] = -2.0 * (loglike[:, 1:] - loglike[:, :1])
        return forms


def check_length(
    samples: int, *, minimum: int, source: str | None, field: str, where: str = ""
) -> None:
    """Refuse a series of fewer than ``minimum`` samples (``where``: e.g. on the clock).

    Parameters
    ----------
    samples : int
        The series' length [samples].
    minimum : int
        Fewest samples accepted.
    source : str or None
        The file named in the error (None: a series built in memory).
    field : str
        The column or field named in the error.
    where : str
        Appended to the count in the error, e.g. ``" on the uniform clock"``.

    Raises
    ------
    DataError
        Naming ``source``, ``field``, the count and the minimum.

    Examples
    --------
    >>> from bayes_jackal.likelihood import check_length
    >>> try:
    ...     check_length(10, minimum=16, source="gyro.csv", field="z")
    ... except ValueError as exc:
    ...     print(exc)
    gyro.csv: z: only 10 samples; a noise series needs at least 16
    """
    if samples < minimum:
        raise DataError(
            f"only {samples} samples{where}; a noise series needs at least {minimum}",
            source=source,
            field=field,
        )


#: The sds a noise series may have [series units]: its covariances (sd^2,
#: and the prior's sds down to 1e-3 of it) stay well inside double
#: precision's 1e-308 to 1e308.
SERIES_SPREAD = (1e-100, 1e100)


def check_series(
    values: object,
    dt: float | None,
    *,
    source: str | None = None,
    field: str = "values",
    minimum: int = MIN_LIKELIHOOD_SAMPLES,
) -> tuple[np.ndarray, float]:
    """A noise series as a read-only float vector and its sample time [s], or an error.

    The one check of :class:`SeriesLikelihood` and
    :class:`bayes_jackal.noise.NoiseSeries`.

    Parameters
    ----------
    values : array_like, shape (n,)
        Numbers [series units]: finite, not all equal, n >= ``minimum``.
    dt : float
        Sample time [s], > 0.
    source, field : str, optional
        Named in errors: the file and the column.
    minimum : int
        Fewest samples.

    Returns
    -------
    values : ndarray, shape (n,)
        A read-only float copy.
    dt : float

    Raises
    ------
    DataError
        For values that are not a 1-D series of numbers, non-finite values
        (naming the first), too few samples, a constant series, or one whose
        sd is outside :data:`SERIES_SPREAD`.
    InputError
        For a ``dt`` that is not a positive number (field ``dt``).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.likelihood import check_series
    >>> values, dt = check_series([1, 2, 1] * 6, 0.01)
    >>> values.dtype, values.flags.writeable, dt
    (dtype('float64'), False, 0.01)
    >>> try:
    ...     check_series(np.full(20, 0.5), 0.01, source="still.csv", field="gyro_z")
    ... except ValueError as exc:
    ...     print(exc)
    still.csv: gyro_z: the series is constant (every sample 0.5): a constant series has no
    noise to characterise
    """
    array = numeric_array(values, source, field)
    if array.ndim != 1:
        raise DataError(f"a series is 1-D, got shape {array.shape}", source=source, field=field)
    check_finite(array, source, field, lambda i: f"sample {i}")
    check_length(len(array), minimum=minimum, source=source, field=field)
    if np.ptp(array) == 0:
        raise DataError(
            f"the series is constant (every sample {array[0]:g}): a constant series has no noise "
            "to characterise",
            source=source,
            field=field,
        )
    # Its spread, computed without squaring the values (which overflow at 1e155).
    largest = float(np.max(np.abs(array)))
    spread = largest * float(np.std(array / largest))
    if not SERIES_SPREAD[0] <= spread <= SERIES_SPREAD[1]:
        raise DataError(
            f"the series' sd is {spread:.3g}, outside {SERIES_SPREAD[0]:g} to "
            f"{SERIES_SPREAD[1]:g}: its variances and covariances would leave double "
            "precision; rescale it (e.g. to SI units)",
            source=source,
            field=field,
        )
    array.setflags(write=False)
    return array, positive_number(dt, name="dt", unit="s", required=True)
