"""The Kalman filters against the dense joint Gaussian, and their steady (FFT) path."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import scipy.linalg

from bayes_jackal import load_profile
from bayes_jackal.filters.kalman_filters import KALMAN_FILTERS, kalman, kalman_filter
from bayes_jackal.filters.state_space import channel_model
from bayes_jackal.io.simulate import NoiseSettings, simulate_experiment
from bayes_jackal.model.kernels import get_family
from bayes_jackal.model.physics import channel_coefficients, discrete_matrices

ROBOT = load_profile()
DT = ROBOT.dt
#: The yaw channel at the thesis' damping (d_lat 110, d_long 30 N s/m).
ALPHA, ROW = (np.asarray(v) for v in channel_coefficients(ROBOT, 110.0, 30.0, "yaw"))
#: The simulator's default noise of the yaw channel [rad/s] and widths [s].
SIGMA_C, SIGMA_N = 0.01, 0.005
WIDTHS = {
    "white": 1.0,
    "gaussian": 0.047,
    "exponential": 0.05,
    "triangular": 0.06,
    "moving-average": 0.045,
}


def truth_prior(channels=("yaw", "vx", "vy"), family="gaussian", sensor="ma1", width=0.047):
    """A prior dict holding the simulator's truth, shaped as export_prior's."""
    Ad, Bd = discrete_matrices(ROBOT, 110.0, 30.0)
    noise = NoiseSettings()
    parameters = {}
    for c in channels:
        i = ["vx", "vy", "yaw"].index(c)
        suffix = f"[{c}]" if len(channels) > 1 else ""
        if family != "white":
            parameters[f"{get_family(family).width_name}{suffix}"] = {"mean": width}
        parameters[f"sigma_c{suffix}"] = {"mean": noise.sigma_c[i]}
        parameters[f"sigma_n{suffix}"] = {"mean": noise.sigma_n[i]}
    return {
        "format": "bayes_jackal.prior/1",
        "robot": {"name": ROBOT.name},
        "dt": DT,
        "damping": {"mean": [110.0, 30.0]},
        "model": {"Ad": Ad.tolist(), "Bd": Bd.tolist()},
        "noise": {
            "family": family,
            "channels": list(channels),
            "sensor": sensor,
            "parameters": parameters,
        },
    }


def noise_autocovariance(family, widths, sigma_c):
    """The draws' mean of sigma_c^2 (h * h reversed)[lag], h the taps of each width."""
    rows = []
    for width, sd in zip(np.atleast_1d(widths), np.atleast_1d(sigma_c), strict=True):
        taps = get_family(family).taps(width, DT)
        rows.append(sd**2 * np.convolve(taps, taps[::-1])[len(taps) - 1 :])
    acov = np.zeros(max(map(len, rows)))
    for row in rows:
        acov[: len(row)] += row / len(rows)
    return acov


def dense_conditional_mean(acov, nugget, sensor_variance, y, inputs):
    """E[x_k | y_0..y_k] and its variance from the joint Gaussian of (x, y), built by brute force.

    x[k+1] = alpha x[k] + b u[k] + w[k] from rest one step before the first
    sample (x[-1] = 0, u[-1] = 0), so x = L d with L[k, i] = alpha^(k - i),
    i <= k, and d = (w[-1], b u[0] + w[0], .., b u[N-2] + w[N-2]); w has
    the autocovariance ``acov`` plus white noise of variance ``nugget``, and
    y = x + n with var(n) = ``sensor_variance``.
    """
    n = len(y)
    lags = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    noise = np.where(lags < len(acov), acov[np.minimum(lags, len(acov) - 1)], 0.0)
    noise += nugget * np.eye(n)
    L = np.tril(ALPHA ** lags.astype(float))
    mean_x = L @ np.concatenate([[0.0], inputs[:-1] @ ROW])
    cov_x = L @ noise @ L.T
    cov_y = cov_x + sensor_variance * np.eye(n)
    means, variances = np.empty(n), np.empty(n)
    for k in range(n):
        weights = np.linalg.solve(cov_y[: k + 1, : k + 1], cov_x[: k + 1, k])
        means[k] = mean_x[k] + weights @ (y[: k + 1] - mean_x[: k + 1])
        variances[k] = cov_x[k, k] - weights @ cov_x[: k + 1, k]
    return means, variances, mean_x, cov_y


