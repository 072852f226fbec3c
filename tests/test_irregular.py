"""The irregular engine against a dense reference written here, and against the Toeplitz engines.

The reference builds the model's linear maps from scratch: the state v and
the travel Q within each step integrated numerically (RK4 on 400 sub-steps,
not the package's closed forms), every observation a vector of
coefficients over (v_0, xi_0, ..., xi_{N-1}), the residuals' covariance a
dense matrix, the density scipy's. The residual is defined as in the
module (the state removed by the ratio of the observations' coefficients
of v_0), so the two must agree to rounding: 1e-8 nats on a few hundred
residuals (the RK4 error of 400 sub-steps of a step whose pole is at most
a few per step is ~1e-13 relative).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.stats

import bayes_jackal as bj
from bayes_jackal.likelihood import (
    IrregularSeries,
    PoseMeasurement,
    RateMeasurement,
    ResidualLikelihood,
    irregular_loglike,
    toeplitz_loglike,
)
from bayes_jackal.model import channel_coefficients, get_family

SUBSTEPS = 400
ROBOT = bj.load_profile()


def _within_step(a: float, forcing: np.ndarray, v: np.ndarray, q: np.ndarray, tau: float):
    """(v, Q) after tau of dv/dt = a v + f, dQ/dt = v, by RK4: coefficient vectors, linear."""
    if tau == 0:
        return v, q
    h = tau / SUBSTEPS
    for _ in range(SUBSTEPS):
        k1v, k1q = a * v + forcing, v
        k2v, k2q = a * (v + h / 2 * k1v) + forcing, v + h / 2 * k1v
        k3v, k3q = a * (v + h / 2 * k2v) + forcing, v + h / 2 * k2v
        k4v, k4q = a * (v + h * k3v) + forcing, v + h * k3v
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
    return v, q


def _forms(poles, dt, ticks, phases, kind):
    """The observations' coefficients over (v_b, xi_b..xi_e) from the first one's tick b.

    Integrated from b over the span (RK4), so that removing the state takes
    no difference of large numbers. Returns (coefficients (M, 1 + L), b).
    """
    base, span = ticks[0], ticks[-1] - ticks[0] + 1
    v, q = np.zeros(span + 1), np.zeros(span + 1)
    v[0] = 1.0
    rows, step = [], 0
    for k, tau in zip(ticks, phases, strict=True):
        while step < k - base:  # whole steps up to the observation's tick
            v, q = _step(poles[base + step], dt, step, v, q, dt)
            step += 1
        v_s, q_s = _step(poles[base + step], dt, step, v, q, tau)
        rows.append(v_s if kind == "rate" else q_s)
    return np.array(rows), base


def _step(a, dt, position, v, q, tau):
    """(v, Q) after tau of the step at ``position``, its drive xi held: f = xi / g."""
    forcing = np.zeros_like(v)
    forcing[1 + position] = a / np.expm1(a * dt)
    return _within_step(a, forcing, v, q, tau)


def dense_loglike(series, family, poles, beta, scale, width, sigma_c, sigma_sensor, sensor):
    """The residuals' log-density by dense linear algebra (module docstring)."""
    n, dt, kind = len(series.inputs), series.dt, series.measurement
    order = 2 if kind == "rate" else 3
    count = len(series.ticks) - order + 1
    weights = np.zeros((count, n))  # each residual's coefficients over xi_0..xi_{N-1}
    combine = np.zeros((count, len(series.ticks)))  # ... over the observations (poses)
    data = np.zeros(count)
    for j in range(count):
        window = slice(j, j + order)
        forms, base = _forms(poles, dt, series.ticks[window], series.phases[window], kind)
        if kind == "pose":
            forms = np.diff(forms, axis=0)  # the two increments
        gamma = forms[1, 0] / forms[0, 0]
        mu = forms[1, 1:] - gamma * forms[0, 1:]
        if kind == "rate":
            weights[j, base : base + len(mu)] = mu
            combine[j, j : j + 2] = [-gamma, 1.0]
            data[j] = series.values[j + 1] - gamma * series.values[j]
        else:  # (D_{j+1} - gamma D_j) / dt with D_j = P_{j+1} - P_j
            weights[j, base : base + len(mu)] = mu / dt
            combine[j, j : j + 3] = np.array([gamma, -1.0 - gamma, 1.0]) / dt
            data[j] = (series.values[j + 1] - gamma * series.values[j]) / dt
    drive_mean = np.einsum("iw,iw->i", beta, series.inputs)
    residuals = data - weights @ drive_mean
    rho = family.autocorrelation(np.array([width]), dt, n)[0]
    process = sigma_c**2 * scipy.linalg.toeplitz(rho)
    noise = np.diag(sigma_sensor**2 / series.counts)
    if kind == "rate" and sensor == "diagonal":
        process += sigma_sensor**2 * np.eye(n)
        noise = 0 * noise
    scaled = weights * scale
    covariance = scaled @ process @ scaled.T + combine @ noise @ combine.T
    return scipy.stats.multivariate_normal(cov=covariance).logpdf(residuals)


