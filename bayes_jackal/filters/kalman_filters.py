"""Kalman filters on the identified model, driven by an exported prior.

On a channel's state-space model (:class:`bayes_jackal.filters.ChannelModel`:
s[k+1] = F s[k] + G u[k] + Gamma eps[k], y[k] = H s[k] + n[k], H = e_0' for
a measured state and the travel's unit vector for a channel recorded as
poses, Q = Gamma Gamma', R = var(n)) the filter gives the filtered mean
E[x_k | y_0..y_k, u] of the state x = s[0] and its variance, and its
Rauch-Tung-Striebel smoother E[x_k | y_0..y_N-1, u] (which the Savitzky-Golay
velocities of a bag, centred on each sample, are to be compared with):

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

from .._runtime import DataError
from ..dem import ActiveInferencePrior
from ..io import Experiment
from ..model import RobotProfile
from .lti import lti_outputs
from .state_space import ChannelModel, check_prior, filter_models, measured_series

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
#: (:data:`bayes_jackal.filters.NOISE_MODELS`).
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
        ``E[x_k | y_0..y_k, u]`` [channel units].
    variance : ndarray
        Its variance [channel units^2].
    innovation : ndarray
        ``nu_k = y_k - E[y_k | y_0..y_k-1, u]`` [the measurement's units: the
        channel's, or m for a channel recorded as poses]; NaN where y_k is
        no measurement (a pose channel's first sample).
    innovation_variance : ndarray
        S_k [their square]: nu_k^2 / S_k is chi-square(1) under the model.
    steady_from : int
        First step run with the converged gain (N: none); for the
        generalised filter, the first sample whose embedding window lies
        inside the run (p + 1, or p + 2 for a pose channel's travel).
    derivatives : ndarray or None
        The generalised filter's mu~, shape (N, p + 1) [units / s^j]; None
        for the Kalman filters.
    smoothed, smoothed_variance : ndarray or None
        E[x_k | y_0..y_N-1, u] and its variance: the Kalman filters'
        Rauch-Tung-Striebel smoother, which also uses the samples after
        t_k (None for the generalised filter).
    nis_spread : float or None
        The sd of log NIS (the mean of nu_k^2 / S_k from the first
        prediction) over the same filter run with the noise parameters of
        the prior's draws instead: how far the NIS moves with the parameters'
        posterior uncertainty (set by
        :func:`bayes_jackal.filters.estimate_states` for the Kalman
        filters; None when not computed).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.filters import StateEstimate
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
    smoothed: np.ndarray | None = None
    smoothed_variance: np.ndarray | None = None
    nis_spread: float | None = None


def kalman(
    model: ChannelModel,
    y: np.ndarray,
    inputs: np.ndarray,
    *,
    fast: bool = True,
    smooth: bool = True,
) -> StateEstimate:
    """The Kalman filter of one channel (module docstring).

    Parameters
    ----------
    model : ChannelModel
    y : ndarray, shape (N,)
        The measurement: the measured state [channel units], or a pose
        channel's travel [m] (:func:`bayes_jackal.filters.measured_series`).
    inputs : ndarray, shape (N, 2)
        Wheel speeds (omega_r, omega_l) [rad/s].
    fast : bool
        Run the steady filter, once its gain has converged, as an FFT
        convolution; False: the step-by-step recursion throughout, which
        keeps every step's covariance for the smoother (N n^2 numbers: 25 MB
        for a 38 s run of the Gaussian family's 25 states, 2 GB an hour).
    smooth : bool
        Run the smoother after the filter; False: no ``smoothed`` fields
        (the innovations and the first state alone, equal to an ulp, in
        about a third of the time on the demo's runs).

    Returns
    -------
    StateEstimate

    Examples
    --------
    A scalar model: the innovation variance converges to P + R, P the
    solution of the Riccati equation P = a^2 P R / (P + R) + q:

    >>> import numpy as np
    >>> import scipy.linalg
    >>> from bayes_jackal.filters import channel_model
    >>> from bayes_jackal.filters import kalman
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
    F, G, H = model.transition, model.input_matrix, model.observation
    Q, R = model.process_covariance, model.sensor_variance
    out = np.empty((4, len(y)))  # mean, variance, innovation, innovation variance
    states = np.empty((len(y), model.size))  # the filtered means m_k|k
    predictions = []  # P_k|k-1 of each step the recursion runs
    m, P = model.initial_mean, model.initial_covariance
    steady_from = len(y)
    for k in range(len(y)):
        predictions.append(P)
        if k < model.first_measured:  # not a measurement: the prediction stands
            filtered, out[2:, k] = P, np.nan
        else:
            m, filtered, _, out[2:, k] = _update(m, P, y[k], R, H)
        states[k], out[1, k] = m, filtered[0, 0]
        following = F @ filtered @ F.T + Q
        converged = np.abs(following - P).max() <= CONVERGED * np.abs(P).max()
        if fast and converged and k + 1 < len(y):
            steady_from = k + 1
            predictions.append(following)
            _steady(model, following, y[k + 1 :], inputs[k:-1], out[:, k + 1 :], states[k:],
                    every_state=smooth)  # fmt: skip
            break
        m, P = F @ m + G @ inputs[k], following
    smoothed = (
        _smoothed(model, states, predictions, out[2:], inputs, steady_from)
        if smooth
        else (None, None)
    )
    return StateEstimate(
        states[:, 0], *out[1:], steady_from=steady_from, smoothed=smoothed[0],
        smoothed_variance=smoothed[1],
    )  # fmt: skip


def _update(
    m: np.ndarray, P: np.ndarray, y: float, R: float, H: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float]]:
    """Measurement update of the predicted (m, P): filtered mean and covariance, gain, (nu, S)."""
    S = H @ P @ H + R
    gain = P @ H / S
    innovation = y - H @ m
    reduce = np.eye(len(m)) - np.outer(gain, H)
    filtered = reduce @ P @ reduce.T + R * np.outer(gain, gain)
    return m + gain * innovation, filtered, gain, (innovation, S)


