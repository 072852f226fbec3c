"""Simulator of thesis-like experiments with known truth."""

import numpy as np
import pytest

from bayes_jackal import InputError, load_profile
from bayes_jackal.io.simulate import (
    REST,
    SERIES,
    NoiseSettings,
    command_profile,
    simulate_experiment,
    simulate_series,
)
from bayes_jackal.model.physics import discrete_matrices, one_step_residuals

ROBOT = load_profile()
DT = 1.0 / 72.0


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
