"""How channels were recorded: the pose channels' residual and its law, against references.

The references are independent of bayes_jackal.likelihood.measurements:

- the exact increment: the model dx/dt = a x + f with a held force f,
  augmented with the travel q (dq/dt = x) and discretised by one block
  matrix exponential, gives x and q at the next sample exactly; the pose
  residual of those increments must be kappa_0 w_{k+1} + kappa_1 w_k to
  rounding: the travel reaches ~2 m, whose rounding (4e-16 m) divided by
  dt and summed over a few terms is ~1e-13 m/s (tolerance 1e-12);
- the law: the residual is a fixed linear map of the process noise w and of
  the pose noise e, so its covariance is L_w T(R) L_w' + sigma_e^2 L_e L_e'
  written out densely; its first row must be the autocovariance
  ``PoseMeasurement.autocovariance`` gives, to rounding;
- the engines: ``fast`` against ``exact`` (Durbin-Levinson) on pose blocks,
  1e-6 nats as for the rate channels (tests/test_likelihood.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from bayes_jackal._runtime.errors import DataError
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.io.pose_track import PoseTrack
from bayes_jackal.likelihood.measurements import (
    PoseMeasurement,
    RateMeasurement,
    pose_weights,
)
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.model.kernels import get_family
from bayes_jackal.model.physics import channel_coefficients, continuous_matrices
from bayes_jackal.model.robot import load_profile

ROBOT = load_profile()
DT = 1 / 72


def _exact_step(a: float, dt: float) -> np.ndarray:
    """expm of the (x, q, f) system over dt: x' = a x + f, q' = x, f held; rows (x, q)."""
    generator = np.array([[a, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    return scipy.linalg.expm(generator * dt)[:2]


@pytest.mark.parametrize("channel", ["vx", "vy"])
def test_the_pose_residual_of_exact_increments_is_the_process_noise_through_two_taps(channel):
    rng = np.random.default_rng(1)
    n = 400
    A, B = continuous_matrices(ROBOT, 110.0, 30.0)
    i = ("vx", "vy").index(channel)
    a, b = A[i, i], B[i]
    u = 12.0 + 0.5 * rng.standard_normal((n, 2))
    force = u @ b + rng.normal(0.0, 0.4, n)  # b . u_k + eta_k, held over step k
    step = _exact_step(a, DT)
    x, q = np.zeros(n + 1), np.zeros(n + 1)
    for k in range(n):
        x[k + 1], q[k + 1] = step @ [x[k], q[k], force[k]]
    increments = np.diff(q)
    alpha, beta = channel_coefficients(ROBOT, 110.0, 30.0, channel, DT)
    w = x[1:] - alpha * x[:-1] - u @ beta  # the discrete process noise of eq. 7-3
    c, pole = PoseMeasurement().coefficients(ROBOT, 110.0, 30.0, channel, DT)
    regressors = np.column_stack([increments[1:], increments[:-1], u[1:], u[:-1]])
    kappa_0, kappa_1 = pose_weights(pole)
    np.testing.assert_allclose(
        regressors @ c, kappa_0 * w[1:] + kappa_1 * w[:-1], rtol=0, atol=1e-12
    )


@pytest.mark.parametrize("family", ["gaussian", "exponential", "moving-average"])
def test_the_pose_residuals_autocovariance_is_its_dense_covariance(family):
    n, samples = 60, 5
    width, sigma_c, sigma_p = np.array([0.05]), np.array([0.004]), np.array([4e-4])
    alpha = np.array([0.9])
    kernel = get_family(family).autocorrelation(width, DT, n + 1)[0]
    kappa_0, kappa_1 = pose_weights(alpha[0])
    # r = L_w w + L_e e / dt, w of n + 1 samples, e of n + 2.
    L_w = np.zeros((n, n + 1))
    L_w[np.arange(n), np.arange(n) + 1], L_w[np.arange(n), np.arange(n)] = kappa_0, kappa_1
    L_e = np.zeros((n, n + 2))
    for lag, weight in enumerate([alpha[0], -(1 + alpha[0]), 1.0]):
        L_e[np.arange(n), np.arange(n) + lag] = weight / DT
    dense = sigma_c[0] ** 2 * L_w @ scipy.linalg.toeplitz(kernel) @ L_w.T
    dense += sigma_p[0] ** 2 / samples * L_e @ L_e.T
    acov = PoseMeasurement().autocovariance(
        get_family(family), width, sigma_c, sigma_p, alpha, DT, n, samples=samples
    )
    np.testing.assert_allclose(scipy.linalg.toeplitz(acov[0]), dense, rtol=1e-12, atol=1e-18)


def test_the_pose_weights_are_a_partition_and_tend_to_one_half():
    alpha = np.exp(-np.logspace(-8, 0.5, 50))
    kappa_0, kappa_1 = pose_weights(alpha)
    np.testing.assert_allclose(kappa_0 + kappa_1, 1.0, rtol=1e-14)
    # Series at small a dt: kappa_0 = 1/2 - a dt / 12 + O((a dt)^2) (-a dt = -log alpha > 0).
    z = np.log(alpha)
    small = np.abs(z) < 1e-3
    np.testing.assert_allclose(kappa_0[small], 0.5 - z[small] / 12, atol=1e-7)
    # The later step weighs more, the more the state decays within the step.
    assert np.all((kappa_0 >= 0.5) & (kappa_0 < 1.0)) and np.all(np.diff(kappa_0) >= 0)


def _pose_run(seed: int, rate: float = 360.0, sd: float = 3e-4) -> Experiment:
    """A 20 s run whose vx, vy are recorded as noisy poses of a wobbling circle."""
    rng = np.random.default_rng(seed)
    t = np.arange(1441) / 72
    s = np.arange(-3, round(20 * rate) + 4) / rate + rng.uniform(0, 1 / rate)
    heading = 0.4 * s + 0.02 * np.sin(3 * s)
    radius = 0.75 + 0.01 * np.sin(1.3 * s)
    x = radius * np.sin(heading) + sd * rng.standard_normal(len(s))
    y = 0.75 - radius * np.cos(heading) + sd * rng.standard_normal(len(s))
    pose = PoseTrack(s, x, y, heading)
    wheels = 10.0 + 0.1 * rng.standard_normal((len(t), 2))
    return Experiment(
        t=t,
        yaw_rate=0.4 + 0.01 * rng.standard_normal(len(t)),
        omega_r=wheels[:, 0],
        omega_l=wheels[:, 1],
        vx=0.3 + 0.001 * rng.standard_normal(len(t)),
        vy=0.001 * rng.standard_normal(len(t)),
        pose=pose,
        name=f"run{seed}",
    )


@pytest.mark.parametrize("family", ["white", "gaussian", "moving-average"])
def test_the_fast_engine_equals_the_exact_one_on_pose_channels(family):
    runs = [_pose_run(1), _pose_run(2)]
    likelihood = ResidualLikelihood(runs, ROBOT, family=family, channels=("yaw", "vx", "vy"))
    assert [b.measurement for b in likelihood.blocks] == ["rate", "pose", "pose"]
    rng = np.random.default_rng(3)
    names = likelihood.parameter_names
    centre = {"d_lat": 110.0, "d_long": 30.0, "sigma_h": 0.05, "width": 0.05, "sigma_c": 0.005}
    centre |= {"sigma_n": 0.005, "sigma_p": 3e-4}
    base = np.array([centre[name.split("[")[0]] for name in names])
    theta = base * np.exp(0.3 * rng.standard_normal((6, len(names))))
    exact = dataclasses.replace(likelihood, engine="exact")(theta)
    # 1e-6 nats: the fast engine's promise (bayes_jackal.likelihood.residual_likelihood).
    np.testing.assert_allclose(likelihood(theta), exact, rtol=0, atol=1e-6)


def test_a_channel_recorded_two_ways_cannot_share_one_model():
    pose = _pose_run(1)
    rate = dataclasses.replace(pose, pose=None, name="measured", source="measured.csv")
    with pytest.raises(DataError, match="records vx as motion-capture poses"):
        ResidualLikelihood([pose, rate], ROBOT, channels=("yaw", "vx"))
    yaw = ResidualLikelihood([pose, rate], ROBOT, channels=("yaw",))
    assert yaw.layout.pose_channels == ()


def test_the_pose_channels_have_the_pose_noise_as_their_sensor_parameter():
    likelihood = ResidualLikelihood([_pose_run(1)], ROBOT, family="white")
    assert likelihood.parameter_names == [
        "d_lat",
        "d_long",
        "sigma_c[yaw]",
        "sigma_n[yaw]",
        "sigma_c[vx]",
        "sigma_p[vx]",
        "sigma_c[vy]",
        "sigma_p[vy]",
    ]
    assert likelihood.pose_samples == {"run1": 5}
    rate = RateMeasurement()
    assert rate.series(_pose_run(1), "yaw").regressors.shape == (1440, 4)
