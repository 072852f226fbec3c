"""The likelihood of a bare noise series (bayes_jackal.likelihood.series_likelihood).

The ``exact`` engine is checked against a dense Gaussian density written
here, with the mean integrated numerically; the ``fast`` engine against
``exact``. The fast engine's tolerances (cepstrum 1e-10, autocovariance
1e-13 of the variance, spectral.py) give 2e-10 to 2e-8 nats on 1e3 to 1e5
residuals (likelihood.py); the three quadratic forms of a series add a
cancellation of order 1e-16 n per form, so 1e-8 nats on 600 samples.
"""

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.stats

from bayes_jackal._runtime.errors import DataError, InputError
from bayes_jackal.likelihood.measurements import residual_autocovariance
from bayes_jackal.likelihood.series_likelihood import (
    MIN_LIKELIHOOD_SAMPLES,
    SeriesLikelihood,
)
from bayes_jackal.likelihood.spectral import evaluate_on_grids, spectral_forms
from bayes_jackal.model.kernels import FAMILIES, get_family

DT = 0.01
#: fast == exact [nats] (module docstring).
AGREEMENT = 1e-8
#: Widths of the issue's range, in samples.
WIDTHS = (0.6, 2.0, 5.0, 20.0)
#: (sigma_c, sigma_n): coloured part dominant, equal, floor dominant.
SDS = ((1.0, 0.1), (1.0, 1.0), (0.2, 1.0))


def _series(family: str, n: int, seed: int, *, width: float = 5.0, mean: float = 3.0):
    """``mean`` + unit-sd noise of ``family`` (width in samples) + a 0.3 floor."""
    rng = np.random.default_rng(seed)
    coloured = get_family(family).noise(width * DT, DT, n, rng=rng)
    return mean + coloured + 0.3 * rng.standard_normal(n)


def _theta(family: str) -> np.ndarray:
    """Every width x sds of the module's ranges; white: the total sds."""
    if family == "white":
        return np.array([[np.hypot(*sds)] for sds in SDS])
    return np.array([[w * DT, *sds] for w in WIDTHS for sds in SDS])


@pytest.mark.parametrize("family", list(FAMILIES))
def test_fast_engine_equals_the_exact_recursion(family):
    values = _series(family, 600, 1)
    fast = SeriesLikelihood(values=values, dt=DT, family=family)
    exact = SeriesLikelihood(values=values, dt=DT, family=family, engine="exact")
    theta = _theta(family)
    np.testing.assert_allclose(fast(theta), exact(theta), rtol=0, atol=AGREEMENT)
    np.testing.assert_allclose(fast.gls_mean(theta), exact.gls_mean(theta), rtol=0, atol=1e-9)


def test_long_memory_falls_back_to_the_time_domain():
    # An exponential kernel of 400 samples on 600: its cepstrum has not
    # decayed within the series, so no grid certifies it (the exponential
    # family's tridiagonal form answers); one of 2 samples is certified on
    # the first grid. Both equal the full recursion.
    values = _series("exponential", 600, 2)
    fast = SeriesLikelihood(values=values, dt=DT, family="exponential")
    exact = SeriesLikelihood(values=values, dt=DT, family="exponential", engine="exact")
    theta = np.array([[400 * DT, 1.0, 0.3], [2 * DT, 1.0, 0.3]])
    np.testing.assert_allclose(fast(theta), exact(theta), rtol=0, atol=AGREEMENT)

    def autocovariance(rows, lags):
        family = get_family("exponential")
        return residual_autocovariance(family, *theta[rows].T, np.zeros(len(rows)), DT, lags)

    coefficients = np.broadcast_to(np.eye(4)[:3], (2, 3, 4))
    out = np.zeros((2, 4))
    pending = evaluate_on_grids(fast.block, autocovariance, coefficients, spectral_forms, out)
    assert pending.tolist() == [0]


