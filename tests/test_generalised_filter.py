"""The generalised filter (DEM D-step): embedding, convergence, LTI path, yaw-rate accuracy."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.special
from synthetic_posteriors import posterior_at

from bayes_jackal import InputError, load_profile
from bayes_jackal.export import export_prior, temporal_covariance
from bayes_jackal.generalised_filter import (
    embed,
    generalised_filter,
    generalised_filter_prior,
    shift_operator,
    white_sensor_precision,
)
from bayes_jackal.physics import continuous_matrices, discrete_matrices
from bayes_jackal.simulate import NoiseSettings, simulate_experiment

ROBOT = load_profile()
A, B = continuous_matrices(ROBOT, 110.0, 30.0)
AD, BD = discrete_matrices(ROBOT, 110.0, 30.0)
DT = ROBOT.dt
YAW = 2
#: The simulator's yaw noise (NoiseSettings defaults): per-step sd, sensor sd, sigma_h [s].
SIGMA_C, SIGMA_N, SIGMA_H = 0.01, 0.005, 0.047
#: The continuous-time sd of the per-step noise, as export.py converts it.
S_C = SIGMA_C * A[YAW, YAW] / (AD[YAW, YAW] - 1)


def process_precision(order: int) -> np.ndarray:
    """Pi_w = inv(V) / s_c^2 of the simulator's Gaussian yaw noise (export.py)."""
    return np.linalg.inv(temporal_covariance("gaussian", np.array(SIGMA_H), order)) / S_C**2


@pytest.mark.parametrize("order", [0, 1, 2, 3, 4])
def test_embedding_is_exact_on_polynomials_of_degree_up_to_the_order(order):
    rng = np.random.default_rng(order)
    dt = 0.05
    t = np.arange(12) * dt
    polynomial = np.polynomial.Polynomial(rng.normal(size=order + 1))
    # Closed form: derivative j of the polynomial at every sample.
    expected = np.column_stack([polynomial.deriv(j)(t) for j in range(order + 1)])
    for lookahead in range(order + 1):
        np.testing.assert_allclose(
            embed(polynomial(t), order, dt, lookahead=lookahead), expected, rtol=1e-8, atol=1e-8
        )
    # One degree more is not exact: the centred first derivative of t^3 is
    # ((t + h)^3 - (t - h)^3) / (2 h) = 3 t^2 + h^2, off by h^2 (closed form).
    if order == 2:
        embedded = embed(t**3, 2, dt)
        np.testing.assert_allclose(embedded[1:-1, 1], 3 * t[1:-1] ** 2 + dt**2, rtol=1e-10)


def test_embedding_of_several_series_and_too_short_series():
    t = np.arange(6) * 0.1
    both = embed(np.column_stack([t, 2 * t]), 1, 0.1)
    assert both.shape == (6, 2, 2)
    np.testing.assert_allclose(both[:, 1], [[1.0, 2.0]] * 6, rtol=1e-12)
    with pytest.raises(InputError, match="needs at least 3 samples"):
        embed(np.ones(2), 2, 0.1)
    with pytest.raises(InputError, match=r"lookahead must lie in 0 \.\. 2"):
        embed(np.ones(5), 2, 0.1, lookahead=3)


@pytest.mark.parametrize(("order", "lookahead"), [(1, 0), (2, 1), (2, 0), (3, 1)])
def test_sensor_precision_is_the_inverse_covariance_of_embedded_white_noise(order, lookahead):
    # Monte Carlo: 200,000 white samples embedded; windows overlap, so about
    # 200,000 / (p + 1) independent ones, and each variance is within
    # ~sqrt(2 (p + 1) / 200,000) < 0.7 % (1 sd): 4 % is > 5 sd.
    dt, sigma = 0.02, 0.3
    noise = sigma * np.random.default_rng(5).standard_normal(200_000)
    embedded = embed(noise, order, dt, lookahead=lookahead)[order:-order]
    expected = np.linalg.inv(white_sensor_precision(order, dt, sigma, lookahead=lookahead))
    scale = np.sqrt(np.diag(expected))
    np.testing.assert_allclose(
        np.cov(embedded.T) / np.outer(scale, scale), expected / np.outer(scale, scale), atol=0.04
    )


