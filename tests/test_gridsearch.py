"""Grid searches (thesis ch. 5 and 9-1-2) against per-pair references and known truth."""

import control
import numpy as np
import pytest

from bayes_jackal import InputError, load_profile
from bayes_jackal.io.simulate import NoiseSettings, simulate_experiment, simulate_series
from bayes_jackal.model.physics import continuous_matrices, one_step_residuals, simulate
from bayes_jackal.thesis.gridsearch import (
    GRID_POINTS,
    damping_grid,
    grid_search,
    onestep_mse,
    prior_grid,
    simulation_mse,
)

ROBOT = load_profile()
#: "Small noise". The one-step least-squares bias from coloured noise scales
#: as sigma_c^2 over the transient (input-unexplained) variance of the state,
#: which is tiny for stiff parameters (time constant ~ 1 sample): at 1e-4
#: rad/s (300, 60) still lands 20 steps down the ridge; at 1e-6 every truth
#: below is recovered exactly.
SMALL_NOISE = NoiseSettings(width=0.047, sigma_c=(1e-6, 1e-6, 1e-6), sigma_n=(1e-7, 1e-7, 1e-7))


@pytest.fixture(scope="module")
def noisy_experiment():
    return simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=11)


def _per_pair(experiment, d_lat, d_long, criterion):
    """The thesis' way: c2d for every pair, then the MSE (a slow, plain reference)."""
    states, inputs = experiment.states(), experiment.inputs
    surface = np.empty((len(d_lat), len(d_long)))
    for i, lat in enumerate(d_lat):
        for j, long in enumerate(d_long):
            A, B = continuous_matrices(ROBOT, lat, long)
            system = control.c2d(control.ss(A, B, np.eye(3), np.zeros((3, 2))), experiment.dt)
            if criterion == "onestep":
                residual = one_step_residuals(system.A, system.B, states, inputs)[:, 2]
            else:
                x0 = np.array([0.0, 0.0, states[0, 2]])
                residual = (
                    simulate(ROBOT, lat, long, inputs, x0, dt=experiment.dt)[:, 2] - states[:, 2]
                )
            surface[i, j] = np.mean(residual**2)
    return surface


@pytest.mark.parametrize("criterion", [onestep_mse, simulation_mse])
def test_vectorised_criteria_match_the_per_pair_reference(noisy_experiment, criterion):
    d_lat, d_long = np.array([20.0, 110.0, 640.0, 1000.0]), np.array([10.0, 30.0, 333.0])
    fast = criterion(noisy_experiment, ROBOT, d_lat, d_long)
    slow = _per_pair(noisy_experiment, d_lat, d_long, criterion.__name__.removesuffix("_mse"))
    # The Gram form cancels sums of y^2 ~ 0.1 down to MSEs ~ 1e-4: rounding
    # ~ 1e-16 * 0.1 / 1e-4 * sqrt(N) ~ 1e-11 relative; 1e-8 leaves margin.
    np.testing.assert_allclose(fast, slow, rtol=1e-8)


@pytest.mark.parametrize(
    ("d_lat", "d_long"), [(110.0, 30.0), (300.0, 60.0), (45.0, 150.0), (900.0, 400.0)]
)
def test_onestep_minimum_is_within_one_step_of_the_truth_when_noise_is_small(d_lat, d_long):
    experiment = simulate_experiment(ROBOT, d_lat, d_long, "v1", SMALL_NOISE, rng=2)
    grid = damping_grid(1.0, 1000.0, 1.0)
    result = grid_search([experiment], ROBOT, grid, grid, "onestep")
    best_lat, best_long, _ = result.argmin()
    assert abs(best_lat - d_lat) <= 1.0
    assert abs(best_long - d_long) <= 1.0
    # Inside the grid on both axes: no edge, no warning.
    assert result.edges() == {} and result.summary()["warnings"] == []


