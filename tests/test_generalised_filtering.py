"""The generalised filter (DEM D-step): embedding, convergence, LTI path, yaw-rate accuracy."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.special
from synthetic_posteriors import posterior_at

from bayes_jackal import InputError, load_profile
from bayes_jackal.dem.export import export_prior, temporal_covariance
from bayes_jackal.filters.generalised import d_step, generalised_filter
from bayes_jackal.filters.generalised import process_precision as process_precision_of
from bayes_jackal.filters.generalised_coordinates import white_sensor_precision
from bayes_jackal.io.simulate import NoiseSettings, simulate_experiment
from bayes_jackal.model.physics import continuous_matrices, discrete_matrices

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


def run_filter(order, y, u, **options):
    lookahead = options.pop("lookahead", None)
    Pz = white_sensor_precision(order, DT, SIGMA_N, lookahead=lookahead)
    return d_step(
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


def test_an_exported_prior_drives_the_filter_and_its_predictions():
    # A yaw-only posterior names its sensor sd plain "sigma_n"; the filter reads
    # the means by channel. Plug-in: Pi_w = inv(V) / s_c^2 at the means, Pi_z
    # the embedded white noise at the mean sd, both built here by hand.
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)
    prior = export_prior(posterior_at([run], [110.0, 30.0, 0.047, 0.01, 0.005]), order=2)
    estimate = generalised_filter(run, prior)["yaw"]
    means = {k: prior["noise"]["parameters"][k]["mean"] for k in ("sigma_h", "sigma_c", "sigma_n")}
    A, B, Ad = (np.asarray(prior["model"][k]) for k in ("A", "B", "Ad"))
    s_c = means["sigma_c"] * A[2, 2] / (Ad[2, 2] - 1)
    Pw = np.linalg.inv(temporal_covariance("gaussian", np.array(means["sigma_h"]), 2)) / s_c**2
    Pz = white_sensor_precision(2, DT, means["sigma_n"], lookahead=0)
    expected = d_step(A[2, 2], B[2], DT, Pw, run.yaw_rate, run.inputs, sensor_precision=Pz,
                      lookahead=0)  # fmt: skip
    # The same operations in another order: equal to rounding, far below 1e-9
    # of each derivative's scale.
    scale = np.abs(expected).max(axis=0)
    assert np.all(np.abs(estimate.derivatives - expected) <= 1e-9 * scale)
    np.testing.assert_array_equal(estimate.mean, estimate.derivatives[:, 0])
    # The prediction of y_k is mu~[k-1] carried one step by the Taylor series
    # (closed form: sum_j mu^(j) dt^j / j!), with variance t' Sigma t + sigma_n^2.
    taylor = DT ** np.arange(3) / scipy.special.factorial(np.arange(3))
    predicted = estimate.derivatives[:-1] @ taylor
    np.testing.assert_allclose(estimate.innovation[1:], run.yaw_rate[1:] - predicted, atol=1e-15)
    M = np.eye(3, k=1) - A[2, 2] * np.eye(3)
    Sigma = np.linalg.inv(Pz + M.T @ Pw @ M)
    np.testing.assert_allclose(estimate.variance, Sigma[0, 0], rtol=1e-9)
    np.testing.assert_allclose(
        estimate.innovation_variance[1:], taylor @ Sigma @ taylor + means["sigma_n"] ** 2,
        rtol=1e-9,
    )  # fmt: skip
    assert np.isnan(estimate.innovation[0]) and np.isnan(estimate.innovation_variance[0])


def test_averaged_process_precision_inverts_the_mean_covariance():
    # averaged: inv(E[s_c^2 V]) over the prior's draws, each draw's damping in
    # s_c's pole, built here by hand from the physics; the export's
    # precision_mean_covariance is the same matrix (one helper computes s_c for
    # both). Both are sums of the same floats in another order: 1e-10.
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)
    prior = export_prior(posterior_at([run], [110.0, 30.0, 0.047, 0.01, 0.005]), order=2)
    draws = {k: np.asarray(prior["draws"][k]) for k in ("d_lat", "d_long", "sigma_h", "sigma_c")}
    A, _ = continuous_matrices(ROBOT, draws["d_lat"], draws["d_long"])
    Ad, _ = discrete_matrices(ROBOT, draws["d_lat"], draws["d_long"])
    s_c = draws["sigma_c"] * A[:, 2, 2] / (Ad[:, 2, 2] - 1)
    V = temporal_covariance("gaussian", draws["sigma_h"], 2)
    by_hand = np.linalg.inv(np.mean(V * s_c[:, None, None] ** 2, axis=0))
    averaged = process_precision_of(prior, "yaw", 2, parameters="averaged")
    np.testing.assert_allclose(averaged, by_hand, rtol=1e-10)
    exported = np.asarray(prior["generalised_coordinates"]["precision_mean_covariance"])
    np.testing.assert_allclose(averaged, exported, rtol=1e-10)
    mean_precision = np.asarray(prior["generalised_coordinates"]["precision"])
    assert np.all(np.diag(mean_precision) > np.diag(exported))
    plug_in = process_precision_of(prior, "yaw", 2)
    assert not np.allclose(plug_in, averaged, rtol=1e-6)  # the spread of the draws shows


def test_prior_driven_filter_refuses_what_it_cannot_run():
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)
    prior = export_prior(posterior_at([run], [110.0, 30.0, 0.047, 0.01, 0.005]), order=2)
    with pytest.raises(InputError, match="no channel 'vx'"):
        generalised_filter(run, prior, channels=["vx"])
    with pytest.raises(InputError, match="experiment is sampled at 72 Hz"):
        generalised_filter(run, prior | {"dt": 0.01})
    with pytest.raises(InputError, match="unknown sensor precision 'pink'"):
        generalised_filter(run, prior, sensor_precision="pink")
    with pytest.raises(InputError, match="sensor-noise sd"):
        generalised_filter(run, prior | {"sensor_noise": None})
    exponential = export_prior(
        posterior_at([run], [110.0, 30.0, 0.05, 0.01, 0.005], family="exponential"), order=0
    )
    with pytest.raises(InputError, match="order"):
        generalised_filter(run, exponential, order=1)
