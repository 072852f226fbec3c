"""Kalman filters on the identified model, driven by an exported prior.

On a channel's state-space model (:class:`bayes_jackal.filter_models.ChannelModel`:
s[k+1] = F s[k] + G u[k] + Gamma eps[k], y[k] = H s[k] + n[k], H = e_0',
Q = Gamma Gamma', R = var(n)) the filter gives the filtered mean
E[x_k | y_0..y_k, u] and its variance:

    S_k = H P_k|k-1 H' + R,        K_k = P_k|k-1 H' / S_k,
    nu_k = y_k - H m_k|k-1,        m_k|k = m_k|k-1 + K_k nu_k,
    P_k|k = (I - K_k H) P_k|k-1 (I - K_k H)' + R K_k K_k'   (Joseph form),
    m_k+1|k = F m_k|k + G u_k,     P_k+1|k = F P_k|k F' + Q,

from the model's prior (m_0|-1, P_0|-1). The two Kalman filters are
this code on two models (:data:`KALMAN_FILTERS`): ``kalman`` assumes white process
noise (the baseline), ``kalman-coloured`` carries the noise family's
shaping filter in its state, which makes it the exact conditional mean
under the identified model.

The covariances do not depend on the data and converge to the solution of
the discrete algebraic Riccati equation. Once P_k+1|k has stopped changing
(relative change below :data:`CONVERGED`) the filter is linear and time
invariant, m_k|k = A m_k-1|k-1 + K y_k + (I - K H) G u_k-1 with
A = (I - K H) F, so the rest of the run is its impulse response
(truncated where A^j is below :data:`TRUNCATION`, or at the run's end)
convolved with the data by FFT, with no loop over time steps
(``fast=True``, the default; equal to the step-by-step recursion within
1e-12 in the tests).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import DataError
from .experiment import Experiment
from .filter_models import ChannelModel, check_prior, filter_models
from .lti import lti_outputs
from .robot import RobotProfile

__all__ = [
    "CONVERGED",
    "DIFFUSE",
    "KALMAN_FILTERS",
    "TRUNCATION",
    "StateEstimate",
    "kalman",
    "kalman_filter",
]

#: The Kalman filters by name, and the process-noise model each assumes
#: (:data:`bayes_jackal.filter_models.NOISE_MODELS`).
KALMAN_FILTERS = {"kalman": "white", "kalman-coloured": "coloured"}
#: Relative change of P_k+1|k (largest entry) below which the gain is taken
#: as converged: a gain error of ~1e-14, far below the data's precision.
CONVERGED = 1e-14
#: Variance of the state before the run [channel units^2] when none is
#: given: diffuse, so the first estimate is the first measurement's (a run
#: recorded in motion does not start at rest).
DIFFUSE = 1e6
#: Largest entry of A^j below which the steady filter's impulse response is cut.
TRUNCATION = 1e-14


@dataclass(frozen=True)
class StateEstimate:
    """A filter's output on one channel, each array shape (N,).

    Attributes
    ----------
    mean : ndarray
        E[x_k | y_0..y_k, u] [channel units].
    variance : ndarray
        Its variance [channel units^2].
    innovation : ndarray
        nu_k = y_k - E[y_k | y_0..y_k-1, u] [channel units].
    innovation_variance : ndarray
        S_k [channel units^2]: nu_k^2 / S_k is chi-square(1) under the model.
    steady_from : int
        First step run with the converged gain (N: none).
    derivatives : ndarray or None
        The generalised filter's mu~, shape (N, p + 1) [units / s^j]; None
        for the Kalman filters.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.kalman import StateEstimate
    >>> estimate = StateEstimate(*np.zeros((4, 3)), steady_from=3)
    >>> estimate.mean.shape
    (3,)
    """

    mean: np.ndarray
    variance: np.ndarray
    innovation: np.ndarray
    innovation_variance: np.ndarray
    steady_from: int
    derivatives: np.ndarray | None = None


def kalman(
    model: ChannelModel, y: np.ndarray, inputs: np.ndarray, *, fast: bool = True
) -> StateEstimate:
    """The Kalman filter of one channel (module docstring).

    Parameters
    ----------
    model : ChannelModel
    y : ndarray, shape (N,)
        Measured state [channel units].
    inputs : ndarray, shape (N, 2)
        Wheel speeds (omega_r, omega_l) [rad/s].
    fast : bool
        Run the steady filter, once its gain has converged, as an FFT
        convolution; False: the step-by-step recursion throughout.

    Returns
    -------
    StateEstimate

    Examples
    --------
    A scalar model: the innovation variance converges to P + R, P the
    solution of the Riccati equation P = a^2 P R / (P + R) + q:

    >>> import numpy as np
    >>> import scipy.linalg
    >>> from bayes_jackal.filter_models import channel_model
    >>> from bayes_jackal.kalman import kalman
    >>> model = channel_model("yaw", 0.72, [0.026, -0.026], family="white", width=1.0,
    ...                       sigma_c=0.01, sigma_n=0.005, dt=1 / 72)
    >>> y, inputs = np.random.default_rng(1).normal(0, 0.01, 500), np.zeros((500, 2))
    >>> estimate = kalman(model, y, inputs)
    >>> P = scipy.linalg.solve_discrete_are(0.72, 1.0, 1e-4, 2.5e-5)
    >>> bool(np.isclose(estimate.innovation_variance[-1], P[0, 0] + 2.5e-5, rtol=1e-12))
    True
    >>> slow = kalman(model, y, inputs, fast=False)
    >>> bool(np.allclose(estimate.mean, slow.mean, rtol=0, atol=1e-14))
    True
    """
    y = np.asarray(y, float)
    inputs = np.asarray(inputs, float)
    if y.ndim != 1 or inputs.shape != (len(y), 2):
        raise DataError(
            f"expected y of shape (N,) and inputs (N, 2), got {y.shape} and {inputs.shape}",
            field=model.channel,
        )
    F, G = model.transition, model.input_matrix
    Q, R = model.process_covariance, model.sensor_variance
    out = np.empty((4, len(y)))  # mean, variance, innovation, innovation variance
    m, P = model.initial_mean, model.initial_covariance
    for k in range(len(y)):
        m, filtered, _, out[2:, k] = _update(m, P, y[k], R)
        out[:2, k] = m[0], filtered[0, 0]
        following = F @ filtered @ F.T + Q
        converged = np.abs(following - P).max() <= CONVERGED * np.abs(P).max()
        if fast and converged and k + 1 < len(y):
            _steady(F, G, following, R, m, y[k + 1 :], inputs[k:-1], out[:, k + 1 :])
            return StateEstimate(*out, steady_from=k + 1)
        m, P = F @ m + G @ inputs[k], following
    return StateEstimate(*out, steady_from=len(y))


def _update(
    m: np.ndarray, P: np.ndarray, y: float, R: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float]]:
    """Measurement update of the predicted (m, P): filtered mean and covariance, gain, (nu, S)."""
    S = P[0, 0] + R
    gain = P[:, 0] / S
    innovation = y - m[0]
    reduce = _reduction(gain)
    filtered = reduce @ P @ reduce.T + R * np.outer(gain, gain)
    return m + gain * innovation, filtered, gain, (innovation, S)


def _reduction(gain: np.ndarray) -> np.ndarray:
    """I - K H, with H = e_0'."""
    reduce = np.eye(len(gain))
    reduce[:, 0] -= gain
    return reduce


