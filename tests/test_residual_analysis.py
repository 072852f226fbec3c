"""Thesis ch. 7 residual analysis.

Residuals, the sigma_h fit, table 7-1, the ``residuals`` command. The generic
series statistics it reads are tested in test_series_statistics.py.
"""

import json
import re

import numpy as np
import pytest

from bayes_jackal import DataError, InputError, load_profile
from bayes_jackal._runtime.defaults import CHANNELS
from bayes_jackal.cli import main
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.io.simulate import NoiseSettings, simulate_experiment, simulate_series
from bayes_jackal.io.tables import read_csv, write_csv
from bayes_jackal.likelihood.residuals import channel_residuals
from bayes_jackal.model.kernels import get_family
from bayes_jackal.model.physics import channel_coefficients, discrete_matrices, one_step_residuals
from bayes_jackal.posterior.series_statistics import (
    autocorrelation_bounds,
    ljung_box,
    sample_autocorrelation,
)
from bayes_jackal.thesis.residual_analysis import (
    SIGMA_H_GRID,
    analyse,
    average_per_series,
    fit_sigma_h,
    sigma_h_table,
)

ROBOT = load_profile()
DT = 1.0 / 72.0
TRUTH = (110.0, 30.0)
NOISE_FREE = NoiseSettings(sigma_c=(0.0, 0.0, 0.0), sigma_n=(0.0, 0.0, 0.0))


@pytest.fixture(scope="module")
def noisy() -> Experiment:
    """A default (thesis-like, sensor noise included) v2 run."""
    return simulate_experiment(ROBOT, *TRUTH, "v2", rng=7)


def bartlett_covariance(rho: np.ndarray, lags: int, n: int) -> np.ndarray:
    """Covariance of the sample autocorrelations r_1..r_lags (Bartlett's formula).

    W_ij = sum_m a_i(m) a_j(m) / n with a_i(m) = rho_{m+i} + rho_{m-i} - 2 rho_i rho_m
    and rho zero past its last entry.
    """
    size = len(rho)
    m = np.arange(-size + 1, size)

    def at(k):
        return np.where(np.abs(k) < size, rho[np.minimum(np.abs(k), size - 1)], 0.0)

    i = np.arange(1, lags + 1)[:, None]
    terms = at(m + i) + at(m - i) - 2.0 * rho[i] * at(m)
    return terms @ terms.T / n


# --- residuals (eq. 7-3) ---------------------------------------------------------------------


@pytest.mark.parametrize("steady", [True, False])
def test_noise_free_residuals_with_the_true_damping_are_zero(steady):
    experiment = simulate_experiment(ROBOT, *TRUTH, "v1", NOISE_FREE, rng=1)
    for channel in CHANNELS:
        residuals = channel_residuals(experiment, ROBOT, *TRUTH, channel, steady=steady)
        window = experiment.steady() if steady else experiment
        y = window.channel(channel)
        assert residuals.shape == (len(y) - 1,)
        # The simulator's FFT convolution and the three residual terms round at
        # ~1e-16 of the signal (observed 3e-16); 1e-12 of the signal leaves margin.
        # (vy is identically zero in the model, so its residual is exactly 0.)
        np.testing.assert_allclose(residuals, 0.0, atol=1e-12 * np.max(np.abs(y)))
    # A wrong damping leaves the input response unexplained: residuals far from zero.
    wrong = channel_residuals(experiment, ROBOT, 300.0, 60.0, "yaw", steady=False)
    assert np.max(np.abs(wrong)) > 1e-3


def test_residuals_are_process_noise_plus_the_sensor_noise_footprint(noisy):
    # y = x + n and x[k+1] = alpha x[k] + Bd u[k] + p[k], so the residual is
    # w[k] = p[k] + n[k+1] - alpha n[k] (docs/design.md §4), exactly up to rounding.
    window = noisy.steady()
    for channel in CHANNELS:
        y = window.channel(channel)
        sensor = y - window.truth_arrays[f"{channel}_state"]
        process = window.truth_arrays[f"{channel}_process_noise"]
        alpha, _ = channel_coefficients(ROBOT, *TRUTH, channel, window.dt)
        expected = process[:-1] + sensor[1:] - alpha * sensor[:-1]
        residuals = channel_residuals(noisy, ROBOT, *TRUTH, channel, steady=True)
        # Same algebra, different rounding (FFT simulation ~1e-16 of the state).
        np.testing.assert_allclose(residuals, expected, rtol=0, atol=1e-12 * np.max(np.abs(y)))


