"""Time-domain Toeplitz densities (bayes_jackal.likelihood.toeplitz) against dense references.

The banded Cholesky is checked against the dense Gaussian density
(numpy's Cholesky of the Toeplitz matrix built here), on the families'
residual autocovariances at conditioning like the ``fast`` engine's
fallback cases (a floor 10x to 100x below the coloured sd: condition
numbers 1e3 to 1e5). Rounding grows with the condition number and n:
measured at most 2e-10 nats on these 600-sample cases (the full recursion
1.4e-9), so 1e-7 nats here; the fallback's agreement with the ``exact``
engine is the engines' 1e-6 bar (test_spectral.py).
"""

import numpy as np
import pytest
import scipy.linalg

from bayes_jackal import load_profile
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.likelihood.measurements import residual_autocovariance
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.likelihood.series_likelihood import SeriesLikelihood
from bayes_jackal.likelihood.spectral import evaluate_on_grids, spectral_forms
from bayes_jackal.likelihood.toeplitz import (
    FALLBACK_BAND,
    banded_toeplitz_loglike,
    fallback_loglike,
    toeplitz_loglike,
)
from bayes_jackal.model.kernels import FAMILIES, bandwidth, get_family

DT = 1.0 / 72.0
#: Banded == dense Cholesky [nats] (module docstring).
DENSE_AGREEMENT = 1e-7
#: The engines' agreement bar [nats] (test_spectral.py).
AGREEMENT = 1e-6
FINITE = [name for name in FAMILIES if name != "exponential"]


def _dense_forms(acov: np.ndarray, x: np.ndarray) -> tuple[float, np.ndarray]:
    """log det T and x' T^-1 x of each row of x (E, n), T = toeplitz(acov), by numpy's Cholesky."""
    factor = np.linalg.cholesky(scipy.linalg.toeplitz(acov))
    z = scipy.linalg.solve_triangular(factor, x.T, lower=True)
    return 2.0 * np.sum(np.log(np.diag(factor))), np.sum(z**2, axis=0)


def _dense_loglike(acov: np.ndarray, x: np.ndarray) -> np.ndarray:
    """log N(x; 0, toeplitz(acov)) of each row of x (E, n)."""
    log_det, quadratic = _dense_forms(acov, x)
    return -0.5 * (quadratic + log_det + x.shape[-1] * np.log(2.0 * np.pi))


@pytest.mark.parametrize("family", FINITE)
@pytest.mark.parametrize("floor", [0.1, 0.01])
def test_banded_cholesky_equals_the_dense_density(family, floor):
    # Widths 0.15 s and 0.25 s (11 and 18 samples at 72 Hz) with the ma1
    # footprint of sensor noise (alpha = 0.9) at a floor below unit sd;
    # series drawn from the covariance (x = L e), so x' T^-1 x ~ n.
    n, widths = 600, np.array([0.15, 0.25])
    one = np.ones(2)
    acov = residual_autocovariance(get_family(family), widths, one, floor * one, 0.9 * one, DT, n)
    white = np.random.default_rng(1).standard_normal((2, n, 3))
    factors = np.linalg.cholesky([scipy.linalg.toeplitz(row) for row in acov])
    x = np.swapaxes(factors @ white, 1, 2)
    width = bandwidth(acov).max()
    assert width < n // 4  # a band, not the whole series
    values = banded_toeplitz_loglike(acov[:, :width], x)
    dense = np.array([_dense_loglike(acov[b], x[b]) for b in range(2)])
    np.testing.assert_allclose(values, dense, rtol=0, atol=DENSE_AGREEMENT)


def test_a_band_longer_than_the_series_uses_its_first_lags():
    # A 40-lag band on 25 samples is the dense 25 x 25 Toeplitz matrix.
    acov = FAMILIES["triangular"].autocorrelation(np.array([0.3]), DT, 40)
    acov[:, 0] += 0.01
    x = np.random.default_rng(2).standard_normal((1, 2, 25))
    np.testing.assert_allclose(
        banded_toeplitz_loglike(acov, x)[0],
        _dense_loglike(acov[0, :25], x[0]),
        rtol=0,
        atol=DENSE_AGREEMENT,
    )


def test_a_covariance_that_is_not_positive_definite_is_minus_infinity():
    # [1, 0.9, 0.9]: the 3 x 3 Toeplitz matrix has a negative eigenvalue.
    acov = np.array([[1.0, 0.9, 0.9], [1.0, 0.5, 0.0]])
    assert np.linalg.eigvalsh(scipy.linalg.toeplitz([1.0, 0.9, 0.9, 0.0, 0.0])).min() < 0
    x = np.random.default_rng(3).standard_normal((2, 1, 5))
    values = banded_toeplitz_loglike(acov, x)
    assert np.isneginf(values[0, 0])
    np.testing.assert_allclose(values[1], _dense_loglike(np.r_[acov[1], 0, 0], x[1]), atol=1e-12)
    # A NaN autocovariance passes dpbtrf (info 0): -inf too, as the recursion gives.
    assert np.isneginf(banded_toeplitz_loglike(np.array([[1.0, np.nan]]), x[:1])).all()