def _dense_marginal(values, acov):
    """log of the integral over mu of N(y; mu 1, toeplitz(acov)), by quadrature.

    The integrand is scaled by its value at the weighted least-squares mean
    (whitened by the Cholesky factor, np.linalg.lstsq) and integrated over
    +-12 of its sds, where the Gaussian in mu is below e^-72.
    """
    cov = scipy.linalg.toeplitz(acov)
    density = scipy.stats.multivariate_normal(cov=cov)
    factor = np.linalg.cholesky(cov)
    ones = np.ones(len(values))
    whitened = [scipy.linalg.solve_triangular(factor, v, lower=True) for v in (ones, values)]
    mean = np.linalg.lstsq(whitened[0][:, None], whitened[1], rcond=None)[0][0]
    sd = 1.0 / np.linalg.norm(whitened[0])
    peak = density.logpdf(values - mean)
    integral, _ = scipy.integrate.quad(
        lambda mu: np.exp(density.logpdf(values - mu) - peak),
        mean - 12 * sd,
        mean + 12 * sd,
        epsabs=0.0,
        epsrel=1e-13,
        limit=200,
    )
    return peak + np.log(integral), mean


def _autocorrelation(family: str, width: float, n: int) -> np.ndarray:
    """rho[0..n-1]: the AR(1)'s phi^l for the exponential family (kernels.py),
    else the taps' direct self-correlation."""
    if family == "exponential":
        return np.exp(-DT / width) ** np.arange(n)
    taps = get_family(family).taps(width, DT)
    return np.r_[np.correlate(taps, taps, "full")[len(taps) - 1 :], np.zeros(n)][:n]


@pytest.mark.parametrize("family", ["white", "gaussian", "exponential", "moving-average"])
def test_exact_engine_equals_a_dense_density_with_the_mean_integrated(family):
    n = 60
    values = _series(family, n, 3, width=3.0)
    likelihood = SeriesLikelihood(values=values, dt=DT, family=family, engine="exact")
    theta = _theta(family)[:3]
    for row in theta:
        if family == "white":
            acov = np.r_[row[0] ** 2, np.zeros(n - 1)]
        else:
            acov = row[1] ** 2 * _autocorrelation(family, row[0], n)
            acov[0] += row[2] ** 2
        marginal, mean = _dense_marginal(values, acov)
        assert likelihood(row[None])[0] == pytest.approx(marginal, abs=1e-9)
        assert likelihood.gls_mean(row[None])[0] == pytest.approx(mean, abs=1e-10)


@pytest.mark.parametrize("engine", ["fast", "exact"])
def test_the_marginal_likelihood_does_not_depend_on_a_constant(engine):
    # Adding 1e3 (3,000 series sds) moves the centring by rounding only
    # (1e-13 per sample); the GLS mean moves by the constant.
    values = _series("gaussian", 300, 4)
    theta = _theta("gaussian")
    base = SeriesLikelihood(values=values, dt=DT, engine=engine)
    shifted = SeriesLikelihood(values=values + 1e3, dt=DT, engine=engine)
    np.testing.assert_allclose(shifted(theta), base(theta), rtol=0, atol=1e-9)
    np.testing.assert_allclose(shifted.gls_mean(theta) - 1e3, base.gls_mean(theta), atol=1e-9)


def test_gls_mean_of_white_noise_is_the_sample_mean():
    # T = sigma^2 I: (1'y) / n whatever sigma.
    values = _series("white", 500, 5)
    likelihood = SeriesLikelihood(values=values, dt=DT, family="white")
    np.testing.assert_allclose(likelihood.gls_mean([[0.5], [2.0]]), values.mean(), rtol=1e-12)


def test_gls_mean_recovers_a_known_mean():
    # 40 Gaussian-coloured series about 3.0 (width 5 samples, floor 0.3): the
    # GLS mean at the true parameters is unbiased with sd (1'T^-1 1)^-1/2;
    # the standardised errors have mean 0 and sd 1 (4-sigma bounds of their
    # sampling spread over 40 series: 4 / sqrt(40), and chi-square).
    theta = np.array([[5 * DT, 1.0, 0.3]])
    acov = residual_autocovariance(get_family("gaussian"), *theta.T, np.zeros(1), DT, 400)
    precision = np.sum(np.linalg.inv(scipy.linalg.toeplitz(acov[0])))  # 1'T^-1 1
    z = []
    for seed in range(40):
        likelihood = SeriesLikelihood(values=_series("gaussian", 400, 100 + seed), dt=DT)
        z.append((likelihood.gls_mean(theta)[0] - 3.0) * np.sqrt(precision))
    assert abs(np.mean(z)) < 4 / np.sqrt(40)
    assert (
        scipy.stats.chi2(40).ppf(1e-4) < np.sum(np.square(z)) < scipy.stats.chi2(40).ppf(1 - 1e-4)
    )