def _steady(
    model: ChannelModel,
    P: np.ndarray,
    y: np.ndarray,
    inputs: np.ndarray,
    out: np.ndarray,
    states: np.ndarray,
    *,
    every_state: bool = True,
) -> None:
    """The steps after the filtered mean ``states[0]``, at the converged P_k+1|k ``P``.

    m_i = A^(i+1) m + sum_j A^j C p_(i-j) with p_i = (y_i, u_(i-1)) and
    C = [K, (I - K H) G] (:func:`~bayes_jackal.filters.lti_outputs`); the
    prediction of y_i is H (F m_(i-1) + G u_(i-1)). Fills ``states[1:]``
    (the filtered means) and ``out`` (4, L) but for its row 0. Without
    ``every_state`` (no smoother to follow), only the first state and the
    prediction H F m_i are convolved: 2 outputs instead of n (25 for the
    Gaussian family), and ``states[1:, 1:]`` is left as it is.
    """
    F, G, H = model.transition, model.input_matrix, model.observation
    _, filtered, gain, (_, S) = _update(np.zeros(len(P)), P, 0.0, model.sensor_variance, H)
    reduce = np.eye(len(P)) - np.outer(gain, H)
    A, C = reduce @ F, np.column_stack([gain, reduce @ G])
    drive = np.column_stack([y, inputs])  # p_i = (y_i, u_(i-1)), (L, 3)
    if every_state:
        states[1:] = lti_outputs(A, C, drive, states[0], tolerance=TRUNCATION)
        predicted = states[:-1] @ (H @ F)
    else:  # rows: the first state, and H F m_i
        outputs = np.vstack([np.eye(len(P))[0], H @ F])
        first, following = lti_outputs(A, C, drive, states[0], outputs=outputs,
                                       tolerance=TRUNCATION).T  # fmt: skip
        states[1:, 0] = first
        predicted = np.concatenate([[states[0] @ (H @ F)], following[:-1]])
    predicted = predicted + inputs @ (H @ G)
    out[1], out[2], out[3] = filtered[0, 0], y - predicted, S


