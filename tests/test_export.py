"""Active Inference export: generalised-coordinate covariances and the prior file."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest
import scipy.integrate
import scipy.signal
from synthetic_posteriors import posterior_at

from bayes_jackal import InputError, load_profile
from bayes_jackal.cli import main
from bayes_jackal.dem.consumer_keys import operating_point
from bayes_jackal.dem.export import (
    MAX_CONDITION,
    allowed_orders,
    autocorrelation_derivatives,
    export_prior,
    temporal_covariance,
)
from bayes_jackal.dem.prior_fields import PRIOR_FORMAT
from bayes_jackal.filters.state_space import channel_model, filter_models
from bayes_jackal.inference.chains import SamplerSettings
from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
from bayes_jackal.inference.sampling import sample_posterior
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.io.simulate import simulate_experiment
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.model.physics import continuous_matrices, discrete_matrices
from bayes_jackal.posterior.posterior import save_posterior

ROBOT = load_profile()
SHORT = SamplerSettings(max_steps=120, check_every=40, design_points=256)


def test_gaussian_covariance_is_the_closed_form():
    s = np.array([0.02, 0.047, 0.3])
    V = temporal_covariance("gaussian", s, 2)
    # rho(t) = exp(-t^2 / (4 s^2)): rho''(0) = -1/(2 s^2), rho''''(0) = 3/(4 s^4).
    second, fourth = -1 / (2 * s**2), 3 / (4 * s**4)
    expected = np.zeros((3, 3, 3))
    expected[:, 0, 0] = 1
    expected[:, 0, 2] = expected[:, 2, 0] = second
    expected[:, 1, 1] = -second
    expected[:, 2, 2] = fourth
    np.testing.assert_allclose(V, expected, rtol=1e-12)
    # Order 4: rho^(6)(0) = -15/(8 s^6) and rho^(8)(0) = 105/(16 s^8).
    derivatives = autocorrelation_derivatives("gaussian", 0.1, 4)
    np.testing.assert_allclose(derivatives[::2], [1, -50, 7500, -1.875e6, 6.5625e8], rtol=1e-12)
    np.testing.assert_array_equal(derivatives[1::2], 0)


@pytest.mark.parametrize(
    ("family", "kernel", "reach"),
    [
        ("gaussian", lambda t, w: np.exp(-(t**2) / (2 * w**2)), 12.0),
        ("triangular", lambda t, w: np.clip(1 - np.abs(t) / w, 0, None), 1.0),
    ],
)
def test_second_derivative_is_minus_the_kernel_slope_energy(family, kernel, reach):
    # rho''(0) = -int k'(t)^2 dt / int k(t)^2 dt for the kernel k: an
    # independent quadrature of the kernels' derivatives. The central
    # difference (h = 1e-7 s) errs by ~h^2 relative plus rounding ~1e-16 / h,
    # both below 1e-8; 1e-6 leaves room for the quadrature.
    w = 0.08
    h = 1e-7

    def slope(t):
        return (kernel(t + h, w) - kernel(t - h, w)) / (2 * h)

    limits = (-reach * w, reach * w)
    energy = scipy.integrate.quad(lambda t: kernel(t, w) ** 2, *limits, points=[0])[0]
    slope_energy = scipy.integrate.quad(lambda t: slope(t) ** 2, *limits, points=[0])[0]
    rho2 = autocorrelation_derivatives(family, w, 1)[2]
    assert rho2 == pytest.approx(-slope_energy / energy, rel=1e-6)


def test_simulated_smooth_noise_has_the_exported_covariance():
    # Unit-variance noise through an (untruncated, +-8 s) Gaussian kernel at
    # dt = s/40; central differences give w' and w''. Their discretisation
    # bias is ~(dt/s)^2 / 2 = 3e-4. 400,000 samples span 10,000 kernel
    # widths: the variance estimates have relative sd of a few per cent,
    # so 12 % is over 4 sd.
    s, dt, n = 0.05, 0.05 / 40, 400_000
    rng = np.random.default_rng(8)
    t = np.arange(-8 * s, 8 * s + dt / 2, dt)
    taps = np.exp(-(t**2) / (2 * s**2))
    taps /= np.sqrt(np.sum(taps**2))
    w = scipy.signal.fftconvolve(rng.standard_normal(n + len(t)), taps, mode="valid")
    coordinates = np.stack(
        [w[1:-1], (w[2:] - w[:-2]) / (2 * dt), (w[2:] - 2 * w[1:-1] + w[:-2]) / dt**2]
    )
    empirical = np.cov(coordinates)
    V = temporal_covariance("gaussian", s, 2)
    scale = np.sqrt(np.outer(np.diag(V), np.diag(V)))
    np.testing.assert_allclose(empirical[V != 0], V[V != 0], rtol=0.12)
    # Odd pairs are uncorrelated: |correlation| below 0.05 (> 4 sd of ~0.01).
    assert np.all(np.abs((empirical / scale)[V == 0]) < 0.05)


@pytest.mark.parametrize(
    ("family", "order", "pattern"),
    [
        ("exponential", 1, "exponential family.*up to order 0"),
        ("moving-average", 2, "up to order 0"),
        ("white", 1, "up to order 0"),
        ("triangular", 2, "up to order 1"),
        ("gaussian", -1, "integer >= 0"),
    ],
)
def test_orders_a_family_cannot_give_are_refused(family, order, pattern):
    with pytest.raises(InputError, match=pattern):
        temporal_covariance(family, 0.1, order)


# yaw_vx_posterior: tests/conftest.py's (a 120-step chain on yaw and vx of a
# simulated v2 run, seed 3, as SHORT here).


def test_exported_precision_is_the_draw_average_of_kronecker_products(yaw_vx_posterior):
    prior = export_prior(yaw_vx_posterior, order=2)
    assert prior["format"] == PRIOR_FORMAT
    channels = prior["noise"]["channels"]
    assert channels == ["yaw", "vx"]
    post = yaw_vx_posterior.posterior
    d_lat, d_long = post["d_lat"].values.ravel(), post["d_long"].values.ravel()
    sigma_h = post["sigma_h"].transpose("chain", "draw", "noise_group").values.reshape(-1, 2)
    sigma_c = post["sigma_c"].transpose("chain", "draw", "noise_group").values.reshape(-1, 2)
    # The obviously-right reference: one draw at a time, np.kron of
    # inv(V_c) with e_c e_c' / s_c^2, s_c the continuous-time sd.
    total = np.zeros((6, 6))
    for k in range(len(d_lat)):
        A, _ = continuous_matrices(ROBOT, d_lat[k], d_long[k])
        Ad, _ = discrete_matrices(ROBOT, d_lat[k], d_long[k], ROBOT.dt)
        for c, channel in enumerate(channels):
            i = ["vx", "vy", "yaw"].index(channel)
            s_c = sigma_c[k, c] * A[i, i] / (Ad[i, i] - 1)
            unit = np.zeros((2, 2))
            unit[c, c] = 1 / s_c**2
            total += np.kron(
                np.linalg.inv(temporal_covariance("gaussian", sigma_h[k, c], 2)), unit
            )
    np.testing.assert_allclose(
        prior["generalised_coordinates"]["precision"], total / len(d_lat), rtol=1e-10
    )
    # The model is at the posterior mean of the damping; C = I.
    A, B = continuous_matrices(ROBOT, d_lat.mean(), d_long.mean())
    np.testing.assert_allclose(prior["model"]["A"], A, rtol=1e-12)
    np.testing.assert_allclose(prior["model"]["B"], B, rtol=1e-12)
    np.testing.assert_array_equal(prior["model"]["C"], np.eye(3))
    np.testing.assert_allclose(prior["damping"]["mean"], [d_lat.mean(), d_long.mean()])
    np.testing.assert_allclose(prior["damping"]["covariance"], np.cov(d_lat, d_long))
    assert prior["draws"]["count"] == min(len(d_lat), 1000)
    assert set(prior["noise"]["parameters"]) == {
        f"{base}[{c}]" for base in ("sigma_h", "sigma_c", "sigma_n") for c in ("yaw", "vx")
    }


@pytest.fixture(scope="module")
def white_diagonal_posterior():
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)
    likelihood = ResidualLikelihood(
        [run], ROBOT, family="white", sensor="diagonal", channels=("yaw", "vx")
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        return sample_posterior(likelihood, SHORT, seed=1)


def test_white_noise_with_the_diagonal_term_exports_one_total_sd(
    white_diagonal_posterior, yaw_vx_posterior
):
    # That model has one variance per channel: sigma_c is the total sd, and
    # there is no sigma_n anywhere in the posterior or the prior.
    assert "sigma_n" not in white_diagonal_posterior.posterior
    prior = export_prior(white_diagonal_posterior, order=0)
    noise = prior["noise"]
    assert noise["sigma_c_is"] == "total"
    assert set(noise["parameters"]) == {"sigma_c[yaw]", "sigma_c[vx]"}
    assert set(prior["draws"]) == {"count", "d_lat", "d_long", "sigma_c[yaw]", "sigma_c[vx]"}
    # Pi = diag(1 / s_c^2) averaged over draws, s_c = sigma_c A / (Ad - 1), V = 1.
    post = white_diagonal_posterior.posterior
    d_lat, d_long = post["d_lat"].values.ravel(), post["d_long"].values.ravel()
    sigma_c = post["sigma_c"].transpose("chain", "draw", "noise_group").values.reshape(-1, 2)
    A, _ = continuous_matrices(ROBOT, d_lat, d_long)
    Ad, _ = discrete_matrices(ROBOT, d_lat, d_long, ROBOT.dt)
    index = [2, 0]  # yaw, vx
    pole = A[:, index, index]
    s_c = sigma_c * pole / (Ad[:, index, index] - 1)
    np.testing.assert_allclose(
        prior["generalised_coordinates"]["precision"], np.diag((1 / s_c**2).mean(axis=0))
    )
    assert export_prior(yaw_vx_posterior, order=0)["noise"]["sigma_c_is"] == "process"


def test_one_width_is_exported_as_one_parameter_the_filters_read():
    # --noise one-width: one sigma_h for yaw and vx. The prior says so, has
    # one sigma_h, one smoothness, and its filters all take that one width.
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)
    theta = [110.0, 30.0, 0.047, 0.01, 0.005, 0.005, 0.003]
    posterior = posterior_at([run], theta, channels=("yaw", "vx"), shared_width=True)
    assert "noise_group" not in posterior.posterior["sigma_h"].dims
    prior = export_prior(posterior, order=2)
    noise = prior["noise"]
    assert noise["shared_width"] is True
    per_channel = {f"{b}[{c}]" for b in ("sigma_c", "sigma_n") for c in ("yaw", "vx")}
    assert set(noise["parameters"]) == {"sigma_h", *per_channel}
    assert set(prior["draws"]) == {"count", "d_lat", "d_long", "sigma_h", *per_channel}
    # The Gaussian's smoothness is sigma_h: one value, both channels.
    sigma_h = posterior.posterior["sigma_h"].values
    smoothness = prior["smoothness"]
    assert smoothness["channels"]["yaw"] == smoothness["channels"]["vx"]
    assert smoothness["shared_seconds"] == pytest.approx(sigma_h.mean(), rel=1e-12)
    models = filter_models(prior)
    Ad, Bd = np.array(prior["model"]["Ad"]), np.array(prior["model"]["Bd"])
    mean = {name: value["mean"] for name, value in noise["parameters"].items()}
    for channel, i in (("yaw", 2), ("vx", 0)):
        reference = channel_model(
            channel, Ad[i, i], Bd[i], family="gaussian", width=mean["sigma_h"],
            sigma_c=mean[f"sigma_c[{channel}]"], sigma_n=mean[f"sigma_n[{channel}]"],
            dt=prior["dt"],
        )  # fmt: skip
        for field in dataclasses.fields(reference):
            np.testing.assert_array_equal(
                getattr(models[channel], field.name), getattr(reference, field.name)
            )
    averaged = filter_models(prior, parameters="averaged")
    assert list(averaged) == ["yaw", "vx"]
    # A width per channel: not shared.
    apart = posterior_at(
        [run], [*theta[:2], 0.047, *theta[3:5], 0.047, *theta[5:]], channels=("yaw", "vx")
    )
    assert export_prior(apart, order=0)["noise"]["shared_width"] is False


def test_export_prior_command_writes_versioned_json(yaw_vx_posterior, tmp_path, capsys):
    posterior = save_posterior(yaw_vx_posterior, tmp_path / "posterior.nc")
    before = posterior.read_bytes()
    out = tmp_path / "prior.json"
    code = main(["export-prior", str(posterior), "--out", str(out), "--order", "3"])
    captured = capsys.readouterr()
    assert code == 0
    prior = json.loads(out.read_text())
    assert prior["format"] == PRIOR_FORMAT
    assert prior["generalised_coordinates"]["order"] == 3
    assert np.shape(prior["generalised_coordinates"]["precision"]) == (8, 8)
    # The short chain did not converge: the file and the terminal say so.
    assert prior["converged"] is False
    assert "NOT CONVERGED" in captured.err
    assert posterior.read_bytes() == before


def test_export_prior_bad_input(yaw_vx_posterior, tmp_path, capsys):
    posterior = save_posterior(yaw_vx_posterior, tmp_path / "posterior.nc")
    code = main(["export-prior", str(tmp_path / "missing.nc"), "--out", str(tmp_path / "p.json")])
    assert code == 2
    assert "missing.nc" in capsys.readouterr().err
    not_posterior = tmp_path / "notes.nc"
    not_posterior.write_text("hello")
    code = main(["export-prior", str(not_posterior), "--out", str(tmp_path / "p.json")])
    assert code == 2
    assert "notes.nc" in capsys.readouterr().err
    code = main(
        ["export-prior", str(posterior), "--out", str(tmp_path / "p.json"), "--order", "-2"]
    )
    assert code == 2
    assert "order" in capsys.readouterr().err
    assert not (tmp_path / "p.json").exists()


def test_orders_whose_precision_is_ill_conditioned_are_refused(yaw_vx_posterior, tmp_path, capsys):
    # The real computation: the highest allowed order exports a finite
    # precision whose condition number is below the bound; the next one is
    # refused naming the allowed orders. Order 99 (NaN/Infinity before) too;
    # the command line refuses the next order the same way (order 99 through
    # the command line, ~3 s: tests/reliability_cases.py).
    post = yaw_vx_posterior.posterior
    sigma_h = post["sigma_h"].transpose("chain", "draw", "noise_group").values.reshape(-1, 2)
    allowed = allowed_orders("gaussian", sigma_h, np.ones_like(sigma_h))
    assert allowed == list(range(len(allowed))) and 3 <= allowed[-1] < 8
    top = export_prior(yaw_vx_posterior, order=allowed[-1])["generalised_coordinates"]
    size = 2 * (allowed[-1] + 1)
    assert np.isfinite(top["precision"]).all() and np.shape(top["precision"]) == (size, size)
    blocks = np.asarray(top["precision"])[np.ix_(range(0, size, 2), range(0, size, 2))]
    assert 1e-4 * MAX_CONDITION < np.linalg.cond(blocks) < MAX_CONDITION
    listed = ", ".join(map(str, allowed))
    for order in (allowed[-1] + 1, 99):
        with pytest.raises(
            InputError, match=rf"order: order {order} .*allowed here are {listed}$"
        ):
            export_prior(yaw_vx_posterior, order=order)
    posterior = save_posterior(yaw_vx_posterior, tmp_path / "posterior.nc")
    out = tmp_path / "prior.json"
    next_order = str(allowed[-1] + 1)
    assert main(["export-prior", str(posterior), "--out", str(out), "--order", next_order]) == 2
    assert f"allowed here are {listed}" in capsys.readouterr().err
    assert not out.exists()
    # White noise: order 0 only, as before (its noise has no derivative).
    assert allowed_orders("white", np.ones((3, 1)), np.ones((3, 1))) == [0]


def test_exported_prior_is_strict_json(yaw_vx_posterior, tmp_path):
    posterior = save_posterior(yaw_vx_posterior, tmp_path / "posterior.nc")
    out = tmp_path / "prior.json"
    assert main(["export-prior", str(posterior), "--out", str(out)]) == 0

    def refuse(constant):
        raise ValueError(f"not JSON: {constant}")

    assert json.loads(out.read_text(), parse_constant=refuse)["format"] == PRIOR_FORMAT


# --- what the consumers need beside Pi (export_consumers) ---------------------------------


def _group_draws(posterior, name):
    """Draws of a per-channel parameter, shaped (draws, channels)."""
    values = posterior.posterior[name].transpose("chain", "draw", "noise_group").values
    return values.reshape(-1, values.shape[-1])


def _closed_form_gaussian_precision(k):
    # inv of V = [[1, 0, -k], [0, k, 0], [-k, 0, 3 k^2]], k = 1 / (2 s^2): the
    # even block [[1, -k], [-k, 3 k^2]] has determinant 2 k^2.
    k = np.asarray(k, float)
    inverse = np.zeros((*k.shape, 3, 3))
    inverse[..., 0, 0] = 1.5
    inverse[..., 0, 2] = inverse[..., 2, 0] = 1 / (2 * k)
    inverse[..., 1, 1] = 1 / k
    inverse[..., 2, 2] = 1 / (2 * k**2)
    return inverse


@pytest.mark.parametrize("smoothness", [0.5, 1.5])
def test_sensor_precision_is_the_closed_form(yaw_vx_posterior, smoothness):
    dt = ROBOT.dt
    prior = export_prior(yaw_vx_posterior, order=2, sensor_smoothness=smoothness)
    sensor = prior["sensor_noise"]
    assert sensor["channels"] == ["yaw", "vx"]
    assert sensor["smoothness_bins"] == smoothness
    assert sensor["smoothness_seconds"] == pytest.approx(smoothness * dt, rel=1e-10)
    precision = (1 / _group_draws(yaw_vx_posterior, "sigma_n") ** 2).mean(axis=0)
    np.testing.assert_allclose(sensor["precision_per_channel"], precision, rtol=1e-12)
    # Pi_z = inv(V(s_z)) kron diag(E[1 / sigma_n^2]), V in bins at k = 1 / (2 s_z^2)
    # and in seconds at k / dt^2 (s_z dt seconds).
    k = 1 / (2 * smoothness**2)
    for key, scale in (("precision_bins", 1.0), ("precision", dt**2)):
        expected = np.kron(_closed_form_gaussian_precision(k / scale), np.diag(precision))
        np.testing.assert_allclose(sensor[key], expected, rtol=1e-10, atol=0)
    np.testing.assert_allclose(
        sensor["temporal_covariance"],
        [[1, 0, -k / dt**2], [0, k / dt**2, 0], [-k / dt**2, 0, 3 * k**2 / dt**4]],
        rtol=1e-9,
    )


@pytest.mark.parametrize("smoothness", [0.0, -1.0, float("nan"), float("inf"), "half"])
def test_bad_sensor_smoothness_is_refused(yaw_vx_posterior, smoothness):
    with pytest.raises(InputError, match="sensor_smoothness: sensor smoothness must be"):
        export_prior(yaw_vx_posterior, order=0, sensor_smoothness=smoothness)


def test_white_noise_without_sigma_n_has_no_sensor_precision(white_diagonal_posterior):
    prior = export_prior(white_diagonal_posterior, order=0)
    assert prior["sensor_noise"] is None
    assert prior["log_precision"]["sensor"] is None
    # White noise has no derivative, so no smoothness describes it.
    assert prior["smoothness"] == {"channels": None, "shared_seconds": None, "shared_bins": None}


def test_bins_are_seconds_rescaled_by_the_sample_time(yaw_vx_posterior):
    prior = export_prior(yaw_vx_posterior, order=2)
    dt = prior["dt"]  # the profile's 1 / 72 s, rounded to 12 digits
    coordinates = prior["generalised_coordinates"]
    sigma_h = _group_draws(yaw_vx_posterior, "sigma_h")
    # Derivative i in bins is dt^i times the one in seconds: V_bins = dt^(i+j) V,
    # the closed form at k = dt^2 / (2 sigma_h^2); inv(V) in bins is the closed form.
    k = dt**2 / (2 * sigma_h**2)  # (draws, channels)
    V = np.zeros((*k.shape, 3, 3))
    V[..., 0, 0] = 1
    V[..., 0, 2] = V[..., 2, 0] = -k
    V[..., 1, 1] = k
    V[..., 2, 2] = 3 * k**2
    np.testing.assert_allclose(coordinates["temporal_covariance_bins"], V.mean(axis=0), rtol=1e-10)
    np.testing.assert_allclose(
        coordinates["temporal_precision_bins"],
        _closed_form_gaussian_precision(k).mean(axis=0),
        rtol=1e-10,
    )
    # The model per bin, dx/dk = (A dt) x + (B dt) u + dt w: its noise dt w has
    # precision Pi[i, j] / dt^(i+j+2). Both come from separate inversions of V
    # (condition ~1e8 in seconds): 1e-7.
    derivative = np.repeat(np.arange(3), 2)
    scale = dt ** (np.add.outer(derivative, derivative) + 2)
    np.testing.assert_allclose(
        np.asarray(coordinates["precision_bins"]) * scale, coordinates["precision"], rtol=1e-7
    )
    np.testing.assert_allclose(prior["model"]["A_bins"], np.asarray(prior["model"]["A"]) * dt)
    np.testing.assert_allclose(prior["model"]["B_bins"], np.asarray(prior["model"]["B"]) * dt)
    # The Gaussian family's smoothness is sigma_h; in bins sigma_h / dt.
    smoothness = prior["smoothness"]
    for c, channel in enumerate(["yaw", "vx"]):
        row = smoothness["channels"][channel]
        assert row["seconds"]["mean"] == pytest.approx(sigma_h[:, c].mean(), rel=1e-12)
        assert row["seconds"]["sd"] == pytest.approx(sigma_h[:, c].std(), rel=1e-10)
        assert row["bins"]["mean"] == pytest.approx(sigma_h[:, c].mean() / dt, rel=1e-12)
    assert smoothness["shared_seconds"] == pytest.approx(sigma_h.mean(), rel=1e-12)


def test_log_precision_moments_are_the_draws(yaw_vx_posterior):
    prior = export_prior(yaw_vx_posterior, order=0)
    moments = prior["log_precision"]
    assert moments["channels"] == ["yaw", "vx"]
    post = yaw_vx_posterior.posterior
    d_lat, d_long = post["d_lat"].values.ravel(), post["d_long"].values.ravel()
    sigma_c = _group_draws(yaw_vx_posterior, "sigma_c")
    sigma_n = _group_draws(yaw_vx_posterior, "sigma_n")
    # s_c = sigma_c A / (Ad - 1), one draw at a time, as the test above.
    s_c = np.empty_like(sigma_c)
    for k in range(len(d_lat)):
        A, _ = continuous_matrices(ROBOT, d_lat[k], d_long[k])
        Ad, _ = discrete_matrices(ROBOT, d_lat[k], d_long[k], ROBOT.dt)
        for c, i in enumerate([2, 0]):  # yaw, vx
            s_c[k, c] = sigma_c[k, c] * A[i, i] / (Ad[i, i] - 1)
    for key, sd in (
        ("process", sigma_c),
        ("process_continuous", s_c),
        ("process_bins", s_c * ROBOT.dt),
        ("sensor", sigma_n),
    ):
        log_precision = np.log(1 / sd**2)
        np.testing.assert_allclose(moments[key]["mean"], log_precision.mean(axis=0), rtol=1e-10)
        np.testing.assert_allclose(
            moments[key]["variance"], log_precision.var(axis=0, ddof=1), rtol=1e-8
        )
        np.testing.assert_allclose(moments[key]["covariance"], np.cov(log_precision.T), rtol=1e-8)


def test_operating_point_is_the_mean_over_the_analysed_window(yaw_vx_posterior):
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)  # the fixture's run
    inside = np.ones(len(run.t), bool)  # the likelihood took every sample (no --steady)
    prior = export_prior(yaw_vx_posterior, order=0)
    point = prior["operating_point"]
    assert point["window"] == "run"
    [row] = point["experiments"]
    assert row["samples"] == inside.sum()
    np.testing.assert_allclose(row["window"], [run.t[inside][0], run.t[inside][-1]])
    u = [run.omega_r[inside].mean(), run.omega_l[inside].mean()]
    y = [run.vx[inside].mean(), run.vy[inside].mean(), run.yaw_rate[inside].mean()]
    np.testing.assert_allclose(row["u"], u, rtol=1e-12)
    np.testing.assert_allclose(row["y"], y, rtol=1e-12)
    assert point["pooled"] == {"samples": row["samples"], "u": row["u"], "y": row["y"]}
    # The model's own steady state there: 0 = A x + B u.
    A, B = np.asarray(prior["model"]["A"]), np.asarray(prior["model"]["B"])
    np.testing.assert_allclose(A @ point["model_steady_state"], -B @ u, atol=1e-12)


def test_operating_point_pools_windows_by_their_samples():
    # Two in-memory runs, 720 and 360 samples; the second measures no vy.
    t = np.arange(720) / 72

    def run(n, level, vy):
        return Experiment(
            t=t[:n],
            yaw_rate=np.full(n, level),
            omega_r=np.full(n, 10 * level),
            omega_l=np.full(n, 5 * level),
            vx=np.full(n, 2 * level),
            vy=np.full(n, level) if vy else None,
            name=f"r{n}",
        )

    point = operating_point(
        [run(720, 1.0, True), run(360, 4.0, False)], steady=True, A=-np.eye(3), B=np.ones((3, 2))
    )
    assert point["pooled"]["samples"] == 1080
    level = (720 * 1.0 + 360 * 4.0) / 1080  # = 2
    np.testing.assert_allclose(point["pooled"]["u"], [10 * level, 5 * level])
    np.testing.assert_allclose(point["pooled"]["y"], [2 * level, 1.0, level])
    assert point["experiments"][1]["y"][1] is None


def test_damping_prior_on_the_matrix_entries_is_the_draws(yaw_vx_posterior):
    prior = export_prior(yaw_vx_posterior, order=0)["damping"]["matrix_prior"]
    post = yaw_vx_posterior.posterior
    d_lat, d_long = post["d_lat"].values.ravel(), post["d_long"].values.ravel()
    # One draw at a time, the entries that depend on the damping (eq. 4-32):
    # the three poles, B's vx row and its yaw row (the vy row is zero).
    cells = [(0, 0), (1, 1), (2, 2)], [(0, 0), (0, 1), (2, 0), (2, 1)]
    continuous, discrete = [], []
    for k in range(len(d_lat)):
        for out, matrices in (
            (continuous, continuous_matrices(ROBOT, d_lat[k], d_long[k])),
            (discrete, discrete_matrices(ROBOT, d_lat[k], d_long[k], ROBOT.dt)),
        ):
            out.append([matrices[m][cell] for m in range(2) for cell in cells[m]])
    for key, values, names in (
        ("continuous", np.array(continuous), ("A", "B")),
        ("discrete", np.array(discrete), ("Ad", "Bd")),
    ):
        expected = [f"{names[m]}[{i},{j}]" for m in range(2) for i, j in cells[m]]
        assert prior[key]["entries"] == expected
        np.testing.assert_allclose(prior[key]["mean"], values.mean(axis=0), rtol=1e-10)
        np.testing.assert_allclose(prior[key]["covariance"], np.cov(values.T), rtol=1e-8)
    # A, B are linear in the damping: the Jacobian of eq. 4-32, and the
    # covariance is J cov(d) J'.
    m, inertia, a, b, r = (
        ROBOT.mass,
        ROBOT.yaw_inertia,
        ROBOT.half_wheelbase,
        ROBOT.half_track,
        ROBOT.wheel_radius,
    )
    jacobian = [
        [0, -4 / m],
        [-4 / m, 0],
        [-4 * a**2 / inertia, -4 * b**2 / inertia],
        [0, 2 * r / m],
        [0, 2 * r / m],
        [0, 2 * b * r / inertia],
        [0, -2 * b * r / inertia],
    ]
    J = np.asarray(prior["continuous"]["jacobian"])
    np.testing.assert_allclose(J, jacobian, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        prior["continuous"]["covariance"], J @ np.cov(d_lat, d_long) @ J.T, rtol=1e-8
    )


def spm_dem_r(n: int, s: float) -> np.ndarray:
    """spm_DEM_R(n, s) of SPM for the Gaussian form, written from its closed form.

    n derivatives (embedding order n - 1), s the sd of the Gaussian kernel in
    time bins. SPM's curvature for k = 0 .. n - 1: rho^(2k)(0) = prod_{j <= k}
    (1 - 2 j) / (sqrt(2) s)^(2k) = (-1)^k (2k - 1)!! / (2 s^2)^k, odd
    derivatives zero; row i of V holds rho^(i + j)(0), j = 0 .. n - 1, its sign
    flipped on every other row; R = inv(V).
    """
    rho = np.zeros(2 * n - 1)
    term = 1.0
    for k in range(n):
        rho[2 * k] = term / (2 * s**2) ** k
        term *= -(2 * k + 1)  # (-1)^(k+1) (2k + 1)!!
    V = np.array([(-1) ** i * rho[i : i + n] for i in range(n)])
    return np.linalg.inv(V)


@pytest.mark.parametrize("order", [1, 2, 3])
def test_exported_precision_in_bins_is_spm_dem_r(yaw_vx_posterior, order):
    # SPM's rho^(2k)(0) = (-1)^k (2k - 1)!! / (2 s^2)^k are the derivatives of
    # exp(-t^2 / (4 s^2)) (rho''(0) = -1 / (2 s^2)): the autocorrelation of
    # white noise through a Gaussian kernel of sd s, which is the thesis'
    # filter of width sigma_h, exp(-t^2 / (2 sigma_h^2)) (eq. 7-5). So SPM's
    # smoothness is s = sigma_h / dt [bins]. In bins, derivative i is w^(i)
    # dt^i: V_bins = S V S with S = diag(dt^i), and inv(V_bins) = S^-1 inv(V) S^-1.
    prior = export_prior(yaw_vx_posterior, order=order)
    dt = prior["dt"]
    post = yaw_vx_posterior.posterior
    sigma_h = post["sigma_h"].transpose("chain", "draw", "noise_group").values.reshape(-1, 2)
    # The export averages inv(V) over the draws, per channel (yaw, vx).
    expected = np.mean([[spm_dem_r(order + 1, s / dt) for s in draw] for draw in sigma_h], axis=0)
    unscale = np.diag(dt ** -np.arange(order + 1.0))
    exported = np.asarray(prior["generalised_coordinates"]["temporal_precision"])
    in_bins = unscale @ exported @ unscale
    # Two closed forms, inverted apart: they agree to rounding, amplified by
    # V's condition (in bins: 23, 270, 2100 at orders 1, 2, 3 for s = 3.4 bins).
    np.testing.assert_allclose(in_bins, expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())


def orders_below(s: float, dt: float, bound: float) -> list[int]:
    """The orders whose Gaussian precision R = spm_DEM_R(P + 1, s / dt) has a condition
    number below ``bound`` in bins and in seconds, where derivative i is 1 / dt^i times
    the one in bins: Pi = S R S, S = diag(dt^i), counted up to the first that fails."""
    orders = []
    for order in range(40):
        R = spm_dem_r(order + 1, s / dt)
        S = np.diag(dt ** np.arange(order + 1.0))
        if not max(np.linalg.cond(R), np.linalg.cond(S @ R @ S)) < bound:
            break
        orders.append(order)
    return orders


@pytest.mark.parametrize(
    ("width", "dt", "top"),
    [
        (0.047, 1 / 72, 4),  # the thesis' sigma_h: seconds bind (5e11 at 4, 1e15 at 5)
        (0.001, 0.001, 1),  # 1 ms at 1 kHz: seconds bind (1.13e12 at 2; in bins 3.9)
        (0.5, 0.01, 3),  # 50 bins: bins bind (2e10 at 3, 3e13 at 4; seconds 2e9 at 8)
    ],
)
def test_orders_are_allowed_in_seconds_and_in_bins(width, dt, top):
    # The prior holds Pi in seconds and in bins, and a consumer's eigenvalues
    # lose log10(condition) digits in the unit it works in: an order is allowed
    # only where both are below MAX_CONDITION (SPM's closed form, written above).
    draws = np.full((6, 1), width)
    sd = np.random.default_rng(2).uniform(0.5, 2.0, (6, 1))  # a scalar per channel: no effect
    expected = orders_below(width, dt, MAX_CONDITION)
    assert expected[-1] == top and allowed_orders("gaussian", draws, sd, dt=dt) == expected
    seconds_only = allowed_orders("gaussian", draws, sd)
    assert seconds_only == orders_below(width, 1.0, MAX_CONDITION)  # dt = 1 s: bins are seconds
    assert (seconds_only == expected) == (width < 0.1)  # only the wide noise is bins-limited