def test_white_equals_a_coloured_family_without_its_coloured_part():
    # sigma_c = 0: sigma_n^2 I whatever the width, the white family's covariance.
    values = _series("white", 200, 6)
    white = SeriesLikelihood(values=values, dt=DT, family="white")
    gaussian = SeriesLikelihood(values=values, dt=DT, family="gaussian")
    sds = np.array([0.5, 1.0, 2.0])
    coloured = np.column_stack([np.full(3, 0.05), np.zeros(3), sds])
    np.testing.assert_allclose(white(sds[:, None]), gaussian(coloured), rtol=0, atol=1e-9)


def test_names_follow_the_family():
    values = _series("white", 100, 7)
    names = {f: SeriesLikelihood(values=values, dt=DT, family=f).names for f in FAMILIES}
    assert names["white"] == ("sigma",)
    assert names["gaussian"] == ("sigma_h", "sigma_c", "sigma_n")
    assert names["exponential"] == ("width", "sigma_c", "sigma_n")


def _bad(values=None, **options):
    options = {"dt": DT, "family": "gaussian", **options}
    values = _series("white", 100, 8) if values is None else values
    return SeriesLikelihood(values=values, **options)


@pytest.mark.parametrize(
    ("options", "error", "field", "shown"),
    [
        (
            {"values": np.r_[np.ones(50), np.nan, np.zeros(9)]},
            DataError,
            "values",
            "nan at sample 50",
        ),
        ({"values": np.full(100, 2.5)}, DataError, "values", "constant series"),
        (
            {"values": np.arange(MIN_LIKELIHOOD_SAMPLES - 1.0)},
            DataError,
            "values",
            f"only {MIN_LIKELIHOOD_SAMPLES - 1}",
        ),
        ({"values": np.ones((10, 10))}, DataError, "values", "(10, 10)"),
        ({"dt": 0.0}, InputError, "dt", "got 0.0"),
        ({"dt": float("nan")}, InputError, "dt", "got nan"),
        ({"family": "pink"}, InputError, "family", "'pink'"),
        ({"engine": "whittle"}, InputError, "engine", "'whittle'"),
    ],
)
def test_bad_input_names_the_field(options, error, field, shown):
    with pytest.raises(error) as caught:
        _bad(**options)
    assert caught.value.field == field
    assert shown in str(caught.value)


def test_parameter_vectors_of_the_wrong_length_are_refused():
    with pytest.raises(InputError, match=r"shape \(B, 3\).*got \(1, 2\)") as caught:
        _bad()(np.array([[0.05, 1.0]]))
    assert caught.value.field == "theta"


@pytest.mark.parametrize("n", [600, 3000])
def test_the_exponential_tridiagonal_form_equals_the_recursion(n):
    # The fast engine's time-domain path for the exponential family (T^-1 x
    # = N^-1 K x, log det T = log det N - log a; series_likelihood's module
    # docstring) against the exact engine's full Durbin-Levinson recursion,
    # time constants from 0.3 samples to n (phi -> 1; the prior's widest is
    # n / 10), sds from the coloured part dominant 1000:1 to the floor
    # dominant 1000:1. log det T and the three quadratic forms within 1e-9
    # relative or 1e-8 absolute (log det T ~ 6e-4 where sigma_c = 1e-3;
    # measured at most 4e-10 relative); the log-likelihood within AGREEMENT
    # or 1e-10 relative: where the floor is 1e-3 it is -4.6e6 nats at tau =
    # n, and both methods are off a dense Cholesky factor's by ~1e-11 of it
    # (measured: 8e-6 and 2e-5 nats on 3,000 samples).
    values = _series("white", n, 9)
    fast = SeriesLikelihood(values=values, dt=DT, family="exponential")
    exact = SeriesLikelihood(values=values, dt=DT, family="exponential", engine="exact")
    widths = np.array([0.3, 2.0, 30.0, n / 10, n]) * DT
    sds = [(1.0, 0.1), (1.0, 1.0), (1e-3, 1.0), (0.01, 1.0), (1.0, 1e-3)]
    theta = np.array([[w, *pair] for w in widths for pair in sds])
    noise = fast._noise(theta)
    np.testing.assert_allclose(
        fast._tridiagonal_forms(noise), exact._recursion(noise), rtol=1e-9, atol=1e-8
    )
    np.testing.assert_allclose(fast(theta), exact(theta), rtol=1e-10, atol=AGREEMENT)
