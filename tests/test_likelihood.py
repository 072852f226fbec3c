"""Residual likelihood: covariance model, exact and Whittle engines, pooling, bad input."""

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize
import scipy.special
import scipy.stats

from bayes_jackal import DataError, InputError, load_profile
from bayes_jackal.inference.sampling import sample_posterior
from bayes_jackal.inference.starts import _binned_periodogram
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.io.simulate import NoiseSettings, simulate_experiment, simulate_series
from bayes_jackal.likelihood import LikelihoodOptions
from bayes_jackal.likelihood.measurements import residual_autocovariance
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood, sample_stationary
from bayes_jackal.likelihood.residuals import channel_residuals
from bayes_jackal.likelihood.toeplitz import toeplitz_loglike
from bayes_jackal.likelihood.whittle import (
    debiased_whittle_loglike,
    expected_periodogram,
    frequency_weights,
)
from bayes_jackal.model.kernels import FAMILIES
from bayes_jackal.model.physics import channel_coefficients
from bayes_jackal.posterior.summary import summarize

ROBOT = load_profile()
DT = 1.0 / 72.0
TRUTH = np.array([[110.0, 30.0, 0.047, 0.01, 0.005]])
#: The yaw channel alone: the layout of TRUTH (the default is every channel).
YAW = ("yaw",)


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
    pooled = ResidualLikelihood(experiments, ROBOT, channels=YAW, engine=engine)(points)
    separate = sum(
        ResidualLikelihood([e], ROBOT, channels=YAW, engine=engine)(points) for e in experiments
    )
    np.testing.assert_allclose(pooled, separate, rtol=1e-12)


@pytest.mark.parametrize("engine", ["fast", "exact"])
def test_one_width_is_the_per_channel_likelihood_at_equal_widths(experiments, engine):
    # The reference: the per-channel layout's vector built by hand, with
    # sigma_h[yaw] = sigma_h[vx] = the one width.
    channels = ("yaw", "vx")
    one = ResidualLikelihood(
        experiments[:1], ROBOT, channels=channels, engine=engine, shared_width=True
    )
    per_channel = ResidualLikelihood(experiments[:1], ROBOT, channels=channels, engine=engine)
    assert one.parameter_names == [
        "d_lat",
        "d_long",
        "sigma_h",
        "sigma_c[yaw]",
        "sigma_n[yaw]",
        "sigma_c[vx]",
        "sigma_n[vx]",
    ]
    theta = np.array(
        [
            [110.0, 30.0, 0.047, 0.01, 0.005, 0.006, 0.003],
            [300.0, 80.0, 0.1, 0.02, 0.004, 0.004, 0.002],
        ]
    )
    d_lat, d_long, width, c_yaw, n_yaw, c_vx, n_vx = theta.T
    by_hand = np.column_stack([d_lat, d_long, width, c_yaw, n_yaw, width, c_vx, n_vx])
    values = one(theta)
    assert np.all(np.isfinite(values))
    np.testing.assert_allclose(values, per_channel(by_hand), rtol=0, atol=1e-10)


def test_engines_agree_at_the_truth_up_to_a_near_constant(experiments):
    # Whittle approximates the exact likelihood; what matters for the
    # posterior is that the difference barely changes between nearby points.
    rng = np.random.default_rng(3)
    points = TRUTH * np.exp(0.05 * rng.standard_normal((16, 5)))
    single = [experiments[0]]
    exact = ResidualLikelihood(single, ROBOT, channels=YAW, engine="exact")(points)
    whittle = ResidualLikelihood(single, ROBOT, channels=YAW, engine="whittle")(points)
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
    separate = ResidualLikelihood(
        experiments[:2], ROBOT, family="white", channels=YAW, shared_noise=False
    )
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
    first = ResidualLikelihood([experiments[0]], ROBOT, family="white", channels=YAW)
    second = ResidualLikelihood([experiments[1]], ROBOT, family="white", channels=YAW)
    first, second = first(theta[:, [0, 1, 2, 3]]), second(theta[:, [0, 1, 4, 5]])
    np.testing.assert_allclose(separate(theta), first + second, rtol=1e-12)


