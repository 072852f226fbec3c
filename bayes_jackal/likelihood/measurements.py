"""How a channel was recorded: its one-step residual, linear in the data, and that residual's law.

A channel enters the likelihood as a residual series r = Z c: regressors Z
built from the data once, coefficients c from the damping. Each way of
recording a channel is a class here (one per idea), registered in
:data:`MEASUREMENT_MODELS` under the names of
:data:`bayes_jackal.io.MEASUREMENTS`:

- :class:`RateMeasurement` (``rate``): a sensor measures the state, y = x +
  n (the IMU's yaw rate; a velocity sensor). The residual is eq. 7-3,

      r_k = y_{k+1} - alpha y_k - beta . u_k = w_k + n_{k+1} - alpha n_k,

  with Z = [y_{k+1}, y_k, u_k] and the sensor noise's MA(1) footprint
  (docs/design.md §4).
- :class:`PoseMeasurement` (``pose``): motion capture records the world
  pose, and vx, vy are seen through the body-frame increments M_k of the
  poses (:mod:`bayes_jackal.io.pose_increments`). Between samples the inputs
  and the process noise are held (zero-order hold, as the thesis'
  discretisation holds the input: eq. 6-6), so over a step of the channel's
  scalar model dx/dt = a x + b.u + eta,

      M_k = g x_k + h (beta / g) . u_k + (h / g) w_k,
      g = dt exprel(a dt) = (alpha - 1) / a,   h = (g - dt) / a,

  with w_k = g eta_k the discrete process noise of eq. 7-3. Applying
  (1 - alpha L) removes the state (A is diagonal: the step's integral
  commutes with Ad), and with the pose noise e of each sample, over dt,

      r_k = (M_{k+1} - alpha M_k) / dt - kappa_0 beta . u_{k+1} - kappa_1 beta . u_k
          = kappa_0 w_{k+1} + kappa_1 w_k + (e_{k+2} - (1 + alpha) e_{k+1} + alpha e_k) / dt,

      kappa_0 = h / (g dt),   kappa_1 = g / dt - alpha kappa_0
      (kappa_0 + kappa_1 = 1; both -> 1/2 as dt -> 0).

  So Z = [M_{k+1}, M_k, u_{k+1}, u_k], the residual is in the channel's
  velocity unit, and its law is stationary Gaussian: the process noise
  through a two-tap filter plus the pose noise's known MA(2) term, of sd
  sigma_p / sqrt(n) per sample (n poses averaged per sample). sigma_p,
  the motion-capture system's position noise [m], is the channel's sensor
  parameter. The scale 1 / dt is the same for every parameter set, so the
  density of r is that of the increments up to a constant: dividing by g,
  which depends on the damping, would add N log g to the likelihood and
  pull the damping down (measured: 80 nats between d_long 10 and 30 on a
  38 s run).

Both laws are Toeplitz, so every engine of
:class:`bayes_jackal.likelihood.ResidualLikelihood` evaluates either. They
need a measurement at every sample (a rate channel) or a pose per sample
(a pose channel): a rate sensor that missed samples
(:attr:`bayes_jackal.io.Experiment.measured`) or poses that drop out split
the series into segments of consecutive ones (:attr:`ChannelSeries.lengths`;
their log-likelihoods add), and poses slower than the samples have no
such series at all. :meth:`Measurement.observations` gives every channel
at its own times instead, for the exact likelihood of
:mod:`bayes_jackal.likelihood.irregular`, which also serves a damping that
changes from one segment of the run to the next.
"""

from __future__ import annotations

import abc
import functools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .._runtime import DataError
from ..io import Experiment, PoseObservations, pose_observations
from ..model import Family, RobotProfile, channel_coefficients, step_integrals
from .irregular import pattern_coefficients

__all__ = [
    "BRIDGED_GAP",
    "MEASUREMENT_MODELS",
    "ChannelObservations",
    "ChannelSeries",
    "Measurement",
    "PoseMeasurement",
    "RateMeasurement",
    "measurement_of",
    "pose_weights",
    "residual_autocovariance",
]