def _case(kind, damping_index, rng, n=90, dt=0.05):
    """A random series, the per-damping poles and rows of the yaw or vx channel."""
    channel = "yaw" if kind == "rate" else "vx"
    d = np.array([[110.0, 30.0], [160.0, 45.0]])[: 1 + int(damping_index is not None)]
    alpha, row = channel_coefficients(ROBOT, d[:, 0], d[:, 1], channel, dt)
    steps = rng.integers(1, 5, size=40)
    ticks = np.cumsum(np.concatenate([[2], steps]))
    ticks = ticks[ticks < n - 1]
    phases = np.where(rng.random(len(ticks)) < 0.7, rng.uniform(0, dt, len(ticks)), 0.0)
    counts = rng.integers(1, 4, len(ticks))
    values = rng.standard_normal(len(ticks) - (kind == "pose")) * 0.01
    inputs = 5.0 + rng.standard_normal((n, 2))
    series = IrregularSeries(channel, kind, 0, dt, ticks, phases, values, counts, inputs,
                             damping_index)  # fmt: skip
    index = np.zeros(n, int) if damping_index is None else damping_index
    poles, beta = np.log(alpha)[index] / dt, row[index]
    gains = np.expm1(np.log(alpha)) / np.log(alpha)
    scale = gains / gains[0]
    return series, alpha, row, scale, poles, beta, scale[index]


@pytest.mark.parametrize("kind", ["rate", "pose"])
@pytest.mark.parametrize("family", ["gaussian", "exponential", "white"])
@pytest.mark.parametrize("two_dampings", [False, True])
def test_the_engine_is_the_dense_density(kind, family, two_dampings):
    rng = np.random.default_rng(7)
    split = np.where(np.arange(90) < 47, 0, 1) if two_dampings else None
    series, alpha, row, scale, poles, beta, tick_scale = _case(kind, split, rng)
    noise = (np.array([0.12]), np.array([0.02]), np.array([0.004]))
    value = irregular_loglike(series, get_family(family), alpha[None], row[None], noise,
                              scale=scale[None])  # fmt: skip
    dense = dense_loglike(series, get_family(family), poles, beta, tick_scale,
                          0.12, 0.02, 0.004, "ma1")  # fmt: skip
    assert value[0] == pytest.approx(dense, abs=1e-8)


def test_the_diagonal_sensor_term_is_white_noise_in_each_drive():
    rng = np.random.default_rng(3)
    series, alpha, row, _, poles, beta, tick_scale = _case("rate", None, rng)
    noise = (np.array([0.08]), np.array([0.02]), np.array([0.01]))
    value = irregular_loglike(series, get_family("gaussian"), alpha[None], row[None], noise,
                              sensor="diagonal")  # fmt: skip
    dense = dense_loglike(series, get_family("gaussian"), poles, beta, tick_scale,
                          0.08, 0.02, 0.01, "diagonal")  # fmt: skip
    assert value[0] == pytest.approx(dense, abs=1e-8)


