"""Residual likelihood: covariance model, exact and Whittle engines, pooling, bad input."""

import numpy as np
import pytest
import scipy.linalg
import scipy.stats

from bayes_jackal import DataError, InputError, load_profile
from bayes_jackal.experiment import Experiment
from bayes_jackal.kernels import FAMILIES
from bayes_jackal.likelihood import (
    ResidualLikelihood,
    debiased_whittle_loglike,
    residual_autocovariance,
    sample_stationary,
    toeplitz_loglike,
)
from bayes_jackal.simulate import simulate_experiment, simulate_series

ROBOT = load_profile()
DT = 1.0 / 72.0
TRUTH = np.array([[110.0, 30.0, 0.047, 0.01, 0.005]])


@pytest.fixture(scope="module")
def experiments():
    return simulate_series(ROBOT, 110.0, 30.0, {"v1": 2, "v2": 1}, rng=4)


@pytest.mark.parametrize("family", list(FAMILIES))
def test_exact_engine_matches_a_dense_gaussian_density(family):
    rng = np.random.default_rng(0)
    n = 250
    widths = np.array([0.02, 0.047, 0.3])
    acov = residual_autocovariance(
        FAMILIES[family],
        widths,
        sigma_c=np.array([0.01, 0.02, 0.005]),
        sigma_n=np.array([0.005, 0.001, 0.01]),
        alpha=np.array([0.7, 0.95, 0.2]),
        dt=DT,
        n=n,
    )
    x = rng.normal(scale=0.02, size=(3, 2, n))
    fast = toeplitz_loglike(acov, x)
    for b in range(3):
        dense = scipy.stats.multivariate_normal(np.zeros(n), scipy.linalg.toeplitz(acov[b]))
        # Both are exact; Levinson and Cholesky round differently by ~cond * eps.
        np.testing.assert_allclose(fast[b], dense.logpdf(x[b]), rtol=1e-9)


def test_whittle_approximates_the_exact_likelihood_of_an_ma1():
    # For a short-memory process the debiased Whittle likelihood differs from
    # the exact one by O(1) nats, not O(n): here 4000 samples, |l| > 1000.
    rng = np.random.default_rng(1)
    n = 4000
    acov = np.zeros((1, n))
    acov[0, :2] = [1.25, -0.5]  # x = e[k] - 0.5 e[k-1]
    e = rng.standard_normal(n + 1)
    x = e[1:] - 0.5 * e[:-1]
    exact = toeplitz_loglike(acov, x[None, None, :])[0, 0]
    periodogram = np.abs(np.fft.rfft(x)) ** 2 / n
    whittle = debiased_whittle_loglike(acov, periodogram[None, :])[0]
    assert abs(exact - whittle) < 2.0
    assert abs(exact) > 1000


def test_residual_autocovariance_is_the_process_plus_sensor_footprint():
    # r[k] = w[k] + n[k+1] - alpha n[k]: simulate it and compare the sample
    # autocovariance with the model at lags 0..3, within 5 standard errors
    # (Bartlett: var(c_k) <= 2 sum_j c_j^2 / N for a Gaussian process).
    rng = np.random.default_rng(2)
    family = FAMILIES["gaussian"]
    alpha, sigma_c, sigma_n, width = 0.72, 0.01, 0.006, 0.047
    n = 400_000
    w = family.noise(width, DT, n, sigma_c, rng)
    sensor = sigma_n * rng.standard_normal(n + 1)
    r = w + sensor[1:] - alpha * sensor[:-1]
    model = residual_autocovariance(
        family,
        np.array([width]),
        np.array([sigma_c]),
        np.array([sigma_n]),
        np.array([alpha]),
        DT,
        60,
    )[0]
    sample = np.array([r[: n - k] @ r[k:] / n for k in range(4)])
    standard_error = np.sqrt(2 * (model[0] ** 2 + 2 * np.sum(model[1:] ** 2)) / n)
    np.testing.assert_allclose(sample, model[:4], atol=5 * standard_error)
    assert model[1] < sigma_c**2 * family.autocorrelation(width, DT, 2)[1]  # -alpha sigma_n^2
    diagonal = residual_autocovariance(
        family, *(np.array([v]) for v in (width, sigma_c, sigma_n, alpha)), DT, 4, "diagonal"
    )[0]
    assert diagonal[0] == pytest.approx(sigma_c**2 + sigma_n**2)
    assert diagonal[1] == pytest.approx(sigma_c**2 * family.autocorrelation(width, DT, 2)[1])


@pytest.mark.parametrize("engine", ["whittle", "exact"])
def test_pooled_shared_noise_is_the_sum_over_experiments(experiments, engine):
    points = np.vstack([TRUTH, [[300.0, 80.0, 0.03, 0.02, 0.004]]])
    pooled = ResidualLikelihood(experiments, ROBOT, engine=engine)(points)
    separate = sum(ResidualLikelihood([e], ROBOT, engine=engine)(points) for e in experiments)
    np.testing.assert_allclose(pooled, separate, rtol=1e-12)