def check_against_dense(family, width, sigma_c, sigma_n, sensor, n=40, seed=4):
    """The filter on y drawn from the dense model (a turn: wheel speeds 10 and 5 rad/s)
    equals the dense conditional mean to 1e-8 rad/s (states ~0.5 rad/s) and
    the variance to 1e-8 relative; returns the filtered means and the data."""
    acov = noise_autocovariance(family, width, sigma_c)
    mean_square = np.mean(np.square(sigma_n))
    nugget, sensor_variance = (mean_square, 0.0) if sensor == "diagonal" else (0.0, mean_square)
    inputs = np.tile([10.0, 5.0], (n, 1))
    dense = functools.partial(dense_conditional_mean, acov, nugget, sensor_variance)
    _, _, mean_y, cov_y = dense(np.zeros(n), inputs)
    y = mean_y + np.linalg.cholesky(cov_y) @ np.random.default_rng(seed).standard_normal(n)
    model = channel_model(
        "yaw", ALPHA, ROW, family=family, width=width, sigma_c=sigma_c, sigma_n=sigma_n,
        dt=DT, sensor=sensor,
    )  # fmt: skip
    means, variances, _, _ = dense(y, inputs)
    estimate = kalman(model, y, inputs, fast=False)
    assert 0.1 < np.abs(means).mean() < 1.0
    np.testing.assert_allclose(estimate.mean, means, rtol=0, atol=1e-8)
    np.testing.assert_allclose(estimate.variance, variances, rtol=1e-8, atol=1e-8 * SIGMA_N**2)
    return estimate.mean, y


@pytest.mark.parametrize("sensor", ["ma1", "diagonal"])
@pytest.mark.parametrize("family", list(WIDTHS))
def test_filter_is_the_dense_conditional_mean(family, sensor):
    # The coloured filter carries the family's shaping filter in its state
    # (exact), the white one is the same code on the white model: each
    # equals the conditional mean of its own model's joint Gaussian, built
    # from the taps with numpy.convolve.
    means, y = check_against_dense(family, WIDTHS[family], SIGMA_C, SIGMA_N, sensor)
    if sensor == "diagonal":  # an exact measurement: the estimate is the data
        np.testing.assert_allclose(means, y, rtol=0, atol=1e-12)


@pytest.mark.parametrize("family", ["gaussian", "exponential", "triangular"])
def test_draw_averaged_filter_is_the_dense_conditional_mean_of_the_averaged_noise(family):
    # Five draws of (width, sigma_c, sigma_n): the filter's Q and R are their
    # means, so the joint Gaussian has the draws' mean autocovariance and
    # sensor variance. The exponential family's widths give AR(1) poles
    # that differ, so its average is realised by its taps.
    rng = np.random.default_rng(5)
    width = WIDTHS[family] * rng.uniform(0.6, 1.4, 5)
    sigma_c, sigma_n = SIGMA_C * rng.uniform(0.7, 1.3, 5), SIGMA_N * rng.uniform(0.7, 1.3, 5)
    check_against_dense(family, width, sigma_c, sigma_n, "ma1")


@pytest.mark.parametrize("family", ["white", "gaussian", "exponential", "moving-average"])
def test_steady_path_equals_the_recursion_and_the_riccati_solution(family):
    # 2,000 samples of a simulated yaw rate: the steady filter's FFT
    # convolution equals the step-by-step recursion to 1e-12, and the
    # converged innovation variance is H P H' + R, P the DARE's solution.
    width = WIDTHS[family]
    noise = NoiseSettings(family=family, width=width)
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", noise, rng=2)
    y, inputs = run.yaw_rate[:2000], run.inputs[:2000]
    model = channel_model(
        "yaw", ALPHA, ROW, family=family, width=width, sigma_c=SIGMA_C, sigma_n=SIGMA_N, dt=DT
    )
    fast, slow = kalman(model, y, inputs), kalman(model, y, inputs, fast=False)
    assert 1 < fast.steady_from < 500 and slow.steady_from == len(y)
    # The same sums in another order (FFT against the recursion), and a gain
    # converged to CONVERGED = 1e-14: rounding of ~1e-15 of states ~0.1-1,
    # so 1e-12 leaves a margin of hundreds and still catches a wrong term.
    for name in ("mean", "innovation"):
        np.testing.assert_allclose(getattr(fast, name), getattr(slow, name), rtol=0, atol=1e-12)
    for name in ("variance", "innovation_variance"):
        np.testing.assert_allclose(getattr(fast, name), getattr(slow, name), rtol=1e-12)
    F, Q = model.transition, model.process_covariance
    H = np.eye(model.size)[:1]
    P = scipy.linalg.solve_discrete_are(F.T, H.T, Q, np.array([[SIGMA_N**2]]))
    np.testing.assert_allclose(fast.innovation_variance[-1], P[0, 0] + SIGMA_N**2, rtol=1e-10)