def run_filter(order, y, u, **options):
    lookahead = options.pop("lookahead", None)
    Pz = white_sensor_precision(order, DT, SIGMA_N, lookahead=lookahead)
    return generalised_filter(
        A[YAW, YAW],
        B[YAW],
        DT,
        options.pop("process", process_precision(order)),
        y,
        u,
        sensor_precision=options.pop("sensor", Pz),
        lookahead=lookahead,
        **options,
    )


@pytest.mark.parametrize(("order", "lookahead"), [(1, 0), (2, 0), (2, 1), (3, 0), (3, 1)])
def test_noise_free_run_converges_to_the_true_state(order, lookahead):
    # Constant wheel speeds from rest: x(t) = x_ss (1 - exp(a t)), x_ss = -b u / a
    # (closed form), measured without noise; the filter starts at zero.
    a, b = A[YAW, YAW], B[YAW]
    u = np.array([10.0, 2.0])
    t = np.arange(144) * DT
    steady = -b @ u / a
    transient = -steady * np.exp(a * t)
    mu = run_filter(
        order,
        steady + transient,
        np.tile(u, (len(t), 1)),
        lookahead=lookahead,
        initial=np.zeros(order + 1),
    )
    # The error follows the transient, within the first Taylor term the
    # embedding drops, (|a| dt)^(p+1) of it (measured: 7.5 % at p = 1,
    # 0.2-1.6 % at p = 2, 0.07-0.5 % at p = 3) ...
    bound = (abs(a) * DT) ** (order + 1) * np.abs(transient)
    assert np.all(np.abs(mu[:, 0] - (steady + transient)) <= bound + 1e-14)
    # ... and vanishes with it: the steady state and zero derivatives (each
    # to 1e-12 of its natural scale |a|^j x_ss).
    scale = steady * np.abs(a) ** np.arange(order + 1)
    np.testing.assert_allclose(mu[-1] / scale, [1.0, *[0.0] * order], rtol=0, atol=1e-12)


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_constant_input_gives_the_steady_state(order):
    # Measured at -A^-1 B u with no noise, the flow's fixed point is that state.
    u = np.array([8.0, 3.0])
    steady = -np.linalg.solve(A, B @ u)[YAW]
    mu = run_filter(order, np.full(30, steady), np.tile(u, (30, 1)), initial=np.zeros(order + 1))
    # Each derivative to 1e-12 of its natural scale |a|^j x_ss.
    scale = steady * np.abs(A[YAW, YAW]) ** np.arange(order + 1)
    np.testing.assert_allclose(mu / scale, [[1.0, *[0.0] * order]] * 30, rtol=0, atol=1e-12)


def step_by_step(order, a, b, Pw, Pz, y, u, lookahead, initial):
    """The plain loop: per sample, embed the window by solving the Taylor system
    T y~ = window, and take one local-linearisation step (spm_dx):
    mu~ += (expm(J dt) - I) J^-1 (D mu~ - K dF/dmu~)."""
    size = order + 1
    D = np.eye(size, k=1)
    M = D - a * np.eye(size)
    K = np.diag(DT ** (-2.0 * np.arange(size))) / DT
    J = D - K @ (Pz + M.T @ Pw @ M)
    update = np.linalg.solve(J, scipy.linalg.expm(J * DT) - np.eye(size))
    factorial = scipy.special.factorial(np.arange(size))
    mu, out = np.array(initial, float), []
    for k in range(len(y)):
        first = min(max(k - (order - lookahead), 0), len(y) - size)
        T = ((np.arange(size)[:, None] - (k - first)) * DT) ** np.arange(size) / factorial
        y_gen = np.linalg.solve(T, y[first : first + size])
        drive_gen = np.linalg.solve(T, u[first : first + size] @ b)
        gradient = -Pz @ (y_gen - mu) + M.T @ Pw @ (M @ mu - drive_gen)
        mu = mu + update @ (D @ mu - K @ gradient)
        out.append(mu)
    return np.array(out)