def _smoothed(
    model: ChannelModel,
    states: np.ndarray,
    predictions: list[np.ndarray],
    innovations: np.ndarray,
    inputs: np.ndarray,
    steady_from: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The Rauch-Tung-Striebel smoother's mean and variance of x, from the filter's pass.

    In the modified Bryson-Frazier form (Bierman 1977), which inverts no
    covariance (a shaping filter's states are nearly collinear, and the
    RTS gain's inverse of P_k+1|k loses digits there):

        s_k = m_k|k-1 + P_k|k-1 lam_k,   lam_k = H' nu_k / S_k + A_k' lam_k+1,
        P^s_k = P_k|k-1 - P_k|k-1 Lam_k P_k|k-1,   Lam_k = H' H / S_k + A_k' Lam_k+1 A_k,

    A_k = F (I - K_k H), lam_N = 0, Lam_N = 0; a sample that is no
    measurement has K_k = 0 and no nu term. Where the filter ran with its
    converged gain, A is constant and lam an LTI recursion in reversed time
    (:func:`~bayes_jackal.filters.lti_outputs`); Lam is iterated back from the
    end until it converges.

    ``predictions`` holds P_k|k-1 of each step the filter's recursion ran
    and, after a steady filter's, its converged P; ``innovations`` (2, N)
    holds nu_k and S_k.
    """
    F, G, H, R = model.transition, model.input_matrix, model.observation, model.sensor_variance
    count, size = states.shape
    start = np.vstack([model.initial_mean, states[:-1] @ F.T + inputs[:-1] @ G.T])  # m_k|k-1
    nu, S = innovations
    weight = np.where(np.arange(count) < model.first_measured, 0.0, 1.0 / S)  # 1 / S_k or 0
    nu = np.where(weight > 0, nu, 0.0)
    mean, variance = np.empty(count), np.empty(count)
    lam, Lam = np.zeros(size), np.zeros((size, size))
    first = count
    if steady_from < count:  # samples steady_from .. N - 1 have the converged gain
        P = predictions[-1]
        gain = P @ H / (H @ P @ H + R)
        A = F @ (np.eye(size) - np.outer(gain, H))
        back = np.arange(count - 1, steady_from - 1, -1)
        drive = (nu * weight)[back, None]
        path = lti_outputs(A.T, H[:, None], drive, lam, tolerance=TRUNCATION)
        mean[back] = start[back, 0] + path @ P[0]
        lam, first = path[-1], steady_from
        spread = []
        for k in back:  # until Lam converges; then it stays
            following = np.outer(H, H) * weight[k] + A.T @ Lam @ A
            converged = np.abs(following - Lam).max() <= CONVERGED * np.abs(following).max()
            Lam = following
            spread.append(P[0, 0] - P[0] @ Lam @ P[0])
            if converged:
                break
        variance[back] = spread[-1]
        variance[back[: len(spread)]] = spread
    for k in range(first - 1, -1, -1):
        P = predictions[k]
        gain = P @ H * weight[k]
        A = F @ (np.eye(size) - np.outer(gain, H))
        lam = H * nu[k] * weight[k] + A.T @ lam
        Lam = np.outer(H, H) * weight[k] + A.T @ Lam @ A
        mean[k] = start[k, 0] + P[0] @ lam
        variance[k] = P[0, 0] - P[0] @ Lam @ P[0]
    return mean, variance


def kalman_filter(
    experiment: Experiment,
    prior: ActiveInferencePrior | Mapping,
    *,
    noise: str = "coloured",
    channels: Sequence[str] | None = None,
    parameters: str = "plug-in",
    robot: RobotProfile | None = None,
    initial_variance: float = DIFFUSE,
    fast: bool = True,
    smooth: bool = True,
) -> dict[str, StateEstimate]:
    """The Kalman filter of every channel of an experiment, with an exported prior's model.

    Parameters
    ----------
    experiment : Experiment
    prior : ActiveInferencePrior or mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`,
        :func:`bayes_jackal.dem.read_prior`), or its JSON as a mapping
        (:meth:`bayes_jackal.dem.ActiveInferencePrior.from_json` checks it).
    noise : {"coloured", "white"}
        ``kalman-coloured`` or ``kalman`` (:data:`KALMAN_FILTERS`,
        :func:`bayes_jackal.filters.filter_models`).
    channels : sequence of str, optional
        By default every channel of the prior.
    parameters : {"plug-in", "averaged"}
        The noise parameters at their posterior means, or Q and R averaged
        over the prior's draws (:func:`bayes_jackal.filters.filter_models`).
    robot : RobotProfile, optional
        When given, its constants must be the prior's.
    initial_variance : float
        Variance of the state one step before the run, around 0 [channel
        units^2]: :data:`DIFFUSE` by default; 0: the run starts at rest.
    fast, smooth : bool
        See :func:`kalman`.

    Returns
    -------
    dict of str to StateEstimate

    Raises
    ------
    InputError
        For a prior with a field missing or of the wrong type, of another
        robot or rate, or without a channel asked for
        (:func:`bayes_jackal.filters.check_prior`).
    DataError
        When the experiment does not measure a channel.

    Examples
    --------
    Both filters on a simulated run with Gaussian-coloured noise, with a prior
    holding the simulation's truth (``bj.export_prior`` writes one from a
    posterior): the coloured filter tracks the true yaw rate more closely.

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import kalman_filter
    >>> from bayes_jackal.model import discrete_matrices
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
    prior = ActiveInferencePrior.from_json(prior)
    channels = check_prior(prior, experiment, channels, robot=robot)
    estimates = {}
    for channel in channels:
        y, samples = measured_series(experiment, channel)
        [model] = filter_models(
            prior,
            noise=noise,
            channels=[channel],
            parameters=parameters,
            initial_variance=initial_variance,
            pose_samples=samples,
        ).values()
        estimates[channel] = kalman(model, y, experiment.inputs, fast=fast, smooth=smooth)
    return estimates
