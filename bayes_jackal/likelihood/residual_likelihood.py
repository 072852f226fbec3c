"""Likelihood of one-step residuals under coloured process noise (docs/design.md §4).

For one channel the measured one-step residual (eq. 7-3) is

    r[k] = y[k+1] - alpha y[k] - beta_r u_r[k] - beta_l u_l[k]
         = w[k] + n[k+1] - alpha n[k],

process noise w filtered from white noise by a family's kernel plus the
footprint of white sensor noise n on the measured state. It is a zero-mean
stationary Gaussian series with Toeplitz covariance

    Sigma = sigma_c^2 R(width) + sigma_n^2 M(alpha),
    M = tridiag(-alpha, 1 + alpha^2, -alpha)      ("ma1", the default)

or M = I ("diagonal", for data without sensor noise). White noise with the
diagonal term, (sigma_c^2 + sigma_n^2) I, has one variance: there sigma_c is
the total sd and sigma_n is not a parameter. The residual is linear
in c = (1, -alpha, -beta_r, -beta_l): r = Z c with the regressors
Z = [y[k+1], y[k], u_r[k], u_l[k]].

That is a channel a sensor measures (the IMU's yaw rate). A channel that
motion capture records through the poses (vx, vy of a bag) has the
residual of its pose increments instead: the process noise through a
two-tap filter plus the pose noise's MA(2) footprint, of sd sigma_p [m]
per recorded pose (:mod:`bayes_jackal.likelihood.measurements`, which holds both
forms). Either is a Toeplitz Gaussian, and the engines below evaluate
either.

Three engines evaluate log N(r; 0, Sigma), vectorised over parameter sets:

- ``exact``: the Durbin-Levinson recursion over all N orders, O(N^2): the
  reference.
- ``fast`` (default): the same density from the spectrum on a short grid
  and the lagged Gram tensor of Z, computed once (strong Szego
  log-determinant, Gohberg-Semencul quadratic form with the spectral-factor
  predictor; :mod:`bayes_jackal.likelihood.spectral`): a cost per evaluation that does
  not grow with N, equal to ``exact`` within 1e-6 nats (measured 2e-10
  to 2e-8 nats on 1e3 to 1e5 residuals, ``benchmarks/bench_engine.py``).
  Parameter sets whose predictor has not converged within the series fall
  back to :func:`bayes_jackal.likelihood.fallback_loglike`: the banded
  Cholesky factor, O(N p^2), where the autocovariance ends at a lag p,
  p + 1 <= 4 sqrt(N) (every family but the exponential), else the recursion
  stopped once its partial autocorrelations are below 1e-13.
- ``whittle``: the debiased Whittle likelihood (Sykulski et al. 2019) over
  cross-periodograms of Z computed once, so a new (d_lat, d_long) costs
  O(N). An approximation: it drops the boundary terms of the Toeplitz
  likelihood, which are small for white, exponential and moving-average
  noise but large for the smooth Gaussian family (measured on 2,376
  Gaussian-coloured residuals: the error varies by 54 nats across nearby
  noise settings, enough to move the posterior), so it is not the default.
  Its periodogram functions live in :mod:`bayes_jackal.likelihood.whittle`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np
import scipy.fft

from .._runtime import (
    DAMPING_MODEL,
    DAMPING_MODELS,
    DEFAULT_CHANNEL_ORDER,
    ENGINE,
    ENGINES,
    FAMILY,
    NOISE,
    NOISE_SHARING,
    SENSOR,
    SENSOR_MODELS,
    SHARED_NOISE,
    STEADY,
    DataError,
    InputError,
    as_rng,
    chunks,
    one_blas_thread,
)
from ..io import Experiment
from ..model import ParameterLayout, RobotProfile, channel_coefficients, get_family, step_integrals
from . import spectral
from .irregular import IrregularSeries, irregular_loglike
from .measurements import MEASUREMENT_MODELS, Measurement, measurement_of
from .residuals import check_residual_window
from .spectral import ResidualBlock, spectral_loglike
from .toeplitz import SCAN_WORK, fallback_loglike, toeplitz_loglike
from .whittle import debiased_whittle_loglike

__all__ = [
    "LikelihoodOptions",
    "ResidualLikelihood",
    "pose_channels",
    "resolve_channels",
    "sample_stationary",
]

#: Fewest residuals a channel must have to enter the likelihood.
MIN_RESIDUALS = 32
#: Narrowest range of the segments' speeds [m/s] the speed model takes.
SPEED_SPAN = 0.05


def sample_stationary(
    acov: np.ndarray, rng: np.random.Generator | int | None = None
) -> np.ndarray:
    """Draws of stationary Gaussian series with the given autocovariances.

    Circulant embedding (Dietrich & Newsam 1997): the autocovariance,
    mirrored and zero-padded to a fast length m >= 2n - 2, is the first row
    of a circulant matrix whose eigenvalues are its FFT; scaling complex
    white noise by their square roots and transforming back gives a series
    with exactly that covariance. Eigenvalues below zero (a short, not
    positive-definite embedding) are clipped, an approximation only for
    long-memory series.

    Parameters
    ----------
    acov : ndarray, shape (B, n)
        Autocovariance at lags 0..n-1, n >= 2.
    rng : numpy.random.Generator, int or None

    Returns
    -------
    ndarray, shape (B, n)

    Examples
    --------
    Many draws of an AR(1) series (phi = 0.5) recover its lag-1 covariance:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import sample_stationary
    >>> acov = np.tile(0.5 ** np.arange(50), (2000, 1))
    >>> x = sample_stationary(acov, rng=1)
    >>> x.shape
    (2000, 50)
    >>> round(float(np.mean(x[:, :-1] * x[:, 1:])), 2)
    0.5
    """
    acov = np.atleast_2d(acov)
    batch, n = acov.shape
    # Zero-padded to a fast length: 2n - 2 can be twice a prime (10 ms for
    # one transform of 43,198 points against 1 ms for 43,200).
    m = scipy.fft.next_fast_len(2 * n - 2)
    circulant = np.zeros((batch, m))
    circulant[:, :n] = acov
    circulant[:, m - n + 2 :] = acov[:, -2:0:-1]
    eigenvalues = np.clip(scipy.fft.fft(circulant, axis=1).real, 0.0, None)
    rng = as_rng(rng)
    white = rng.standard_normal(circulant.shape) + 1j * rng.standard_normal(circulant.shape)
    return scipy.fft.fft(np.sqrt(eigenvalues / m) * white, axis=1).real[:, :n]


def pose_channels(experiments: Sequence[Experiment], channels: Sequence[str]) -> tuple[str, ...]:
    """The channels the experiments record as poses (:meth:`Experiment.measurement`).

    A channel must be recorded one way in every experiment: a pose
    channel's sensor parameter is the pose noise sigma_p [m], a rate
    channel's the sensor noise sigma_n [its unit], and one likelihood gives
    a channel one of them.

    Raises
    ------
    DataError
        Naming two experiments that record a channel in different ways.

    Examples
    --------
    A simulated run measures its velocities with a sensor:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import pose_channels
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> pose_channels([run], ("yaw", "vx", "vy"))
    ()
    """
    chosen = []
    for channel in channels:
        kinds = {e.measurement(channel): e for e in experiments}
        if len(kinds) > 1:
            pose, rate = kinds["pose"], kinds["rate"]
            raise DataError(
                f"{pose.source} records {channel} as motion-capture poses and {rate.source} "
                f"as a measured {channel}: one model cannot give the channel both noise models; "
                "analyse them apart",
                source=rate.source,
                field=channel,
            )
        if "pose" in kinds:
            chosen.append(channel)
    return tuple(chosen)


def resolve_channels(
    experiments: list[Experiment], channels: Sequence[str] | None = None
) -> tuple[str, ...]:
    """The channels a likelihood uses: those given, or every one all experiments measure.

    Parameters
    ----------
    experiments : list of Experiment
    channels : sequence of {"yaw", "vx", "vy"}, optional
        Distinct channel names; None selects every channel measured in all
        experiments, yaw first (the thesis' channel), then vx, vy. Yaw is
        always measured, so the default is never empty.

    Returns
    -------
    tuple of str

    Raises
    ------
    InputError
        For no, unknown or repeated channel names.
    DataError
        When an experiment does not measure a requested channel, naming its
        file and the channels it has.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import resolve_channels
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v1", rng=1)
    >>> resolve_channels([run])
    ('yaw', 'vx', 'vy')
    >>> resolve_channels([run], ["vx", "yaw"])
    ('vx', 'yaw')
    >>> try:
    ...     resolve_channels([run], ["yaw", "yaw"])
    ... except ValueError as error:
    ...     print(error)
    channels: channels must be distinct names among ('yaw', 'vx', 'vy'), got ('yaw', 'yaw')
    """
    if channels is None:
        return tuple(c for c in DEFAULT_CHANNEL_ORDER if all(c in e.channels for e in experiments))
    channels = tuple(channels)
    unknown = [c for c in channels if c not in DEFAULT_CHANNEL_ORDER]
    if not channels or unknown or len(set(channels)) != len(channels):
        raise InputError(
            f"channels must be distinct names among {DEFAULT_CHANNEL_ORDER}, got {channels}",
            field="channels",
        )
    for experiment in experiments:
        missing = [c for c in channels if c not in experiment.channels]
        if missing:
            raise DataError(
                f"channel(s) {missing} not measured; this experiment has "
                f"{list(experiment.channels)}: choose among them with channels (--channels)",
                source=experiment.source,
                field="channels",
            )
    return channels


@dataclass(frozen=True)
class LikelihoodOptions:
    """How the residuals are modelled, besides the noise family: one object for every layer.

    The options of :func:`bayes_jackal.sample` and :func:`bayes_jackal.compare`
    and of the flags ``--channels``, ``--noise``, ``--sensor-noise`` and
    ``--engine``; the comparison, the state estimation on runs left out and
    the whole analysis take them as they are.

    Parameters
    ----------
    channels : sequence of str, optional
        Channels among ``yaw``, ``vx``, ``vy``; None: every channel measured
        in all experiments (:func:`resolve_channels`).
    noise : {"shared", "per-experiment", "one-width"}
        One noise setting per channel for all experiments, one per
        experiment and channel, or shared with one width for every channel.
    sensor : {"ma1", "diagonal"}
    engine : {"fast", "exact", "whittle"}
    steady : bool
        Each experiment's steady window only (its ``steady_window``: the
        thesis' crop of the ramps, ``--steady``), or every sample (the
        default: transients are data the model covers).
    damping : {"constant", "speed"}
        One damping, or one that depends on each segment's speed
        (``--damping speed``; :class:`ResidualLikelihood`).

    Raises
    ------
    InputError
        For a ``noise`` not in :data:`~bayes_jackal._runtime.defaults.NOISE_SHARING`
        (the likelihood checks the others).

    Examples
    --------
    >>> from bayes_jackal.likelihood import LikelihoodOptions
    >>> options = LikelihoodOptions(channels=["yaw"], noise="one-width")
    >>> options.keywords  # doctest: +NORMALIZE_WHITESPACE
    {'channels': ('yaw',), 'shared_noise': True, 'sensor': 'ma1', 'engine': 'fast',
     'steady': False, 'shared_width': True, 'damping': 'constant'}
    >>> try:
    ...     LikelihoodOptions(noise="per-run")
    ... except ValueError as error:
    ...     print(error)
    noise: unknown noise 'per-run'; use one of ('shared', 'per-experiment', 'one-width')
    """

    channels: tuple[str, ...] | None = None
    noise: str = NOISE
    sensor: str = SENSOR
    engine: str = ENGINE
    steady: bool = STEADY
    damping: str = DAMPING_MODEL

    def __post_init__(self) -> None:
        if self.damping not in DAMPING_MODELS:
            raise InputError(
                f"unknown damping {self.damping!r}; use one of {DAMPING_MODELS}", field="damping"
            )
        if self.noise not in NOISE_SHARING:
            raise InputError(
                f"unknown noise {self.noise!r}; use one of {NOISE_SHARING}", field="noise"
            )
        if self.channels is not None:
            object.__setattr__(self, "channels", tuple(self.channels))

    @classmethod
    def of(cls, options: LikelihoodOptions | None) -> LikelihoodOptions:
        """``options`` as given, or the defaults for None.

        Raises
        ------
        InputError
            For anything else, e.g. a dict of the keywords.
        """
        if options is None:
            return cls()
        if not isinstance(options, cls):
            raise InputError(
                f"give a LikelihoodOptions, not a {type(options).__name__}: e.g. "
                'LikelihoodOptions(channels=["yaw"])',
                field="likelihood_options",
            )
        return options

    @property
    def keywords(self) -> dict:
        """The keywords of :class:`ResidualLikelihood` these options set."""
        return {
            "channels": self.channels,
            "shared_noise": self.noise != "per-experiment",
            "sensor": self.sensor,
            "engine": self.engine,
            "steady": self.steady,
            "shared_width": self.noise == "one-width",
            "damping": self.damping,
        }

    def likelihood(
        self, experiments: Sequence[Experiment], robot: RobotProfile, family: str
    ) -> ResidualLikelihood:
        """The likelihood of ``experiments`` under ``family`` with these options."""
        return ResidualLikelihood(list(experiments), robot, family=family, **self.keywords)


@dataclass
class ResidualLikelihood:
    """Log-likelihood of the one-step residuals of experiments and channels.

    The damping (d_lat, d_long) is shared; each channel has its own noise
    parameters, shared across experiments (``shared_noise=True``) or
    separate per experiment, and a width of its own or one width for all
    (``shared_width``): :attr:`layout` (a
    :class:`~bayes_jackal.model.ParameterLayout`) names them, their
    groups and columns. Log-likelihoods of experiments add: series are never
    concatenated. Each channel enters as it was recorded
    (:mod:`bayes_jackal.likelihood.measurements`): vx, vy of experiments with poses
    through the poses (their sensor parameter ``sigma_p``), the rest as
    measured states; ``pose_samples`` holds, per experiment with poses, the
    recorded poses each sample of its window averages.

    Parameters
    ----------
    experiments : list of Experiment
    robot : RobotProfile
    family : str
        Process-noise family name.
    channels : tuple of str, optional
        Channels among ``yaw``, ``vx``, ``vy``; None (default): every channel
        measured in all experiments (:func:`resolve_channels`). Resolved to
        a tuple on construction.
    shared_noise : bool
        One noise setting per channel for all experiments, or one per
        experiment and channel.
    sensor : {"ma1", "diagonal"}
    engine : {"fast", "exact", "whittle"}
    steady : bool
        Use the steady-state window of each experiment (default: every sample).
    fallback : bool
        With the ``fast`` engine, evaluate parameter sets the spectral
        method cannot certify (long memory, spectral nulls) in the time
        domain (True: :func:`~bayes_jackal.likelihood.fallback_loglike`), or
        only those whose banded factor is cheap and -inf for the rest
        (False: the fallback's ``recursion=False``, the MAP search's quick,
        exact-where-defined scan of the prior).
    shared_width : bool
        One width for every channel and experiment (True), or the family's
        width in every noise group (False; ``--noise one-width`` is True
        with ``shared_noise``). No effect for white noise, which has none.
    damping : {"constant", "speed"}
        One damping (d_lat, d_long), or, with ``speed``, a damping that
        depends on each segment's speed v (its command steps,
        :attr:`bayes_jackal.io.Experiment.segments`; v the mean of
        r_w (omega_r + omega_l) / 2 over the segment, in absolute value):
        log d = log d_ref + log(r) (v - v_ref) / (v_max - v_min), with the
        parameters ``speed_ratio_lat``, ``speed_ratio_long`` = r after the
        damping and d_lat, d_long at v_ref = (v_min + v_max) / 2, the middle of
        the segments' speeds (:attr:`speed_range`). The process noise is a
        held force of one sd, so each segment's is scaled by g(d) / g(d_ref)
        (:mod:`bayes_jackal.likelihood.irregular`), and every channel takes
        the irregular engine, exact at a cost that grows with the run.

    Examples
    --------
    The yaw channel of a simulated run under the thesis' Gaussian filter; its
    value is the residuals' Gaussian density under their Toeplitz covariance,
    written out densely:

    >>> import numpy as np
    >>> import scipy.linalg
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.likelihood import ResidualLikelihood, residual_autocovariance
    >>> from bayes_jackal.model import channel_coefficients
    >>> from bayes_jackal.likelihood import channel_residuals
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="gaussian", channels=("yaw",))
    >>> likelihood.parameter_names
    ['d_lat', 'd_long', 'sigma_h', 'sigma_c', 'sigma_n']
    >>> theta = np.array([[110.0, 30.0, 0.047, 0.01, 0.005]])
    >>> value = likelihood(theta)
    >>> round(float(value[0]), 2)
    9416.67
    >>> residuals = channel_residuals(run, robot, 110.0, 30.0, "yaw")
    >>> alpha, _ = channel_coefficients(robot, 110.0, 30.0, "yaw", run.dt)
    >>> acov = residual_autocovariance(
    ...     get_family("gaussian"), *theta[:, 2:].T, alpha[None], run.dt, len(residuals)
    ... )
    >>> L = np.linalg.cholesky(scipy.linalg.toeplitz(acov[0]))
    >>> y = scipy.linalg.solve_triangular(L, residuals, lower=True)
    >>> dense = -0.5 * (y @ y + 2 * np.log(np.diag(L)).sum() + len(y) * np.log(2 * np.pi))
    >>> bool(abs(value[0] - dense) < 1e-6)
    True
    """

    experiments: list[Experiment]
    robot: RobotProfile
    family: str = FAMILY
    channels: tuple[str, ...] | None = None
    shared_noise: bool = SHARED_NOISE
    sensor: str = SENSOR
    engine: str = ENGINE
    steady: bool = STEADY
    fallback: bool = True
    shared_width: bool = False
    damping: str = DAMPING_MODEL
    layout: ParameterLayout = field(init=False)
    speed_range: tuple[float, float, float] | None = field(init=False, default=None)
    blocks: list[ResidualBlock] = field(init=False, repr=False)
    irregular: list[IrregularSeries] = field(init=False, repr=False)
    pose_samples: dict[str, int] = field(init=False, repr=False)
    pose_clocks: dict[str, tuple[int, float] | None] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._family = get_family(self.family)
        for value, allowed, name in (
            (self.sensor, SENSOR_MODELS, "sensor"),
            (self.engine, ENGINES, "engine"),
        ):
            if value not in allowed:
                raise InputError(f"unknown {name} {value!r}; use one of {allowed}", field=name)
        if not self.experiments:
            raise InputError("no experiments given", field="experiments")
        self.channels = resolve_channels(self.experiments, self.channels)
        self.layout = ParameterLayout(
            self.family,
            self.sensor,
            self.channels,
            tuple(e.name for e in self.experiments),
            self.shared_noise,
            shared_width=self.shared_width,
            pose_channels=pose_channels(self.experiments, self.channels),
            damping=self.damping,
        )
        self._speeds = self._segment_speeds() if self.damping == "speed" else None
        self.blocks = self._build_blocks()

    def _build_blocks(self) -> list[ResidualBlock]:
        """The Toeplitz blocks of the regular channels; :attr:`irregular` the others'."""
        series: dict[tuple, list[np.ndarray]] = {}
        self.pose_samples, self.pose_clocks, self.irregular = {}, {}, []
        for experiment in self.experiments:
            window = experiment.steady() if self.steady else experiment
            for channel in self.channels:
                group = self.layout.group(channel, experiment.name)
                check_residual_window(experiment, channel, MIN_RESIDUALS, self.steady)
                measurement = measurement_of(window, channel)
                if measurement.name == "pose":  # the same for each pose channel
                    self.pose_samples[experiment.name] = measurement.samples(window)
                    regular = measurement.regular(window)
                    self.pose_clocks[experiment.name] = (
                        measurement.clock(window) if regular else None
                    )
                if self._speeds is not None or not measurement.regular(window):
                    self.irregular += self._irregular(window, channel, measurement, group)
                    continue
                channel_series = measurement.series(window, channel)
                clock = measurement.clock(window)
                for regressors in channel_series.segments():
                    key = (channel, group, round(experiment.dt, 12), measurement.name,
                           channel_series.samples, clock, len(regressors))  # fmt: skip
                    series.setdefault(key, []).append(regressors)
        return [
            ResidualBlock(channel, group, dt, np.stack(members), measurement, samples, clock)
            for (channel, group, dt, measurement, samples, clock, _), members in series.items()
        ]

    def _irregular(
        self, experiment: Experiment, channel: str, measurement: Measurement, group: int
    ) -> list[IrregularSeries]:
        """The channel's pieces at their own times (the irregular engine's)."""
        index = None if self._speeds is None else self._speeds[experiment.name][0]
        return [
            IrregularSeries(channel, measurement.name, group, experiment.dt, piece.ticks,
                            piece.phases, piece.values, piece.counts, experiment.inputs, index)
            for piece in measurement.observations(experiment, channel)
        ]  # fmt: skip

    def _segment_speeds(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per experiment: each sample's segment (over all experiments) and the segments' speeds.

        Sets :attr:`speed_range`. Raises an InputError where the segments
        share one speed: no speed dependence to identify.
        """
        out, first = {}, 0
        for experiment in self.experiments:
            window = experiment.steady() if self.steady else experiment
            starts = window.segment_starts
            labels = np.cumsum(np.isin(np.arange(len(window.t)), starts)) - 1
            speed = np.abs(self.robot.wheel_radius * window.inputs.sum(axis=1) / 2)
            means = np.bincount(labels, weights=speed) / np.bincount(labels)
            out[experiment.name] = (first + labels, means)
            first += len(starts)
        speeds = np.concatenate([means for _, means in out.values()])
        low, high = float(speeds.min()), float(speeds.max())
        if high - low < SPEED_SPAN:
            raise InputError(
                f"the runs' segments all move at {low:.3g} m/s (within {SPEED_SPAN} m/s): "
                "a damping that depends on the speed needs segments at different speeds "
                "(command steps, or runs at several speeds: --damping constant)",
                field="damping",
            )
        self.speed_range = (low, (low + high) / 2, high)
        return out

    def segment_dampings(self, theta: np.ndarray) -> np.ndarray:
        """(d_lat, d_long) of every segment of every experiment [N s/m], shape (B, S, 2).

        One segment, the damping itself, with ``damping="constant"``.
        """
        damping = theta[:, None, :2]
        if self._speeds is None:
            return damping
        low, reference, high = self.speed_range
        speeds = np.concatenate([means for _, means in self._speeds.values()])
        exponent = (speeds - reference) / (high - low)  # (S,)
        ratios = theta[:, None, 2:4]
        return damping * ratios ** exponent[None, :, None]

    @property
    def noise_groups(self) -> list[tuple[str, str]]:
        """Noise groups as (channel, experiment or "all"): :attr:`ParameterLayout.groups`."""
        return list(self.layout.groups)

    @property
    def noise_parameter_names(self) -> list[str]:
        """Base names of the groups' noise parameters (:attr:`ParameterLayout.noise_bases`)."""
        return list(self.layout.noise_bases)

    @property
    def parameter_names(self) -> list[str]:
        """Names in parameter-vector order (:attr:`ParameterLayout.names`)."""
        return list(self.layout.names)

    @property
    def n_residuals(self) -> int:
        """Total number of residuals entering the likelihood."""
        return sum(block.regressors.shape[0] * block.regressors.shape[1] for block in self.blocks)

    def noise_parameters(self, theta: np.ndarray, group: int) -> tuple[np.ndarray, ...]:
        """(width, sigma_c, sensor sd) of one group: :meth:`ParameterLayout.noise_parameters`."""
        return self.layout.noise_parameters(theta, group)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Log-likelihood of each parameter vector.

        Parameters
        ----------
        theta : ndarray, shape (B, P)
            Parameter vectors in natural units, ordered as
            :attr:`parameter_names`.

        Returns
        -------
        ndarray, shape (B,)
        """
        with one_blas_thread():  # many small factorisations (bayes_jackal._runtime.threads)
            return self._loglike(np.atleast_2d(np.asarray(theta, float)))

    def group_loglike(self, theta: np.ndarray, group: int) -> np.ndarray:
        """The log-likelihood of one noise group's series alone, shape (B,).

        The likelihood is the sum of its noise groups' (each depends on the
        damping and its own noise parameters only); the MAP search profiles
        them one at a time.
        """
        with one_blas_thread():
            return self._loglike(np.atleast_2d(np.asarray(theta, float)), group)

    def _loglike(self, theta: np.ndarray, group: int | None = None) -> np.ndarray:
        """:meth:`__call__` on a 2-d ``theta``; with ``group``, that noise group's part only."""
        total = np.zeros(len(theta))
        coefficients: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        for block in self.blocks:
            if group is not None and block.noise_group != group:
                continue
            key = (block.channel, block.dt, block.measurement, block.clock)
            if key not in coefficients:
                coefficients[key] = MEASUREMENT_MODELS[block.measurement].coefficients(
                    self.robot, theta[:, 0], theta[:, 1], block.channel, block.dt,
                    clock=block.clock,
                )  # fmt: skip
            c, alpha = coefficients[key]
            noise = np.column_stack([*self.noise_parameters(theta, block.noise_group), alpha])
            engine = self._fast if self.engine == "fast" else self._reference
            total += engine(block, noise, c)
        dampings = self.segment_dampings(theta)  # (B, S, 2)
        for series in self.irregular:
            if group is not None and series.noise_group != group:
                continue
            alpha, beta = channel_coefficients(
                self.robot, dampings[..., 0], dampings[..., 1], series.channel, series.dt
            )
            scale = None
            if self._speeds is not None:  # the held force's scale g(d) / g(d_ref)
                reference, _ = channel_coefficients(
                    self.robot, theta[:, 0], theta[:, 1], series.channel, series.dt
                )
                scale = step_integrals(alpha, 1.0)[0] / step_integrals(reference, 1.0)[0][:, None]
            noise = self.noise_parameters(theta, series.noise_group)
            total += irregular_loglike(series, self._family, alpha, beta, noise, scale=scale,
                                       sensor=self.sensor,
                                       max_work=None if self.fallback else SCAN_WORK)  # fmt: skip
        return total

    def _autocovariance(self, block: ResidualBlock, noise: np.ndarray, lags: int) -> np.ndarray:
        """Residual autocovariance at lags 0..lags-1 of (width, sigma_c, sensor sd, alpha) rows."""
        return MEASUREMENT_MODELS[block.measurement].autocovariance(
            self._family, *noise.T, block.dt, lags, sensor=self.sensor, samples=block.samples,
            clock=block.clock,
        )  # fmt: skip

    def _reference(self, block: ResidualBlock, noise: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The ``exact`` or ``whittle`` engine, in chunks of parameter sets."""
        if self.engine == "exact":
            return self._recursion(block, noise, c)
        loglike = np.empty(len(c))
        for rows in chunks(len(c), block.count * block.n, budget=spectral.CHUNK_ELEMENTS):
            acov = self._autocovariance(block, noise[rows], block.n)
            cc = c[rows, :, None] * c[rows, None, :]
            periodogram = cc.reshape(len(cc), -1) @ block.periodogram.T
            loglike[rows] = debiased_whittle_loglike(acov, periodogram, block.count)
        return loglike

    def _recursion(
        self,
        block: ResidualBlock,
        noise: np.ndarray,
        c: np.ndarray,
        density: Callable[[np.ndarray, np.ndarray], np.ndarray] = toeplitz_loglike,
    ) -> np.ndarray:
        """A time-domain density (default: :func:`toeplitz_loglike`) in chunks of sets."""
        loglike = np.empty(len(c))
        for rows in chunks(len(c), block.count * block.n, budget=spectral.CHUNK_ELEMENTS):
            acov = self._autocovariance(block, noise[rows], block.n)
            loglike[rows] = density(acov, block.residuals(c[rows])).sum(axis=-1)
        return loglike

    def _fast(self, block: ResidualBlock, noise: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The ``fast`` engine: each set on the first spectral grid that certifies it.

        Sets no grid certifies (long memory, or a moving-average kernel's
        spectral nulls) go to :func:`~bayes_jackal.likelihood.fallback_loglike`,
        without ``fallback`` to its scans' cheap bands only.
        """
        loglike = np.full(len(c), -np.inf)

        def autocovariance(rows: np.ndarray, lags: int) -> np.ndarray:
            return self._autocovariance(block, noise[rows], lags)

        pending = spectral.evaluate_on_grids(block, autocovariance, c, spectral_loglike, loglike)
        if len(pending):
            density = partial(fallback_loglike, recursion=self.fallback)
            loglike[pending] = self._recursion(block, noise[pending], c[pending], density)
        return loglike
