"""Linear Gaussian state-space models of each channel, built from an exported prior.

The identified model is one scalar recursion per channel c (A is diagonal,
:func:`bayes_jackal.model.channel_coefficients`),

    x[k+1] = alpha x[k] + b . u[k] + w[k] (+ sigma_n v[k], "diagonal" sensor),
    y[k]   = x[k] + n[k]                  (n ~ N(0, sigma_n^2), "ma1" sensor),

with u = (omega_r, omega_l) [rad/s] and w = sigma_c (taps * e), e white: the
noise family's unit-energy kernel (:mod:`bayes_jackal.model.kernels`). Its shaping
filter has an exact state-space realisation,
:meth:`bayes_jackal.model.Family.realisation` (T, g, c, d): the taps in
observable form for the finite kernels (T shifts up, c = e_1, g the taps
after the first, d the first), one AR(1) state for the exponential family,
none for white noise. Augmenting x with the filter's state z (scaled by
sigma_c) gives the model a Kalman filter runs on, s = (x, z):

    s[k+1] = F s[k] + G u[k] + Gamma eps[k],   eps ~ N(0, I),   y[k] = s[k][0] + n[k]

    F = [[alpha, c'], [0, T]],  G = [[b], [0]],
    Gamma = [[sigma_c d, nugget], [sigma_c g, 0]],  R = var(n),

where nugget = sigma_n and R = 0 for the ``diagonal`` sensor term (the
likelihood's residual is w + sigma_n v: white noise in the state update and
an exact measurement, so a filter's estimate there is the measurement
itself), nugget = 0 and R = sigma_n^2 for ``ma1``. The ``white`` model is the
same with the white family's realisation: process noise of the same
variance per step, sigma_c^2 + nugget^2 (the taps have unit energy), but no
memory. (alpha, b) are the prior's ``model.Ad``, ``model.Bd`` at the
posterior mean of the damping. The noise parameters are either plug-ins,
the width, sigma_c and sigma_n at their posterior means
(``noise.parameters``), or ``averaged``: Q and R averaged over the prior's
draws (``draws``). The covariance of (x, y) is linear in Q and R, so the
averaged model's Kalman filter is the best linear estimator under the
noise parameters' posterior spread, as the exported precision Pi is
averaged over draws (:func:`channel_model`). The damping stays at its
mean: its posterior is narrow, and a spread pole would not give a
stationary model of one transition.

The run is taken to start at rest: x[-1] = 0 (variance
``initial_variance``), u[-1] = 0, with the shaping filter's state in its
stationary distribution, as :func:`bayes_jackal.io.simulate_experiment`
starts its runs. So x[0] = w[-1] (+ sigma_n v[-1]) a priori.

A channel recorded as motion-capture poses (vx, vy of a bag;
:mod:`bayes_jackal.likelihood.measurements`) is measured through its travel q, the
sum of the body-frame increments, not its velocity. Its state gains q,
which the step's integral of the held model moves (g, h as there):

    q[k+1] = q[k] + g x[k] + (h / g) (b . u[k] + w[k]),   y[k] = q[k] + e[k],

with R = sigma_p^2 / n, the pose noise of a sample that averages n
recorded poses. The measured travel Q_k = M_0 + .. + M_(k-1) is q_k + e_k
- e_0 (:func:`bayes_jackal.io.body_displacement`): the state
q' = q - e_0 starts at 0 with the variance R, and is measured with white
noise from the second sample on; the first, Q_0 = 0, says nothing and is
not a measurement (:attr:`ChannelModel.first_measured`). The estimate is x,
the velocity.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .._runtime import CHANNELS, FILTER_PARAMETERS, SENSOR, SENSOR_MODELS, InputError
from ..dem import ActiveInferencePrior, prior_field, prior_layout
from ..io import Experiment, body_displacement, tick_poses
from ..model import DAMPING, Family, RobotProfile, get_family, load_profile, step_integrals
from ..posterior import ROBOT_CONSTANTS

__all__ = [
    "NOISE_MODELS",
    "PARAMETERS",
    "PRIOR_RATE_TOLERANCE",
    "ChannelModel",
    "channel_model",
    "check_prior",
    "filter_models",
    "measured_series",
    "noise_parameters",
    "parameter_values",
    "prior_robot",
]

#: The process-noise models a filter can assume: the prior's family
#: (``coloured``, the shaping filter in the state) or white noise of the
#: same variance per step (``white``).
NOISE_MODELS = ("coloured", "white")
#: The noise parameters of a model: at their posterior means, or Q and R
#: averaged over the prior's draws (:func:`channel_model`).
PARAMETERS = FILTER_PARAMETERS
#: Largest relative difference between an experiment's sample time and the
#: prior's: the discrete pole is exp(a dt), so 1 % in dt moves ln(alpha) by 1 %.
PRIOR_RATE_TOLERANCE = 0.01


@dataclass(frozen=True)
class ChannelModel:
    """The linear Gaussian state-space model of one channel (module docstring).

    s[k+1] = F s[k] + G u[k] + Gamma eps[k] with eps ~ N(0, I); the
    measurement is y[k] = H s[k] + n[k] with var(n) = R: the state x_c
    (H = e_0') for a rate channel, its travel q for a pose channel. The
    estimated state is ``s[k][0]``, x_c.

    Attributes
    ----------
    channel : str
        ``vx``, ``vy`` or ``yaw``.
    transition : ndarray, shape (n, n)
        F [-].
    input_matrix : ndarray, shape (n, 2)
        G [channel units / (rad/s)]: only row 0, Bd[c, :], is non-zero.
    noise_matrix : ndarray, shape (n, q)
        Gamma [channel units].
    sensor_variance : float
        R [channel units^2; m^2 for a pose channel].
    initial_mean, initial_covariance : ndarray, shapes (n,), (n, n)
        The state's prior at k = 0.
    observation : ndarray, shape (n,)
        H: e_0 for a rate channel, the travel's unit vector for a pose channel.
    first_measured : int
        The first sample that is a measurement: 0, or 1 for a pose channel
        (its travel is 0 at the first sample by definition).

    Examples
    --------
    The white model of the yaw channel has one state; its process variance
    per step is sigma_c^2:

    >>> from bayes_jackal.filters import channel_model
    >>> model = channel_model("yaw", 0.72, [0.026, -0.026], family="white", width=1.0,
    ...                       sigma_c=0.01, sigma_n=0.005, dt=1 / 72)
    >>> model.size, round(float(model.process_covariance[0, 0]), 12), model.sensor_variance
    (1, 0.0001, 2.5e-05)
    """

    channel: str
    transition: np.ndarray
    input_matrix: np.ndarray
    noise_matrix: np.ndarray
    sensor_variance: float
    initial_mean: np.ndarray
    initial_covariance: np.ndarray
    observation: np.ndarray
    first_measured: int = 0

    @property
    def size(self) -> int:
        """Number of states n."""
        return len(self.transition)

    @property
    def process_covariance(self) -> np.ndarray:
        """Q = Gamma Gamma' [channel units^2], shape (n, n)."""
        return self.noise_matrix @ self.noise_matrix.T


def channel_model(
    channel: str,
    alpha: float,
    input_row: Sequence[float],
    *,
    family: str,
    width: float | np.ndarray,
    sigma_c: float | np.ndarray,
    sigma_n: float | np.ndarray,
    dt: float,
    sensor: str = SENSOR,
    initial_variance: float = 0.0,
    measurement: str = "rate",
    samples: int = 1,
) -> ChannelModel:
    """The augmented model of one channel with the noise of ``family``.

    With several draws of the noise parameters the model's Q and R are
    their averages over the draws: the covariance of (x, y) is linear in Q
    and R, so this is the model whose Kalman filter is the best linear
    estimator under the draws' spread (at the fixed pole and input row).
    Averaging Q needs a transition shared by the draws: a family whose
    realisation's T or c depends on the width (the exponential family's
    AR(1)) is realised by its taps in observable form instead
    (:meth:`bayes_jackal.model.Family.realisation` of the base class).

    Parameters
    ----------
    channel : str
    alpha : float
        Discrete pole ``Ad[c, c]`` [-].
    input_row : sequence of 2 floats
        ``Bd[c, :]`` [channel units / (rad/s)].
    family : str
        Noise family (:data:`bayes_jackal.model.FAMILIES`); ``"white"`` for
        the white-noise model.
    width : float or ndarray, shape (D,)
        The family's width [s] (ignored for white noise); D draws.
    sigma_c, sigma_n : float or ndarray, shape (D,)
        Process-noise sd per step and sensor-noise sd [channel units]; for
        a pose channel the pose noise sigma_p per recorded pose [m].
    dt : float
        Sample time [s].
    sensor : {"ma1", "diagonal"}
        How a rate channel's sensor noise enters (module docstring).
    initial_variance : float
        Variance of x[-1] about 0 [channel units^2]; 0: the run starts at rest.
    measurement : {"rate", "pose"}
        How the channel was recorded (:data:`bayes_jackal.io.MEASUREMENTS`).
    samples : int
        A pose channel's recorded poses per sample, n: R = sigma_p^2 / n.

    Returns
    -------
    ChannelModel
        Its ``noise_matrix`` is [Gamma_1, .., Gamma_D] / sqrt(D), so that
        Q = Gamma Gamma' is the draws' mean of Gamma_d Gamma_d'.

    Examples
    --------
    The Gaussian filter of sigma_h = 0.047 s at 72 Hz has 23 taps: x and 22
    states of the taps' observable form. The process noise x receives has
    variance sigma_c^2 per step, as the white model's:

    >>> from bayes_jackal.filters import channel_model
    >>> model = channel_model("yaw", 0.72, [0.026, -0.026], family="gaussian",
    ...                       width=0.047, sigma_c=0.01, sigma_n=0.005, dt=1 / 72)
    >>> model.size
    23
    >>> import scipy.linalg
    >>> F, Q = model.transition, model.process_covariance
    >>> stationary = scipy.linalg.solve_discrete_lyapunov(F[1:, 1:], Q[1:, 1:])
    >>> round(float(F[0, 1:] @ stationary @ F[0, 1:] + Q[0, 0]), 12)
    0.0001

    The vx channel recorded as poses at 5 poses per sample gains its travel,
    measured with the pose noise's variance sigma_p^2 / 5:

    >>> pose = channel_model("vx", 0.9, [0.005, 0.005], family="white", width=1.0,
    ...                      sigma_c=0.005, sigma_n=5e-4, dt=1 / 72, measurement="pose",
    ...                      samples=5)
    >>> pose.size, pose.observation.tolist(), pose.sensor_variance
    (2, [0.0, 1.0], 5e-08)
    """
    if sensor not in SENSOR_MODELS:
        raise InputError(
            f"unknown sensor model {sensor!r}; use one of {SENSOR_MODELS}", field="sensor"
        )
    width, sigma_c, sigma_n = np.broadcast_arrays(*np.atleast_1d(width, sigma_c, sigma_n))
    shaping = get_family(family)
    T, g, c, d = _realisation(shaping.realisation, width, dt)
    if T is None:
        T, g, c, d = _realisation(functools.partial(Family.realisation, shaping), width, dt)
    m, draws = len(T), len(width)
    F = np.block([[np.array([[alpha]]), c[None, :]], [np.zeros((m, 1)), T]])
    G = np.zeros((m + 1, 2))
    G[0] = input_row
    diagonal = sensor == "diagonal" and measurement == "rate"
    nugget, R = (sigma_n, 0.0) if diagonal else (0.0 * sigma_n, np.mean(sigma_n**2))
    Gamma = np.zeros((draws, m + 1, 2))  # per draw: (e, v) -> (x, z)
    Gamma[:, 0, 0], Gamma[:, 0, 1] = sigma_c * d, nugget
    Gamma[:, 1:, 0] = sigma_c[:, None] * g
    Gamma = np.concatenate(Gamma, axis=1) / np.sqrt(draws)
    Q = Gamma @ Gamma.T
    before = scipy.linalg.block_diag(
        [[initial_variance]], scipy.linalg.solve_discrete_lyapunov(T, Q[1:, 1:])
    )
    model = ChannelModel(
        channel=channel,
        transition=F,
        input_matrix=G,
        noise_matrix=Gamma,
        sensor_variance=float(R),
        initial_mean=np.zeros(m + 1),
        initial_covariance=F @ before @ F.T + Q,
        observation=np.eye(m + 1)[0],
    )
    if measurement == "pose":
        return _with_travel(model, alpha, dt, np.mean(sigma_n**2) / samples)
    return model


def _with_travel(model: ChannelModel, alpha: float, dt: float, variance: float) -> ChannelModel:
    """A pose channel's model: the state gains the travel q, which y measures (module docstring).

    q[k+1] = q[k] + g x[k] + (h / g) (b . u[k] + w[k]): the travel's row is
    g times x's unit vector plus h / g times x's own row (its noise and
    input too), with R the pose noise's ``variance``.
    """
    n = model.size
    g, h = (float(v) for v in step_integrals(alpha, dt))
    h_over_g = h / g
    F = np.zeros((n + 1, n + 1))
    F[:n, :n] = model.transition
    F[n, :n] = h_over_g * model.transition[0]
    F[n, 0] = g
    F[n, n] = 1.0
    G = np.vstack([model.input_matrix, h_over_g * model.input_matrix[0]])
    Gamma = np.vstack([model.noise_matrix, h_over_g * model.noise_matrix[0]])
    return ChannelModel(
        channel=model.channel,
        transition=F,
        input_matrix=G,
        noise_matrix=Gamma,
        sensor_variance=float(variance),
        initial_mean=np.zeros(n + 1),
        initial_covariance=scipy.linalg.block_diag(model.initial_covariance, [[variance]]),
        observation=np.eye(n + 1)[n],
        first_measured=1,
    )


def _realisation(realise, width: np.ndarray, dt: float) -> tuple:
    """(T, g, c, d) of D widths: T, c shared, g (D, m), d (D,); T None when T or c vary."""
    T, g, c, d = realise(width, dt)
    m = np.shape(g)[-1]
    T, c = np.broadcast_to(T, (len(width), m, m)), np.broadcast_to(c, (len(width), m))
    if not ((T == T[0]).all() and (c == c[0]).all()):
        return None, None, None, None
    return T[0], np.broadcast_to(g, (len(width), m)), c[0], np.broadcast_to(d, width.shape)


def _prior_channels(
    prior: ActiveInferencePrior | Mapping, channels: Sequence[str] | None
) -> tuple[str, ...]:
    """The channels asked for (None: all the prior's), each one the prior has."""
    known = list(prior_field(prior, "noise.channels"))
    channels = tuple(known if channels is None else channels)
    missing = [c for c in channels if c not in known]
    if missing:
        raise InputError(
            f"the prior has no channel {missing[0]!r}; it has {known}", field="channels"
        )
    return channels


def check_prior(
    prior: ActiveInferencePrior | Mapping,
    experiment: Experiment,
    channels: Sequence[str] | None = None,
    *,
    robot: RobotProfile | None = None,
) -> tuple[str, ...]:
    """Check that a prior fits an experiment; the channels to filter.

    Parameters
    ----------
    prior : ActiveInferencePrior or mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`,
        :func:`bayes_jackal.dem.read_prior`), or its JSON as a mapping
        (:meth:`bayes_jackal.dem.ActiveInferencePrior.from_json` checks it).
    experiment : Experiment
    channels : sequence of str, optional
        Channels to filter; by default every channel of the prior.
    robot : RobotProfile, optional
        When given, its constants must be the prior's.

    Returns
    -------
    tuple of str

    Raises
    ------
    InputError
        For a prior of another format, a field the filters read missing or
        of the wrong type, a number they cannot trust (a parameter that is
        not finite and positive, a model matrix of the wrong shape, not
        finite or unstable: :func:`bayes_jackal.dem.check_prior_fields`),
        or a prior of another robot or sample time (beyond
        :data:`PRIOR_RATE_TOLERANCE`) or without a channel asked for, naming the
        field and value.
    DataError
        When the experiment does not measure a channel.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import check_prior
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> prior = {"format": "bayes_jackal.prior/1", "dt": 1 / 36, "robot": {"name": "jackal"},
    ...          "damping": {"mean": [110.0, 30.0]}, "model": {},
    ...          "noise": {"family": "white", "channels": ["yaw"],
    ...                    "parameters": {"sigma_c": {"mean": 0.01}, "sigma_n": {"mean": 0.005}}}}
    >>> try:
    ...     check_prior(prior, run)
    ... except ValueError as error:
    ...     print(error)
    dt: the prior is for 36 Hz (dt = 0.02778 s), the experiment is sampled at 72 Hz
    (dt = 0.01389 s)
    """
    prior = ActiveInferencePrior.from_json(prior)
    constants = prior.robot
    name = experiment.provenance.get("robot")
    if name is not None and name != constants.get("name"):
        raise InputError(
            f"the prior is for robot {constants.get('name')!r}, the experiment is of {name!r}",
            field="robot",
        )
    # Where the profile came from is no constant: a prior exported elsewhere fits.
    physical = [key for key in ROBOT_CONSTANTS if key != "source"]
    for key in physical if robot is not None else ():
        if constants.get(key) != getattr(robot, key):
            raise InputError(
                f"the prior's {constants.get(key)!r} differs from the profile's "
                f"{getattr(robot, key)!r}",
                field=f"robot.{key}",
            )
    dt = float(prior.dt)
    if not abs(experiment.dt / dt - 1.0) <= PRIOR_RATE_TOLERANCE:
        raise InputError(
            f"the prior is for {1 / dt:.4g} Hz (dt = {dt:.4g} s), the experiment is sampled "
            f"at {1 / experiment.dt:.4g} Hz (dt = {experiment.dt:.4g} s)",
            field="dt",
        )
    channels = _prior_channels(prior, channels)
    poses = prior_layout(prior).pose_channels
    for channel in channels:
        recorded = experiment.measurement(channel)  # a DataError when it is not measured
        modelled = "pose" if channel in poses else "rate"
        if recorded != modelled:
            raise InputError(
                f"the prior models {channel} as {_RECORDED[modelled]}, the experiment "
                f"({experiment.source}) records it as {_RECORDED[recorded]}",
                field="noise.pose_channels",
            )
    return channels


#: How a prior or an experiment has a channel recorded, in words.
_RECORDED = {"pose": "motion-capture poses", "rate": "a measured state"}


def measured_series(experiment: Experiment, channel: str) -> tuple[np.ndarray, int]:
    """What the filters take as a channel's measurement, and the poses averaged per sample.

    A rate channel's measured state [its unit] (n = 1); a pose channel's
    travel along its body axis [m]
    (:func:`bayes_jackal.io.body_displacement`) and its n.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import measured_series
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> y, samples = measured_series(run, "yaw")
    >>> y.shape, samples
    ((1873,), 1)
    """
    if experiment.measurement(channel) == "rate":
        return experiment.channel(channel), 1
    ticks = tick_poses(experiment)
    return body_displacement(ticks, channel), ticks.samples


def filter_models(
    prior: ActiveInferencePrior | Mapping,
    *,
    noise: str = "coloured",
    channels: Sequence[str] | None = None,
    parameters: str = "plug-in",
    initial_variance: float = 0.0,
    pose_samples: int = 1,
) -> dict[str, ChannelModel]:
    """The state-space model of each channel, from an exported prior (module docstring).

    Parameters
    ----------
    prior : ActiveInferencePrior or mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`,
        :func:`bayes_jackal.dem.read_prior`), or a mapping holding the fields
        read here, as they would be in ``prior.json`` (not checked:
        :func:`check_prior` checks a whole prior).
    noise : {"coloured", "white"}
        The prior's noise family with its shaping filter in the state, or
        white process noise of the same variance per step.
    channels : sequence of str, optional
        By default every channel of the prior.
    parameters : {"plug-in", "averaged"}
        The noise parameters at their posterior means, or Q and R averaged
        over the prior's draws.
    initial_variance : float
        Variance of x[-1] about rest [channel units^2] (:func:`channel_model`).
    pose_samples : int
        Recorded poses per sample of the run filtered (:func:`measured_series`),
        for the prior's pose channels.

    Returns
    -------
    dict of str to ChannelModel

    Raises
    ------
    InputError
        For a field the prior lacks, a channel it lacks, or an unknown
        ``noise`` or ``parameters``.

    Examples
    --------
    The models of a prior (here built by hand; ``bj.export_prior`` writes
    them): one yaw channel with Gaussian noise of sigma_h = 0.047 s:

    >>> import numpy as np
    >>> from bayes_jackal.filters import filter_models
    >>> Ad, Bd = np.diag([0.90, 0.69, 0.72]), [[0.0047, 0.0047], [0, 0], [0.026, -0.026]]
    >>> prior = {"dt": 1 / 72, "damping": {"mean": [110.0, 30.0]},
    ...          "model": {"Ad": Ad.tolist(), "Bd": Bd},
    ...          "noise": {"family": "gaussian", "channels": ["yaw"], "sensor": "ma1",
    ...                    "parameters": {"sigma_h": {"mean": 0.047},
    ...                                   "sigma_c": {"mean": 0.01},
    ...                                   "sigma_n": {"mean": 0.005}}}}
    >>> [(c, m.size) for c, m in filter_models(prior).items()]
    [('yaw', 23)]
    >>> filter_models(prior, noise="white")["yaw"].transition.tolist()
    [[0.72]]

    Averaged over draws, the white model's process variance is the mean of
    sigma_c^2 (here of 0.01^2 and 0.02^2):

    >>> prior["draws"] = {"d_lat": [110.0, 110.0], "d_long": [30.0, 30.0],
    ...                   "sigma_h": [0.04, 0.05], "sigma_c": [0.01, 0.02],
    ...                   "sigma_n": [0.005, 0.005]}
    >>> white = filter_models(prior, noise="white", parameters="averaged")["yaw"]
    >>> round(float(white.process_covariance[0, 0]), 12)
    0.00025
    """
    if noise not in NOISE_MODELS:
        raise InputError(
            f"unknown noise model {noise!r}; use one of {NOISE_MODELS}", field="noise"
        )
    layout = prior_layout(prior)
    Ad, Bd = np.asarray(prior_field(prior, "model.Ad")), np.asarray(prior_field(prior, "model.Bd"))
    dt = float(prior_field(prior, "dt"))
    family = layout.family if noise == "coloured" else "white"
    models = {}
    for channel in _prior_channels(prior, channels):
        width, sigma_c, sigma_n = noise_parameters(prior, channel, parameters=parameters)
        i = CHANNELS.index(channel)
        models[channel] = channel_model(
            channel,
            Ad[i, i],
            Bd[i],
            family=family,
            width=width,
            sigma_c=sigma_c,
            sigma_n=sigma_n,
            dt=dt,
            sensor=layout.sensor,
            initial_variance=initial_variance,
            measurement="pose" if channel in layout.pose_channels else "rate",
            samples=pose_samples,
        )
    return models


def parameter_values(
    prior: ActiveInferencePrior | Mapping, *, parameters: str = "plug-in"
) -> np.ndarray:
    """The prior's parameter vectors: the posterior means (one row) or its draws.

    Parameters
    ----------
    prior : ActiveInferencePrior or mapping
        An exported prior, or a mapping holding the fields read here
        (``noise``, ``damping.mean``, ``draws``), as :func:`filter_models`.
    parameters : {"plug-in", "averaged"}

    Returns
    -------
    ndarray, shape (1, k) or (draws, k)
        Columns in the layout's order: d_lat, d_long [N s/m], then the noise
        parameters (:class:`bayes_jackal.model.ParameterLayout`).

    Examples
    --------
    >>> from bayes_jackal.filters import parameter_values
    >>> prior = {"damping": {"mean": [110.0, 30.0]},
    ...          "noise": {"family": "white", "channels": ["yaw"], "sensor": "ma1",
    ...                    "parameters": {"sigma_c": {"mean": 0.01}, "sigma_n": {"mean": 0.005}}},
    ...          "draws": {"d_lat": [100.0, 120.0], "d_long": [30.0, 30.0],
    ...                    "sigma_c": [0.01, 0.01], "sigma_n": [0.004, 0.006]}}
    >>> parameter_values(prior).tolist(), parameter_values(prior, parameters="averaged").shape
    ([[110.0, 30.0, 0.01, 0.005]], (2, 4))
    """
    if parameters not in PARAMETERS:
        raise InputError(
            f"unknown parameters {parameters!r}; use one of {PARAMETERS}", field="parameters"
        )
    names = prior_layout(prior).names
    if parameters == "plug-in":
        means = [prior_field(prior, f"noise.parameters.{n}.mean") for n in names[len(DAMPING) :]]
        return np.array([[*prior_field(prior, "damping.mean")[: len(DAMPING)], *means]], float)
    return np.column_stack([prior_field(prior, f"draws.{n}") for n in names]).astype(float)


def noise_parameters(
    prior: ActiveInferencePrior | Mapping, channel: str, *, parameters: str = "plug-in"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The noise parameters of one channel of an exported prior.

    Parameters
    ----------
    prior : ActiveInferencePrior or mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`), or a
        mapping holding the fields read here, as :func:`parameter_values`.
    channel : str
        One of the prior's channels.
    parameters : {"plug-in", "averaged"}
        The posterior means (one value each) or the prior's draws
        (:func:`parameter_values`).

    Returns
    -------
    width, sigma_c, sigma_n : ndarray, shape (1,) or (draws,)
        The family's width [s] (1 for white noise), the per-step process sd
        and the sensor sd [channel units] (0 where the fit has one total sd;
        for a pose channel the pose noise sigma_p per recorded pose [m]).

    Raises
    ------
    InputError
        For an unknown ``parameters``, a channel the prior lacks or a
        missing field (named).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.filters import noise_parameters
    >>> prior = {"damping": {"mean": [110.0, 30.0]},
    ...          "noise": {"family": "gaussian", "channels": ["yaw"], "sensor": "ma1",
    ...                    "parameters": {"sigma_h": {"mean": 0.05}, "sigma_c": {"mean": 0.01},
    ...                                   "sigma_n": {"mean": 0.005}}},
    ...          "draws": {"d_lat": [100.0, 120.0], "d_long": [30.0, 30.0],
    ...                    "sigma_h": [0.04, 0.06], "sigma_c": [0.01, 0.01],
    ...                    "sigma_n": [0.004, 0.006]}}
    >>> [float(v[0]) for v in noise_parameters(prior, "yaw")]
    [0.05, 0.01, 0.005]
    >>> noise_parameters(prior, "yaw", parameters="averaged")[0].tolist()
    [0.04, 0.06]
    """
    theta = parameter_values(prior, parameters=parameters)
    layout = prior_layout(prior)
    (channel,) = _prior_channels(prior, [channel])
    return layout.noise_parameters(theta, layout.channels.index(channel))


def prior_robot(prior: ActiveInferencePrior | Mapping) -> RobotProfile:
    """The robot an exported prior was identified on: its constants in the default profile.

    Only the physical constants, the rate and the wheel-speed conversion
    enter the model; the profile's priors, topics and wheel joints are the
    installed default's. ``prior`` is an
    :class:`~bayes_jackal.dem.ActiveInferencePrior` or a mapping with its
    ``robot`` field.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import prior_robot
    >>> prior = {"robot": {"name": "jackal", "mass": 20.0}}
    >>> prior_robot(prior).mass, prior_robot(prior).wheel_radius == bj.load_profile().wheel_radius
    (20.0, True)
    """
    constants = prior_field(prior, "robot")
    return load_profile().replace(**{k: v for k, v in constants.items() if k in ROBOT_CONSTANTS})
