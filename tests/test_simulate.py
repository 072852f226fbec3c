"""Simulator and the Gaussian noise kernel (thesis eq. 7-5)."""

import numpy as np
import pytest

from bayes_jackal import InputError, load_profile
from bayes_jackal.kernels import autocorrelation, coloured_noise, gaussian_kernel
from bayes_jackal.physics import discrete_matrices, one_step_residuals
from bayes_jackal.simulate import (
    REST,
    SERIES,
    NoiseSettings,
    command_profile,
    simulate_experiment,
    simulate_series,
)

ROBOT = load_profile()
DT = 1.0 / 72.0


def _bartlett_sd(rho: np.ndarray, lag: int, n: int) -> float:
    """Standard deviation of the sample autocorrelation at ``lag`` (Bartlett's formula)."""
    full = np.concatenate([rho[:0:-1], rho, np.zeros(lag)])
    centre = len(rho) - 1
    j = np.arange(-centre, centre + 1)
    terms = full[centre + j + lag] + full[centre + j - lag] - 2 * rho[lag] * full[centre + j]
    return float(np.sqrt(np.sum(terms**2) / n))


def test_gaussian_kernel_is_eq_7_5_normalised_to_unit_energy():
    sigma_h = 0.047
    kernel = gaussian_kernel(sigma_h, DT)
    assert np.sum(kernel**2) == pytest.approx(1.0, rel=1e-14)
    half = len(kernel) // 2
    assert half == int(3 * sigma_h / DT)  # truncated at +-3 sigma_h
    t = np.arange(-half, half + 1) * DT
    eq_7_5 = np.sqrt(DT / (sigma_h * np.sqrt(np.pi))) * np.exp(-(t**2) / (2 * sigma_h**2))
    # The analytic prefactor misses only the truncated tail, erfc(3) ~ 2.2e-5 of the energy.
    np.testing.assert_allclose(kernel, eq_7_5, rtol=2e-5)
    # For sigma_h << dt the sampled kernel is a single tap: white noise.
    np.testing.assert_array_equal(gaussian_kernel(0.001, DT), [1.0])
    with pytest.raises(InputError, match="sigma_h"):
        gaussian_kernel(-0.1, DT)


def test_discrete_autocorrelation_approaches_the_continuous_form():
    # White noise through h has autocorrelation exp(-tau^2 / (4 sigma_h^2)) in
    # the continuous limit (DESIGN §3). Sampling errors are exponentially small
    # for sigma_h >> dt; what remains is the +-3 sigma_h truncation, which is
    # scale-free and moves the self-correlation by about 3e-3 at any width.
    for sigma_h in (0.047, 0.1, 0.2):
        rho = autocorrelation(gaussian_kernel(sigma_h, DT), 60)
        tau = np.arange(60) * DT
        np.testing.assert_allclose(rho, np.exp(-(tau**2) / (4 * sigma_h**2)), atol=5e-3)
        assert rho[0] == pytest.approx(1.0)


def test_filtered_white_noise_has_the_kernel_autocorrelation():
    kernel = gaussian_kernel(0.047, DT)
    n = 400_000
    noise = coloured_noise(kernel, n, scale=np.array([2.0, 0.5]), rng=42)
    assert noise.shape == (n, 2)
    lags = 15
    rho = autocorrelation(kernel, 2 * len(kernel))
    for column, scale in zip(noise.T, (2.0, 0.5), strict=True):
        # Sample variance: sd of the estimate ~ scale^2 sqrt(2 sum rho^2 / n) ~ 0.4 %.
        assert np.var(column) == pytest.approx(scale**2, rel=0.03)
        centred = column - column.mean()
        sample = np.array([centred[: n - k] @ centred[k:] for k in range(lags)]) / (
            centred @ centred
        )
        sd = np.array([_bartlett_sd(rho, k, n) for k in range(lags)])
        # 5 sd per lag: with 15 lags a false alarm has probability < 1e-5.
        np.testing.assert_array_less(np.abs(sample - rho[:lags]), 5 * sd + 1e-12)
    # Same seed, same noise; another seed, other noise.
    np.testing.assert_array_equal(
        coloured_noise(kernel, 100, 1.0, 3), coloured_noise(kernel, 100, 1.0, 3)
    )
    assert not np.allclose(
        coloured_noise(kernel, 100, 1.0, 3), coloured_noise(kernel, 100, 1.0, 4)
    )


def test_command_profile_rests_ramps_holds_and_stops():
    t, v, w = command_profile(SERIES["v1"], DT)
    assert len(t) == round(38.0 * 72) + 1
    assert v[0] == v[-1] == w[0] == w[-1] == 0.0
    steady = (t > REST + 1.0) & (t < t[-1] - REST - 1.0)
    np.testing.assert_allclose(v[steady], 0.3)
    np.testing.assert_allclose(w[steady], np.deg2rad(22.5))
    assert np.all(np.diff(v[t < 10]) >= 0)


def test_simulated_experiment_carries_its_truth():
    experiment = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=9)
    assert experiment.truth["d_lat"] == 110.0 and experiment.truth["sigma_h"] == 0.047
    assert experiment.series == "v2" and experiment.dt == pytest.approx(DT)
    assert experiment.t[-1] == pytest.approx(26.0, abs=DT)
    start, stop = experiment.steady_window
    assert 0 < start < stop < experiment.t[-1]
    states = np.column_stack([experiment.truth_arrays[f"{c}_state"] for c in ("vx", "vy", "yaw")])
    noise = np.column_stack(
        [experiment.truth_arrays[f"{c}_process_noise"] for c in ("vx", "vy", "yaw")]
    )
    # The noise-free states satisfy eq. 6-4 with the stored process noise exactly.
    Ad, Bd = discrete_matrices(ROBOT, 110.0, 30.0)
    residuals = one_step_residuals(Ad, Bd, states, experiment.inputs)
    np.testing.assert_allclose(residuals, noise[:-1], rtol=0, atol=1e-12)
    # Measured = truth + white sensor noise of sd sigma_n (sd of the sample sd
    # is sigma_n / sqrt(2 N) ~ 1 % here: 5 % is five of those).
    sensor = experiment.yaw_rate - states[:, 2]
    assert np.std(sensor) == pytest.approx(0.005, rel=0.05)
    # Steady cornering: the commanded yaw rate times the model's gain.
    window = experiment.steady()
    assert abs(np.mean(window.yaw_rate) - np.mean(states[-len(window.t) :, 2])) < 0.05


def test_same_seed_same_experiments_and_independent_runs():
    first = simulate_series(ROBOT, 110.0, 30.0, {"v1": 2, "v2": 1}, rng=123)
    again = simulate_series(ROBOT, 110.0, 30.0, {"v1": 2, "v2": 1}, rng=123)
    assert [e.name for e in first] == ["v1_01", "v1_02", "v2_01"]
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a.yaw_rate, b.yaw_rate)
    assert not np.allclose(first[0].yaw_rate, first[1].yaw_rate)


def test_bad_simulation_settings_are_rejected():
    with pytest.raises(InputError, match="series"):
        simulate_experiment(ROBOT, 110.0, 30.0, "v9")
    with pytest.raises(InputError, match="sigma_c"):
        NoiseSettings(sigma_c=(0.1, -1.0, 0.1))
    with pytest.raises(InputError, match="width"):
        NoiseSettings(width=0.0)
    with pytest.raises(InputError, match="pink"):
        NoiseSettings(family="pink")
    with pytest.raises(InputError, match="d_lat"):
        simulate_experiment(ROBOT, -110.0, 30.0)
