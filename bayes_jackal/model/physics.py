"""The thesis' linear skid-steer model and its discretisation (ch. 4 and 6).

State x = (vx, vy, r): body-frame longitudinal and lateral velocity [m/s] and
yaw rate [rad/s]. Input u = (omega_r, omega_l): right and left wheel speeds
[rad/s]. The wheel-ground contact is a viscous damper with coefficients
d_lat and d_long [N s/m].

Every function here is vectorised over arrays of (d_lat, d_long): parameter
arrays broadcast against each other and the matrices gain their shape as
leading axes, e.g. ``A.shape == (*broadcast(d_lat, d_long).shape, 3, 3)``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.fft
import scipy.linalg
import scipy.special

from .._runtime import CHANNELS, InputError
from .robot import RobotProfile

__all__ = [
    "Method",
    "channel_coefficients",
    "continuous_matrices",
    "discrete_matrices",
    "discretise",
    "one_step_prediction",
    "one_step_residuals",
    "propagate",
    "simulate",
    "step_integrals",
    "wheel_speeds",
]


Method = Literal["zoh", "euler"]


def _check_damping(d_lat, d_long) -> tuple[np.ndarray, np.ndarray]:
    d_lat, d_long = np.broadcast_arrays(np.asarray(d_lat, float), np.asarray(d_long, float))
    for name, values in (("d_lat", d_lat), ("d_long", d_long)):
        bad = ~(np.isfinite(values) & (values > 0))
        if bad.any():
            raise InputError(
                f"damping must be positive and finite, got {float(values[bad].flat[0])!r} N s/m",
                field=name,
            )
    return d_lat, d_long


def _pole(robot: RobotProfile, d_lat: np.ndarray, d_long: np.ndarray, index: int) -> np.ndarray:
    """Diagonal entry A[index, index] of eq. 4-32 [1/s]."""
    if index == 0:
        return -4.0 * d_long / robot.mass  # eq. 4-29
    if index == 1:
        return -4.0 * d_lat / robot.mass  # eq. 4-30
    a, b = robot.half_wheelbase, robot.half_track
    return -4.0 / robot.yaw_inertia * (b**2 * d_long + a**2 * d_lat)  # eq. 4-31


def _input_row(robot: RobotProfile, d_long: np.ndarray, index: int) -> np.ndarray:
    """Row B[index, :] of eq. 4-32, shape (..., 2)."""
    if index == 0:
        force = 2.0 * d_long * robot.wheel_radius / robot.mass
        return np.stack([force, force], axis=-1)
    if index == 1:
        return np.zeros((*np.shape(d_long), 2))
    torque = 2.0 * robot.half_track * d_long * robot.wheel_radius / robot.yaw_inertia
    return np.stack([torque, -torque], axis=-1)


def _check_method(method: str) -> str:
    if method not in ("zoh", "euler"):
        raise InputError(
            f"unknown discretisation {method!r}; use 'zoh' or 'euler'", field="method"
        )
    return method


def _channel_index(channel: str) -> int:
    if channel not in CHANNELS:
        raise InputError(f"unknown channel {channel!r}; use one of {CHANNELS}", field="channel")
    return CHANNELS.index(channel)


def continuous_matrices(
    robot: RobotProfile, d_lat: np.ndarray | float, d_long: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time state matrices A and B of the thesis' model (eq. 4-32).

    Parameters
    ----------
    robot : RobotProfile
        Body constants m [kg], I [kg m^2], a, b, r_w [m].
    d_lat, d_long : array_like
        Lateral and longitudinal damping [N s/m], broadcast together.

    Returns
    -------
    A : ndarray, shape (..., 3, 3)
        Diagonal state matrix [1/s].
    B : ndarray, shape (..., 3, 2)
        Input matrix mapping wheel speeds [rad/s] to state derivatives.

    Examples
    --------
    A is diagonal: the longitudinal pole is -4 d_long / m (eq. 4-29).

    >>> import numpy as np
    >>> from bayes_jackal.model import continuous_matrices
    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> A, B = continuous_matrices(robot, 110.0, 30.0)
    >>> A.shape, B.shape
    ((3, 3), (3, 2))
    >>> [round(float(a), 3) for a in np.diag(A)]
    [-7.263, -26.63, -23.213]
    >>> bool(np.isclose(A[0, 0], -4 * 30.0 / robot.mass))
    True

    Arrays of damping add leading axes:

    >>> continuous_matrices(robot, [100.0, 110.0, 120.0], 30.0)[0].shape
    (3, 3, 3)
    """
    d_lat, d_long = _check_damping(d_lat, d_long)
    poles = np.stack([_pole(robot, d_lat, d_long, i) for i in range(3)], axis=-1)
    B = np.stack([_input_row(robot, d_long, i) for i in range(3)], axis=-2)
    return poles[..., :, None] * np.eye(3), B