#: Longest stretch without an observation that one residual of the irregular
#: engine bridges [s] (the bag reader's ``max_gap``): a longer one splits the
#: channel, whose pieces' log-likelihoods add.
BRIDGED_GAP = 0.25


@dataclass(frozen=True)
class ChannelSeries:
    """The regressors of one channel of one experiment, and its pose count.

    Attributes
    ----------
    regressors : ndarray, shape (n, K)
        Z: the residuals are Z c; the segments' rows one after the other.
    samples : int
        Recorded poses averaged into each sample (1 for a rate channel).
    lengths : tuple of int
        The residuals of each segment of consecutive measurements, in
        order (they add up to n); one segment when nothing was missed.
    ticks : ndarray of int, shape (n,), optional
        The sample k of each row's residual r_k (the first of the samples
        it spans); by default 0..n-1.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.likelihood import ChannelSeries
    >>> ChannelSeries(np.zeros((100, 4))).lengths
    (100,)
    """

    regressors: np.ndarray
    samples: int = 1
    lengths: tuple[int, ...] = ()
    ticks: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not self.lengths:
            object.__setattr__(self, "lengths", (len(self.regressors),))
        if self.ticks is None:
            object.__setattr__(self, "ticks", np.arange(len(self.regressors)))

    def segments(self) -> list[np.ndarray]:
        """The regressors of each segment."""
        return np.split(self.regressors, np.cumsum(self.lengths)[:-1])


@dataclass(frozen=True)
class ChannelObservations:
    """One piece of a channel observed at its own times (the irregular engine's input).

    Attributes
    ----------
    ticks, phases : ndarray, shape (M,)
        The sample each observation falls after, and how long after [s].
    values : ndarray
        A rate channel's measurements (M,); a pose channel's body-frame
        increments between consecutive observations (M - 1,) [m].
    counts : ndarray of int, shape (M,)
        Recorded poses averaged into each observation (ones for a rate channel).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.likelihood import ChannelObservations
    >>> piece = ChannelObservations(np.arange(4), np.zeros(4), np.ones(4), np.ones(4, int))
    >>> len(piece.ticks)
    4
    """

    ticks: np.ndarray
    phases: np.ndarray
    values: np.ndarray
    counts: np.ndarray


class Measurement(abc.ABC):
    """A way of recording a channel: its residual's regressors, coefficients and law.

    Attributes
    ----------
    name : str
        Key in :data:`MEASUREMENT_MODELS`.
    sensor_parameter : str
        The channel's sensor-noise parameter: ``sigma_n`` (the state's
        sensor [channel unit]) or ``sigma_p`` (the pose's position [m]).
    regressor_count : int
        K, the columns of Z.

    Examples
    --------
    The registered models, by name:

    >>> from bayes_jackal.likelihood import MEASUREMENT_MODELS
    >>> for name, model in MEASUREMENT_MODELS.items():
    ...     print(name, model.sensor_parameter, model.regressor_count)
    rate sigma_n 4
    pose sigma_p 6
    """

    name: ClassVar[str]
    sensor_parameter: ClassVar[str]
    regressor_count: ClassVar[int]

    @abc.abstractmethod
    def series(self, experiment: Experiment, channel: str) -> ChannelSeries:
        """The regressors Z of ``channel`` over the whole ``experiment``, by segment."""

    def samples(self, experiment: Experiment) -> int:
        """The recorded poses each observation of ``experiment`` averages (1: none)."""
        return 1

    def regular(self, experiment: Experiment) -> bool:
        """Whether :meth:`series` holds the channel: a stationary series of residuals."""
        return True

    def clock(self, experiment: Experiment) -> tuple[int, float]:
        """(m, phase [s]): the channel observed every m samples, phase after each (1, 0)."""
        return (1, 0.0)

    @abc.abstractmethod
    def observations(self, experiment: Experiment, channel: str) -> list[ChannelObservations]:
        """``channel`` at its own times, in pieces split at gaps over :data:`BRIDGED_GAP`."""

    @abc.abstractmethod
    def coefficients(
        self,
        robot: RobotProfile,
        d_lat: np.ndarray | float,
        d_long: np.ndarray | float,
        channel: str,
        dt: float,
        *,
        clock: tuple[int, float] = (1, 0.0),
    ) -> tuple[np.ndarray, np.ndarray]:
        """c, shape (..., K), and the channel's discrete pole alpha = Ad[c, c], shape (...).

        ``clock``: :meth:`clock` of the experiment whose series c multiplies.
        """

    @abc.abstractmethod
    def autocovariance(
        self,
        family: Family,
        width: np.ndarray,
        sigma_c: np.ndarray,
        sigma_sensor: np.ndarray,
        alpha: np.ndarray,
        dt: float,
        lags: int,
        *,
        sensor: str = "ma1",
        samples: int = 1,
        clock: tuple[int, float] = (1, 0.0),
    ) -> np.ndarray:
        """The residual's autocovariance at lags 0..lags-1, shape (B, lags).

        ``width`` [s], ``sigma_c`` (process noise per step [channel unit]),
        ``sigma_sensor`` (:attr:`sensor_parameter`'s value) and ``alpha``
        are arrays of shape (B,); ``sensor`` is the rate channels' sensor
        term (``ma1`` or ``diagonal``), ``samples`` the poses per sample,
        ``clock`` the series' (:meth:`clock`; lags count its steps).
        """