def test_residuals_match_the_physics_module_and_vectorise_over_damping(noisy):
    window = noisy.steady()
    Ad, Bd = discrete_matrices(ROBOT, *TRUTH, window.dt)
    reference = one_step_residuals(Ad, Bd, window.states(), window.inputs)
    for i, channel in enumerate(CHANNELS):
        # Identical formulas evaluated in another order: rounding ~1e-16 of the signal.
        np.testing.assert_allclose(
            channel_residuals(noisy, ROBOT, *TRUTH, channel, steady=True),
            reference[:, i],
            rtol=0,
            atol=1e-13 * np.max(np.abs(window.channel(channel))),
        )
    d_lat = np.array([50.0, 110.0, 400.0])
    stacked = channel_residuals(noisy, ROBOT, d_lat, 30.0, steady=True)
    assert stacked.shape == (3, len(window.t) - 1)
    for row, value in zip(stacked, d_lat, strict=True):
        # A batched matrix product rounds differently: ~1e-17 on residuals ~1e-2.
        single = channel_residuals(noisy, ROBOT, value, 30.0, steady=True)
        np.testing.assert_allclose(row, single, rtol=0, atol=1e-15)


# --- sigma_h fit (eq. 7-6) --------------------------------------------------------------------


def test_fit_recovers_sigma_h_of_long_gaussian_coloured_noise():
    sigma_h, n, lags = 0.047, 200_000, 30
    x = get_family("gaussian").noise(sigma_h, DT, n, rng=12)
    fitted, curve = fit_sigma_h(x, DT, lags)
    assert curve.shape == SIGMA_H_GRID.shape
    assert fitted == SIGMA_H_GRID[np.argmin(curve)]
    # Tolerance: the fit returns a grid point (step 0.001 s; the truth is on the
    # grid, one step covers any rounding to a neighbour) plus 4 statistical sd.
    # The sd follows from the delta method on the least squares of eq. 7-6:
    # sd(sigma_hat) = sqrt(g' W g) / (g' g) with W the Bartlett covariance of
    # r_1..r_30 and g = d rho / d sigma_h = rho tau^2 / (2 sigma_h^3) of the
    # continuous form exp(-tau^2 / (4 sigma_h^2)); about 5.5e-4 s here.
    rho = get_family("gaussian").autocorrelation(sigma_h, DT, 200)
    tau = np.arange(1, lags + 1) * DT
    g = np.exp(-(tau**2) / (4 * sigma_h**2)) * tau**2 / (2 * sigma_h**3)
    sd = np.sqrt(g @ bartlett_covariance(rho, lags, n) @ g) / (g @ g)
    assert 3e-4 < sd < 1e-3
    assert abs(fitted - sigma_h) <= 0.001 + 4 * sd


def test_fit_is_vectorised_and_takes_a_grid():
    rng = np.random.default_rng(2)
    x = np.stack([get_family("gaussian").noise(w, DT, 3000, rng=rng) for w in (0.03, 0.1)])
    fitted, curves = fit_sigma_h(x, DT)
    assert fitted.shape == (2,)
    assert curves.shape == (2, len(SIGMA_H_GRID))
    for row, value, curve in zip(x, fitted, curves, strict=True):
        alone, alone_curve = fit_sigma_h(row, DT)
        assert alone == value
        np.testing.assert_array_equal(alone_curve, curve)
    grid = np.array([0.02, 0.1, 0.5])
    coarse, coarse_curve = fit_sigma_h(x[1], DT, grid=grid)
    assert coarse == 0.1
    # The coarse curve is the fine curve at the same sigma_h values (same formula).
    np.testing.assert_allclose(coarse_curve, curves[1][[19, 99, 499]], rtol=1e-12)