def test_engines_agree_at_the_truth_up_to_a_near_constant(experiments):
    # Whittle approximates the exact likelihood; what matters for the
    # posterior is that the difference barely changes between nearby points.
    rng = np.random.default_rng(3)
    points = TRUTH * np.exp(0.05 * rng.standard_normal((16, 5)))
    single = [experiments[0]]
    exact = ResidualLikelihood(single, ROBOT, engine="exact")(points)
    whittle = ResidualLikelihood(single, ROBOT, engine="whittle")(points)
    spread = exact - whittle
    assert np.ptp(exact) > 50  # the points differ a lot in likelihood ...
    assert np.std(spread) < 0.5  # ... and the engines by a near-constant


def test_parameter_layout_for_channels_and_per_experiment_noise(experiments):
    pooled = ResidualLikelihood(experiments[:2], ROBOT, channels=("yaw", "vx"))
    assert pooled.parameter_names == [
        "d_lat",
        "d_long",
        "sigma_h[yaw]",
        "sigma_c[yaw]",
        "sigma_n[yaw]",
        "sigma_h[vx]",
        "sigma_c[vx]",
        "sigma_n[vx]",
    ]
    separate = ResidualLikelihood(experiments[:2], ROBOT, family="white", shared_noise=False)
    assert separate.parameter_names == [
        "d_lat",
        "d_long",
        "sigma_c[v1_01]",
        "sigma_n[v1_01]",
        "sigma_c[v1_02]",
        "sigma_n[v1_02]",
    ]
    # Per-experiment noise equals the sum of single-experiment likelihoods
    # with each experiment's own noise values.
    theta = np.array([[110.0, 30.0, 0.01, 0.005, 0.02, 0.004]])
    first = ResidualLikelihood([experiments[0]], ROBOT, family="white")(theta[:, [0, 1, 2, 3]])
    second = ResidualLikelihood([experiments[1]], ROBOT, family="white")(theta[:, [0, 1, 4, 5]])
    np.testing.assert_allclose(separate(theta), first + second, rtol=1e-12)


def test_truth_beats_the_prior_edge_of_the_ridge_with_the_ma1_sensor_model(experiments):
    # DESIGN §4: with a diagonal nugget the ridge runs to the prior edge; the
    # MA(1) footprint of the sensor noise keeps the truth ahead.
    edge = np.array([[1000.0, 1000.0 / 3.667, 0.047, 0.01, 0.005]])
    likelihood = ResidualLikelihood([experiments[0]], ROBOT)
    assert likelihood(TRUTH)[0] > likelihood(edge)[0]


def test_bad_input_is_rejected(experiments, tmp_path):
    with pytest.raises(InputError, match="family"):
        ResidualLikelihood(experiments, ROBOT, family="pink")
    with pytest.raises(InputError, match="engine"):
        ResidualLikelihood(experiments, ROBOT, engine="mcmc")
    with pytest.raises(InputError, match="sensor"):
        ResidualLikelihood(experiments, ROBOT, sensor="laplace")
    with pytest.raises(InputError, match="channels must be distinct"):
        ResidualLikelihood(experiments, ROBOT, channels=("yaw", "yaw"))
    with pytest.raises(InputError, match="no experiments"):
        ResidualLikelihood([], ROBOT)
    short = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=1)
    t = short.t[:20]
    tiny = Experiment(
        t, short.yaw_rate[:20], short.omega_r[:20], short.omega_l[:20], source="x.csv"
    )
    with pytest.raises(
        DataError, match=r"x\.csv: yaw: the experiment holds 20 samples, 19 one-step residuals"
    ):
        ResidualLikelihood([tiny], ROBOT, steady=False)
    flat = Experiment(
        short.t, np.full_like(short.t, 0.3), short.omega_r, short.omega_l, source="flat.csv"
    )
    with pytest.raises(DataError, match=r"flat\.csv: yaw_rate: channel 'yaw' is constant"):
        ResidualLikelihood([flat], ROBOT, steady=False)
    with pytest.raises(DataError, match="'vx' is not in this experiment"):
        ResidualLikelihood([flat], ROBOT, channels=("vx",), steady=False)


def test_stationary_draws_have_the_autocovariance_of_a_dense_cholesky():
    # Gaussian-coloured residual plus MA(1) sensor noise, 40 lags.
    family = FAMILIES["gaussian"]
    one = np.ones(1)
    acov = residual_autocovariance(family, 0.05 * one, 0.01 * one, 0.005 * one, 0.7 * one, DT, 40)
    draws = sample_stationary(np.repeat(acov, 20_000, axis=0), rng=4)
    # The reference: the dense Toeplitz covariance. Each sample covariance
    # of 20,000 draws has sd <= sqrt(2 / 20000) acov[0] = 0.01 acov[0]: 5 sd.
    dense = scipy.linalg.toeplitz(acov[0])
    np.testing.assert_allclose(np.cov(draws.T), dense, atol=0.05 * acov[0, 0])
    # The grand mean has variance sum(dense) / 40^2 / 20000.
    assert abs(draws.mean()) < 5 * np.sqrt(dense.sum() / 40**2 / 20_000)