def test_bandwidth_is_the_last_nonzero_lag_plus_one():
    acov = np.zeros((2, 10))
    acov[:, 0] = 1.0
    assert bandwidth(acov).tolist() == [1, 1]
    acov[1, 6] = 1e-300
    assert bandwidth(acov).tolist() == [1, 7]


@pytest.mark.parametrize("family", ["moving-average", "exponential"])
def test_the_fallback_equals_the_full_recursion(family):
    # The moving-average's band (p + 1 <= 4 sqrt(n) lags) takes the banded
    # Cholesky, the exponential's unending autocovariance the stopped recursion.
    n = 800
    acov = FAMILIES[family].autocorrelation(np.array([0.2, 0.5]), DT, n)
    acov[:, 0] += 1e-4
    x = np.random.default_rng(4).standard_normal((2, 2, n))
    assert np.all(bandwidth(acov) ** 2 <= FALLBACK_BAND**2 * n) == (family == "moving-average")
    np.testing.assert_allclose(
        fallback_loglike(acov, x), toeplitz_loglike(acov, x), rtol=0, atol=DENSE_AGREEMENT
    )


def _moving_average_run(n: int, seed: int) -> Experiment:
    """n + 1 samples of yaw rate: 0.15 s moving-average noise over a 10x smaller floor."""
    rng = np.random.default_rng(seed)
    t = np.arange(n + 1) * DT
    yaw = 0.3 + FAMILIES["moving-average"].noise(0.15, DT, n + 1, 0.01, rng)
    omega = 4.0 + 0.01 * rng.standard_normal(n + 1)
    return Experiment(t, yaw + 0.001 * rng.standard_normal(n + 1), omega, omega - 1.0)


def test_the_residual_likelihood_fallback_is_exact():
    # A 0.15 s boxcar over a floor 10x below it: spectral nulls that no
    # grid certifies within 2,000 residuals (the family test's slow case,
    # tests/test_evidence.py), so the fast engine takes the banded fallback.
    run = _moving_average_run(2_000, 1)
    options = {"family": "moving-average", "channels": ("yaw",), "steady": False}
    fast = ResidualLikelihood([run], load_profile(), **options)
    exact = ResidualLikelihood([run], load_profile(), engine="exact", **options)
    theta = np.array([[110.0, 30.0, 0.15, 0.01, 0.001], [110.0, 30.0, 0.3, 0.01, 0.0005]])
    np.testing.assert_allclose(fast(theta), exact(theta), rtol=0, atol=AGREEMENT)
    # The MAP search's scan takes the cheap bands too (n (p + 1)^2 <= 1e8:
    # p + 1 <= 223 lags at n = 2,000; these have 11 and 22), and nothing
    # longer (a 4 s boxcar: 289 lags).
    scan = ResidualLikelihood([run], load_profile(), fallback=False, **options)
    np.testing.assert_array_equal(scan(theta), fast(theta))
    assert np.isneginf(scan(np.array([[110.0, 30.0, 4.0, 0.01, 0.001]])))


def test_the_series_likelihood_fallback_is_exact():
    # The bare series of the same noise, its mean integrated out (the
    # closed form of series_likelihood.py from dense forms): no grid
    # certifies either set, and the banded fallback is within 1e-8 nats of
    # the dense density. (The full recursion, the ``exact`` engine, is off by
    # 3e-8 nats on y'T^-1 y ~ 1e4 of the wider set: both are rounding, the
    # recursion's larger; the engines' 1e-6 bar holds.)
    rng = np.random.default_rng(5)
    n = 1_000
    values = FAMILIES["moving-average"].noise(0.15, DT, n, 1.0, rng) + 0.01 * rng.standard_normal(
        n
    )
    fast = SeriesLikelihood(values=values, dt=DT, family="moving-average")
    exact = SeriesLikelihood(values=values, dt=DT, family="moving-average", engine="exact")
    theta = np.array([[0.15, 1.0, 0.01], [0.3, 1.0, 0.005]])
    acov = fast.autocovariance(theta, n)
    pending = evaluate_on_grids(
        fast.block,
        lambda rows, lags: acov[rows, :lags],
        np.broadcast_to(np.eye(4)[:3], (2, 3, 4)),
        spectral_forms,
        np.zeros((2, 4)),
    )
    assert pending.tolist() == [0, 1]
    y = values - values.mean()
    dense = []
    for row in acov:
        log_det, (yy, ones, both) = _dense_forms(row, np.stack([y, np.ones(n), y + 1.0]))
        cross = 0.5 * (both - yy - ones)
        quadratic = yy - cross**2 / ones
        dense.append(-0.5 * (quadratic + log_det + np.log(ones) + (n - 1) * np.log(2.0 * np.pi)))
    # Measured 1.5e-10 nats on quadratic forms ~1e4 (the dense marginal's
    # cancellation yy - cross^2 / ones); 1e-8 leaves room for another BLAS.
    np.testing.assert_allclose(fast(theta), dense, rtol=0, atol=1e-8)
    np.testing.assert_allclose(fast(theta), exact(theta), rtol=0, atol=AGREEMENT)