def test_sensor_noise_biases_the_thesis_fit_low():
    # The thesis ignores the sensor noise (ch. 7-2-2). With it, the yaw residual
    # is p[k] + n[k+1] - a n[k]: a white spike at lag 0 and -a sigma_n^2 at lag 1
    # (a = Ad = 0.724) scale the autocorrelation down, so eq. 7-6 picks a
    # narrower Gaussian. Fitting the thesis' curve to the population
    # autocorrelation of the default simulation (sigma_c 0.01, sigma_n 0.005
    # rad/s, truth sigma_h 0.047 s) gives 0.037 s. Measured with the thesis
    # procedure on default simulated runs (truth d, seed 1): v1 0.040 s,
    # v2 0.043 s; on their true process noise alone 0.052 s and 0.058 s (the
    # single-run scatter of the fit is ~0.004 s). Seeds 1..8 give 0.031..0.043 s.
    fits = {}
    for series in ("v1", "v2"):
        experiment = simulate_experiment(ROBOT, *TRUTH, series, rng=1)
        measured = fit_sigma_h(channel_residuals(experiment, ROBOT, *TRUTH, steady=True), DT)[0]
        process = experiment.steady().truth_arrays["yaw_process_noise"]
        fits[series] = (float(measured), float(fit_sigma_h(process, DT)[0]))
    # Paired: the same process noise with and without the sensor noise. The
    # population bias (0.010 s) is what separates them, not the scatter.
    for measured, process in fits.values():
        assert measured < process


# --- table 7-1 ---------------------------------------------------------------------------------


def test_average_per_series_is_the_thesis_arithmetic():
    # Ten v1 runs at 0.051 s and five v2 runs at 0.041 s (table 7-1): the mean
    # over all 15 runs is (10 * 0.051 + 5 * 0.041) / 15 = 0.047667 s. The
    # thesis prints 0.047, the mean of the two series means is 0.046.
    values = {f"v1_{i:02d}": 0.051 for i in range(10)} | {f"v2_{i:02d}": 0.041 for i in range(5)}
    labels = {name: name[:2] for name in values}
    table = average_per_series(values, labels)
    # Means of at most 15 floats: summation rounding below 1e-16 * 15.
    assert table["series"]["v1"] == pytest.approx(0.051, abs=1e-15)
    assert table["series"]["v2"] == pytest.approx(0.041, abs=1e-15)
    assert table["all"] == pytest.approx(0.715 / 15, abs=1e-15)
    assert table["members"]["v2"] == [f"v2_{i:02d}" for i in range(5)]
    unlabelled = average_per_series({"a": 0.01, "b": 0.03}, {"a": None, "b": None})
    assert unlabelled["series"] == {"unlabelled": pytest.approx(0.02, abs=1e-15)}
    with pytest.raises(InputError, match="experiments"):
        average_per_series({}, {})


def test_sigma_h_table_fits_each_experiment_and_averages_per_series():
    experiments = simulate_series(ROBOT, *TRUTH, {"v1": 2, "v2": 1}, rng=21)
    table = sigma_h_table(experiments, ROBOT, *TRUTH)
    assert list(table["experiments"]) == ["v1_01", "v1_02", "v2_01"]
    for experiment in experiments:
        residuals = channel_residuals(experiment, ROBOT, *TRUTH, steady=True)
        assert table["experiments"][experiment.name] == fit_sigma_h(residuals, DT)[0]
    values = table["experiments"]
    # Grid values averaged: rounding of 2 or 3 summands, far below 1e-15.
    assert table["series"]["v1"] == pytest.approx(
        (values["v1_01"] + values["v1_02"]) / 2, abs=1e-15
    )
    assert table["series"]["v2"] == values["v2_01"]
    assert table["all"] == pytest.approx(sum(values.values()) / 3, abs=1e-15)
    assert table["members"] == {"v1": ["v1_01", "v1_02"], "v2": ["v2_01"]}
    assert table["lags"] == 30