def discretise(
    A: np.ndarray, B: np.ndarray, dt: float, method: Method = "zoh"
) -> tuple[np.ndarray, np.ndarray]:
    """Discretise any continuous (A, B), vectorised over leading axes.

    ``"zoh"`` is the exact zero-order-hold discretisation (eq. 6-6, MATLAB's
    ``c2d``), computed as the matrix exponential of the block matrix
    ``[[A, B], [0, 0]] dt`` so that a singular A needs no inverse.
    ``"euler"`` is the forward-Euler approximation (eq. 6-5).

    Parameters
    ----------
    A : ndarray, shape (..., n, n)
    B : ndarray, shape (..., n, m)
    dt : float
        Sample time [s].
    method : {"zoh", "euler"}

    Returns
    -------
    Ad : ndarray, shape (..., n, n)
    Bd : ndarray, shape (..., n, m)

    Examples
    --------
    The zero-order hold is the matrix exponential, Ad = expm(A dt) and
    Bd = A^-1 (Ad - I) B for an invertible A (eq. 6-6):

    >>> import numpy as np
    >>> import scipy.linalg
    >>> from bayes_jackal.model import discretise
    >>> A = np.array([[-1.0, 2.0], [0.0, -3.0]])
    >>> B = np.array([[0.0], [1.0]])
    >>> Ad, Bd = discretise(A, B, 0.1)
    >>> bool(np.allclose(Ad, scipy.linalg.expm(0.1 * A)))
    True
    >>> bool(np.allclose(Bd, np.linalg.solve(A, (Ad - np.eye(2)) @ B)))
    True
    >>> Ad, Bd = discretise(A, B, 0.1, "euler")  # I + A dt, B dt (eq. 6-5)
    >>> np.round(Ad, 12).tolist(), np.round(Bd, 12).tolist()
    ([[0.9, 0.2], [0.0, 0.7]], [[0.0], [0.1]])
    """
    n, m = B.shape[-2:]
    if _check_method(method) == "euler":
        return np.eye(n) + A * dt, B * dt
    shape = np.broadcast_shapes(A.shape[:-2], B.shape[:-2])
    block = np.zeros((*shape, n + m, n + m))
    block[..., :n, :n] = A
    block[..., :n, n:] = B
    exponential = scipy.linalg.expm(block * dt)
    return exponential[..., :n, :n], exponential[..., :n, n:]


def discrete_matrices(
    robot: RobotProfile,
    d_lat: np.ndarray | float,
    d_long: np.ndarray | float,
    dt: float | None = None,
    method: Method = "zoh",
) -> tuple[np.ndarray, np.ndarray]:
    """Ad and Bd of the thesis' model in closed form (A is diagonal).

    For the exact method Ad = exp(A dt) and Bd = A^-1 (Ad - I) B (eq. 6-6),
    written with ``exprel`` so that it stays exact as A -> 0; for Euler
    Ad = I + A dt, Bd = B dt (eq. 6-5). Agrees with :func:`discretise` and
    with python-control's ``c2d`` to rounding.

    Parameters
    ----------
    robot : RobotProfile
    d_lat, d_long : array_like
        Damping [N s/m], broadcast together.
    dt : float, optional
        Sample time [s]; ``robot.dt`` when omitted.
    method : {"zoh", "euler"}

    Returns
    -------
    Ad : ndarray, shape (..., 3, 3)
    Bd : ndarray, shape (..., 3, 2)

    Examples
    --------
    The closed form agrees with the general :func:`discretise`:

    >>> import numpy as np
    >>> from bayes_jackal.model import continuous_matrices, discrete_matrices, discretise
    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> Ad, Bd = discrete_matrices(robot, 110.0, 30.0)
    >>> A, B = continuous_matrices(robot, 110.0, 30.0)
    >>> Ad_general, Bd_general = discretise(A, B, robot.dt)
    >>> bool(np.allclose(Ad, Ad_general) and np.allclose(Bd, Bd_general))
    True
    >>> [round(float(alpha), 4) for alpha in np.diag(Ad)]  # exp(a dt) at 72 Hz
    [0.9041, 0.6908, 0.7244]
    """
    rows = [channel_coefficients(robot, d_lat, d_long, c, dt, method) for c in CHANNELS]
    alpha = np.stack([pole for pole, _ in rows], axis=-1)
    return alpha[..., :, None] * np.eye(3), np.stack([row for _, row in rows], axis=-2)