class RateMeasurement(Measurement):
    """A sensor measures the state: y = x + n (eq. 7-3; module docstring).

    Examples
    --------
    The yaw rate's residuals are Z (1, -alpha, -beta):

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import RateMeasurement
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v2", rng=1)
    >>> series = RateMeasurement().series(run, "yaw")
    >>> c, alpha = RateMeasurement().coefficients(robot, 110.0, 30.0, "yaw", run.dt)
    >>> series.regressors.shape, c.shape, round(float(alpha), 4)
    ((1872, 4), (4,), 0.7244)
    """

    name = "rate"
    sensor_parameter = "sigma_n"
    regressor_count = 4

    def series(self, experiment: Experiment, channel: str) -> ChannelSeries:
        y, observed = experiment.channel(channel), experiment.observed(channel)
        rows = np.column_stack([y[1:], y[:-1], experiment.inputs[:-1]])
        return _segmented(rows, observed[1:] & observed[:-1])

    def observations(self, experiment: Experiment, channel: str) -> list[ChannelObservations]:
        ticks = np.flatnonzero(experiment.observed(channel))
        values = experiment.channel(channel)[ticks]
        ones = np.ones(len(ticks), int)
        return _pieces(ticks, np.zeros(len(ticks)), values, ones, experiment.dt, increments=False)

    def coefficients(self, robot, d_lat, d_long, channel, dt, *, clock=(1, 0.0)):
        alpha, beta = channel_coefficients(robot, d_lat, d_long, channel, dt)
        ones = np.ones((*alpha.shape, 1))
        return np.concatenate([ones, -alpha[..., None], -beta], axis=-1), alpha

    def autocovariance(
        self,
        family,
        width,
        sigma_c,
        sigma_sensor,
        alpha,
        dt,
        lags,
        *,
        sensor="ma1",
        samples=1,
        clock=(1, 0.0),
    ):
        return residual_autocovariance(
            family, width, sigma_c, sigma_sensor, alpha, dt, lags, sensor
        )


