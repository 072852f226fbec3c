"""One-step residuals and their regressors (thesis eq. 7-3).

The one-step residual of a measured channel y is w[k] = y[k+1] - Ad y[k]
- Bd u[k]: what the linear model leaves unexplained. It is linear in the
regressors Z = [y[k+1], y[k], u_r[k], u_l[k]], w = Z (1, -Ad[c, c],
-Bd[c, :]); the likelihood works on Z, the residual analysis
(:mod:`bayes_jackal.residual_analysis`, thesis ch. 7), the posterior files and the
model criticism on w.
"""

from __future__ import annotations

import numpy as np

from .errors import DataError
from .experiment import CHANNEL_FIELDS, Experiment
from .physics import channel_coefficients
from .robot import RobotProfile

__all__ = ["channel_residuals", "check_residual_window", "residual_regressors"]


def channel_residuals(
    experiment: Experiment,
    robot: RobotProfile,
    d_lat: np.ndarray | float,
    d_long: np.ndarray | float,
    channel: str = "yaw",
    steady: bool = True,
    samples: slice = slice(None),
) -> np.ndarray:
    """One-step residuals of one measured channel (eq. 7-3).

    w[k] = y[k+1] - Ad y[k] - Bd u[k] for k = 0..N-2, with the channel's
    exact (ZOH) pole Ad[c, c] and input row Bd[c, :] at the experiment's
    sample time (eq. 6-6). The thesis evaluates the steady-state window only
    (ch. 7-1: acceleration and deceleration left out).

    Parameters
    ----------
    experiment : Experiment
    robot : RobotProfile
    d_lat, d_long : float or array_like
        Damping [N s/m], broadcast together; arrays add leading axes.
    channel : {"yaw", "vx", "vy"}
        Measured state: yaw rate [rad/s] or body velocity [m/s].
    steady : bool
        Use ``experiment.steady()`` (the whole experiment when it has no
        steady-state window); False uses every sample.
    samples : slice
        Which residuals to compute (default all): a window of a long run
        costs only its own length.

    Returns
    -------
    ndarray, shape (..., N - 1) or (..., window length)
        Residuals in the channel's unit ([rad/s] or [m/s]).

    Raises
    ------
    DataError
        When the experiment does not measure the channel.
    InputError
        For an unknown channel or non-positive damping.
    """
    dt = (experiment.steady() if steady else experiment).dt
    alpha, input_row = channel_coefficients(robot, d_lat, d_long, channel, dt)
    # eq. 7-3 for one channel of the diagonal model: Z (1, -alpha, -Bd[c, :])
    coefficients = np.concatenate([np.ones((*alpha.shape, 1)), -alpha[..., None], -input_row], -1)
    return coefficients @ residual_regressors(experiment, channel, steady)[samples].T


def residual_regressors(experiment: Experiment, channel: str, steady: bool = True) -> np.ndarray:
    """Regressors Z = [y[k+1], y[k], u_r[k], u_l[k]] of one channel, shape (N - 1, 4).

    The one-step residual (eq. 7-3) is linear in them: w = Z (1, -Ad[c, c],
    -Bd[c, 0], -Bd[c, 1]).

    Parameters
    ----------
    experiment : Experiment
    channel : {"yaw", "vx", "vy"}
    steady : bool
        The steady-state window (the whole experiment when it has none), or
        every sample.
    """
    window = experiment.steady() if steady else experiment
    y = window.channel(channel)
    return np.column_stack([y[1:], y[:-1], window.inputs[:-1]])


def check_residual_window(
    experiment: Experiment,
    channel: str,
    minimum: int,
    steady: bool = True,
    reason: str = "",
    field: str | None = None,
) -> None:
    """Raise unless the window holds ``minimum`` residuals of a varying channel.

    Parameters
    ----------
    experiment : Experiment
    channel : {"yaw", "vx", "vy"}
    minimum : int
        Fewest one-step residuals the caller needs.
    steady : bool
        Check the steady-state window (or every sample).
    reason : str
        What needs them, appended to the message (e.g. " for 30 lags").
    field : str, optional
        Field the short-window error names; the channel by default.

    Raises
    ------
    DataError
        Naming the file, the field and the sample count, or the constant value.
    """
    window = experiment.steady() if steady else experiment
    y = window.channel(channel)
    span = "the steady-state window" if steady and experiment.steady_window else "the experiment"
    if len(y) - 1 < minimum:
        raise DataError(
            f"{span} holds {len(y)} samples, {len(y) - 1} one-step residuals; at least "
            f"{minimum} are needed{reason}",
            source=experiment.source,
            field=field or channel,
        )
    if np.ptp(y) == 0:
        raise DataError(
            f"channel {channel!r} is constant ({y[0]:g}) in {span}: it carries no information",
            source=experiment.source,
            field=CHANNEL_FIELDS[channel],
        )