def test_analyse_summarises_every_experiment_and_channel(noisy):
    result = analyse([noisy], ROBOT, *TRUTH, ["yaw", "vx"], lags=20)
    json.dumps(result)  # JSON-ready
    row = result["experiments"]["v2"]["yaw"]
    residuals = channel_residuals(noisy, ROBOT, *TRUTH, steady=True)
    q, p = ljung_box(residuals, 20)
    assert row["n"] == len(residuals)
    assert row["mean"] == pytest.approx(np.mean(residuals), rel=1e-12)
    assert row["sd"] == pytest.approx(np.std(residuals, ddof=1), rel=1e-12)
    assert (row["ljung_box_q"], row["ljung_box_p"]) == (pytest.approx(q), pytest.approx(p))
    np.testing.assert_allclose(
        row["autocorrelation"], sample_autocorrelation(residuals, 20)[1:6], rtol=1e-12
    )
    assert row["bound"] == autocorrelation_bounds(len(residuals))
    assert row["sigma_h"] == fit_sigma_h(residuals, DT, 20)[0]
    assert set(result["experiments"]["v2"]) == {"yaw", "vx"}
    assert result["sigma_h"] == {"v2": row["sigma_h"], "all": row["sigma_h"]}
    # Without the yaw channel the table is still the yaw fit (thesis table 7-1).
    assert analyse([noisy], ROBOT, *TRUTH, ["vx"], lags=20)["sigma_h"] == result["sigma_h"]


# --- bad input --------------------------------------------------------------------------------


def test_window_shorter_than_the_lags_names_the_file_and_lag_count(tmp_path):
    path = write_csv(simulate_experiment(ROBOT, *TRUTH, "v2", rng=1), tmp_path / "short.csv")
    experiment = read_csv(path)
    n = len(experiment.t)
    for call in (
        lambda lags: analyse([experiment], ROBOT, *TRUTH, ["yaw"], lags),
        lambda lags: sigma_h_table([experiment], ROBOT, *TRUTH, lags),
    ):
        with pytest.raises(DataError, match=rf"{re.escape(str(path))}: lags: .*{n - 1} lags"):
            call(n - 1)  # n samples give n - 1 residuals: one short of n - 1 lags
        call(n - 2)  # the shortest window that works


def test_constant_channel_names_the_file_and_channel(tmp_path):
    t = np.arange(200) * DT
    experiment = Experiment(
        t=t,
        yaw_rate=np.full_like(t, 0.25),
        omega_r=np.full_like(t, 3.0),
        omega_l=np.full_like(t, 2.0),
        vx=np.sin(t),
    )
    path = write_csv(experiment, tmp_path / "stuck_imu.csv")
    loaded = read_csv(path)
    pattern = rf"{re.escape(str(path))}: yaw_rate: channel 'yaw' is constant"
    with pytest.raises(DataError, match=pattern):
        analyse([loaded], ROBOT, *TRUTH, ["yaw"], 30)
    with pytest.raises(DataError, match=pattern):
        sigma_h_table([loaded], ROBOT, *TRUTH)
    # A channel the file does not have is named too.
    with pytest.raises(DataError, match=rf"{re.escape(str(path))}: vy: .*'vy'"):
        analyse([loaded], ROBOT, *TRUTH, ["vy"], 30)


@pytest.mark.parametrize("lags", [0, -3, 1.5, True])
def test_bad_lag_counts_are_rejected(noisy, lags):
    x = np.random.default_rng(0).standard_normal(100)
    for call in (
        lambda: sample_autocorrelation(x, lags),
        lambda: ljung_box(x, lags),
        lambda: fit_sigma_h(x, DT, lags),
        lambda: analyse([noisy], ROBOT, *TRUTH, ["yaw"], lags),
        lambda: sigma_h_table([noisy], ROBOT, *TRUTH, lags),
    ):
        with pytest.raises(InputError, match="lags: number of lags must be an integer >= 1"):
            call()


def test_bad_arrays_and_arguments_are_rejected(noisy):
    x = np.random.default_rng(0).standard_normal(100)
    with pytest.raises(InputError, match=r"lags: 100 samples are too few for 100 lags"):
        sample_autocorrelation(x, 100)
    with pytest.raises(InputError, match="x: series is constant"):
        ljung_box(np.full(50, 2.0), 5)
    with pytest.raises(InputError, match="x: series holds non-finite"):
        sample_autocorrelation(np.append(x, np.nan), 5)
    with pytest.raises(InputError, match=r"dt: .*-0\.1"):
        fit_sigma_h(x, -0.1)
    with pytest.raises(InputError, match=r"grid: .*-0\.01"):
        fit_sigma_h(x, DT, grid=[0.1, -0.01])
    with pytest.raises(InputError, match=r"channels: .*'yaw_rate'"):
        analyse([noisy], ROBOT, *TRUTH, ["yaw_rate"])
    with pytest.raises(InputError, match=r"d_lat: .*-5"):
        analyse([noisy], ROBOT, -5.0, 30.0)
    with pytest.raises(InputError, match=r"name: .*'v2'"):
        analyse([noisy, noisy], ROBOT, *TRUTH)
    with pytest.raises(InputError, match="experiments"):
        sigma_h_table([], ROBOT, *TRUTH)