def test_truth_beats_the_prior_edge_of_the_ridge_with_the_ma1_sensor_model(experiments):
    # docs/design.md §4: with a diagonal nugget the ridge runs to the prior edge; the
    # MA(1) footprint of the sensor noise keeps the truth ahead.
    edge = np.array([[1000.0, 1000.0 / 3.667, 0.047, 0.01, 0.005]])
    likelihood = ResidualLikelihood([experiments[0]], ROBOT, channels=YAW)
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
    with pytest.raises(DataError, match=r"flat\.csv: channels: .*\['vx'\] not measured"):
        ResidualLikelihood([flat], ROBOT, channels=("vx",), steady=False)
    with pytest.raises(InputError, match="channels must be distinct names among"):
        ResidualLikelihood(experiments, ROBOT, channels=("yaw", "roll"))


def test_default_channels_are_those_every_experiment_measures(experiments):
    assert ResidualLikelihood(experiments, ROBOT).channels == ("yaw", "vx", "vy")
    # An experiment without vx, vy (a yaw-rate-only log) narrows the default.
    first = experiments[0]
    yaw_only = Experiment(first.t, first.yaw_rate, first.omega_r, first.omega_l, name="imu")
    likelihood = ResidualLikelihood([first, yaw_only], ROBOT)
    assert likelihood.channels == ("yaw",)
    assert likelihood.noise_groups == [("yaw", "all")]


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


# --- the Gaussian family is continuous in sigma_h -----------------------------------------------


def _truncated_gaussian(sigma_h: float) -> np.ndarray:
    """The old kernel: eq. 7-5 cut hard at |k| <= floor(3 sigma_h / dt)."""
    k = np.arange(-int(3 * sigma_h / DT), int(3 * sigma_h / DT) + 1)
    return np.exp(-((k * DT) ** 2) / (2 * sigma_h**2))


def _edge_weighted_gaussian(sigma_h: float) -> np.ndarray:
    """eq. 7-5 with the taps |k| = K + 1 weighted by the fraction of 3 sigma_h / dt past K."""
    reach = 3 * sigma_h / DT
    k = np.arange(-int(reach) - 1, int(reach) + 2)
    weight = np.where(np.abs(k) <= int(reach), 1.0, reach - int(reach))
    return weight * np.exp(-((k * DT) ** 2) / (2 * sigma_h**2))


def _reference_loglike(experiment, kernel, widths, sigma_c, sigma_n, d_lat, d_long):
    """log N(r; 0, Sigma) of the yaw residuals, one kernel width at a time, by Levinson."""
    r = channel_residuals(experiment, ROBOT, d_lat, d_long, "yaw")
    alpha = float(channel_coefficients(ROBOT, d_lat, d_long, "yaw", DT)[0])
    acov = np.zeros((len(widths), len(r)))
    for row, sigma_h in zip(acov, widths, strict=True):
        h = kernel(sigma_h)
        rho = np.correlate(h, h, mode="full")[len(h) - 1 :] / (h @ h)
        row[: len(rho)] = sigma_c**2 * rho
    acov[:, :2] += sigma_n**2 * np.array([1 + alpha**2, -alpha])
    return toeplitz_loglike(acov, np.broadcast_to(r, (len(widths), 1, len(r))))[:, 0]


def _boundary_step_ratios(loglike: np.ndarray, points: int) -> np.ndarray:
    """Per window: the step across the tap boundary over the largest other step."""
    steps = np.abs(np.diff(loglike.reshape(-1, points), axis=1))
    middle = points // 2 - 1
    return steps[:, middle] / np.delete(steps, middle, axis=1).max(axis=1)