def test_simulation_mse_valley_follows_a_constant_damping_ratio():
    # Ridge of thesis fig. 5-4: the yaw steady state depends on d_lat/d_long
    # only, so for every d_long the best d_lat is ratio x d_long, to within
    # the d_lat grid step (the transient moves it by less than that).
    experiments = simulate_series(ROBOT, 110.0, 30.0, {"v1": 1, "v2": 1}, rng=5)
    grid = damping_grid(10.0, 1000.0, 10.0)
    result = grid_search(experiments, ROBOT, grid, grid, "simulation")
    ratio = 110.0 / 30.0
    inside = grid * ratio + 10.0 <= 1000.0
    best_lat = grid[np.argmin(result.mse, axis=0)]
    assert inside.sum() >= 25
    np.testing.assert_array_less(np.abs(best_lat - ratio * grid)[inside], 10.0 + 1e-9)
    # The valley is flat next to the surface: along it the MSE stays within 5 %
    # of the minimum (the process noise dominates), off it > 10x higher. From
    # d_long = 30 on, where the nearest grid d_lat misses ratio x d_long by
    # at most 2.3 % (9 % at d_long = 10, enough to raise the MSE by 17 %).
    valley = result.mse.min(axis=0)[inside & (grid >= 30.0)]
    assert valley.max() < 1.05 * result.mse.min()
    assert np.median(result.mse) > 10.0 * result.mse.min()
    assert result.argmin()[:2] == (110.0, 30.0)


def test_series_means_and_total_follow_eq_5_2_and_5_3():
    experiments = simulate_series(ROBOT, 110.0, 30.0, {"v1": 2, "v2": 1}, rng=8)
    d_lat, d_long = damping_grid(50.0, 200.0, 50.0), damping_grid(10.0, 50.0, 20.0)
    result = grid_search(experiments, ROBOT, d_lat, d_long, "onestep")
    per = result.experiment_mse
    assert result.series_members == {"v1": ["v1_01", "v1_02"], "v2": ["v2_01"]}
    np.testing.assert_allclose(result.series_mse["v1"], (per["v1_01"] + per["v1_02"]) / 2)
    np.testing.assert_allclose(result.series_mse["v2"], per["v2_01"])
    np.testing.assert_allclose(result.mse, result.series_mse["v1"] + result.series_mse["v2"])
    summary = result.summary()
    i, j = np.unravel_index(np.argmin(result.mse), result.mse.shape)
    assert (summary["d_lat"], summary["d_long"]) == (d_lat[i], d_long[j])
    assert summary["mse"] == result.mse[i, j]
    assert set(summary["experiments"]) == {"v1_01", "v1_02", "v2_01"}


def test_damping_grid_includes_stop_and_rejects_impossible_ranges():
    np.testing.assert_array_equal(damping_grid(10, 1000, 10), np.arange(10, 1001, 10))
    assert len(damping_grid(1, 1000, 1)) == 1000
    assert damping_grid(0.1, 0.3, 0.1)[-1] == pytest.approx(0.3)
    for bad in [(0, 100, 10), (-10, 100, 10), (10, 100, 0), (10, 100, -1), (100, 10, 1)]:
        with pytest.raises(InputError, match="d_lat: grid needs"):
            damping_grid(*bad, name="d_lat")
    with pytest.raises(InputError, match="nan"):
        damping_grid(np.nan, 100, 10)


def test_grid_search_rejects_unknown_method_and_empty_input(noisy_experiment):
    grid = damping_grid(10, 30, 10)
    with pytest.raises(InputError, match="'mle'"):
        grid_search([noisy_experiment], ROBOT, grid, grid, "mle")
    with pytest.raises(InputError, match="no experiments"):
        grid_search([], ROBOT, grid, grid)


@pytest.mark.parametrize("name", ["jackal", "husky", "warthog"])
@pytest.mark.parametrize("method", ["onestep", "simulation"])
def test_the_default_grid_spans_the_profiles_prior_log_spaced(name, method):
    robot = load_profile(name)
    for parameter in ("d_lat", "d_long"):
        grid = prior_grid(robot, parameter, method)
        # The profile's own range, bound to bound (the Warthog's 121.04-12104.34
        # N s/m, its mass-scaled prior), with the thesis' count of values.
        assert (grid[0], grid[-1]) == pytest.approx(robot.priors[parameter], rel=1e-12)
        assert len(grid) == GRID_POINTS[method] == {"onestep": 1000, "simulation": 100}[method]
        # Equal ratios: (high / low)^(1 / (n - 1)), 100^(1/99) = 1.0476 for a
        # mass-scaled prior's factor 100.
        low, high = robot.priors[parameter]
        step = (high / low) ** (1.0 / (len(grid) - 1))
        np.testing.assert_allclose(grid[1:] / grid[:-1], step, rtol=1e-9)


