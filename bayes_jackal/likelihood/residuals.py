"""One-step residuals and their regressors (thesis eq. 7-3).

The one-step residual of a channel measured by a sensor (the yaw rate) is
w[k] = y[k+1] - Ad y[k] - Bd u[k]: what the linear model leaves
unexplained. It is linear in the regressors Z = [y[k+1], y[k], u_r[k],
u_l[k]], w = Z (1, -Ad[c, c], -Bd[c, :]). A channel recorded through
motion-capture poses (vx, vy of a bag) has the residual of its pose
increments instead, linear in its own regressors
(:class:`bayes_jackal.likelihood.PoseMeasurement`): the same
functions here give either, by how the experiment recorded the channel
(:meth:`~bayes_jackal.io.Experiment.measurement`). The likelihood
works on Z, the residual analysis (:mod:`bayes_jackal.thesis.residual_analysis`,
thesis ch. 7), the posterior files and the model criticism on w.
"""

from __future__ import annotations

import numpy as np

from .._runtime import DataError
from ..io import CHANNEL_FIELDS, Experiment
from ..model import RobotProfile, channel_coefficients
from .irregular import IrregularSeries, irregular_residuals
from .measurements import measurement_of

__all__ = [
    "channel_residuals",
    "check_residual_window",
    "residual_count",
    "residual_regressors",
    "residual_times",
]


def channel_residuals(
    experiment: Experiment,
    robot: RobotProfile,
    d_lat: np.ndarray | float,
    d_long: np.ndarray | float,
    channel: str = "yaw",
    steady: bool = False,
    samples: slice = slice(None),
) -> np.ndarray:
    """One-step residuals of one measured channel (eq. 7-3).

    w[k] = y[k+1] - Ad y[k] - Bd u[k] for k = 0..N-2, with the channel's
    exact (ZOH) pole Ad[c, c] and input row Bd[c, :] at the experiment's
    sample time (eq. 6-6); for a channel recorded as poses, the residual of
    its pose increments (k = 0..N-3,
    :class:`~bayes_jackal.likelihood.PoseMeasurement`), in the same unit.
    The thesis evaluates the steady-state window only (ch. 7-1:
    acceleration and deceleration left out).

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
        steady-state window), as the thesis (ch. 7-1); False (the default)
        uses every sample.
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

    Examples
    --------
    The yaw channel of :func:`bayes_jackal.model.one_step_residuals` over
    every sample, vectorised over the damping:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.model import discrete_matrices, one_step_residuals
    >>> from bayes_jackal.likelihood import channel_residuals
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> w = channel_residuals(run, robot, 110.0, 30.0, "yaw")
    >>> w.shape
    (2736,)
    >>> states = np.column_stack([run.channel(c) for c in ("vx", "vy", "yaw")])
    >>> Ad, Bd = discrete_matrices(robot, 110.0, 30.0, run.dt)
    >>> bool(np.allclose(w, one_step_residuals(Ad, Bd, states, run.inputs)[:, 2]))
    True
    >>> channel_residuals(run, robot, [100.0, 110.0, 120.0], 30.0).shape
    (3, 2736)
    """
    window = experiment.steady() if steady else experiment
    measurement = measurement_of(window, channel)
    if not measurement.regular(window):
        return _irregular_residuals(window, robot, d_lat, d_long, channel)[..., samples]
    coefficients, _ = measurement.coefficients(
        robot, d_lat, d_long, channel, window.dt, clock=measurement.clock(window)
    )
    return coefficients @ measurement.series(window, channel).regressors[samples].T


def _irregular_residuals(
    experiment: Experiment,
    robot: RobotProfile,
    d_lat: np.ndarray | float,
    d_long: np.ndarray | float,
    channel: str,
) -> np.ndarray:
    """The residuals of a channel observed at its own times, its pieces one after the other."""
    d_lat, d_long = np.broadcast_arrays(np.asarray(d_lat, float), np.asarray(d_long, float))
    alpha, beta = channel_coefficients(
        robot, d_lat.ravel(), d_long.ravel(), channel, experiment.dt
    )
    measurement = measurement_of(experiment, channel)
    pieces = [
        irregular_residuals(
            IrregularSeries(channel, measurement.name, 0, experiment.dt, piece.ticks,
                            piece.phases, piece.values, piece.counts, experiment.inputs),
            alpha[:, None],
            beta[:, None],
        )
        for piece in measurement.observations(experiment, channel)
    ]  # fmt: skip
    return np.concatenate(pieces, axis=1).reshape(*d_lat.shape, -1)


