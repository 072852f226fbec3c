"""Physics: eq. 4-32, its discretisation (eq. 6-5, 6-6), thesis fixtures (docs/design.md §1)."""

import control
import numpy as np
import pytest

from bayes_jackal import InputError, load_profile
from bayes_jackal.model.physics import (
    channel_coefficients,
    continuous_matrices,
    discrete_matrices,
    discretise,
    one_step_residuals,
    propagate,
    simulate,
    wheel_speeds,
)

ROBOT = load_profile()
DT = 1.0 / 72.0
#: Series v1 command (table 2-2).
V1, W1 = 0.3, np.deg2rad(22.5)
#: Table 6-1/6-2, "Exact" row: vx from rest, steps 0..10.
TABLE_6_1_EXACT = [
    0,
    0.0144,
    0.0274,
    0.0392,
    0.0498,
    0.0594,
    0.0681,
    0.0760,
    0.0831,
    0.0895,
    0.0953,
]


def test_eq_6_7_and_6_8_are_reproduced():
    A, B = continuous_matrices(ROBOT, 110.0, 30.0)
    printed = {(0, 0): -7.263, (1, 1): -26.63}
    for index, value in printed.items():
        assert A[index] == pytest.approx(value, rel=0.005)
    # A33 is printed as -23.31; the constants give -23.21 (docs/design.md §1): within 1 %.
    assert A[2, 2] == pytest.approx(-23.31, rel=0.01)
    assert A[2, 2] == pytest.approx(-23.21, abs=0.005)
    assert B[0, 0] == B[0, 1] == pytest.approx(0.3559, rel=0.005)
    assert B[2, 0] == -B[2, 1] == pytest.approx(2.227, rel=0.005)
    assert np.all(B[1] == 0)
    assert np.count_nonzero(A - np.diag(np.diag(A))) == 0


def test_table_6_1_exact_row_to_four_decimals():
    omega = wheel_speeds(ROBOT, V1, W1, conversion="thesis")
    states = simulate(ROBOT, 110.0, 30.0, np.tile(omega, (11, 1)), dt=DT)
    np.testing.assert_array_equal(np.round(states[:, 0], 4), TABLE_6_1_EXACT)


def test_table_6_1_euler_row_matches_only_its_first_step():
    # The printed Euler row (0.0151, 0.0281, ...) is not reproducible past
    # step 1 (docs/design.md §1); step 1 of forward Euler is dt B u whatever A is.
    omega = wheel_speeds(ROBOT, V1, W1, conversion="thesis")
    states = simulate(ROBOT, 110.0, 30.0, np.tile(omega, (3, 1)), dt=DT, method="euler")
    assert round(states[1, 0], 4) == 0.0151
    assert round(states[2, 0], 4) != 0.0281


def test_printed_ad_matches_dt_of_one_73rd_not_one_72nd():
    # Eq. 6-10 prints Ad11 = 0.9053; with A11 = -7.263 that is dt = 1/73 (docs/design.md §1).
    A, _ = continuous_matrices(ROBOT, 110.0, 30.0)
    assert round(np.exp(A[0, 0] / 73.0), 4) == 0.9053
    assert round(np.exp(A[0, 0] / 72.0), 4) == 0.9041


@pytest.mark.parametrize("method", ["zoh", "euler"])
def test_discretisation_agrees_with_python_control_c2d(method):
    d_lat = np.array([10.0, 110.0, 999.0, 400.0])
    d_long = np.array([1000.0, 30.0, 10.0, 400.0])
    Ad, Bd = discrete_matrices(ROBOT, d_lat, d_long, DT, method)
    A, B = continuous_matrices(ROBOT, d_lat, d_long)
    Ad_general, Bd_general = discretise(A, B, DT, method)
    for i in range(len(d_lat)):
        system = control.ss(A[i], B[i], np.eye(3), np.zeros((3, 2)))
        reference = control.c2d(system, DT, method=method)
        np.testing.assert_allclose(Ad[i], reference.A, rtol=0, atol=1e-12)
        np.testing.assert_allclose(Bd[i], reference.B, rtol=0, atol=1e-12)
        np.testing.assert_allclose(Ad_general[i], reference.A, rtol=0, atol=1e-12)
        np.testing.assert_allclose(Bd_general[i], reference.B, rtol=0, atol=1e-12)


def test_general_discretisation_handles_a_non_diagonal_singular_model():
    # A double integrator: singular A, where A^-1 (Ad - I) B is undefined.
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0]])
    Ad, Bd = discretise(A, B, 0.5)
    np.testing.assert_allclose(Ad, [[1.0, 0.5], [0.0, 1.0]], atol=1e-14)
    np.testing.assert_allclose(Bd, [[0.125], [0.5]], atol=1e-14)


