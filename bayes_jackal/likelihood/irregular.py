"""Channels observed at their own times: residuals that remove the state, and their exact density.

The one-step residuals of :mod:`bayes_jackal.likelihood.measurements` need a
measurement at every tick of the experiment's clock (a rate channel), or a
pose per tick (a pose channel). Labs record otherwise: lidar-ICP poses at
4-10 Hz beside a 20-200 Hz IMU, motion capture slower than the IMU, poses
held on a logger's clock, and a damping that changes from one command step
to the next (:class:`~bayes_jackal.likelihood.LikelihoodOptions`' ``damping``
``"speed"``). This module gives such a channel its exact likelihood.

The model is the thesis' (eq. 4-32, 6-6), one scalar channel at a time (A
is diagonal): on the clock t_i = t_0 + i dt, with the input and the noise
held over each step (zero-order hold),

    v_{i+1} = alpha_i v_i + xi_i,   xi_i = beta_i . u_i + s_i w_i,

alpha_i, beta_i the channel's pole and input row at tick i (from that
tick's damping), w the coloured process noise (autocovariance sigma_c^2
R(l dt), the family's), and s_i = g_i / g_ref its scale: the noise is a
held force eta, w_i = g_i eta_i with g_i = (alpha_i - 1) / a_i, so a tick
whose damping differs from the reference one's (``damping="speed"``) has
its noise scaled by g_i / g_ref (1 for a constant damping). Within step i,
at t_i + tau (0 <= tau < dt), with g(tau) = (e^{a tau} - 1) / a and h(tau)
= (g(tau) - tau) / a (:func:`bayes_jackal.model.step_integrals`):

    v(t_i + tau)        = e^{a tau} v_i + (g(tau) / g) xi_i,
    Q(t_i + tau) - Q(t_i) = g(tau) v_i + (h(tau) / g) xi_i          (the travel).

A channel is observed at times s_j = t_{k_j} + tau_j:

- ``rate``: y_j = v(s_j) + n_j, sensor noise n of sd sigma_n;
- ``pose``: the travel between two poses, D_j = Q(s_{j+1}) - Q(s_j) + e_{j+1}
  - e_j (the body-frame increment of :func:`bayes_jackal.io.body_increments`),
  pose noise e of sd sigma_p / sqrt(n_j) for a pose that averages n_j
  recorded ones.

Each observation is a linear form in the state v_b at a base tick b and the
drives xi_b, xi_{b+1}, ...: O = c_v v_b + sum_q c_q xi_{b+q}. Two (rate) or
three (pose) consecutive observations give one residual free of the state:

    rate:  r_j = y_{j+1} - gamma_j y_j - sum_q mu_jq beta_q . u_q,
           gamma_j = c_v(y_{j+1}) / c_v(y_j),
    pose:  r_j = (D_{j+1} - gamma_j D_j) / dt - sum_q mu_jq beta_q . u_q,
           gamma_j = c_v(D_{j+1}) / c_v(D_j),

with mu_j the coefficients of the drives that remain (over dt for a pose).
The map from the observations to (the first one or two, r) is triangular
with a unit diagonal, so r has the density the engines of
:mod:`bayes_jackal.likelihood.residual_likelihood` give the one-step
residuals: where the observations are every tick (rate) or a pose per tick
(pose) and the damping constant, r is exactly their residual series (the
tests check the two against each other). Its noise,

    r_j = sum_q mu_jq s_q w_{b_j + q} + (sensor terms),

is Gaussian with a banded covariance: sigma_c^2 mu_j R mu_j' over the ticks
the residuals share (R reaches as far as the family's autocorrelation:
every family but the exponential ends; the exponential's is cut below
:data:`REACH_TOLERANCE` of its variance), plus the sensor noise's, which
couples a residual with its neighbours (rate: sigma_n^2 (1 + gamma_j^2)
on the diagonal, -gamma_{j+1} sigma_n^2 next to it; pose: the MA(2) of
(e_{j+2} - (1 + gamma_j) e_{j+1} + gamma_j e_j) / dt, each e of its own
variance). The ``diagonal`` sensor term is white noise of sd sigma_n added
to each step's drive. LAPACK's banded Cholesky factor (dpbtrf) gives the
density exactly, O(J p^2) for J residuals and a band of p.

The coefficients come from two short recursions over each residual's span
(:func:`_observation_forms`), vectorised over the residuals and the
parameter sets. The cost per evaluation grows with the number of
observations, unlike the flat cost of the Toeplitz engines: this engine
serves the channels those cannot (:class:`IrregularSeries`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .._runtime import InputError, chunks
from ..model import Family, step_integrals
from .toeplitz import banded_loglike

__all__ = ["IrregularSeries", "irregular_loglike", "irregular_residuals", "pattern_coefficients"]

#: Autocorrelations below this fraction of the variance are taken as zero: the
#: exponential family's tail (phi^l), which never ends. The density moves by
#: about this fraction times the number of residuals the tail would couple.
REACH_TOLERANCE = 1e-13
#: Elements of the largest work array of one chunk of parameter sets (32 MiB).
_CHUNK_ELEMENTS = 2**22
#: Observations each residual combines, by measurement.
_ORDER = {"rate": 2, "pose": 3}


@dataclass(frozen=True, eq=False)
class IrregularSeries:
    """One channel of one experiment, observed at its own times on the experiment's clock.

    Attributes
    ----------
    channel : str
        ``yaw``, ``vx`` or ``vy``.
    measurement : {"rate", "pose"}
        A sensor measures the state, or poses its travel (module docstring).
    noise_group : int
        The channel's noise group in the likelihood's layout.
    dt : float
        The clock's step [s].
    ticks : ndarray of int, shape (M,)
        k_j, the tick before each observation (non-decreasing; increasing
        for a rate channel).
    phases : ndarray, shape (M,)
        tau_j = s_j - t_{k_j} [s], in [0, dt).
    values : ndarray
        ``rate``: the observations y_j, shape (M,) [channel unit]; ``pose``:
        the body-frame increments D_j between consecutive poses, shape
        (M - 1,) [m].
    counts : ndarray of int, shape (M,)
        Recorded poses averaged into each observation (ones for a rate channel).
    inputs : ndarray, shape (N, 2)
        The wheel speeds (omega_r, omega_l) at every tick of the clock [rad/s].
    damping_index : ndarray of int, shape (N,), optional
        Which damping each tick takes (its segment's, for ``damping="speed"``);
        None: one damping.

    Examples
    --------
    A rate channel observed at every other tick of a 10 Hz clock:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import IrregularSeries
    >>> series = IrregularSeries("yaw", "rate", 0, 0.1, np.arange(0, 20, 2), np.zeros(10),
    ...                          np.linspace(0, 1, 10), np.ones(10, int), np.ones((20, 2)))
    >>> series.residual_count, series.span
    (9, 3)
    """

    channel: str
    measurement: str
    noise_group: int
    dt: float
    ticks: np.ndarray
    phases: np.ndarray
    values: np.ndarray
    counts: np.ndarray
    inputs: np.ndarray
    damping_index: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.measurement not in _ORDER:
            raise InputError(
                f"unknown measurement {self.measurement!r}; use one of {tuple(_ORDER)}",
                field="measurement",
            )
        ticks = np.asarray(self.ticks, int)
        expected = len(ticks) - (1 if self.measurement == "pose" else 0)
        if (
            len(ticks) < _ORDER[self.measurement] + 1
            or np.shape(self.values) != (expected,)
            or np.shape(self.phases) != ticks.shape
            or np.shape(self.counts) != ticks.shape
            or (np.diff(ticks) < 0).any()
            or ticks[0] < 0
            or ticks[-1] >= len(self.inputs)
        ):
            raise InputError(
                f"{self.channel}: observations must be at least {_ORDER[self.measurement] + 1}, "
                "at non-decreasing ticks of the clock, with one phase and count each and "
                f"{expected} values",
                field=self.channel,
            )

    @property
    def residual_count(self) -> int:
        """J, the residuals: M - 1 (rate) or M - 2 (pose)."""
        return len(self.ticks) - _ORDER[self.measurement] + 1

    @property
    def order(self) -> int:
        """The observations one residual combines: 2 (rate) or 3 (pose)."""
        return _ORDER[self.measurement]

    def _window(self, values: np.ndarray) -> np.ndarray:
        """Each residual's observations' ``values`` (per observation), shape (order, J)."""
        return values[np.arange(self.order)[:, None] + np.arange(self.residual_count)]

    @cached_property
    def _positions(self) -> np.ndarray:
        """Each residual's observations' ticks from its base tick, shape (order, J)."""
        window = self._window(np.asarray(self.ticks, int))
        return window - window[:1]

    @cached_property
    def _phases(self) -> np.ndarray:
        """Each residual's observations' phases [s], shape (order, J)."""
        return self._window(np.asarray(self.phases, float))

    @property
    def span(self) -> int:
        """L, the most ticks one residual's drives cover."""
        return int(self._positions[-1].max()) + 1

    @cached_property
    def _span_ticks(self) -> np.ndarray:
        """The tick of each position of each residual's span, clipped to the clock, (L, J)."""
        ticks = np.asarray(self.ticks, int)[: self.residual_count]
        return np.minimum(np.arange(self.span)[:, None] + ticks, len(self.inputs) - 1)

    @cached_property
    def _data(self) -> tuple[np.ndarray, np.ndarray]:
        """The two observations (or increments) each residual combines: (later, earlier)."""
        count = self.residual_count
        values = np.asarray(self.values, float)
        return values[1 : count + 1], values[:count]

    @cached_property
    def _noise_variances(self) -> np.ndarray:
        """The relative sensor-noise variance of each observation: 1 / n_j."""
        return 1.0 / np.asarray(self.counts, float)

    def reach(self, lags: int) -> np.ndarray:
        """For each residual, the residuals after it whose drives lie within ``lags`` ticks."""
        base = np.asarray(self.ticks, int)[: self.residual_count]
        last = base + self._positions[-1]
        return np.searchsorted(base, last + lags, side="right") - 1 - np.arange(len(base))

    def band_pairs(self, band: int) -> list[list[tuple[int, np.ndarray | slice]]]:
        """For each offset o < ``band``, the residuals j by the shift b_{j+o} - b_j of their bases.

        A list per offset of (shift [ticks], the residuals j): a slice where
        every j shares one shift (observations evenly spaced), else the
        indices of each shift's residuals.
        """
        if band not in self._pairs:
            base, count = np.asarray(self.ticks, int)[: self.residual_count], self.residual_count
            pairs = []
            for offset in range(band):
                shifts = base[offset:] - base[: count - offset]
                values = np.unique(shifts)
                if len(values) == 1:
                    pairs.append([(int(values[0]), slice(0, count - offset))])
                else:
                    pairs.append([(int(v), np.flatnonzero(shifts == v)) for v in values])
            self._pairs[band] = pairs
        return self._pairs[band]

    @cached_property
    def _pairs(self) -> dict:
        return {}


def irregular_loglike(
    series: IrregularSeries,
    family: Family,
    alpha: np.ndarray,
    beta: np.ndarray,
    noise: tuple[np.ndarray, np.ndarray, np.ndarray],
    *,
    scale: np.ndarray | None = None,
    sensor: str = "ma1",
    max_work: float | None = None,
) -> np.ndarray:
    """Exact log-density of an irregularly observed channel's residuals (module docstring).

    Parameters
    ----------
    series : IrregularSeries
    family : Family
        The process noise's.
    alpha : ndarray, shape (B, D)
        The channel's discrete pole at each of the D dampings
        (:attr:`IrregularSeries.damping_index`; D = 1 for one damping).
    beta : ndarray, shape (B, D, 2)
        Its input row at each damping.
    noise : (width, sigma_c, sigma_sensor), each ndarray of shape (B,)
        The noise group's width [s], process-noise sd per step and sensor
        sd (sigma_n [channel unit] or sigma_p [m]).
    scale : ndarray, shape (B, D), optional
        s, the process noise's scale at each damping (ones by default).
    sensor : {"ma1", "diagonal"}
        A rate channel's sensor term.
    max_work : float, optional
        Sets whose banded factor would cost more than J p^2 > ``max_work``
        are -inf (a scan's quick look); None evaluates every set.

    Returns
    -------
    ndarray, shape (B,)
        [nats]; -inf where the covariance is not positive definite.

    Examples
    --------
    A yaw rate measured at every other tick of a 20 Hz clock: the density of
    its residuals under the true damping and under a stiffer one:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import IrregularSeries, irregular_loglike
    >>> from bayes_jackal.model import channel_coefficients, get_family
    >>> robot = bj.load_profile()
    >>> rng = np.random.default_rng(1)
    >>> alpha, beta = channel_coefficients(robot, np.array([110.0, 300.0]), 30.0, "yaw", 0.05)
    >>> u = np.column_stack([np.full(200, 6.0), np.full(200, 4.0)])
    >>> yaw = np.zeros(200)
    >>> for k in range(199):
    ...     yaw[k + 1] = alpha[0] * yaw[k] + beta[0] @ u[k] + 0.01 * rng.standard_normal()
    >>> ticks = np.arange(0, 200, 2)
    >>> series = IrregularSeries("yaw", "rate", 0, 0.05, ticks, 0.0 * ticks, yaw[ticks],
    ...                          np.ones(100, int), u)
    >>> noise = (np.ones(2), np.full(2, 0.01), np.full(2, 1e-4))
    >>> family = get_family("white")
    >>> value = irregular_loglike(series, family, alpha[:, None], beta[:, None], noise)
    >>> bool(value[0] > value[1])
    True
    """
    batch = len(alpha)
    scale = np.ones_like(alpha) if scale is None else scale
    width, sigma_c, sigma_sensor = noise
    lags = _reach(family, width, series.dt, series.span)
    loglike = np.full(batch, -np.inf)
    count, span = series.residual_count, series.span
    per_set = count * (span * (_ORDER[series.measurement] + 4) + 2 * int(lags.max()) + 16)
    white_drive = series.measurement == "rate" and sensor == "diagonal"
    for rows in chunks(batch, per_set, budget=_CHUNK_ELEMENTS):
        reach = int(lags[rows].max())
        band = int(max(series.reach(reach).max(), _ORDER[series.measurement] - 1)) + 1
        if max_work is not None and count * band**2 > max_work:
            continue
        mu, gamma = _coefficients(series, alpha[rows])
        residuals = _residuals(series, mu, gamma, beta[rows])
        acov = sigma_c[rows, None] ** 2 * family.autocorrelation(width[rows], series.dt, reach + 1)
        acov = np.where(np.abs(acov) > REACH_TOLERANCE * acov[:, :1], acov, 0.0)
        if white_drive:
            acov[:, 0] += sigma_sensor[rows] ** 2
        covariance = _process_band(series, mu * _span(series, scale[rows]), acov, band)
        if not white_drive:
            covariance[:, :3] += _sensor_band(series, gamma, sigma_sensor[rows], band)
        loglike[rows] = banded_loglike(covariance, residuals)
    return loglike


def irregular_residuals(
    series: IrregularSeries, alpha: np.ndarray, beta: np.ndarray
) -> np.ndarray:
    """The residuals r_j of the module docstring, shape (B, J) [channel unit].

    ``alpha`` (B, D) and ``beta`` (B, D, 2) as in :func:`irregular_loglike`.

    Examples
    --------
    Observed at every tick, a rate channel's residuals are eq. 7-3's:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import IrregularSeries, irregular_residuals
    >>> y, u = np.array([0.0, 0.5, 0.8, 0.9]), np.ones((4, 2))
    >>> series = IrregularSeries("yaw", "rate", 0, 0.1, np.arange(4), np.zeros(4), y,
    ...                          np.ones(4, int), u)
    >>> alpha, beta = np.array([[0.6]]), np.array([[[0.3, 0.2]]])
    >>> irregular_residuals(series, alpha, beta).round(6).tolist()
    [[0.0, 0.0, -0.08]]
    """
    mu, gamma = _coefficients(series, alpha)
    return _residuals(series, mu, gamma, beta)


def pattern_coefficients(
    measurement: str, dt: float, stride: int, phase: float, alpha: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """mu and gamma of evenly spaced observations: every ``stride`` ticks, ``phase`` after one.

    The residual of such a channel is the same function of its span for
    every j, so its series is stationary: the Toeplitz engines evaluate it
    (:class:`bayes_jackal.likelihood.PoseMeasurement`'s stride).

    Parameters
    ----------
    measurement : {"rate", "pose"}
    dt : float
        The clock's step [s].
    stride : int
        Ticks between observations, m >= 1.
    phase : float
        Their time after their tick [s], in [0, dt).
    alpha : ndarray, shape (B,)
        The channel's pole.

    Returns
    -------
    mu : ndarray, shape (B, L)
        The drives' coefficients over the residual's span, L = (order - 1) m + 1.
    gamma : ndarray, shape (B,)

    Examples
    --------
    A pose per tick: mu is (kappa_1, kappa_0, 0) of the one-step pose model:

    >>> import numpy as np
    >>> from bayes_jackal.likelihood import pattern_coefficients, pose_weights
    >>> mu, gamma = pattern_coefficients("pose", 0.01, 1, 0.0, np.array([0.9]))
    >>> kappa_0, kappa_1 = pose_weights(np.array([0.9]))
    >>> bool(np.allclose(mu[0, :2], [kappa_1[0], kappa_0[0]])), round(float(gamma[0]), 12)
    (True, 0.9)
    """
    order = _ORDER[measurement]
    series = _pattern_series(measurement, dt, stride, phase)
    mu, gamma = _coefficients(series, np.asarray(alpha, float)[:, None])
    return mu[:, : (order - 1) * stride + 1, 0], gamma[:, 0]


@functools.lru_cache(maxsize=32)
def _pattern_series(measurement: str, dt: float, stride: int, phase: float) -> IrregularSeries:
    """One residual's observations every ``stride`` ticks at ``phase`` (kept: cheap to reuse)."""
    order = _ORDER[measurement]
    ticks = np.arange(order + 1) * stride
    return IrregularSeries(
        "pattern", measurement, 0, dt, ticks, np.full(order + 1, phase),
        np.zeros(order + 1 - (measurement == "pose")), np.ones(order + 1, int),
        np.zeros((ticks[-1] + 1, 2)),
    )  # fmt: skip


def _reach(family: Family, width: np.ndarray, dt: float, span: int) -> np.ndarray:
    """The last lag of each set's autocorrelation above :data:`REACH_TOLERANCE` [ticks]."""
    lags = max(8, 2 * span)
    while True:
        rho = np.abs(family.autocorrelation(width, dt, lags))
        significant = rho > REACH_TOLERANCE * rho[:, :1]
        last = lags - 1 - np.argmax(significant[:, ::-1], axis=1)
        if (last < lags - 1).all():
            return last
        lags *= 2


def _span(series: IrregularSeries, per_damping: np.ndarray) -> np.ndarray:
    """A value at each damping, (B, D[, 2]), over each residual's span: (B, L, J[, 2]).

    With one damping it is the same at every tick: (B, 1, 1[, 2]), to broadcast.
    """
    if series.damping_index is None:
        return per_damping[:, :1, None]
    return per_damping[:, series.damping_index[series._span_ticks]]


def _column(values: np.ndarray, q: int) -> np.ndarray:
    """Position q of a span array (B, L or 1, J or 1): (B, 1, J or 1)."""
    index = min(q, values.shape[1] - 1)
    return values[:, index : index + 1]


@dataclass(frozen=True)
class _Patterns:
    """The distinct residuals of a series: their observations' positions and phases, and dampings.

    Residuals of one pattern have one set of coefficients: a pose every m
    samples at one phase under one damping gives a handful, whatever the
    run's length, and :func:`_coefficients` computes each once.
    """

    positions: np.ndarray  # (order, U)
    phases: np.ndarray  # (order, U) [s]
    span_damping: np.ndarray | None  # (L, U): each position's damping
    at_damping: np.ndarray | None  # (order, U): the damping of each observation's step
    inverse: np.ndarray  # (J,): each residual's pattern


def _patterns(series: IrregularSeries) -> _Patterns:
    """The series' :class:`_Patterns` (computed once per series)."""
    if "_patterns" in series.__dict__:
        return series.__dict__["_patterns"]
    keys = [series._positions, series._phases]
    span_damping = at_damping = None
    if series.damping_index is not None:
        span_damping = series.damping_index[series._span_ticks]
        at_damping = series.damping_index[series._window(np.asarray(series.ticks, int))]
        keys += [span_damping, at_damping]
    rows = np.concatenate([np.asarray(k, float) for k in keys], axis=0).T  # (J, keys)
    _, first, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    pick = (slice(None), first)
    patterns = _Patterns(
        series._positions[pick],
        series._phases[pick],
        None if span_damping is None else span_damping[pick],
        None if at_damping is None else at_damping[pick],
        inverse.ravel(),
    )
    series.__dict__["_patterns"] = patterns
    return patterns


def _observation_forms(
    patterns: _Patterns, measurement: str, dt: float, alpha: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The linear form of each pattern's observations in v_b and the span's drives.

    Returns ``(coefficient of v_b, shape (B, order, U); coefficients of the
    drives xi_{b+q}, shape (B, L, order, U))``. With P_q = prod_{q<r<p}
    alpha_r and S_q = sum_{q<r<p} g_r prod_{q<r'<r} alpha_{r'} for an
    observation at position p (both by the recursion q -> q - 1 from
    P_{p-1} = 1, S_{p-1} = 0), the drive xi_q (q < p) enters a rate
    observation with e^{a tau} P_q and a pose's travel with h_q / g_q + S_q
    + g(tau) P_q; xi_p enters with g(tau) / g_p (rate) or h(tau) / g_p
    (pose); and v_b with e^{a tau} alpha_0 P_0 (rate) or g_0 + alpha_0 S_0
    + g(tau) alpha_0 P_0 (pose), e^{a tau} and g(tau) alone where p = 0.
    """
    g_damping, h_damping = step_integrals(alpha, dt)
    positions, phases = patterns.positions, patterns.phases  # (order, U)
    order, count = positions.shape
    span = int(positions[-1].max()) + 1

    def over(values: np.ndarray, index: np.ndarray | None) -> np.ndarray:
        return values[:, :1, None] if index is None else values[:, index]

    alphas, g = over(alpha, patterns.span_damping), over(g_damping, patterns.span_damping)
    ratio = over(h_damping / g_damping, patterns.span_damping)
    at_alpha, at_g = over(alpha, patterns.at_damping), over(g_damping, patterns.at_damping)
    if phases.any():
        partial = at_alpha ** (phases / dt)  # e^{a tau}, (B, order, U)
        g_unit, h_unit = step_integrals(partial, 1.0)  # of a tau: g(tau) / tau, h(tau) / tau^2
        g_tau, h_tau = g_unit * phases, h_unit * phases**2
    else:  # every observation on a tick
        partial, g_tau, h_tau = np.ones(1), np.zeros(1), np.zeros(1)
    pose = measurement == "pose"
    at_end = (h_tau if pose else g_tau) / at_g
    drives = np.zeros((len(alpha), span, order, count))
    product = np.ones((len(alpha), order, count))
    suffix = np.zeros((len(alpha), order, count))
    for q in range(span - 1, -1, -1):
        started = q == positions - 1
        if q + 1 < span:  # from P_{q+1}, S_{q+1} to P_q, S_q
            step_alpha = _column(alphas, q + 1)
            product = np.where(started, 1.0, step_alpha * product)
            suffix = np.where(started, 0.0, _column(g, q + 1) + step_alpha * suffix)
        value = (_column(ratio, q) + suffix + g_tau * product) if pose else partial * product
        drives[:, q] = np.where(q < positions, value, np.where(q == positions, at_end, 0.0))
    first = positions > 0
    alpha_0, g_0 = _column(alphas, 0), _column(g, 0)
    if pose:
        state = np.where(first, g_0 + alpha_0 * suffix + g_tau * alpha_0 * product, g_tau)
    else:
        state = partial * np.where(first, alpha_0 * product, 1.0)
    return state, drives


def _coefficients(series: IrregularSeries, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """mu (B, L, J), the drives' coefficients in each residual, and gamma (B, J).

    Computed for each distinct pattern (:func:`_patterns`) and spread to its residuals.
    """
    patterns = _patterns(series)
    state, drives = _observation_forms(patterns, series.measurement, series.dt, alpha)
    if series.measurement == "rate":
        gamma = state[:, 1] / state[:, 0]
        mu = drives[:, :, 1] - gamma[:, None] * drives[:, :, 0]
    else:
        later_state, earlier_state = state[:, 2] - state[:, 1], state[:, 1] - state[:, 0]
        later = drives[:, :, 2] - drives[:, :, 1]
        earlier = drives[:, :, 1] - drives[:, :, 0]
        gamma = later_state / earlier_state
        mu = (later - gamma[:, None] * earlier) / series.dt
    width = series.span
    mu = np.pad(mu, ((0, 0), (0, width - mu.shape[1]), (0, 0)))
    return mu[:, :, patterns.inverse], gamma[:, patterns.inverse]


def _residuals(
    series: IrregularSeries, mu: np.ndarray, gamma: np.ndarray, beta: np.ndarray
) -> np.ndarray:
    """r_j: the observations' combination less the inputs' part, shape (B, J)."""
    later, earlier = series._data
    combined = later[None] - gamma * earlier[None]
    if series.measurement == "pose":
        combined = combined / series.dt
    index = slice(None) if series.damping_index is None else series.damping_index
    drive = np.einsum("bnw,nw->bn", beta[:, index], series.inputs)  # beta_i . u_i, (B, N)
    return combined - np.einsum("blj,blj->bj", mu, drive[:, series._span_ticks])


def _process_band(
    series: IrregularSeries, scaled: np.ndarray, acov: np.ndarray, band: int
) -> np.ndarray:
    """sigma_c^2 mu_j R mu_{j+o}' for o < ``band``, shape (B, band, J) (zero past the end).

    Y_j[t] = sum_q mu_jq R(t - reach - q), each residual's coefficients
    through R on the ticks around its span (one batched product); then the
    covariance with the residual o later, whose span starts shift ticks on,
    is sum_q Y_j[shift + reach + q] mu_{j+o, q}
    (:meth:`IrregularSeries.band_pairs`).
    """
    batch, span, count = scaled.shape
    reach = acov.shape[1] - 1
    width = span + 2 * reach
    kernel = np.concatenate([acov[:, :0:-1], acov], axis=1)  # R(-reach..reach)
    spread = np.zeros((batch, width, span))
    for q in range(span):
        spread[:, q : q + 2 * reach + 1, q] = kernel
    filtered = np.matmul(spread, scaled)  # (B, width, J)
    out = np.zeros((batch, band, count))
    for offset, groups in enumerate(series.band_pairs(band)):
        for shift, earlier in groups:
            start = shift + reach
            if start >= width:
                continue  # that far on, the residuals share no noise
            stop = min(start + span, width)
            if isinstance(earlier, slice):
                later = slice(earlier.start + offset, earlier.stop + offset)
                pieces = filtered[:, start:stop, earlier]
            else:
                later = earlier + offset
                pieces = filtered[:, start:stop][:, :, earlier]
            out[:, offset, earlier] = np.einsum(
                "blj,blj->bj", pieces, scaled[:, : stop - start, later]
            )
    return out


def _sensor_band(
    series: IrregularSeries, gamma: np.ndarray, sigma: np.ndarray, band: int
) -> np.ndarray:
    """The sensor noise's covariance of residual j with j + o, o < 3, shape (B, 3, J)."""
    batch, count = gamma.shape
    variances = series._noise_variances  # (M,)
    out = np.zeros((batch, min(3, band), count))
    if series.measurement == "rate":
        # r_j = ... + n_{j+1} - gamma_j n_j
        out[:, 0] = variances[1 : count + 1] + gamma**2 * variances[:count]
        if band > 1:
            out[:, 1, :-1] = -gamma[:, 1:] * variances[1:count]
        return sigma[:, None, None] ** 2 * out
    # r_j = (e_{j+2} - (1 + gamma_j) e_{j+1} + gamma_j e_j) / dt
    v0, v1, v2 = variances[:count], variances[1 : count + 1], variances[2 : count + 2]
    out[:, 0] = v2 + (1 + gamma) ** 2 * v1 + gamma**2 * v0
    if band > 1:
        out[:, 1, :-1] = (
            -(1 + gamma[:, 1:]) * v2[:-1] - (1 + gamma[:, :-1]) * gamma[:, 1:] * v1[:-1]
        )
    if band > 2:
        out[:, 2, :-2] = gamma[:, 2:] * v2[:-2]
    return (sigma[:, None, None] / series.dt) ** 2 * out