def residual_regressors(experiment: Experiment, channel: str, steady: bool = False) -> np.ndarray:
    """Regressors Z = [y[k+1], y[k], u_r[k], u_l[k]] of one channel, shape (N - 1, 4).

    The one-step residual (eq. 7-3) is linear in them: w = Z (1, -Ad[c, c],
    -Bd[c, 0], -Bd[c, 1]). A channel recorded as poses has the regressors of
    :class:`~bayes_jackal.likelihood.PoseMeasurement`, shape (N - 2, 6).

    Parameters
    ----------
    experiment : Experiment
    channel : {"yaw", "vx", "vy"}
    steady : bool
        The steady-state window (the whole experiment when it has none), or
        every sample.

    Examples
    --------
    The residuals are Z (1, -Ad[c, c], -Bd[c, :]):

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.model import channel_coefficients
    >>> from bayes_jackal.likelihood import channel_residuals, residual_regressors
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> Z = residual_regressors(run, "yaw")
    >>> Z.shape
    (2736, 4)
    >>> alpha, row = channel_coefficients(robot, 110.0, 30.0, "yaw", run.dt)
    >>> c = np.concatenate([[1.0, -alpha], -row])
    >>> bool(np.allclose(Z @ c, channel_residuals(run, robot, 110.0, 30.0, "yaw")))
    True
    """
    window = experiment.steady() if steady else experiment
    return measurement_of(window, channel).series(window, channel).regressors


def residual_times(experiment: Experiment, channel: str, steady: bool = False) -> np.ndarray:
    """When each residual of :func:`channel_residuals` ends: the time of its last sample [s].

    Examples
    --------
    A rate sensor that missed one sample: the two residuals that needed it
    are not there:

    >>> import numpy as np
    >>> from bayes_jackal.io import Experiment
    >>> from bayes_jackal.likelihood import residual_times
    >>> t = np.arange(6) / 10
    >>> run = Experiment(t=t, yaw_rate=np.sin(t), omega_r=1 + 0 * t, omega_l=1 + 0 * t,
    ...                  measured={"yaw_rate": np.array([1, 1, 0, 1, 1, 1], bool)})
    >>> residual_times(run, "yaw").tolist()
    [0.1, 0.4, 0.5]
    """
    window = experiment.steady() if steady else experiment
    measurement = measurement_of(window, channel)
    if measurement.regular(window):
        stride = measurement.clock(window)[0]
        span = 2 * stride if measurement.name == "pose" else 1
        return window.t[measurement.series(window, channel).ticks + span]
    order = 3 if measurement.name == "pose" else 2
    return np.concatenate(
        [
            window.t[piece.ticks[order - 1 :]] + piece.phases[order - 1 :]
            for piece in measurement.observations(window, channel)
        ]
    )


def residual_count(experiment: Experiment, channel: str) -> int:
    """The residuals ``channel`` of ``experiment`` gives: one-step, or at its own times.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import residual_count
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> residual_count(run, "yaw"), len(run.t)
    (1872, 1873)
    """
    measurement = measurement_of(experiment, channel)
    if measurement.regular(experiment):
        return len(measurement.series(experiment, channel).regressors)
    order = 3 if measurement.name == "pose" else 2
    return sum(
        len(piece.ticks) - order + 1 for piece in measurement.observations(experiment, channel)
    )


def check_residual_window(
    experiment: Experiment,
    channel: str,
    minimum: int,
    steady: bool = False,
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

    Examples
    --------
    Silent when the window is long enough; otherwise a
    :class:`~bayes_jackal._runtime.errors.DataError` (a ``ValueError``) naming the file
    (``<memory>`` for a simulated run), the field and the counts:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import check_residual_window
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v1", rng=1)
    >>> check_residual_window(run, "yaw", 32)
    >>> try:
    ...     check_residual_window(run, "yaw", 10_000, reason=" for this example")
    ... except ValueError as error:
    ...     print(error)
    <memory>: yaw: the experiment holds 2737 samples, 2736 one-step
    residuals; at least 10000 are needed for this example
    """
    window = experiment.steady() if steady else experiment
    y = window.channel(channel)
    span = "the steady-state window" if steady and experiment.steady_window else "the experiment"
    count = residual_count(window, channel)
    if count < minimum:
        raise DataError(
            f"{span} holds {len(y)} samples, {count} one-step residuals; at least "
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