# --- command line -----------------------------------------------------------------------------


def test_cli_residuals_json(simulated, capsys):
    code = main(["residuals", *simulated, "--channels", "yaw,vx,vy", "--lags", "25", "--json"])
    captured = capsys.readouterr()
    assert code == 0
    payload = json.loads(captured.out)
    assert payload["d_lat"] == 110.0
    assert payload["d_long"] == 30.0
    assert payload["lags"] == 25
    assert set(payload["experiments"]) == {"v1_01", "v2_01"}
    for channels in payload["experiments"].values():
        assert set(channels) == {"yaw", "vx", "vy"}
        for row in channels.values():
            assert set(row) == {
                "n",
                "mean",
                "sd",
                "ljung_box_q",
                "ljung_box_p",
                "autocorrelation",
                "bound",
                "sigma_h",
                "derived",
            }
            assert row["derived"] is False  # simulated experiment files: measured velocities
            assert len(row["autocorrelation"]) == 5
            assert 0.0 < row["sigma_h"] <= 1.0
    assert set(payload["sigma_h"]) == {"v1", "v2", "all"}
    yaw = {name: rows["yaw"]["sigma_h"] for name, rows in payload["experiments"].items()}
    assert payload["sigma_h"]["v1"] == yaw["v1_01"]
    assert payload["sigma_h"]["all"] == pytest.approx((yaw["v1_01"] + yaw["v2_01"]) / 2)
    assert "Ljung-Box" in captured.err


def test_cli_residuals_text_goes_to_stdout(simulated, capsys):
    code = main(["residuals", *simulated])
    captured = capsys.readouterr()
    assert code == 0
    assert captured.err == ""
    lines = captured.out.splitlines()
    assert sum(line.startswith(("v1_01 ", "v2_01 ")) for line in lines) == 2
    assert any(re.match(r"all\s+2\s+0\.\d{4}$", line) for line in lines)


def test_cli_residuals_too_many_lags_is_bad_input(simulated, capsys):
    code = main(["residuals", *simulated, "--lags", "100000", "--json"])
    captured = capsys.readouterr()
    assert code == 2
    assert "Traceback" not in captured.err
    # Each input on its own (README, "Your data is safe"): both are named, with the reason.
    errors = [line for line in captured.err.splitlines() if line.startswith("bayes-jackal: ")]
    assert len(errors) == 2, captured.err
    for path, line in zip(simulated, errors, strict=True):
        assert line.startswith(f"bayes-jackal: error: {path}: ") and "100000 lags" in line
    assert json.loads(captured.out) == {
        "experiments": {},
        "failed": {
            path: errors[i].removeprefix("bayes-jackal: error: ")
            for i, path in enumerate(simulated)
        },
    }


def test_pose_channels_are_analysed_on_their_derived_velocities(tmp_path):
    # The thesis analysed velocities derived from motion capture (eq. 7-3 on
    # a measured state): a bag's vx is analysed so and flagged, and its
    # residuals are those of the bag's derived vx under the rate model.
    import dataclasses

    from bayes_jackal.io.bag_writer import write_bag
    from bayes_jackal.io.bags import read_bag
    from bayes_jackal.likelihood.residuals import channel_residuals

    robot = load_profile()
    run = simulate_experiment(robot, 110.0, 30.0, "v2", rng=3)
    bag = read_bag(write_bag(run, tmp_path / "v2.bag", robot, "ros1", rng=3), robot)
    row = analyse([bag], robot, 110.0, 30.0, channels=("yaw", "vx"))["experiments"]["v2"]
    assert row["vx"]["derived"] is True and row["yaw"]["derived"] is False
    derived = channel_residuals(
        dataclasses.replace(bag, pose=None), robot, 110.0, 30.0, "vx", steady=True
    )
    assert row["vx"]["n"] == len(derived)
    assert row["vx"]["sd"] == pytest.approx(np.std(derived, ddof=1))