def _steady(
    F: np.ndarray,
    G: np.ndarray,
    P: np.ndarray,
    R: float,
    m: np.ndarray,
    y: np.ndarray,
    inputs: np.ndarray,
    out: np.ndarray,
) -> None:
    """Fill ``out`` (4, L) for the steps after the filtered mean ``m``, at the converged P_k+1|k.

    m_i = A^(i+1) m + sum_j A^j C p_(i-j) with p_i = (y_i, u_(i-1)) and
    C = [K, (I - K H) G]; the outputs O m_i, O = [H; H F], give the filtered
    mean and (plus H G u_i) the next prediction of y (:func:`~bayes_jackal.lti.lti_outputs`).
    """
    _, filtered, gain, (_, S) = _update(np.zeros(len(P)), P, 0.0, R)
    reduce = _reduction(gain)
    A, C = reduce @ F, np.column_stack([gain, reduce @ G])
    outputs = np.vstack([np.eye(len(P))[0], F[0]])
    drive = np.column_stack([y, inputs])  # p_i = (y_i, u_(i-1)), (L, 3)
    states = lti_outputs(A, C, drive, m, outputs=outputs, tolerance=TRUNCATION).T
    predicted = np.concatenate([[F[0] @ m], states[1, :-1]]) + inputs @ G[0]
    out[0], out[1] = states[0], filtered[0, 0]
    out[2], out[3] = y - predicted, S