@pytest.mark.parametrize(
    ("order", "lookahead", "scale"),
    [(2, 1, 1.0), (2, 0, 1.0), (3, 1, 1.0), (1, 0, 1e-4), (2, 1, 1e-6), (3, 1, 1e-5)],
)
def test_convolution_equals_the_step_by_step_integration(order, lookahead, scale):
    # scale 1: the simulator's precisions, so stiff that expm(J dt) < 1e-17 and
    # the impulse response is one sample; scaled down the flow is slower and
    # the response has 15 (p = 1), 735 (p = 2: all 300 samples) and 42 (p = 3)
    # taps, so the convolution is exercised in full. (Much smaller precisions
    # make the flow unstable: D - K Pi has eigenvalues ~ (K Pi)^(1/(p+1)).)
    rng = np.random.default_rng(order)
    u = np.column_stack([np.linspace(0, 10, 300), np.linspace(0, 4, 300)])
    y = 0.3 + 0.05 * rng.standard_normal(300)
    Pw = process_precision(order) * scale
    Pz = white_sensor_precision(order, DT, SIGMA_N, lookahead=lookahead) * scale
    initial = rng.normal(size=order + 1)
    expected = step_by_step(order, A[YAW, YAW], B[YAW], Pw, Pz, y, u, lookahead, initial)
    mu = run_filter(order, y, u, lookahead=lookahead, process=Pw, sensor=Pz, initial=initial)
    # Both are exact for the held data; they differ by rounding, relative to
    # each derivative's scale (its largest magnitude).
    scale = np.abs(expected).max(axis=0)
    np.testing.assert_allclose(mu / scale, expected / scale, rtol=0, atol=1e-9)


def test_a_flow_without_precision_is_refused():
    with pytest.raises(InputError, match="not stable"):
        run_filter(
            2, np.ones(10), np.ones((10, 2)), process=np.zeros((3, 3)), sensor=np.zeros((3, 3))
        )
    with pytest.raises(InputError, match=r"\(3, 3\) precision"):
        run_filter(2, np.ones(10), np.ones((10, 2)), sensor=np.eye(2))
    with pytest.raises(InputError, match="must be finite"):
        run_filter(2, np.array([1.0, np.nan, 1.0, 1.0]), np.ones((4, 2)))


def white_kalman(y, u):
    """The Kalman filter that takes the coloured process noise as white, per step."""
    alpha, row = AD[YAW, YAW], BD[YAW]
    x, P = y[0], SIGMA_N**2
    out = np.empty_like(y)
    for k in range(len(y)):
        if k:
            x, P = alpha * x + row @ u[k - 1], alpha**2 * P + SIGMA_C**2
        gain = P / (P + SIGMA_N**2)
        x, P = x + gain * (y[k] - x), (1 - gain) * P
        out[k] = x
    return out


def test_generalised_filter_beats_the_white_kalman_filter_on_coloured_noise():
    # The simulator's Gaussian-coloured yaw noise (sigma_h = 0.047 s), a v1 run.
    # Over seeds 0-19 the RMSE ratio to the white Kalman filter was 0.919 +-
    # 0.009 (max 0.935) for the causal filter (lookahead 0) and 0.637 +- 0.010
    # for SPM's centred embedding, which also sees the next sample: > 7 sd of
    # margin for the assertions below.
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", NoiseSettings(), rng=11)
    y, u, truth = run.yaw_rate, run.inputs, run.truth_arrays["yaw_state"]

    def rmse(estimate):
        return math.sqrt(np.mean((estimate - truth) ** 2))

    raw, kalman = rmse(y), rmse(white_kalman(y, u))
    causal = rmse(run_filter(2, y, u, lookahead=0)[:, 0])
    centred = rmse(run_filter(2, y, u)[:, 0])
    assert centred < causal < kalman < raw