def test_every_tick_is_the_toeplitz_residual_density():
    """Observed at every tick, the residuals are the one-step ones of the Toeplitz engines."""
    run = bj.simulate_experiment(ROBOT, 110.0, 30.0, bj.io.Series(0.3, 0.39, 8.0), rng=2)
    family, width, sigma_c, sigma_n = get_family("gaussian"), 0.047, 0.01, 0.004
    for measurement, channel in ((RateMeasurement(), "yaw"), (PoseMeasurement(), "vx")):
        if measurement.name == "pose":
            run = _with_poses(run)
            values, counts = _pose_increments(run, channel)
        else:
            values, counts = run.yaw_rate, np.ones(len(run.t), int)
        ticks = np.arange(len(run.t))
        series = IrregularSeries(channel, measurement.name, 0, run.dt, ticks, 0.0 * ticks,
                                 values, counts, run.inputs)  # fmt: skip
        c, alpha = measurement.coefficients(ROBOT, 110.0, 30.0, channel, run.dt)
        residuals = measurement.series(run, channel).regressors @ c
        one = np.ones(1)
        acov = measurement.autocovariance(family, width * one, sigma_c * one, sigma_n * one,
                                          alpha[None], run.dt, len(residuals),
                                          samples=int(counts[0]))  # fmt: skip
        expected = toeplitz_loglike(acov, residuals[None, None])[0, 0]
        _, row = channel_coefficients(ROBOT, 110.0, 30.0, channel, run.dt)
        noise = (width * one, sigma_c * one, sigma_n * one)
        value = irregular_loglike(series, family, alpha[None, None], row[None, None], noise)
        assert value[0] == pytest.approx(expected, abs=1e-7), measurement.name


def _with_poses(run):
    """The run with noise-free poses at its ticks, from its states (a pose per sample)."""
    heading = np.concatenate([[0.0], np.cumsum(run.yaw_rate[:-1] * run.dt)])
    cos, sin = np.cos(heading), np.sin(heading)
    world = np.column_stack([run.vx * cos - run.vy * sin, run.vx * sin + run.vy * cos])
    position = np.concatenate([[[0.0, 0.0]], np.cumsum(world[:-1] * run.dt, axis=0)])
    rng = np.random.default_rng(4)
    position = position + 1e-4 * rng.standard_normal(position.shape)
    pose = bj.io.PoseTrack(run.t, position[:, 0], position[:, 1], heading)
    return bj.io.Experiment(t=run.t, yaw_rate=run.yaw_rate, omega_r=run.omega_r,
                            omega_l=run.omega_l, vx=run.vx, vy=run.vy, pose=pose)  # fmt: skip


def _pose_increments(run, channel):
    ticks = bj.io.tick_poses(run)
    return bj.io.body_increments(ticks, channel), np.full(len(run.t), ticks.samples)


@pytest.mark.parametrize(("rate", "phase"), [(10.0, 0.0043), (25.0, 0.0)])
def test_poses_every_m_samples_are_the_irregular_density_at_a_flat_cost(rate, phase):
    """Poses on a clock of their own (every m samples at one phase) take the Toeplitz engines.

    Their residuals are the irregular engine's with the same poses at the
    same times: the two densities agree within the spectral engine's 1e-6 nats.
    """
    rng = np.random.default_rng(5)
    run = bj.simulate_experiment(ROBOT, 110.0, 30.0, bj.io.Series(0.3, 0.39, 12.0), rng=2)
    t = np.arange(0, 50 * 12) / 50.0  # a 50 Hz clock
    s = np.arange(1, int(12 * rate)) / rate + phase
    heading = 0.39 * s
    pose = bj.io.PoseTrack(s, np.cos(s) + 0.02 * rng.standard_normal(len(s)),
                           np.sin(s) + 0.02 * rng.standard_normal(len(s)), heading)  # fmt: skip
    experiment = bj.io.Experiment(
        t=t, yaw_rate=np.interp(t, run.t, run.yaw_rate), omega_r=np.interp(t, run.t, run.omega_r),
        omega_l=np.interp(t, run.t, run.omega_l), vx=np.interp(t, run.t, run.vx),
        vy=np.interp(t, run.t, run.vy), pose=pose,
    )  # fmt: skip
    measurement = PoseMeasurement()
    assert measurement.regular(experiment) and measurement.clock(experiment)[0] == 50 / rate
    theta = np.array([[110.0, 30.0, 0.1, 0.01, 0.02], [300.0, 60.0, 0.05, 0.02, 0.01]])
    strided = ResidualLikelihood([experiment], ROBOT, channels=("vx",))
    assert not strided.irregular
    [piece] = measurement.observations(experiment, "vx")
    series = IrregularSeries("vx", "pose", 0, experiment.dt, piece.ticks, piece.phases,
                             piece.values, piece.counts, experiment.inputs)  # fmt: skip
    alpha, beta = channel_coefficients(ROBOT, theta[:, 0], theta[:, 1], "vx", experiment.dt)
    exact = irregular_loglike(series, get_family("gaussian"), alpha[:, None], beta[:, None],
                              (theta[:, 2], theta[:, 3], theta[:, 4]))  # fmt: skip
    np.testing.assert_allclose(strided(theta), exact, rtol=0, atol=1e-6)