def kalman_filter(
    experiment: Experiment,
    prior: Mapping,
    *,
    noise: str = "coloured",
    channels: Sequence[str] | None = None,
    parameters: str = "plug-in",
    robot: RobotProfile | None = None,
    initial_variance: float = DIFFUSE,
    fast: bool = True,
) -> dict[str, StateEstimate]:
    """The Kalman filter of every channel of an experiment, with an exported prior's model.

    Parameters
    ----------
    experiment : Experiment
    prior : mapping
        An exported prior (:func:`bayes_jackal.export.export_prior`, ``prior.json``).
    noise : {"coloured", "white"}
        ``kalman-coloured`` or ``kalman`` (:data:`KALMAN_FILTERS`,
        :func:`bayes_jackal.filter_models.filter_models`).
    channels : sequence of str, optional
        By default every channel of the prior.
    parameters : {"plug-in", "averaged"}
        The noise parameters at their posterior means, or Q and R averaged
        over the prior's draws (:func:`bayes_jackal.filter_models.filter_models`).
    robot : RobotProfile, optional
        When given, its constants must be the prior's.
    initial_variance : float
        Variance of the state one step before the run, around 0 [channel
        units^2]: :data:`DIFFUSE` by default; 0: the run starts at rest.
    fast : bool
        See :func:`kalman`.

    Returns
    -------
    dict of str to StateEstimate

    Raises
    ------
    InputError
        For a prior of another robot or rate, or channels it lacks
        (:func:`bayes_jackal.filter_models.check_prior`).
    DataError
        When the experiment does not measure a channel.

    Examples
    --------
    Both filters on a simulated run with Gaussian-coloured noise, with a prior
    holding the simulation's truth (``bj.export_prior`` writes one from a
    posterior): the coloured filter tracks the true yaw rate more closely.

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.kalman import kalman_filter
    >>> from bayes_jackal.physics import discrete_matrices
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> Ad, Bd = discrete_matrices(robot, 110.0, 30.0)
    >>> prior = {"format": "bayes_jackal.prior/1", "dt": robot.dt, "robot": {"name": "jackal"},
    ...          "damping": {"mean": [110.0, 30.0]},
    ...          "model": {"Ad": Ad.tolist(), "Bd": Bd.tolist()},
    ...          "noise": {"family": "gaussian", "channels": ["yaw"], "sensor": "ma1",
    ...                    "parameters": {"sigma_h": {"mean": 0.047},
    ...                                   "sigma_c": {"mean": 0.01},
    ...                                   "sigma_n": {"mean": 0.005}}}}
    >>> truth = run.truth_arrays["yaw_state"]
    >>> rmse = {noise: np.sqrt(np.mean((kalman_filter(run, prior, noise=noise)["yaw"].mean
    ...                                 - truth) ** 2)) for noise in ("white", "coloured")}
    >>> bool(rmse["coloured"] < rmse["white"])
    True
    """
    channels = check_prior(prior, experiment, channels, robot=robot)
    models = filter_models(
        prior,
        noise=noise,
        channels=channels,
        parameters=parameters,
        initial_variance=initial_variance,
    )
    return {
        channel: kalman(model, experiment.channel(channel), experiment.inputs, fast=fast)
        for channel, model in models.items()
    }