def test_coloured_filter_beats_the_white_one_on_gaussian_coloured_runs():
    # The coloured filter is the conditional mean under the simulated model,
    # so its yaw-rate error against the true states is the smaller one. The
    # ratio measured on seeds 1..10 (38 s v1 runs, the simulator's defaults,
    # prior = truth) lies in [0.81, 0.83], mean 0.82; three seeds pooled
    # must show at least a 10 % gain.
    prior = truth_prior(channels=("yaw",))
    errors = {name: 0.0 for name in KALMAN_FILTERS}
    for seed in (1, 2, 3):
        run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", rng=seed)
        truth = run.truth_arrays["yaw_state"]
        for name, noise in KALMAN_FILTERS.items():
            estimate = kalman_filter(run, prior, noise=noise)["yaw"]
            errors[name] += np.mean((estimate.mean - truth) ** 2)
    ratio = np.sqrt(errors["kalman-coloured"] / errors["kalman"])
    assert ratio < 0.9


@pytest.mark.parametrize("family", ["white", "gaussian", "exponential"])
def test_the_smoother_is_the_dense_conditional_mean_given_the_whole_run(family):
    # E[x_k | y_0..y_N-1] of the same joint Gaussian (every y weighs in),
    # to 1e-8 rad/s, as the filter's check; its variance to 1e-8 relative.
    n = 60
    acov = noise_autocovariance(family, WIDTHS[family], SIGMA_C)
    inputs = np.tile([10.0, 5.0], (n, 1))
    _, _, mean_y, cov_y = dense_conditional_mean(acov, 0.0, SIGMA_N**2, np.zeros(n), inputs)
    y = mean_y + np.linalg.cholesky(cov_y) @ np.random.default_rng(6).standard_normal(n)
    cov_x = cov_y - SIGMA_N**2 * np.eye(n)
    weights = np.linalg.solve(cov_y, cov_x)  # cov(x, y) = cov(x)
    smoothed = mean_y + weights.T @ (y - mean_y)
    variance = np.diag(cov_x - cov_x @ weights)
    model = channel_model(
        "yaw", ALPHA, ROW, family=family, width=WIDTHS[family], sigma_c=SIGMA_C,
        sigma_n=SIGMA_N, dt=DT,
    )  # fmt: skip
    for fast in (False, True):
        estimate = kalman(model, y, inputs, fast=fast)
        np.testing.assert_allclose(estimate.smoothed, smoothed, rtol=0, atol=1e-8)
        np.testing.assert_allclose(estimate.smoothed_variance, variance, rtol=1e-8)


@pytest.mark.parametrize("family", ["gaussian", "exponential"])
def test_the_steady_smoother_equals_its_recursion(family):
    # As the filter's steady path: the backward LTI pass (FFT) against the
    # step-by-step one, on 2,000 samples; 1e-12 on states ~0.1-1 rad/s.
    noise = NoiseSettings(family=family, width=WIDTHS[family])
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", noise, rng=3)
    y, inputs = run.yaw_rate[:2000], run.inputs[:2000]
    model = channel_model(
        "yaw", ALPHA, ROW, family=family, width=WIDTHS[family], sigma_c=SIGMA_C,
        sigma_n=SIGMA_N, dt=DT,
    )  # fmt: skip
    fast, slow = kalman(model, y, inputs), kalman(model, y, inputs, fast=False)
    assert fast.steady_from < 500
    np.testing.assert_allclose(fast.smoothed, slow.smoothed, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.smoothed_variance, slow.smoothed_variance, rtol=1e-10)
    truth = run.truth_arrays["yaw_state"][:2000]
    assert np.std(fast.smoothed - truth) < np.std(fast.mean - truth)


def test_a_filter_without_the_smoother_has_the_same_innovations():
    # The NIS spread over a prior's draws reads the innovations alone: the
    # filter run without its smoother gives them, and no smoothed fields.
    # Its steady part convolves the prediction H F m_i itself instead of
    # every state (then multiplied by H F): the same sums in another order,
    # equal to rounding (measured 3e-16 on this 0.3 rad/s run; 1e-13 allows 300x).
    noise = NoiseSettings(family="gaussian", width=WIDTHS["gaussian"])
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", noise, rng=4)
    model = channel_model(
        "yaw", ALPHA, ROW, family="gaussian", width=WIDTHS["gaussian"], sigma_c=SIGMA_C,
        sigma_n=SIGMA_N, dt=DT,
    )  # fmt: skip
    for fast in (False, True):
        full = kalman(model, run.yaw_rate, run.inputs, fast=fast)
        alone = kalman(model, run.yaw_rate, run.inputs, fast=fast, smooth=False)
        assert alone.smoothed is None and alone.smoothed_variance is None
        for field in ("variance", "innovation_variance"):  # the gains: the same recursion
            np.testing.assert_array_equal(getattr(alone, field), getattr(full, field))
        for field in ("mean", "innovation"):
            np.testing.assert_allclose(getattr(alone, field), getattr(full, field), rtol=0,
                                       atol=1e-13)  # fmt: skip
        if not fast:  # the recursion throughout: bit for bit
            np.testing.assert_array_equal(alone.innovation, full.innovation)