def test_the_default_grid_takes_overrides_and_refuses_what_is_no_damping_grid():
    grid = prior_grid(ROBOT, "d_long", "simulation", priors={"d_long": (5.0, 50.0)})
    assert (grid[0], grid[-1]) == pytest.approx((5.0, 50.0))
    with pytest.raises(InputError, match=r"parameter: a grid spans a damping.*'sigma_h'"):
        prior_grid(ROBOT, "sigma_h")
    with pytest.raises(InputError, match=r"method: unknown method 'mle'"):
        prior_grid(ROBOT, "d_lat", "mle")
    with pytest.raises(InputError, match=r"d_lat"):
        prior_grid(ROBOT, "d_lat", priors={"d_lat": (50.0, 5.0)})


#: Grids that leave out the truth (110, 30) N s/m on one side of one
#: damping's axis: (channel, that damping, its grid, the edge, its value).
#: The yaw rate's MSE along d_lat at the true d_long = 30 (a one-value axis)
#: is least at the truth; vx's pole and input depend on d_long alone (eq.
#: 4-29), so its MSE along d_long is least at the truth whatever d_lat.
EDGE_CASES = [
    ("yaw", "d_lat", (120.0, 200.0, 10.0), "low", 120.0),
    ("yaw", "d_lat", (50.0, 100.0, 10.0), "high", 100.0),
    ("vx", "d_long", (35.0, 60.0, 5.0), "low", 35.0),
    ("vx", "d_long", (10.0, 25.0, 5.0), "high", 25.0),
]


@pytest.mark.parametrize(("channel", "parameter", "values", "side", "value"), EDGE_CASES)
def test_a_minimum_outside_the_grid_is_flagged_on_its_edge(
    channel, parameter, values, side, value
):
    # With SMALL_NOISE the one-step minimum is the truth (the test above); a
    # grid without it has its minimum at the edge nearest to it. The other
    # axis is no search (yaw: the one value 30) or ties throughout (vx along
    # d_lat): no edge there.
    experiment = simulate_experiment(ROBOT, 110.0, 30.0, "v1", SMALL_NOISE, rng=2)
    other = {"yaw": damping_grid(30.0, 30.0, 5.0), "vx": damping_grid(50.0, 200.0, 10.0)}
    grids = {"d_lat": other[channel], "d_long": other[channel], parameter: damping_grid(*values)}
    result = grid_search([experiment], ROBOT, grids["d_lat"], grids["d_long"], "onestep", channel)
    assert result.edges() == {parameter: side}
    best = dict(zip(("d_lat", "d_long"), result.argmin()[:2], strict=True))
    assert best[parameter] == value
    (warning,) = result.edge_warnings()
    assert warning == {
        "kind": "grid-edge",
        "message": warning["message"],
        "method": "onestep",
        "parameter": parameter,
        "side": side,
        "value": value,
    }
    where = "below" if side == "low" else "above"
    assert f"lies on the {side} edge of the {parameter} grid" in warning["message"]
    assert f"lower {where} {parameter} = {value:g} N s/m" in warning["message"]
    summary = result.summary()
    assert summary["warnings"] == [warning] and summary["edge"] == {parameter: side}
    assert summary["series"]["v1"]["edge"] == summary["experiments"]["v1"]["edge"]


def test_an_axis_of_one_value_has_no_edge():
    # --d-lat 110 110 10 fixes d_lat: no search along it, so no edge there.
    experiment = simulate_experiment(ROBOT, 110.0, 30.0, "v1", SMALL_NOISE, rng=2)
    result = grid_search(
        [experiment], ROBOT, damping_grid(110, 110, 10), damping_grid(10, 50, 5), "onestep"
    )
    assert result.argmin()[:2] == (110.0, 30.0)
    assert result.edges() == {} and result.edge_warnings() == []