def channel_coefficients(
    robot: RobotProfile,
    d_lat: np.ndarray | float,
    d_long: np.ndarray | float,
    channel: str,
    dt: float | None = None,
    method: Method = "zoh",
) -> tuple[np.ndarray, np.ndarray]:
    """Discrete pole Ad[c, c] and input row Bd[c, :] of one channel.

    A is diagonal, so each channel is the scalar recursion
    x_c[k+1] = alpha x_c[k] + Bd[c, :] u[k]. Exact (eq. 6-6):
    alpha = exp(a dt), Bd[c, :] = dt exprel(a dt) B[c, :] with a = A[c, c];
    Euler (eq. 6-5): alpha = 1 + a dt, Bd[c, :] = dt B[c, :].

    Parameters
    ----------
    robot : RobotProfile
    d_lat, d_long : array_like
        Damping [N s/m], broadcast together.
    channel : {"vx", "vy", "yaw"}
    dt : float, optional
        Sample time [s]; ``robot.dt`` when omitted.
    method : {"zoh", "euler"}

    Returns
    -------
    alpha : ndarray, shape (...)
    input_row : ndarray, shape (..., 2)
        Coefficients of (omega_r, omega_l).

    Examples
    --------
    The yaw channel's pole is exp(A[2, 2] dt), and the wheels drive it with
    opposite signs:

    >>> import numpy as np
    >>> from bayes_jackal.model import channel_coefficients, continuous_matrices
    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> alpha, row = channel_coefficients(robot, 110.0, 30.0, "yaw")
    >>> A, _ = continuous_matrices(robot, 110.0, 30.0)
    >>> bool(np.isclose(alpha, np.exp(A[2, 2] * robot.dt)))
    True
    >>> bool(row[0] == -row[1])
    True
    >>> alpha, _ = channel_coefficients(robot, 110.0, 30.0, "yaw", method="euler")
    >>> bool(np.isclose(alpha, 1 + A[2, 2] * robot.dt))
    True
    """
    index = _channel_index(channel)
    dt = robot.dt if dt is None else float(dt)
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"sample time must be positive, got {dt!r} s", field="dt")
    d_lat, d_long = _check_damping(d_lat, d_long)
    pole_dt = _pole(robot, d_lat, d_long, index) * dt
    if _check_method(method) == "zoh":
        alpha, gain = np.exp(pole_dt), dt * scipy.special.exprel(pole_dt)
    else:
        alpha, gain = 1.0 + pole_dt, np.full_like(pole_dt, dt)
    return alpha, gain[..., None] * _input_row(robot, d_long, index)