def test_matrices_broadcast_over_parameter_grids():
    d_lat = np.linspace(10, 1000, 7)[:, None]
    d_long = np.linspace(10, 1000, 5)[None, :]
    A, B = continuous_matrices(ROBOT, d_lat, d_long)
    Ad, Bd = discrete_matrices(ROBOT, d_lat, d_long)
    assert A.shape == Ad.shape == (7, 5, 3, 3)
    assert B.shape == Bd.shape == (7, 5, 3, 2)
    Ad_one, Bd_one = discrete_matrices(ROBOT, d_lat[3, 0], d_long[0, 2])
    np.testing.assert_array_equal(Ad[3, 2], Ad_one)
    np.testing.assert_array_equal(Bd[3, 2], Bd_one)
    alpha, row = channel_coefficients(ROBOT, d_lat, d_long, "yaw")
    np.testing.assert_array_equal(alpha, Ad[..., 2, 2])
    np.testing.assert_array_equal(row, Bd[..., 2, :])


@pytest.mark.parametrize("bad", [0.0, -5.0, np.nan, np.inf])
def test_impossible_damping_is_rejected_with_its_value(bad):
    with pytest.raises(InputError, match="d_long: damping must be positive"):
        continuous_matrices(ROBOT, 110.0, np.array([30.0, bad]))
    with pytest.raises(InputError, match="d_lat"):
        discrete_matrices(ROBOT, bad, 30.0)


def test_unknown_method_and_channel_are_rejected():
    with pytest.raises(InputError, match="tustin"):
        discrete_matrices(ROBOT, 110.0, 30.0, method="tustin")
    with pytest.raises(InputError, match="'roll'"):
        channel_coefficients(ROBOT, 110.0, 30.0, "roll")


def test_ros_conversion_inverts_to_the_command():
    omega_r, omega_l = wheel_speeds(ROBOT, V1, W1)
    r_w, span = ROBOT.wheel_radius, ROBOT.wheel_separation * ROBOT.wheel_separation_multiplier
    assert r_w * (omega_r + omega_l) / 2 == pytest.approx(V1, rel=1e-14)
    assert r_w * (omega_r - omega_l) / span == pytest.approx(W1, rel=1e-14)
    # Eq. 4-33/34 drop the track width: (omega_r - omega_l) r_w = w.
    thesis_r, thesis_l = wheel_speeds(ROBOT, V1, W1, conversion="thesis")
    assert (thesis_r - thesis_l) * r_w == pytest.approx(W1, rel=1e-14)
    assert (thesis_r + thesis_l) * r_w == pytest.approx(V1, rel=1e-14)
    with pytest.raises(InputError, match="conversion"):
        wheel_speeds(ROBOT, V1, W1, conversion="tank")


def test_propagate_matches_a_per_step_loop():
    rng = np.random.default_rng(7)
    alpha = np.r_[rng.uniform(-0.5, 0.9999, 30), 0.0, 0.99999]
    drive = rng.normal(size=(alpha.size, 2000))
    x0 = rng.normal(size=alpha.size)
    reference = np.empty_like(drive)
    reference[:, 0] = x0
    for k in range(drive.shape[1] - 1):
        reference[:, k + 1] = alpha * reference[:, k] + drive[:, k]
    # FFT rounding: a few eps times the largest intermediate (values ~ 1e2).
    np.testing.assert_allclose(propagate(alpha, drive, x0), reference, rtol=0, atol=1e-10)


def test_one_step_residuals_recover_the_process_noise():
    rng = np.random.default_rng(3)
    n = 500
    inputs = np.column_stack([np.full(n, 4.0), np.full(n, 2.5)])
    noise = rng.normal(scale=0.01, size=(n, 3))
    states = simulate(
        ROBOT, 110.0, 30.0, inputs, x0=np.array([0.1, 0.0, 0.2]), process_noise=noise
    )
    Ad, Bd = discrete_matrices(ROBOT, 110.0, 30.0)
    residuals = one_step_residuals(Ad, Bd, states, inputs)
    np.testing.assert_allclose(residuals, noise[:-1], rtol=0, atol=1e-12)
    # Vectorised over parameters: the truth gives the smallest residual.
    Ad_grid, Bd_grid = discrete_matrices(ROBOT, np.array([100.0, 110.0, 120.0]), 30.0)
    mse = np.mean(one_step_residuals(Ad_grid, Bd_grid, states, inputs) ** 2, axis=(-2, -1))
    assert np.argmin(mse) == 1


def test_yaw_steady_state_depends_on_the_damping_ratio_only():
    # x_ss = -A^-1 B u: for yaw, b r_w (omega_r - omega_l) / (2 (b^2 + a^2 d_lat/d_long)).
    omega = np.array(wheel_speeds(ROBOT, V1, W1))
    A, B = continuous_matrices(
        ROBOT, np.array([110.0, 220.0, 440.0]), np.array([30.0, 60.0, 60.0])
    )
    steady = -np.linalg.solve(A, (B @ omega)[..., None])[..., 2, 0]
    assert steady[0] == pytest.approx(steady[1], rel=1e-12)
    assert steady[2] < 0.9 * steady[0]
    a, b, r_w = ROBOT.half_wheelbase, ROBOT.half_track, ROBOT.wheel_radius
    closed_form = b * r_w * (omega[0] - omega[1]) / (2 * (b**2 + a**2 * 110.0 / 30.0))
    assert steady[0] == pytest.approx(closed_form, rel=1e-12)