def test_prior_dict_drives_the_filter_per_channel():
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=2)
    order, n = 1, 2
    blocks = {"yaw": process_precision(order), "vx": 2 * process_precision(order)}
    precision = np.zeros((order + 1, n, order + 1, n))
    for c, channel in enumerate(["yaw", "vx"]):
        precision[:, c, :, c] = blocks[channel]
    # The fields of an exported prior (export.export_prior) the filter reads.
    prior = {
        "format": "bayes_jackal.prior/1",
        "robot": {"name": ROBOT.name},
        "dt": DT,
        "model": {"A": A.tolist(), "B": B.tolist()},
        "noise": {"channels": ["yaw", "vx"]},
        "sensor_noise": {"sd": {"yaw": {"mean": SIGMA_N}, "vx": {"mean": 0.003}}},
        "generalised_coordinates": {"order": order, "precision": precision.reshape(4, 4).tolist()},
    }
    mu = generalised_filter_prior(run, prior)
    assert mu.shape == (len(run.t), 2, 2)
    expected = generalised_filter(
        A[0, 0],
        B[0],
        DT,
        blocks["vx"],
        run.vx,
        run.inputs,
        sensor_precision=white_sensor_precision(order, DT, 0.003),
    )
    np.testing.assert_array_equal(mu[:, 1], expected)
    np.testing.assert_array_equal(
        generalised_filter_prior(run, prior, channels=["vx"])[:, 0], expected
    )
    with pytest.raises(InputError, match="no channel 'vy'"):
        generalised_filter_prior(run, prior, channels=["vy"])
    with pytest.raises(InputError, match="experiment is sampled at 72 Hz"):
        generalised_filter_prior(run, prior | {"dt": 0.01})
    del prior["sensor_noise"]["sd"]["vx"]
    with pytest.raises(InputError, match=r"no field 'sensor_noise\.sd\.vx\.mean'"):
        generalised_filter_prior(run, prior)
    with pytest.raises(InputError, match="pass sensor_precision"):
        generalised_filter_prior(run, prior | {"sensor_noise": None})


def test_shift_operator_moves_each_derivative_up():
    x = np.array([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(shift_operator(3) @ x, [2.0, 3.0, 4.0, 0.0])


def test_an_exported_one_channel_prior_drives_the_filter():
    # A yaw-only posterior names its sensor sd plain "sigma_n"; the filter reads
    # it by channel from the export's sensor_noise block. Its Pi_z is then the
    # embedded white noise at that sd, and Pi_w the exported block.
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)
    prior = export_prior(posterior_at([run], [110.0, 30.0, 0.047, 0.01, 0.005]), order=2)
    mu = generalised_filter_prior(run, prior, lookahead=0)
    sigma_n = prior["sensor_noise"]["sd"]["yaw"]["mean"]
    A, B = (np.asarray(prior["model"][k]) for k in ("A", "B"))
    expected = generalised_filter(
        A[2, 2],
        B[2],
        DT,
        np.asarray(prior["generalised_coordinates"]["precision"]),
        run.yaw_rate,
        run.inputs,
        sensor_precision=white_sensor_precision(2, DT, sigma_n, lookahead=0),
        lookahead=0,
    )
    # The prior function takes the mean sd and the blocks by its own path
    # (float sums in another order): equal to rounding, far below 1e-9 of
    # each derivative's scale.
    scale = np.abs(expected).max(axis=0)
    assert np.all(np.abs(mu[:, 0] - expected) <= 1e-9 * scale)