def test_gaussian_loglike_is_continuous_across_tap_boundaries(experiments):
    # Windows of 10 widths 1e-5 s apart around sigma_h = K dt / 3, where the
    # hard +-3 sigma_h truncation gained a tap (K = 9..12, 0.042-0.056 s,
    # around the truth 0.047). A continuous log-likelihood changes across the
    # boundary by its derivative times the step, as between the other
    # neighbours: the ratio stays near 1 (1.5 allows for the kink where a tap
    # becomes whole). The old kernel jumps by 0.06-1.4 nats there, 5-14 times
    # the smooth step on this 2,300-residual run, so the check fails for it.
    points, theta_rest = 10, (0.01, 0.005, 110.0, 30.0)
    widths = np.concatenate(
        [K * DT / 3 + 1e-5 * (np.arange(points) - (points - 1) / 2) for K in (9, 10, 11, 12)]
    )
    taps_gained = np.diff(np.floor(3 * widths / DT).reshape(4, points), axis=1)
    assert np.all(taps_gained[:, points // 2 - 1] == 1) and taps_gained.sum() == 4
    experiment = experiments[0]
    old = _reference_loglike(experiment, _truncated_gaussian, widths, *theta_rest)
    assert np.all(_boundary_step_ratios(old, points) > 4)
    # The reference with the edge-weighted kernel written here is what the
    # package computes, with both exact engines ...
    new = _reference_loglike(experiment, _edge_weighted_gaussian, widths, *theta_rest)
    theta = np.column_stack(
        [np.full_like(widths, 110.0), np.full_like(widths, 30.0), widths]
        + [np.full_like(widths, v) for v in (0.01, 0.005)]
    )
    for engine in ("fast", "exact"):
        loglike = ResidualLikelihood([experiment], ROBOT, channels=YAW, engine=engine)(theta)
        np.testing.assert_allclose(loglike, new, rtol=0, atol=1e-6)
        # ... and it is continuous.
        assert np.all(_boundary_step_ratios(loglike, points) < 1.5)


# --- no parameter the data cannot inform ---------------------------------------------------------


@pytest.mark.parametrize(
    ("family", "sensor", "noise"),
    [
        ("white", "diagonal", ["sigma_c"]),
        ("white", "ma1", ["sigma_c", "sigma_n"]),
        ("gaussian", "diagonal", ["sigma_h", "sigma_c", "sigma_n"]),
        ("exponential", "ma1", ["width", "sigma_c", "sigma_n"]),
    ],
)
def test_noise_parameters_per_family_and_sensor_model(experiments, family, sensor, noise):
    likelihood = ResidualLikelihood(
        experiments[:1], ROBOT, family=family, sensor=sensor, channels=YAW
    )
    assert likelihood.noise_parameter_names == noise
    assert likelihood.parameter_names == ["d_lat", "d_long", *noise]


@pytest.mark.parametrize("engine", ["fast", "exact"])
def test_white_noise_with_the_diagonal_term_has_one_total_sd(experiments, engine):
    # Covariance (sigma_c^2 + sigma_n^2) I: one sd, the total. The reference:
    # white Gaussian residuals of that sd, summed independently with scipy.
    likelihood = ResidualLikelihood(
        experiments[:1], ROBOT, family="white", sensor="diagonal", channels=YAW, engine=engine
    )
    theta = np.array([[110.0, 30.0, 0.011], [300.0, 80.0, 0.02], [50.0, 40.0, 0.005]])
    _, sigma_c, sigma_n = likelihood.noise_parameters(theta, 0)
    np.testing.assert_array_equal(sigma_c, theta[:, 2])
    np.testing.assert_array_equal(sigma_n, 0.0)
    residuals = [
        channel_residuals(experiments[0], ROBOT, d_lat, d_long) for d_lat, d_long, _ in theta
    ]
    expected = [
        scipy.stats.norm.logpdf(r, 0, sd).sum()
        for r, sd in zip(residuals, theta[:, 2], strict=True)
    ]
    np.testing.assert_allclose(likelihood(theta), expected, rtol=1e-10)


@pytest.mark.slow
def test_white_noise_with_the_diagonal_term_samples_its_one_sd_quickly():
    # White residuals of sd 0.02 rad/s without sensor noise: the model is
    # exact. Under the log-uniform prior (Jeffreys) with the damping
    # marginalised (locally linear, 2 coefficients), sigma^2 | data is
    # inverse-gamma((N - 2) / 2, RSS_min / 2): the closed form of sigma's
    # posterior mean and sd.
    noise = NoiseSettings(family="white", sigma_c=(0.005, 0.005, 0.02), sigma_n=(0.0, 0.0, 0.0))
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", noise, rng=7)
    likelihood = ResidualLikelihood([run], ROBOT, family="white", sensor="diagonal", channels=YAW)
    idata = sample_posterior(likelihood, seed=1)
    summary = summarize(idata)
    assert summary["converged"]
    # Two parameters for one variance made a flat ridge: tau 210 and 10,500
    # steps on this run; with one sd tau is ~12 (1,100 steps).
    assert max(summary["autocorr_time"].values()) < 30
    rss = scipy.optimize.minimize(
        lambda z: np.sum(channel_residuals(run, ROBOT, *np.exp(z)) ** 2),
        np.log([110.0, 30.0]),
        method="Nelder-Mead",
        options={"xatol": 1e-8, "fatol": 1e-14},
    ).fun
    a, b = (likelihood.n_residuals - 2) / 2, rss / 2
    mean = np.sqrt(b) * np.exp(scipy.special.gammaln(a - 0.5) - scipy.special.gammaln(a))
    sd = np.sqrt(b / (a - 1) - mean**2)
    row = summary["sigma_c"]
    # Monte Carlo error of the chain's mean and sd: sd / sqrt(ESS) and
    # sd / sqrt(2 ESS); 5 of them.
    ess = row["ess_autocorr"]
    assert abs(row["mean"] - mean) < 5 * sd / np.sqrt(ess)
    assert row["sd"] == pytest.approx(sd, rel=5 / np.sqrt(2 * ess))


# --- the MAP search's noise profile on long runs ----------------------------------------------


def test_expected_periodogram_of_a_long_series_on_a_short_grid():
    # E[I_j] = sum_{|tau|<L} (1 - |tau|/n) c_tau exp(-i w_j tau), w_j = 2 pi j / L,
    # written as the per-frequency sum, for L = 64 lags of a series of n = 1,000.
    acov = 0.8 ** np.arange(64)[None]
    expected = expected_periodogram(acov, 1_000)
    tau = np.arange(-63, 64)
    taper = (1.0 - np.abs(tau) / 1_000) * 0.8 ** np.abs(tau)
    omega = 2 * np.pi * np.arange(33) / 64
    direct = (taper * np.exp(-1j * np.outer(omega, tau))).sum(axis=1).real
    np.testing.assert_allclose(expected[0], direct, rtol=1e-12)


def test_the_profile_bins_a_long_periodogram_keeping_its_weights_and_energy(experiments):
    # Averaged onto 512 frequencies, the bins' multiplicities still count the
    # n Fourier frequencies and the weighted periodogram keeps its sum (the
    # energy, Parseval); with as many points as residuals nothing changes.
    block = ResidualLikelihood(experiments[:1], ROBOT, channels=YAW).blocks[0]
    binned, weights = _binned_periodogram(block, 512)
    assert binned.shape == (257, 16) and weights.sum() == block.n
    full_weights = frequency_weights(block.n)
    np.testing.assert_allclose(weights @ binned, full_weights @ block.periodogram, rtol=1e-12)
    same, same_weights = _binned_periodogram(block, block.n)
    assert same is block.periodogram and np.array_equal(same_weights, full_weights)


def test_likelihood_options_are_an_object_not_a_dict():
    # The options travel as one object; the old dict of keywords is refused,
    # saying what to give instead, before any work.
    assert LikelihoodOptions.of(None) == LikelihoodOptions()
    options = LikelihoodOptions(channels=["yaw"], noise="per-experiment")
    assert LikelihoodOptions.of(options) is options and options.channels == ("yaw",)
    with pytest.raises(
        InputError, match="likelihood_options: give a LikelihoodOptions, not a dict"
    ):
        LikelihoodOptions.of({"channels": ["yaw"]})
