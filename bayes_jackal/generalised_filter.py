"""A generalised filter (the DEM D-step) for the identified linear model.

Each channel c of the model is the scalar system, in continuous time,

    dx/dt = a x + b . u + w,     y = x + z,

with a = A[c, c] [1/s], b = B[c, :], w coloured process noise and z white
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
(:mod:`bayes_jackal.export`), and Pi_z the sensor precision (below). For this
linear model the flow is linear with constant coefficients,

    d mu~/dt = J mu~ + K (Pi_z y~ + M' Pi_w b . u~),   J = D - K (Pi_z + M' Pi_w M),

and it is integrated with the local linearisation of SPM's ``spm_dx``
(Ozaki 1992): over a sample, with the data held, mu~[k] = expm(J dt)
mu~[k-1] + int_0^dt expm(J s) ds K (Pi_z y~[k] + M' Pi_w b . u~[k]), with
the generalised data of sample k, so the estimate at t_k uses the samples
up to t_k (and the embedding's look-ahead). The gain K is SPM's: ``spm_DEM`` runs the flow in
time bins with derivatives in bins (derivative i times dt^i) and unit gain,
which is K = diag(dt^(-2 i)) / dt in seconds.

The data's generalised coordinates come from a local Taylor expansion of
p + 1 samples, as ``spm_DEM_embed``: with T[i, j] = ((i - x) dt)^j / j!, the
sample i of a window is y[i] = sum_j T[i, j] y^(j)(t_x), so y~ = inv(T) y. The
window holds ``lookahead`` samples after the estimated one (SPM's centring:
floor(p / 2)); at the ends of a series it is moved inside the series and
the expansion point moves in it, so the embedding stays exact on
polynomials of degree <= p (``spm_DEM_embed`` repeats the end sample).

White sensor noise has no derivatives, so its generalised precision needs a
choice. Here it is the exact covariance of the embedded noise: z~ = inv(T)
z_window has covariance sigma_n^2 inv(T) inv(T)', so Pi_z = T' T / sigma_n^2
(:func:`white_sensor_precision`): no smoothness parameter, and it depends
on the embedding actually used.

(A prior that carries its own Pi_z, from a chosen sensor smoothness, passes
it as ``sensor_precision``.)

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

import math
from collections.abc import Mapping, Sequence

import numpy as np
import scipy.linalg
import scipy.special

from .errors import InputError
from .experiment import Experiment
from .filter_models import check_prior, prior_field
from .lti import lti_outputs
from .physics import CHANNELS
from .robot import RobotProfile

__all__ = [
    "embed",
    "embedding_operator",
    "generalised_filter",
    "generalised_filter_prior",
    "shift_operator",
    "white_sensor_precision",
]

#: The impulse response is cut where expm(J dt)^m falls below this (relative
#: to 1): the terms left off are below double precision's rounding.
TAIL = 1e-17


def _check_order(order: int) -> int:
    if isinstance(order, bool) or not isinstance(order, int | np.integer) or order < 0:
        raise InputError(f"embedding order must be an integer >= 0, got {order!r}", field="order")
    return int(order)


def _lookahead(order: int, lookahead: int | None) -> int:
    if lookahead is None:
        return order // 2  # spm_DEM_embed's centred window
    if isinstance(lookahead, bool) or not isinstance(lookahead, int | np.integer):
        raise InputError(f"lookahead must be an integer, got {lookahead!r}", field="lookahead")
    if not 0 <= lookahead <= order:
        raise InputError(
            f"lookahead must lie in 0 .. {order} (the order), got {lookahead}", field="lookahead"
        )
    return int(lookahead)


def shift_operator(order: int) -> np.ndarray:
    """The derivative operator D of generalised coordinates, shape (p + 1, p + 1).

    D (x, x', .., x^(p)) = (x', .., x^(p), 0): ones on the first
    superdiagonal. The highest derivative's motion is truncated to zero.

    Examples
    --------
    >>> from bayes_jackal.generalised_filter import shift_operator
    >>> shift_operator(2).tolist()
    [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]
    """
    return np.eye(_check_order(order) + 1, k=1)


def _taylor_matrix(order: int, dt: float, position: np.ndarray | int) -> np.ndarray:
    """T[i, j] = ((i - x) dt)^j / j!, shape (..., p + 1, p + 1), x = ``position``."""
    i, j = np.indices((order + 1, order + 1))
    offset = (i - np.asarray(position)[..., None, None]) * dt
    return offset**j / scipy.special.factorial(j)


def embedding_operator(order: int, dt: float, *, lookahead: int | None = None) -> np.ndarray:
    """The operator E = inv(T) from p + 1 samples to generalised coordinates.

    The local Taylor expansion of ``spm_DEM_embed``: sample i of the window
    is y[i] = sum_j T[i, j] y^(j)(t*), T[i, j] = ((i - x) dt)^j / j!, with
    t* the sample x = p - ``lookahead`` of the window; E solves for the
    derivatives at t*. Exact for polynomials of degree <= p.

    Parameters
    ----------
    order : int
        Embedding order p (p + 1 samples, derivatives 0 .. p).
    dt : float
        Sample time [s].
    lookahead : int, optional
        Samples of the window after t*; by default SPM's centring, floor(p / 2).

    Returns
    -------
    ndarray, shape (p + 1, p + 1)
        Row j gives derivative j [channel units / s^j] from the window.

    Examples
    --------
    Order 2, centred: the central differences, (y[2] - y[0]) / (2 dt) and
    (y[0] - 2 y[1] + y[2]) / dt^2:

    >>> import numpy as np
    >>> from bayes_jackal.generalised_filter import embedding_operator
    >>> E = embedding_operator(2, 0.5)
    >>> np.round(E, 12).tolist()
    [[0.0, 1.0, 0.0], [-1.0, 0.0, 1.0], [4.0, -8.0, 4.0]]
    """
    order = _check_order(order)
    return np.linalg.inv(_taylor_matrix(order, dt, order - _lookahead(order, lookahead)))


def embed(
    series: np.ndarray, order: int, dt: float, *, lookahead: int | None = None
) -> np.ndarray:
    """Generalised coordinates of a sampled series at every sample.

    Each sample's window is the p + 1 samples around it (``lookahead`` after
    it, see :func:`embedding_operator`); near the ends the window is moved
    inside the series and the expansion point moves within it, so every
    sample's coordinates are exact for polynomials of degree <= p.

    Parameters
    ----------
    series : array_like, shape (N, ...)
        Samples along the first axis, N >= p + 1.
    order : int
        Embedding order p.
    dt : float
        Sample time [s].
    lookahead : int, optional
        As :func:`embedding_operator`.

    Returns
    -------
    ndarray, shape (N, p + 1, ...)
        Derivative j of sample k at ``[k, j]`` [units / s^j].

    Raises
    ------
    InputError
        For a series shorter than p + 1 samples.

    Examples
    --------
    A quadratic is embedded exactly, ends included: y = t^2 has y' = 2 t and
    y'' = 2:

    >>> import numpy as np
    >>> from bayes_jackal.generalised_filter import embed
    >>> t = np.arange(5) * 0.1
    >>> y = embed(t**2, 2, 0.1)
    >>> bool(np.allclose(y, np.column_stack([t**2, 2 * t, np.full(5, 2.0)])))
    True
    """
    order = _check_order(order)
    ahead = _lookahead(order, lookahead)
    series = np.asarray(series, float)
    n = len(series)
    if n < order + 1:
        raise InputError(
            f"embedding order {order} needs at least {order + 1} samples, got {n}",
            field="order",
        )
    k = np.arange(n)
    start = np.clip(k - (order - ahead), 0, n - order - 1)
    operators = np.linalg.inv(_taylor_matrix(order, dt, np.arange(order + 1)))
    windows = np.lib.stride_tricks.sliding_window_view(series, order + 1, axis=0)[start]
    # windows: (N, ..., p + 1); the operator of each sample's position in its window
    return np.einsum("kij,k...j->ki...", operators[k - start], windows)


def white_sensor_precision(
    order: int, dt: float, sigma: float, *, lookahead: int | None = None
) -> np.ndarray:
    """Pi_z = T' T / sigma^2: the precision of embedded white sensor noise.

    White noise z of sd ``sigma`` has no derivatives, but its embedding
    z~ = E z_window (:func:`embedding_operator`, E = inv(T)) has the covariance
    sigma^2 E E', whose inverse is T' T / sigma^2. This is the sensor
    precision the filter uses by default: no smoothness parameter to choose,
    and consistent with the embedding of the data.

    Parameters
    ----------
    order : int
        Embedding order p.
    dt : float
        Sample time [s].
    sigma : float
        Sensor-noise sd [channel units], > 0.
    lookahead : int, optional
        As :func:`embedding_operator`.

    Returns
    -------
    ndarray, shape (p + 1, p + 1)
        [1 / (units / s^i) / (units / s^j)].

    Examples
    --------
    At order 0 it is 1 / sigma^2; at order 1 (backward difference) the
    derivative's variance is 2 sigma^2 / dt^2, as the closed form says:

    >>> import numpy as np
    >>> from bayes_jackal.generalised_filter import white_sensor_precision
    >>> white_sensor_precision(0, 0.1, 0.5).tolist()
    [[4.0]]
    >>> covariance = np.linalg.inv(white_sensor_precision(1, 0.1, 0.5))
    >>> bool(np.isclose(covariance[1, 1], 2 * 0.5**2 / 0.1**2))
    True
    """
    if not (math.isfinite(sigma) and sigma > 0):
        raise InputError(f"sensor-noise sd must be positive, got {sigma!r}", field="sigma_n")
    order = _check_order(order)
    T = _taylor_matrix(order, dt, order - _lookahead(order, lookahead))
    return T.T @ T / sigma**2


def _check_precision(matrix: np.ndarray, size: int, name: str) -> np.ndarray:
    matrix = np.asarray(matrix, float)
    if matrix.shape != (size, size) or not np.isfinite(matrix).all():
        raise InputError(
            f"expected a finite ({size}, {size}) precision, got shape {matrix.shape}", field=name
        )
    return matrix


def _flow(
    a: float, dt: float, process_precision: np.ndarray, sensor_precision: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """J and the input matrix G of d mu~/dt = J mu~ + G (y~, b . u~) (module docstring).

    With the free energy F above, dF/dmu~ = -Pi_z (y~ - mu~) + M' Pi_w
    (M mu~ - b . u~); the flow D mu~ - K dF/dmu~ collects into J mu~ + G c.
    """
    order = len(process_precision) - 1
    D = shift_operator(order)
    M = D - a * np.eye(order + 1)
    K = np.diag(dt ** (-2.0 * np.arange(order + 1))) / dt  # spm_DEM's unit gain in bins
    J = D - K @ (sensor_precision + M.T @ process_precision @ M)
    G = K @ np.hstack([sensor_precision, M.T @ process_precision])
    return J, G


def generalised_filter(
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
) -> np.ndarray:
    """The D-step estimate of one channel's state in generalised coordinates.

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
        The channel's pole A[c, c] [1/s].
    b : array_like, shape (m,)
        The channel's input row B[c, :] [units / s per input unit].
    dt : float
        Sample time [s].
    process_precision : array_like, shape (p + 1, p + 1)
        Pi_w of the continuous process noise in generalised coordinates
        (the export's inv(V) / s_c^2); its size sets the order p.
    y : array_like, shape (N,)
        Measurements [units], N >= p + 1.
    u : array_like, shape (N, m)
        Inputs at the samples.
    sensor_precision : array_like, shape (p + 1, p + 1)
        Pi_z, e.g. :func:`white_sensor_precision`.
    lookahead : int, optional
        Samples after t_k in the embedding window (:func:`embedding_operator`;
        SPM's floor(p / 2) by default, 0 for a causal filter).
    initial : array_like, shape (p + 1,), optional
        mu~ before the first sample; by default the embedded first measurement.

    Returns
    -------
    ndarray, shape (N, p + 1)
        mu~[k] = (x, x', .., x^(p)) estimated at t_k [units / s^j].

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
    >>> from bayes_jackal.generalised_filter import generalised_filter, white_sensor_precision
    >>> a, b, dt = -20.0, np.array([0.5]), 0.01
    >>> u = np.ones((50, 1))
    >>> y = np.full(50, -0.5 / a)
    >>> Pw, Pz = np.diag([1.0, 1e-2, 1e-4]), white_sensor_precision(2, dt, 0.01)
    >>> mu = generalised_filter(a, b, dt, Pw, y, u, sensor_precision=Pz, initial=np.zeros(3))
    >>> bool(np.allclose(mu[-1], [0.025, 0.0, 0.0], atol=1e-12))
    True
    """
    process_precision = np.asarray(process_precision, float)
    size = len(process_precision)
    process_precision = _check_precision(process_precision, size, "process_precision")
    sensor_precision = _check_precision(sensor_precision, size, "sensor_precision")
    y, u, b = np.asarray(y, float), np.asarray(u, float), np.atleast_1d(np.asarray(b, float))
    if y.ndim != 1 or u.shape != (len(y), len(b)):
        raise InputError(
            f"expected y of shape (N,) and u of shape (N, {len(b)}), got {y.shape} and {u.shape}",
            field="y",
        )
    if not (np.isfinite(y).all() and np.isfinite(u).all()):
        raise InputError("measurements and inputs must be finite", field="y")
    order = size - 1
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
        [embed(y, order, dt, lookahead=lookahead), embed(u @ b, order, dt, lookahead=lookahead)]
    )
    start = data[0, :size] if initial is None else np.asarray(initial, float)
    if start.shape != (size,):
        raise InputError(f"expected shape ({size},), got {start.shape}", field="initial")
    return lti_outputs(Phi, forcing_matrix, data, start, tolerance=TAIL)


def generalised_filter_prior(
    experiment: Experiment,
    prior: Mapping,
    *,
    channels: Sequence[str] | None = None,
    robot: RobotProfile | None = None,
    sensor_precision: np.ndarray | None = None,
    lookahead: int | None = None,
) -> np.ndarray:
    """Run :func:`generalised_filter` on an experiment with an exported prior.

    Each channel uses the prior's model at the posterior mean (a = A[c, c],
    b = B[c, :]), its process precision (the channel's block of
    ``generalised_coordinates.precision``, averaged over the posterior
    draws), and its embedding order.

    Parameters
    ----------
    experiment : Experiment
        Measurements and wheel speeds, at the prior's sample time.
    prior : mapping
        An exported prior (:func:`bayes_jackal.export.export_prior`, ``prior.json``).
    channels : sequence of str, optional
        Channels to filter; by default every channel of the prior.
    robot : RobotProfile, optional
        When given, its constants must be the prior's.
    sensor_precision : array_like, shape (channels, p + 1, p + 1), optional
        Pi_z per channel [seconds, as Pi_w]; by default
        :func:`white_sensor_precision` at the posterior mean of the channel's
        sensor-noise sd (``sensor_noise.sd``).
    lookahead : int, optional
        As :func:`embedding_operator` (SPM's centring by default).

    Returns
    -------
    ndarray, shape (N, channels, p + 1)
        The estimated state of each channel and its derivatives at every sample.

    Raises
    ------
    InputError
        For a prior that does not fit the experiment
        (:func:`bayes_jackal.filter_models.check_prior`: format, robot,
        sample time, channels), or a prior without a sensor-noise sd (white
        noise fitted with one total sd) and no ``sensor_precision``.
    DataError
        For a channel the experiment does not measure.

    Examples
    --------
    A hand-made prior of order 1 for the yaw channel (the fields
    ``export_prior`` writes that the filter reads), on a simulated run: the
    estimate is closer to the true yaw rate than the measurement is:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.generalised_filter import generalised_filter_prior
    >>> from bayes_jackal.physics import continuous_matrices
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v2", rng=1)
    >>> A, B = continuous_matrices(robot, 110.0, 30.0)
    >>> Pw = np.diag([1.0, 2 * 0.047**2]) / 0.84**2  # inv(V) / s_c^2, Gaussian, order 1
    >>> prior = {"format": "bayes_jackal.prior/1", "robot": {"name": robot.name},
    ...          "dt": robot.dt, "model": {"A": A.tolist(), "B": B.tolist()},
    ...          "noise": {"channels": ["yaw"]}, "sensor_noise": {"sd": {"yaw": {"mean": 0.005}}},
    ...          "generalised_coordinates": {"order": 1, "precision": Pw.tolist()}}
    >>> mu = generalised_filter_prior(run, prior)
    >>> truth = run.truth_arrays["yaw_state"]
    >>> def rmse(x):
    ...     return float(np.sqrt(np.mean((x - truth) ** 2)))
    >>> mu.shape, rmse(mu[:, 0, 0]) < rmse(run.yaw_rate)
    ((1873, 1, 2), True)
    """
    channels = check_prior(prior, experiment, channels, robot=robot)
    known = list(prior_field(prior, "noise.channels"))
    dt = float(prior_field(prior, "dt"))
    order = int(prior_field(prior, "generalised_coordinates.order"))
    precision = np.asarray(prior_field(prior, "generalised_coordinates.precision"), float)
    precision = precision.reshape(order + 1, len(known), order + 1, len(known))
    A = np.asarray(prior_field(prior, "model.A"), float)
    B = np.asarray(prior_field(prior, "model.B"), float)
    estimates = []
    for k, channel in enumerate(channels):
        c, row = known.index(channel), CHANNELS.index(channel)
        estimates.append(
            generalised_filter(
                A[row, row],
                B[row],
                dt,
                precision[:, c, :, c],
                experiment.channel(channel),
                experiment.inputs,
                sensor_precision=_sensor_precision(prior, channel, order, dt, lookahead)
                if sensor_precision is None
                else np.asarray(sensor_precision, float)[k],
                lookahead=lookahead,
            )
        )
    return np.stack(estimates, axis=1)


def _sensor_precision(
    prior: Mapping, channel: str, order: int, dt: float, lookahead: int | None
) -> np.ndarray:
    """The default Pi_z of a channel: embedded white noise at the posterior-mean sigma_n.

    Read from the prior's ``sensor_noise`` block, keyed by channel whatever
    the posterior's parameter names (a one-channel fit names it ``sigma_n``).
    """
    if prior.get("sensor_noise") is None:
        raise InputError(
            "the prior has no sensor-noise sd (its noise fit has one total sd): "
            "pass sensor_precision",
            field="sensor_noise",
        )
    sigma = prior_field(prior, f"sensor_noise.sd.{channel}.mean")
    return white_sensor_precision(order, dt, float(sigma), lookahead=lookahead)
