"""A generalised filter (the DEM D-step) for the identified linear model.

Each channel c of the model is the scalar system, in continuous time,

    dx/dt = a x + b . u + w,     y = x + z,

with a = ``A[c, c]`` [1/s], b = ``B[c, :]``, w coloured process noise and z white
sensor noise. Generalised filtering (Friston 2008, "Hierarchical models in
the brain", DEM; Friston et al. 2010, "Generalised filtering") describes the
state by its generalised coordinates mu~ = (mu, mu', .., mu^(p)) of embedding
order p and lets them flow as

    d mu~/dt = D mu~ - K dF/dmu~,

with D the shift operator (D mu~ = (mu', .., mu^(p), 0)) and, for Gaussian
noise, the free energy (in nats, up to constants)

    F = 1/2 e_z' Pi_z e_z + 1/2 e_w' Pi_w e_w,
    e_z = y~ - mu~,   e_w = M mu~ - b . u~,   M = D - a I.

Pi_w is the process precision the prior exports, inv(V) / s_c^2
(:mod:`bayes_jackal.dem.export`), and Pi_z the sensor precision (below). For this
linear model the flow is linear with constant coefficients,

    d mu~/dt = J mu~ + K (Pi_z y~ + M' Pi_w b . u~),   J = D - K (Pi_z + M' Pi_w M),

and it is integrated with the local linearisation of SPM's ``spm_dx``
(Ozaki 1992): over a sample, with the data held, mu~[k] = expm(J dt)
mu~[k-1] + int_0^dt expm(J s) ds K (Pi_z y~[k] + M' Pi_w b . u~[k]), with
the generalised data of sample k, so the estimate at t_k uses the samples
up to t_k (and the embedding's look-ahead). The gain K is SPM's: ``spm_DEM`` runs the flow in
time bins with derivatives in bins (derivative i times dt^i) and unit gain,
which is K = diag(dt^(-2 i)) / dt in seconds.

The data's generalised coordinates y~ come from a local Taylor expansion of
p + 1 samples, as ``spm_DEM_embed`` (:mod:`bayes_jackal.filters.generalised_coordinates`);
the sensor precision is by default that of embedded white noise, T' T /
sigma_n^2 (:func:`~bayes_jackal.filters.white_sensor_precision`),
or SPM's Gaussian smoothness s_z exported with the prior.

A channel recorded as motion-capture poses (vx, vy of a bag) is measured
through its travel q (dq/dt = x; :mod:`bayes_jackal.filters.state_space`), so its
generalised state is the travel's, of one order more: mu~ = (q, q', ..,
q^(p+1)), whose derivatives q^(i+1) = x^(i) are the velocity's. The
sensor error is e_z = y~ - mu~ with y~ the embedded travel and Pi_z the
precision of the pose noise (sd sigma_p / sqrt(n) per sample), and the
process error reads the velocity's part, e_w = M S mu~ - b . u~ with
S = [0 | I]. The estimate is x = mu~[1].

Because the update is linear time-invariant, the filter is the convolution
of its impulse response expm(J dt)^m Gamma with the data (FFT), not a loop.
With the identified model's precisions the flow is stiff (every eigenvalue
of J dt lies below -3e4 for the simulated yaw channel at orders 1-3), expm(J dt) falls
below 1e-17 and the response is one sample long: each estimate is the
flow's moving equilibrium for its own window, and the filter remembers
nothing beyond its p + 1 samples, unlike a Kalman filter. The unit gain K
makes this depend on the channel's units, as in ``spm_DEM``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.linalg

from .._runtime import CHANNELS, LOOKAHEAD, SENSOR_PRECISIONS, InputError
from ..dem import (
    ActiveInferencePrior,
    checked_precision,
    continuous_sd,
    mean_covariance_precision,
    prior_field,
    temporal_covariance,
)
from ..io import Experiment
from ..model import DAMPING, RobotProfile, get_family
from .generalised_coordinates import embed, shift_operator, taylor_step, white_sensor_precision
from .kalman_filters import StateEstimate
from .lti import lti_outputs
from .state_space import (
    check_prior,
    measured_series,
    noise_parameters,
    parameter_values,
    prior_robot,
)

__all__ = ["TAIL", "conditional_covariance", "d_step", "generalised_filter", "process_precision"]


#: The impulse response is cut where expm(J dt)^m falls below this (relative
#: to 1): the terms left off are below double precision's rounding.
TAIL = 1e-17


def _check_precision(matrix: np.ndarray, size: int, name: str) -> np.ndarray:
    matrix = np.asarray(matrix, float)
    if matrix.shape != (size, size) or not np.isfinite(matrix).all():
        raise InputError(
            f"expected a finite ({size}, {size}) precision, got shape {matrix.shape}", field=name
        )
    return matrix


def _motion(a: float, order: int, size: int) -> np.ndarray:
    """M S: the process error's map from a generalised state of ``size`` (module docstring).

    M = D - a I on the velocity's p + 1 coordinates, which are the state's
    last p + 1: the whole state for a measured velocity (S = I), all but
    the travel for a pose channel (S = [0 | I]).
    """
    select = np.eye(order + 1, size, k=size - order - 1)
    return (shift_operator(order) - a * np.eye(order + 1)) @ select


def _flow(
    a: float, dt: float, process_precision: np.ndarray, sensor_precision: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """J and the input matrix G of d mu~/dt = J mu~ + G (y~, b . u~) (module docstring).

    With the free energy F above, dF/dmu~ = -Pi_z (y~ - mu~) + (M S)' Pi_w
    (M S mu~ - b . u~); the flow D mu~ - K dF/dmu~ collects into J mu~ + G c.
    """
    size = len(sensor_precision)
    M = _motion(a, len(process_precision) - 1, size)
    D = shift_operator(size - 1)
    K = np.diag(dt ** (-2.0 * np.arange(size))) / dt  # spm_DEM's unit gain in bins
    J = D - K @ (sensor_precision + M.T @ process_precision @ M)
    G = K @ np.hstack([sensor_precision, M.T @ process_precision])
    return J, G


def d_step(
    a: float,
    b: np.ndarray,
    dt: float,
    process_precision: np.ndarray,
    y: np.ndarray,
    u: np.ndarray,
    *,
    sensor_precision: np.ndarray,
    lookahead: int | None = None,
    initial: np.ndarray | None = None,
    travel: bool = False,
) -> np.ndarray:
    """The D-step estimate of one channel's state in generalised coordinates.

    For a channel recorded as poses (``travel``), ``y`` is its travel and
    ``sensor_precision`` one order larger than ``process_precision``: the
    state is then the travel's generalised coordinates (module docstring).

    Integrates d mu~/dt = D mu~ - K dF/dmu~ (module docstring: the model, F,
    the gain K of ``spm_DEM``) with the local linearisation, sample by
    sample with the data of each sample held:

        mu~[k] = Phi mu~[k-1] + Gamma G c[k],   Phi = expm(J dt),
        Gamma = int_0^dt expm(J s) ds,   c[k] = (y~[k], b . u~[k]).

    The update is linear time-invariant, so mu~ is computed at once as
    Phi^(k+1) mu~[-1] plus the convolution of the impulse response Phi^m
    with the forcing Gamma G c (overlap-add FFT), cut where Phi^m < 1e-17.

    Parameters
    ----------
    a : float
        The channel's pole ``A[c, c]`` [1/s].
    b : array_like, shape (m,)
        The channel's input row ``B[c, :]`` [units / s per input unit].
    dt : float
        Sample time [s].
    process_precision : array_like, shape (p + 1, p + 1)
        Pi_w of the continuous process noise in generalised coordinates
        (the export's inv(V) / s_c^2); its size sets the order p.
    y : array_like, shape (N,)
        Measurements [units], N >= p + 1: the state, or a pose channel's
        travel [m].
    u : array_like, shape (N, m)
        Inputs at the samples.
    sensor_precision : array_like, shape (p + 1, p + 1), or (p + 2, p + 2) with ``travel``
        Pi_z, e.g.
        :func:`~bayes_jackal.filters.white_sensor_precision`;
        of order p + 1 for a pose channel's travel.
    lookahead : int, optional
        Samples after t_k in the embedding window
        (:func:`~bayes_jackal.filters.embedding_operator`;
        SPM's floor(p / 2) by default, 0 for a causal filter).
    initial : array_like, shape (p + 1,), optional
        mu~ before the first sample; by default the embedded first measurement.
    travel : bool
        ``y`` is a pose channel's travel [m]: its generalised coordinates,
        one order more, are the state (module docstring).

    Returns
    -------
    ndarray, shape (N, p + 1) or (N, p + 2)
        mu~[k] = (x, x', .., x^(p)) estimated at t_k [units / s^j]; for a
        pose channel (q, x, .., x^(p)).

    Raises
    ------
    InputError
        For arrays of the wrong shape, non-finite values, or precisions
        under which the flow is not stable (J has an eigenvalue with a
        non-negative real part).

    Examples
    --------
    A noise-free run at the steady state x = -b u / a, started from rest:
    the estimate reaches the steady state, with zero derivatives:

    >>> import numpy as np
    >>> from bayes_jackal.filters import white_sensor_precision
    >>> from bayes_jackal.filters import d_step
    >>> a, b, dt = -20.0, np.array([0.5]), 0.01
    >>> u = np.ones((50, 1))
    >>> y = np.full(50, -0.5 / a)
    >>> Pw, Pz = np.diag([1.0, 1e-2, 1e-4]), white_sensor_precision(2, dt, 0.01)
    >>> mu = d_step(a, b, dt, Pw, y, u, sensor_precision=Pz, initial=np.zeros(3))
    >>> bool(np.allclose(mu[-1], [0.025, 0.0, 0.0], atol=1e-12))
    True
    """
    process_precision = np.asarray(process_precision, float)
    order = len(process_precision) - 1
    process_precision = _check_precision(process_precision, order + 1, "process_precision")
    size = order + 1 + travel
    sensor_precision = _check_precision(sensor_precision, size, "sensor_precision")
    y, u, b = np.asarray(y, float), np.asarray(u, float), np.atleast_1d(np.asarray(b, float))
    if y.ndim != 1 or u.shape != (len(y), len(b)):
        raise InputError(
            f"expected y of shape (N,) and u of shape (N, {len(b)}), got {y.shape} and {u.shape}",
            field="y",
        )
    if not (np.isfinite(y).all() and np.isfinite(u).all()):
        raise InputError("measurements and inputs must be finite", field="y")
    J, G = _flow(float(a), dt, process_precision, sensor_precision)
    if not np.linalg.eigvals(J).real.max() < 0:
        raise InputError(
            "the D-step flow is not stable with these precisions (J has an eigenvalue with "
            "real part >= 0): the filter would diverge",
            field="process_precision",
        )
    # Gamma = inv(J) (Phi - I), as spm_dx: J is stable, hence invertible, and the solve
    # keeps full precision where J dt is stiff (eigenvalues down to -5e6 for the yaw
    # channel at order 3), where the block exponential of physics.discretise loses digits
    Phi = scipy.linalg.expm(J * dt)
    forcing_matrix = np.linalg.solve(J, (Phi - np.eye(size)) @ G)
    data = np.hstack(
        [
            embed(y, size - 1, dt, lookahead=lookahead),
            embed(u @ b, order, dt, lookahead=lookahead),
        ]
    )
    start = data[0, :size] if initial is None else np.asarray(initial, float)
    if start.shape != (size,):
        raise InputError(f"expected shape ({size},), got {start.shape}", field="initial")
    return lti_outputs(Phi, forcing_matrix, data, start, tolerance=TAIL)


def conditional_covariance(
    a: float,
    process_precision: np.ndarray,
    sensor_precision: np.ndarray,
    *,
    travel: bool = False,
) -> np.ndarray:
    """The D-step's conditional covariance of mu~: inv(Pi_z + (M S)' Pi_w M S), M = D - a I.

    Under the Laplace assumption of DEM the conditional precision of the
    generalised state is the curvature of the free energy F (module
    docstring) in mu~, which for this linear model is constant.

    Parameters
    ----------
    a : float
        The channel's pole ``A[c, c]`` [1/s].
    process_precision, sensor_precision : array_like
        Pi_w (p + 1, p + 1) and Pi_z, as :func:`d_step` (one order more for a
        pose channel's travel).
    travel : bool
        As :func:`d_step`.

    Returns
    -------
    ndarray, shape of ``sensor_precision``
        [units / s^i x units / s^j].

    Examples
    --------
    At order 0 the precisions add: 1 / (1 / 4 + a^2 / 1):

    >>> from bayes_jackal.filters import conditional_covariance
    >>> conditional_covariance(-2.0, [[1.0]], [[0.25]]).tolist()
    [[0.23529411764705882]]
    """
    process_precision = np.atleast_2d(np.asarray(process_precision, float))
    order = len(process_precision) - 1
    size = order + 1 + travel
    sensor_precision = _check_precision(sensor_precision, size, "sensor_precision")
    M = _motion(a, order, size)
    return np.linalg.inv(sensor_precision + M.T @ process_precision @ M)


def process_precision(
    prior: ActiveInferencePrior | Mapping, channel: str, order: int, *, parameters: str = "plug-in"
) -> np.ndarray:
    """Pi_w of one channel at embedding order p, from an exported prior's noise parameters.

    inv(s_c^2 V) (:func:`bayes_jackal.dem.temporal_covariance`), with
    s_c the continuous-time sd (:func:`bayes_jackal.dem.continuous_sd`,
    each draw's damping in its pole). ``plug-in`` evaluates it at the
    posterior means; ``averaged`` inverts the draws' mean covariance,
    E[s_c^2 V] (:func:`bayes_jackal.dem.mean_covariance_precision`,
    the export's ``precision_mean_covariance``): the Gaussian that matches
    the noise's covariance under the posterior, as the Kalman filters
    average Q. (The draws' mean precision, E[inv(V) / s_c^2], the export's
    ``precision``, is larger by Jensen's inequality: twice the plug-in on a
    wide posterior, where it makes the filter trust a poorly identified model.)

    Parameters
    ----------
    prior : ActiveInferencePrior or mapping
        An exported prior, or a mapping holding the fields read here
        (``robot``, ``dt``, ``noise``, ``damping.mean``, ``draws``), as
        :func:`bayes_jackal.filters.filter_models`.
    channel : str
        One of its channels.
    order : int
        Embedding order p: at most the family's
        (:meth:`bayes_jackal.model.Family.check_order`), and one whose
        precision keeps 4 significant digits at these parameters
        (:func:`bayes_jackal.dem.checked_precision`, as ``export-prior``).
    parameters : {"plug-in", "averaged"}
        As :func:`bayes_jackal.filters.noise_parameters`.

    Returns
    -------
    ndarray, shape (p + 1, p + 1)
        [s^(i + j + 2) / units^2]: w is in units / s (dx/dt = a x + b u + w).

    Examples
    --------
    At order 0 it is 1 / s_c^2; at order 1 the Gaussian family adds the
    derivative's precision 2 sigma_h^2 / s_c^2:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.dem import continuous_sd
    >>> from bayes_jackal.filters import process_precision
    >>> robot = bj.load_profile()
    >>> prior = {"robot": {"name": "jackal"}, "dt": robot.dt, "damping": {"mean": [110.0, 30.0]},
    ...          "noise": {"family": "gaussian", "channels": ["vx"], "sensor": "ma1",
    ...                    "parameters": {"sigma_h": {"mean": 0.05}, "sigma_c": {"mean": 0.01},
    ...                                   "sigma_n": {"mean": 0.005}}}}
    >>> s = continuous_sd(robot, np.array([[110.0, 30.0]]), robot.dt, ["vx"], np.array([[0.01]]))
    >>> Pw = process_precision(prior, "vx", 1)
    >>> bool(np.allclose(Pw, np.diag([1.0, 2 * 0.05**2]) / s[0, 0] ** 2))
    True
    """
    family = str(prior_field(prior, "noise.family"))
    get_family(family).check_order(order)
    width, sigma_c, _ = noise_parameters(prior, channel, parameters=parameters)
    damping = parameter_values(prior, parameters=parameters)[:, : len(DAMPING)]
    dt = float(prior_field(prior, "dt"))
    sd = continuous_sd(prior_robot(prior), damping, dt, [channel], sigma_c[:, None])
    _, V, _ = checked_precision(family, width[:, None], sd, order, dt=dt)
    return mean_covariance_precision(V, sd)


def generalised_filter(
    experiment: Experiment,
    prior: ActiveInferencePrior | Mapping,
    *,
    channels: Sequence[str] | None = None,
    order: int | None = None,
    parameters: str = "plug-in",
    sensor_precision: str = SENSOR_PRECISIONS[0],
    lookahead: int = LOOKAHEAD,
    robot: RobotProfile | None = None,
) -> dict[str, StateEstimate]:
    """Run the generalised filter (:func:`d_step`) on an experiment with an exported prior.

    Each channel uses the prior's model at the posterior mean (a = A[c, c],
    b = B[c, :]) and its process precision (:func:`process_precision`).
    Its prediction of y_k is the estimate at t_(k-1) carried one sample by
    the generalised motion, t . mu~[k-1]
    (:func:`~bayes_jackal.filters.taylor_step`), with the
    variance t' Sigma t + sigma_n^2, Sigma the D-step's conditional
    covariance (:func:`conditional_covariance`): the filter's own account of
    its uncertainty, checked by the normalised innovations
    (:func:`bayes_jackal.filters.score_estimates`).

    Parameters
    ----------
    experiment : Experiment
        Measurements and wheel speeds, at the prior's sample time.
    prior : ActiveInferencePrior or mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`,
        :func:`bayes_jackal.dem.read_prior`), or its JSON as a mapping
        (:meth:`bayes_jackal.dem.ActiveInferencePrior.from_json` checks it).
    channels : sequence of str, optional
        Channels to filter; by default every channel of the prior.
    order : int, optional
        Embedding order p; by default the prior's (``generalised_coordinates.order``).
    parameters : {"plug-in", "averaged"}
        Pi_w and Pi_z at the posterior means, or the inverses of the
        covariances averaged over the draws (:func:`process_precision`).
    sensor_precision : {"white", "exported"}
        Pi_z (:data:`SENSOR_PRECISIONS`): embedded white noise at the sensor
        sd, or the Gaussian smoothness the prior exports (``sensor_noise``).
    lookahead : int
        Samples after t_k in the embedding (:data:`LOOKAHEAD`: causal).
    robot : RobotProfile, optional
        When given, its constants must be the prior's.

    Returns
    -------
    dict of str to StateEstimate
        Per channel: the state, its conditional variance, the prediction
        error and its variance (NaN at the first sample, which has no
        estimate before it, and everywhere with a look-ahead, where the
        estimate at t_(k-1) has seen y_k), and ``derivatives``, mu~ shaped
        (N, p + 1).

    Raises
    ------
    InputError
        For a prior that does not fit the experiment
        (:func:`bayes_jackal.filters.check_prior`), an order the
        family's noise does not have, an unknown ``sensor_precision``, or a
        prior without a sensor-noise sd (white noise fitted with one total sd).
    DataError
        For a channel the experiment does not measure.

    Examples
    --------
    The prior of one simulated run's posterior (a chain capped at 20 steps
    to keep the example quick: a ConvergenceWarning), on another run: the
    causal order-2 filter's estimate is closer to the true yaw rate than the
    measurement is:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=seed) for seed in (1, 2)]
    >>> posterior = bj.sample(runs[:1], family="gaussian", channels=["yaw"], max_steps=20, seed=1)
    >>> prior = bj.export_prior(posterior, order=2)
    >>> estimate = bj.filters.generalised_filter(runs[1], prior)["yaw"]
    >>> def rmse(x):
    ...     return float(np.sqrt(np.mean((x - runs[1].truth_arrays["yaw_state"]) ** 2)))
    >>> estimate.derivatives.shape[1], rmse(estimate.mean) < rmse(runs[1].yaw_rate)
    (3, True)
    """
    prior = ActiveInferencePrior.from_json(prior)
    channels = check_prior(prior, experiment, channels, robot=robot)
    if sensor_precision not in SENSOR_PRECISIONS:
        raise InputError(
            f"unknown sensor precision {sensor_precision!r}; use one of {SENSOR_PRECISIONS}",
            field="sensor_precision",
        )
    if prior_field(prior, "sensor_noise") is None:
        raise InputError(
            "the prior has no sensor-noise sd (its noise fit has one total sd), which the "
            "generalised filter needs",
            field="sensor_noise",
        )
    dt = float(prior.dt)
    if order is None:
        order = int(prior_field(prior, "generalised_coordinates.order"))
    A = np.asarray(prior_field(prior, "model.A"), float)
    B = np.asarray(prior_field(prior, "model.B"), float)
    estimates = {}
    for channel in channels:
        row = CHANNELS.index(channel)
        y, samples = measured_series(experiment, channel)
        travel = int(experiment.measurement(channel) == "pose")  # the travel's extra order
        Pw = process_precision(prior, channel, order, parameters=parameters)
        Pz, variance = _sensor_precision(
            prior, channel, order + travel, dt, parameters, sensor_precision, lookahead, samples
        )
        mu = d_step(A[row, row], B[row], dt, Pw, y, experiment.inputs, sensor_precision=Pz,
                    lookahead=lookahead, travel=bool(travel))  # fmt: skip
        Sigma = conditional_covariance(A[row, row], Pw, Pz, travel=bool(travel))
        step = taylor_step(order + travel, dt)
        predicted = np.full(len(y), np.nan)
        if lookahead == 0:  # with a look-ahead the estimate at t_(k-1) has seen y_k
            predicted[1:] = mu[:-1] @ step
        spread = step @ Sigma @ step + variance
        estimates[channel] = StateEstimate(
            mean=mu[:, travel],
            variance=np.full(len(y), Sigma[travel, travel]),
            innovation=y - predicted,
            innovation_variance=np.concatenate([[np.nan], np.full(len(y) - 1, spread)]),
            steady_from=order + 1 + travel,  # the first window inside the run
            derivatives=mu[:, travel:],
        )
    return estimates


def _sensor_precision(
    prior: ActiveInferencePrior,
    channel: str,
    order: int,
    dt: float,
    parameters: str,
    choice: str,
    lookahead: int,
    samples: int,
) -> tuple[np.ndarray, float]:
    """Pi_z of one channel's measurement at ``order``, and the sensor variance E[sd^2].

    Embedded white noise, or the prior's Gaussian s_z, per E[sigma_n^2]; for
    a pose channel per E[sigma_p^2] / n, n the poses averaged per sample.
    """
    _, _, sd = noise_parameters(prior, channel, parameters=parameters)
    variance = float(np.mean(sd**2)) / samples
    if choice == "white":
        shape = white_sensor_precision(order, dt, 1.0, lookahead=lookahead)
    else:
        seconds = float(prior_field(prior, "sensor_noise.smoothness_seconds"))
        shape = np.linalg.inv(temporal_covariance("gaussian", np.array(seconds), order))
    return shape / variance, variance