def step_integrals(alpha: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """g and h of a channel's pole over a step of held input (the zero-order hold, eq. 6-6).

    With z = a dt = log alpha: g = (alpha - 1) / a = dt exprel(z), the held
    input's gain, and h = (g - dt) / a = dt^2 phi_2(z), with phi_2(z) =
    (exprel(z) - 1) / z = (e^z - 1 - z) / z^2 taken from its series where
    |z| is small: the held input's gain on the step's integral
    (:mod:`bayes_jackal.likelihood.measurements`: the pose increments).

    Examples
    --------
    A slow pole: g -> dt, h -> dt^2 / 2:

    >>> import numpy as np
    >>> from bayes_jackal.model import step_integrals
    >>> [round(float(v), 12) for v in step_integrals(np.array(1 - 1e-12), 0.01)]
    [0.01, 5e-05]
    """
    z = np.log(np.asarray(alpha, float))
    small = np.abs(z) < 1e-4
    safe = np.where(small, 1.0, z)
    phi_2 = np.where(small, 0.5 + z / 6.0 + z**2 / 24.0, (scipy.special.exprel(safe) - 1) / safe)
    return dt * scipy.special.exprel(z), dt**2 * phi_2


def wheel_speeds(
    robot: RobotProfile,
    v: np.ndarray | float,
    w: np.ndarray | float,
    conversion: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Convert a velocity command (cmd_vel) into wheel speeds.

    ``"ros"`` is ROS diff_drive_controller's formula
    omega_{r,l} = (v +- w s k / 2) / r_w with wheel separation s and
    multiplier k from the profile. ``"thesis"`` is eq. 4-33/34,
    omega_{r,l} = 0.5 (v +- w) / r_w, which drops the track width and is kept
    to reproduce the thesis (docs/design.md §1).

    Parameters
    ----------
    robot : RobotProfile
    v : array_like
        Commanded forward speed [m/s].
    w : array_like
        Commanded yaw rate [rad/s].
    conversion : {"ros", "thesis"}, optional
        ``robot.conversion`` when omitted.

    Returns
    -------
    omega_r, omega_l : ndarray
        Right and left wheel speeds [rad/s].

    Examples
    --------
    ROS's formula: the wheels' speed difference times r_w / (s k) is the
    commanded yaw rate.

    >>> from bayes_jackal.model import wheel_speeds
    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> omega_r, omega_l = wheel_speeds(robot, 0.3, 0.4)
    >>> round(float(omega_r), 3), round(float(omega_l), 3)
    (4.211, 1.911)
    >>> yaw_rate = (omega_r - omega_l) * robot.wheel_radius / robot.wheel_separation
    >>> round(float(yaw_rate / robot.wheel_separation_multiplier), 12)
    0.4
    """
    conversion = robot.conversion if conversion is None else conversion
    v, w = np.asarray(v, float), np.asarray(w, float)
    if conversion == "ros":
        half_span = 0.5 * w * robot.wheel_separation * robot.wheel_separation_multiplier
        return (v + half_span) / robot.wheel_radius, (v - half_span) / robot.wheel_radius
    if conversion == "thesis":
        return 0.5 * (v + w) / robot.wheel_radius, 0.5 * (v - w) / robot.wheel_radius
    raise InputError(
        f"unknown conversion {conversion!r}; use 'ros' or 'thesis'", field="conversion"
    )


def propagate(alpha: np.ndarray, drive: np.ndarray, x0: np.ndarray | float) -> np.ndarray:
    """Run the scalar recursion x[k+1] = alpha x[k] + drive[k] from x[0] = x0.

    Vectorised over leading axes. The solution is x0 alpha^k plus the
    convolution of ``drive`` with alpha^k, computed by FFT. The powers
    alpha^k come from a running product (relative error below k * eps, and
    valid for the zero or negative poles of a coarse Euler step); those below
    the smallest normal number (1e-308) are taken as zero.

    Parameters
    ----------
    alpha : array_like, shape (...)
        Discrete pole, |alpha| < 1 for a stable channel.
    drive : array_like, shape (..., N)
        Input term Bd u[k] plus noise for k = 0..N-1 (the last is unused).
    x0 : array_like, shape (...)
        Initial state.

    Returns
    -------
    ndarray, shape (..., N)
        x[0..N-1].

    Examples
    --------
    A constant drive b from x0 = 0 gives x[k] = b (1 - alpha^k) / (1 - alpha):

    >>> import numpy as np
    >>> from bayes_jackal.model import propagate
    >>> x = propagate(0.5, np.ones(5), 0.0)
    >>> np.round(x, 12).tolist()
    [0.0, 1.0, 1.5, 1.75, 1.875]
    >>> k = np.arange(5)
    >>> bool(np.allclose(x, (1 - 0.5**k) / (1 - 0.5)))
    True
    """
    alpha = np.asarray(alpha, float)[..., None]
    drive = np.asarray(drive, float)
    n = drive.shape[-1] - 1
    powers = np.ones((*alpha.shape[:-1], n + 1))
    np.cumprod(np.broadcast_to(alpha, powers[..., 1:].shape), axis=-1, out=powers[..., 1:])
    # Powers past 1e-308 are subnormal numbers, which the FFT takes ~4x as long
    # to add and multiply (a fast pole's tail is mostly such); as zeros they
    # change no sum beside the powers above them.
    powers[np.abs(powers) < np.finfo(float).tiny] = 0.0
    size = scipy.fft.next_fast_len(2 * n, real=True)
    spectrum = scipy.fft.rfft(powers[..., :n], size) * scipy.fft.rfft(drive[..., :n], size)
    states = np.asarray(x0, float)[..., None] * powers
    states[..., 1:] += scipy.fft.irfft(spectrum, size)[..., :n]
    return states


def simulate(
    robot: RobotProfile,
    d_lat: float | np.ndarray,
    d_long: float | np.ndarray,
    inputs: np.ndarray,
    x0: np.ndarray | None = None,
    process_noise: np.ndarray | None = None,
    dt: float | None = None,
    method: Method = "zoh",
) -> np.ndarray:
    """Simulate the discretised model x[k+1] = Ad x[k] + Bd u[k] + w[k] (eq. 6-4).

    Parameters
    ----------
    robot : RobotProfile
    d_lat, d_long : float or array_like
        Damping [N s/m]; arrays add leading axes to the result.
    inputs : ndarray, shape (N, 2)
        Wheel speeds (omega_r, omega_l) [rad/s] at each sample.
    x0 : ndarray, shape (3,) or (..., 3), optional
        Initial state (vx, vy, r); at rest when omitted.
    process_noise : ndarray, shape (N, 3), optional
        w[k] added to the state update.
    dt : float, optional
        Sample time [s]; ``robot.dt`` when omitted.
    method : {"zoh", "euler"}

    Returns
    -------
    ndarray, shape (..., N, 3)
        States (vx, vy, r) at each sample.

    Examples
    --------
    Constant wheel speeds from rest: the state settles at the fixed point
    -A^-1 B u of the continuous model.

    >>> import numpy as np
    >>> from bayes_jackal.model import continuous_matrices, simulate, wheel_speeds
    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> u = np.column_stack(wheel_speeds(robot, 0.3, 0.4))
    >>> inputs = np.repeat(u, 360, axis=0)  # 5 s at 72 Hz
    >>> states = simulate(robot, 110.0, 30.0, inputs)
    >>> states.shape
    (360, 3)
    >>> A, B = continuous_matrices(robot, 110.0, 30.0)
    >>> bool(np.allclose(states[-1], -np.linalg.solve(A, B @ u[0])))
    True
    """
    Ad, Bd = discrete_matrices(robot, d_lat, d_long, dt, method)
    alpha = np.diagonal(Ad, axis1=-2, axis2=-1)
    drive = np.einsum("...ij,nj->...in", Bd, np.asarray(inputs, float))
    if process_noise is not None:
        drive = drive + np.asarray(process_noise, float).T
    x0 = np.zeros(3) if x0 is None else np.asarray(x0, float)
    return np.swapaxes(propagate(alpha, drive, x0), -1, -2)


def one_step_prediction(
    Ad: np.ndarray, Bd: np.ndarray, states: np.ndarray, inputs: np.ndarray
) -> np.ndarray:
    """Predict each next state from the measured one (eq. 9-1).

    x_est[k+1] = Ad x[k] + Bd u[k] for k = 0..N-2.

    Parameters
    ----------
    Ad : ndarray, shape (..., n, n)
    Bd : ndarray, shape (..., n, m)
    states : ndarray, shape (N, n)
        Measured states.
    inputs : ndarray, shape (N, m)
        Measured inputs.

    Returns
    -------
    ndarray, shape (..., N - 1, n)

    Examples
    --------
    Without process noise every next state is predicted exactly:

    >>> import numpy as np
    >>> from bayes_jackal.model import discrete_matrices, one_step_prediction, simulate
    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> inputs = np.tile([4.0, 2.0], (100, 1))  # wheel speeds [rad/s]
    >>> states = simulate(robot, 110.0, 30.0, inputs)
    >>> Ad, Bd = discrete_matrices(robot, 110.0, 30.0)
    >>> predicted = one_step_prediction(Ad, Bd, states, inputs)
    >>> predicted.shape, bool(np.allclose(predicted, states[1:]))
    ((99, 3), True)
    """
    return np.einsum("...ij,kj->...ki", Ad, states[:-1]) + np.einsum(
        "...ij,kj->...ki", Bd, inputs[:-1]
    )


def one_step_residuals(
    Ad: np.ndarray, Bd: np.ndarray, states: np.ndarray, inputs: np.ndarray
) -> np.ndarray:
    """One-step residuals w[k] = x[k+1] - Ad x[k] - Bd u[k] (eq. 7-3).

    Parameters and shapes as :func:`one_step_prediction`.

    Examples
    --------
    At the true damping the residuals are the process noise itself (eq. 7-3):

    >>> import numpy as np
    >>> from bayes_jackal.model import discrete_matrices, one_step_residuals, simulate
    >>> from bayes_jackal.model import load_profile
    >>> robot = load_profile()
    >>> inputs = np.tile([4.0, 2.0], (100, 1))
    >>> noise = 0.01 * np.random.default_rng(1).standard_normal((100, 3))
    >>> states = simulate(robot, 110.0, 30.0, inputs, process_noise=noise)
    >>> Ad, Bd = discrete_matrices(robot, 110.0, 30.0)
    >>> bool(np.allclose(one_step_residuals(Ad, Bd, states, inputs), noise[:-1]))
    True
    """
    return states[1:] - one_step_prediction(Ad, Bd, states, inputs)