class PoseMeasurement(Measurement):
    """Motion capture records the pose; vx, vy are seen through its increments (module docstring).

    Examples
    --------
    The coefficients of the vx channel at 72 Hz: the input weights kappa_0,
    kappa_1 of the two steps are near 1/2, and the residual of a noise-free
    steady drive is zero:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import PoseMeasurement, pose_weights
    >>> robot = bj.load_profile()
    >>> c, alpha = PoseMeasurement().coefficients(robot, 110.0, 30.0, "vx", 1 / 72)
    >>> c.shape, [round(float(w), 4) for w in pose_weights(alpha)]
    ((6,), [0.5084, 0.4916])
    >>> v = 0.4  # the steady speed: u gives x = -b.u / a, and M = v dt each step
    >>> u = np.array([v / robot.wheel_radius] * 2)
    >>> residual = c @ np.concatenate([[v / 72, v / 72], u, u])
    >>> bool(abs(residual) < 1e-12)
    True
    """

    name = "pose"
    sensor_parameter = "sigma_p"
    regressor_count = 6

    def samples(self, experiment: Experiment) -> int:
        return observed_poses(experiment).samples

    def regular(self, experiment: Experiment) -> bool:
        return observed_poses(experiment).regime != "stamp"

    def clock(self, experiment: Experiment) -> tuple[int, float]:
        return observed_poses(experiment).clock

    def series(self, experiment: Experiment, channel: str) -> ChannelSeries:
        poses = observed_poses(experiment)
        if poses.regime == "stride":
            return _strided_series(experiment, poses, channel)
        if poses.regime != "tick":
            raise DataError(
                f"the poses ({poses.rate:.4g} Hz) are slower than the samples "
                f"({1 / experiment.dt:.4g} Hz): no pose per sample, so no one-step series; "
                "the likelihood observes them at their own stamps (observations)",
                source=experiment.source,
                field="pose",
            )
        increments = np.full(len(experiment.t) - 1, np.nan)
        consecutive = np.diff(poses.ticks) == 1
        increments[poses.ticks[:-1][consecutive]] = poses.increments(channel)[consecutive]
        u = experiment.inputs
        rows = np.column_stack([increments[1:], increments[:-1], u[1:-1], u[:-2]])
        return _segmented(rows, np.isfinite(rows[:, :2]).all(axis=1), poses.samples)

    def observations(self, experiment: Experiment, channel: str) -> list[ChannelObservations]:
        poses = observed_poses(experiment)
        counts = np.full(len(poses.ticks), poses.samples)
        return _pieces(poses.ticks, poses.phases, poses.increments(channel), counts,
                       experiment.dt, increments=True)  # fmt: skip

    def coefficients(self, robot, d_lat, d_long, channel, dt, *, clock=(1, 0.0)):
        alpha, beta = channel_coefficients(robot, d_lat, d_long, channel, dt)
        if clock[0] > 1:  # every m samples: the inputs over the residual's span
            mu, gamma = _pattern(alpha, dt, clock)
            inputs = -(mu[..., None] * beta[..., None, :]).reshape(*alpha.shape, -1)
            return np.concatenate([np.full((*alpha.shape, 1), 1.0 / dt),
                                   (-gamma / dt)[..., None], inputs], axis=-1), alpha  # fmt: skip
        kappa_0, kappa_1 = pose_weights(alpha)
        columns = [
            np.full((*alpha.shape, 1), 1.0 / dt),
            (-alpha / dt)[..., None],
            -kappa_0[..., None] * beta,
            -kappa_1[..., None] * beta,
        ]
        return np.concatenate(columns, axis=-1), alpha

    def autocovariance(
        self,
        family,
        width,
        sigma_c,
        sigma_sensor,
        alpha,
        dt,
        lags,
        *,
        sensor="ma1",
        samples=1,
        clock=(1, 0.0),
    ):
        variance = sigma_sensor**2 / (samples * dt**2)
        if clock[0] > 1:
            mu, gamma = _pattern(alpha, dt, clock)
            acov = sigma_c[:, None] ** 2 * _strided_process(family, width, mu, dt, clock[0], lags)
        else:
            gamma = alpha
            kappa_0, kappa_1 = (w[:, None] for w in pose_weights(alpha))
            kernel = family.autocorrelation(width, dt, lags + 1)
            before = np.concatenate([kernel[:, 1:2], kernel[:, : lags - 1]], axis=1)  # R(l - 1)
            acov = sigma_c[:, None] ** 2 * (
                (kappa_0**2 + kappa_1**2) * kernel[:, :lags]
                + kappa_0 * kappa_1 * (before + kernel[:, 1:])
            )
        ma2 = np.stack([1.0 + (1.0 + gamma) ** 2 + gamma**2, -((1.0 + gamma) ** 2), gamma], -1)
        kept = min(3, lags)
        acov[:, :kept] += variance[:, None] * ma2[:, :kept]
        return acov


def pose_weights(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """kappa_0 = h / (g dt) and kappa_1 = g / dt - alpha kappa_0 of a pose channel's pole.

    :func:`bayes_jackal.model.step_integrals` at dt = 1 (both are functions of
    a dt alone).

    Examples
    --------
    Both weights tend to 1/2 for a slow pole, and always add up to 1:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import pose_weights
    >>> [round(float(w), 6) for w in pose_weights(np.array(1 - 1e-9))]
    [0.5, 0.5]
    >>> float(sum(pose_weights(np.array(0.3))))
    1.0
    """
    g, h = step_integrals(alpha, 1.0)
    kappa_0 = h / g
    return kappa_0, g - np.asarray(alpha, float) * kappa_0


def _pattern(
    alpha: np.ndarray, dt: float, clock: tuple[int, float]
) -> tuple[np.ndarray, np.ndarray]:
    """mu (..., 2m + 1) and gamma (...) of a pose every m samples at one phase.

    The last few are kept: an evaluation asks for them once for the
    coefficients and again for each spectral grid's autocovariance.
    """
    alpha = np.asarray(alpha, float)
    key = (alpha.tobytes(), alpha.shape, dt, clock)
    if key not in _PATTERNS:
        mu, gamma = pattern_coefficients("pose", dt, clock[0], clock[1], alpha.ravel())
        if len(_PATTERNS) >= 8:
            _PATTERNS.pop(next(iter(_PATTERNS)))
        _PATTERNS[key] = (mu.reshape(*alpha.shape, -1), gamma.reshape(alpha.shape))
    return _PATTERNS[key]


#: The last few :func:`_pattern` results, by their arguments.
_PATTERNS: dict = {}


def _strided_process(
    family: Family, width: np.ndarray, mu: np.ndarray, dt: float, stride: int, lags: int
) -> np.ndarray:
    """sum_{p,q} mu_p mu_q R(l m + q - p) at lags l < ``lags`` of the poses' clock, (B, lags).

    With c(d) = sum_p mu_p mu_{p+d}, the residual's autocorrelation through
    the noise's at lag l is sum_d c(d) R(l m + d), |d| <= 2m.
    """
    span = mu.shape[1]
    rho = family.autocorrelation(width, dt, lags * stride + span)
    rho = np.concatenate([rho[:, span - 1 : 0 : -1], rho], axis=1)  # R(-(span-1)..)
    shifts = np.arange(-(span - 1), span)
    padded = np.concatenate([mu, np.zeros_like(mu)], axis=1)
    # c(d) = sum_p mu_p mu_{p+d}, from the correlation of mu with itself.
    spectrum = np.fft.rfft(padded, axis=1)
    correlation = np.fft.irfft(np.abs(spectrum) ** 2, 2 * span, axis=1)
    c = correlation[:, shifts % (2 * span)]  # (B, 2 span - 1)
    index = np.arange(lags)[:, None] * stride + span - 1 + shifts  # R(l m + d) in rho's index
    return np.einsum("bd,bld->bl", c, rho[:, index])


def _strided_series(
    experiment: Experiment, poses: PoseObservations, channel: str
) -> ChannelSeries:
    """The regressors [D_{j+1}, D_j, u over the span] of poses every m samples, by segment."""
    stride = poses.stride
    increments = poses.increments(channel)
    consecutive = np.diff(poses.ticks) == stride
    valid = consecutive[1:] & consecutive[:-1]  # residual j: poses j, j + 1, j + 2
    base = poses.ticks[:-2]
    span = np.clip(base[:, None] + np.arange(2 * stride + 1), 0, len(experiment.t) - 1)
    inputs = experiment.inputs[span].reshape(len(base), -1)  # (J, 2 (2m + 1))
    rows = np.column_stack([increments[1:], increments[:-1], inputs])
    valid &= base + 2 * stride <= len(experiment.t) - 1
    series = _segmented(rows, valid, poses.samples)
    return ChannelSeries(series.regressors, series.samples, series.lengths, base[valid])


def _segmented(rows: np.ndarray, valid: np.ndarray, samples: int = 1) -> ChannelSeries:
    """The valid rows of a one-step series, by segment of consecutive valid rows."""
    starts = np.flatnonzero(valid & ~np.concatenate([[False], valid[:-1]]))
    stops = np.flatnonzero(valid & ~np.concatenate([valid[1:], [False]])) + 1
    lengths = tuple(int(n) for n in stops - starts)
    return ChannelSeries(rows[valid], samples, lengths, np.flatnonzero(valid))


def _pieces(
    ticks: np.ndarray,
    phases: np.ndarray,
    values: np.ndarray,
    counts: np.ndarray,
    dt: float,
    *,
    increments: bool,
) -> list[ChannelObservations]:
    """Observations split where consecutive ones lie more than :data:`BRIDGED_GAP` apart.

    A piece too short for two residuals (four observations) is left out.
    """
    times = ticks * dt + phases
    cuts = np.flatnonzero(np.diff(times) > BRIDGED_GAP) + 1
    pieces = []
    for start, stop in zip([0, *cuts], [*cuts, len(ticks)], strict=True):
        if stop - start < 4:
            continue
        part = slice(start, stop)
        kept = values[start : stop - 1] if increments else values[part]
        pieces.append(ChannelObservations(ticks[part], phases[part], kept, counts[part]))
    return pieces


@functools.lru_cache(maxsize=16)
def observed_poses(experiment: Experiment) -> PoseObservations:
    """:func:`bayes_jackal.io.pose_observations` of an experiment, kept for its pose channels.

    Experiments are immutable: the last few are remembered by identity, so
    that vx, vy and every caller share one computation.
    """
    return pose_observations(experiment)


#: The measurement models by name (:data:`bayes_jackal.io.MEASUREMENTS`).
MEASUREMENT_MODELS: dict[str, Measurement] = {
    model.name: model for model in (RateMeasurement(), PoseMeasurement())
}


def measurement_of(experiment: Experiment, channel: str) -> Measurement:
    """The model of how ``channel`` of ``experiment`` was recorded.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import measurement_of
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> measurement_of(run, "vx").name
    'rate'
    """
    return MEASUREMENT_MODELS[experiment.measurement(channel)]


def residual_autocovariance(
    family: Family,
    width: np.ndarray,
    sigma_c: np.ndarray,
    sigma_n: np.ndarray,
    alpha: np.ndarray,
    dt: float,
    n: int,
    sensor: str = "ma1",
) -> np.ndarray:
    """Autocovariance of a rate channel's one-step residual at lags 0..n-1.

    Parameters
    ----------
    family : Family
        Process-noise filter family.
    width, sigma_c, sigma_n, alpha : ndarray, shape (B,)
        Kernel width [s], process-noise sd, sensor-noise sd [channel units],
        and the channel's discrete pole Ad[c, c].
    dt : float
        Sample time [s].
    n : int
        Number of lags.
    sensor : {"ma1", "diagonal"}

    Returns
    -------
    ndarray, shape (B, n)

    Examples
    --------
    White process noise and the MA(1) footprint of sensor noise:
    sigma_c^2 + sigma_n^2 (1 + alpha^2) at lag 0, -sigma_n^2 alpha at lag 1:

    >>> import numpy as np
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.likelihood import residual_autocovariance
    >>> one = np.ones(1)
    >>> acov = residual_autocovariance(
    ...     get_family("white"), one, 0.01 * one, 0.005 * one, 0.9 * one, dt=0.01, n=4
    ... )
    >>> bool(np.allclose(acov, [[1e-4 + 2.5e-5 * 1.81, -2.5e-5 * 0.9, 0.0, 0.0]]))
    True
    """
    acov = sigma_c[:, None] ** 2 * family.autocorrelation(width, dt, n)
    if sensor == "ma1":
        acov[:, 0] += sigma_n**2 * (1.0 + alpha**2)
        acov[:, 1] -= sigma_n**2 * alpha
    else:
        acov[:, 0] += sigma_n**2
    return acov
