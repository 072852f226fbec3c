"""What DEM and Active Inference codes need beside the process precision (issue 14).

:func:`bayes_jackal.dem.export_prior` writes, besides the model and the
process-noise precision Pi in generalised coordinates:

- **time bins.** DEM codes (SPM's ``spm_DEM_R``, dempy) count time in
  samples, k = t / dt. Derivative i of a signal in bins is dt^i times the one
  in seconds, so a covariance in bins is ``V_bins[i, j] = dt^(i+j) V[i, j]``,
  which is V at the width ``width / dt``. The model written per bin is
  dx/dk = (A dt) x + (B dt) u + dt w: its noise is dt w, so its precision is
  ``Pi_bins[i, j] = Pi[i, j] / dt^(i+j+2)``. The sensor noise n of
  y = x + n is not a rate: only its derivatives are rescaled.
- **Pi_z, the sensor-noise precision.** White sensor noise of sd sigma_n has
  no derivatives; DEM codes give it a small Gaussian smoothness s_z. The
  default, :data:`SENSOR_SMOOTHNESS` = 0.5 bins, is SPM's default smoothness
  (``M(1).E.s = 1/2``) and the one whose derivative has the variance of white
  noise's one-step difference: rho''(0) = -1 / (2 s_z^2) = -2 per bin^2, and
  var(n[k+1] - n[k]) = 2 sigma_n^2. Pi_z = inv(V(s_z)) kron diag(E[1/sigma_n^2]).
- **smoothness** in seconds and bins: the Gaussian kernel sd s with the same
  rho''(0) as the family, s = (-2 rho''(0))^(-1/2) (:func:`gaussian_smoothness`:
  sigma_h itself for the Gaussian family), the ``s`` of ``spm_DEM_R`` and the
  ``s_w`` of a Jackal Active Inference filter.
- **log-precision hyperpriors**: the mean and (co)variance over draws of
  log(1 / sd^2) (:func:`log_precision_moments`; SPM's ``hE``/``hC``, ``gE``/``gC``).
- **the operating point**: mean inputs and outputs over the analysed windows
  (:func:`operating_point`).
- **the damping prior on the entries of A, B** (:func:`matrix_prior`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._runtime import CHANNELS, SENSOR_SMOOTHNESS, InputError
from ..io import Experiment
from ..model import RobotProfile, continuous_matrices, discrete_matrices, get_family

__all__ = [
    "channel_moments",
    "continuous_sd",
    "gaussian_smoothness",
    "generalised_precision",
    "log_precision_moments",
    "matrix_prior",
    "mean_covariance_precision",
    "operating_point",
]

#: Relative step of the damping for the Jacobian of A, B (exact: they are linear in it).
_STEP = 1e-3


def continuous_sd(
    robot: RobotProfile,
    damping: np.ndarray,
    dt: float,
    channels: Sequence[str],
    sigma_c: np.ndarray,
) -> np.ndarray:
    """s_c = sigma_c a / (alpha - 1): the continuous-time sd of the per-step process noise.

    The fitted sigma_c is the sd per step of x[k+1] = alpha x[k] + b u[k] + w[k];
    noise of sd s_c in dx/dt = a x + b u + w, held over a step, gives it.

    Parameters
    ----------
    robot : RobotProfile
    damping : ndarray, shape (draws, 2)
        (d_lat, d_long) per draw [N s/m].
    dt : float
        Sample time [s].
    channels : sequence of str
    sigma_c : ndarray, shape (draws, channels)
        The per-step sd per draw [channel units].

    Returns
    -------
    ndarray, shape (draws, channels)
        [channel units / s].

    Examples
    --------
    With alpha = exp(a dt), s_c dt / sigma_c = a dt / (exp(a dt) - 1), which
    is close to 1 for a slow pole (|a| dt << 1):

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.dem import continuous_sd
    >>> from bayes_jackal.model import continuous_matrices
    >>> robot = bj.load_profile()
    >>> s = continuous_sd(robot, np.array([[110.0, 30.0]]), robot.dt, ["vx"], np.array([[0.005]]))
    >>> a_dt = continuous_matrices(robot, 110.0, 30.0)[0][0, 0] * robot.dt
    >>> ratio = float(s[0, 0] * robot.dt / 0.005)
    >>> round(ratio, 3), bool(np.isclose(ratio, a_dt / np.expm1(a_dt)))
    (1.051, True)
    """
    A, _ = continuous_matrices(robot, damping[:, 0], damping[:, 1])
    Ad, _ = discrete_matrices(robot, damping[:, 0], damping[:, 1], dt)
    index = [CHANNELS.index(c) for c in channels]
    return sigma_c * A[:, index, index] / (Ad[:, index, index] - 1.0)


def generalised_precision(temporal_precision: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """Pi = mean over draws of sum_c inv(V_c) kron e_c e_c' / sd_c^2, derivative-major.

    Parameters
    ----------
    temporal_precision : ndarray, shape (draws, channels, P + 1, P + 1) or (P + 1, P + 1)
        inv(V) per draw and channel, or one for all.
    sd : ndarray, shape (draws, channels)
        The noise sd per draw and channel [channel units].

    Returns
    -------
    ndarray, shape ((P + 1) C, (P + 1) C)
        Row i * C + c is derivative i of channel c.

    Examples
    --------
    Two channels at order 1 with V = diag(1, 2): the blocks are
    diag(1, 1/2) / sd_c^2, averaged over the two draws:

    >>> import numpy as np
    >>> from bayes_jackal.dem import generalised_precision
    >>> sd = np.array([[1.0, 2.0], [1.0, 4.0]])  # (draws, channels)
    >>> Pi = generalised_precision(np.diag([1.0, 0.5]), sd)
    >>> np.diag(Pi).tolist()  # (w_0, w_1, w_0', w_1')
    [1.0, 0.15625, 0.5, 0.078125]
    """
    n = sd.shape[1]
    size = temporal_precision.shape[-1]
    S = np.broadcast_to(temporal_precision, (*sd.shape, size, size))
    blocks = np.einsum("dcij,ce->dicje", S / sd[..., None, None] ** 2, np.eye(n))
    return blocks.reshape(len(sd), size * n, size * n).mean(axis=0)


def mean_covariance_precision(temporal_covariance: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """Pi from the draws' mean covariance: sum_c inv(E[sd_c^2 V_c]) kron e_c e_c'.

    The Gaussian that matches the noise's covariance under the posterior
    (what the filters' ``averaged`` parameters use); :func:`generalised_precision`
    averages the precision instead, E[inv(V_c) / sd_c^2], which is larger
    (Jensen's inequality) by as much as the draws spread.

    Parameters
    ----------
    temporal_covariance : ndarray, shape (draws, channels, P + 1, P + 1) or (P + 1, P + 1)
        V per draw and channel, or one for all.
    sd : ndarray, shape (draws, channels)
        The noise sd per draw and channel [channel units].

    Returns
    -------
    ndarray, shape ((P + 1) C, (P + 1) C)
        Row i * C + c is derivative i of channel c [1 / (units / s^i) / (units / s^j)
        for V in seconds and sd in units].

    Examples
    --------
    One channel at order 0 whose sd is 1 or 3: the mean covariance is 5, so
    Pi = 1/5, where the mean precision is (1 + 1/9) / 2 = 0.556:

    >>> import numpy as np
    >>> from bayes_jackal.dem import generalised_precision, mean_covariance_precision
    >>> sd = np.array([[1.0], [3.0]])  # (draws, channels)
    >>> float(mean_covariance_precision(np.eye(1), sd)[0, 0])
    0.2
    >>> round(float(generalised_precision(np.eye(1), sd)[0, 0]), 3)
    0.556
    """
    n, size = sd.shape[1], temporal_covariance.shape[-1]
    V = np.broadcast_to(temporal_covariance, (*sd.shape, size, size))
    blocks = np.linalg.inv((V * sd[..., None, None] ** 2).mean(axis=0))  # (channels, P+1, P+1)
    return np.einsum("cij,ce->icje", blocks, np.eye(n)).reshape(size * n, size * n)


def gaussian_smoothness(family: str, width: np.ndarray) -> np.ndarray | None:
    """The Gaussian smoothness s with the family's rho''(0): s = (-2 rho''(0))^(-1/2).

    Gaussian noise of kernel sd s has rho(t) = exp(-t^2 / (4 s^2)), so
    rho''(0) = -1 / (2 s^2): its s is the ``s`` of SPM's ``spm_DEM_R`` and
    ``sigma_h`` of the Gaussian family. For another family with a
    derivative (triangular) it is the Gaussian smoothness whose V agrees up
    to order 1.

    Parameters
    ----------
    family : str
        A registered noise family.
    width : ndarray
        Its width, in seconds or in bins; s comes in the same unit.

    Returns
    -------
    ndarray or None
        Shaped like ``width``; None when the family's noise has no
        derivative (exponential, moving average, white): no smoothness
        describes it.

    Examples
    --------
    The Gaussian family's s is sigma_h; the triangular filter of half-width w
    has rho''(0) = -3 / w^2, so s = w / sqrt(6):

    >>> import numpy as np
    >>> from bayes_jackal.dem import gaussian_smoothness
    >>> float(gaussian_smoothness("gaussian", np.array(0.047)))
    0.047
    >>> bool(np.isclose(gaussian_smoothness("triangular", np.array(0.06)), 0.06 / np.sqrt(6)))
    True
    >>> gaussian_smoothness("exponential", np.array(0.05)) is None
    True
    """
    chosen = get_family(family)
    if chosen.max_order is not None and chosen.max_order < 1:
        return None
    curvature = chosen.autocorrelation_derivatives(np.asarray(width, float), 1)[..., 2]
    return 1.0 / np.sqrt(-2.0 * curvature)


def log_precision_moments(sd: np.ndarray) -> dict[str, list]:
    """Mean and (co)variance over draws of the log precision log(1 / sd^2), per channel.

    Parameters
    ----------
    sd : ndarray, shape (draws, channels)
        Draws of a noise sd [channel units].

    Returns
    -------
    dict
        ``mean`` and ``variance`` (lists, one per channel) and ``covariance``
        (channels x channels) of log(1 / sd^2) [log of 1 / channel unit^2].

    Examples
    --------
    sd = exp(z) gives the log precision -2 z: its mean is -2 E[z], its
    variance 4 var(z):

    >>> import numpy as np
    >>> from bayes_jackal.dem import log_precision_moments
    >>> z = np.array([[0.0, 1.0], [0.5, 1.0], [1.0, 1.0]])  # (draws, channels)
    >>> moments = log_precision_moments(np.exp(z))
    >>> moments["mean"], moments["variance"]
    ([-1.0, -2.0], [1.0, 0.0])
    """
    log_precision = -2.0 * np.log(sd)
    covariance = np.atleast_2d(np.cov(log_precision.T))
    return {
        "mean": log_precision.mean(axis=0).tolist(),
        "variance": np.diag(covariance).tolist(),
        "covariance": covariance.tolist(),
    }


def _window_means(experiment: Experiment) -> dict:
    """Samples, span [s], mean inputs and outputs (None where unmeasured) of one window."""
    measured = experiment.channels
    return {
        "name": experiment.name,
        "window": [float(experiment.t[0]), float(experiment.t[-1])],
        "samples": len(experiment.t),
        "u": experiment.inputs.mean(axis=0).tolist(),
        "y": [float(experiment.channel(c).mean()) if c in measured else None for c in CHANNELS],
    }


def operating_point(
    experiments: Sequence[Experiment], *, steady: bool, A: np.ndarray, B: np.ndarray
) -> dict:
    """The operating point: mean inputs and outputs over the analysed windows.

    A DEM or Active Inference filter of the linear model works on deviations
    from it (u - u0, y - y0), as the thesis' fits work on steady circles.

    Parameters
    ----------
    experiments : sequence of Experiment
    steady : bool
        Whether the fit used the steady windows (each experiment's
        :meth:`~bayes_jackal.io.Experiment.steady`); else the whole runs.
    A, B : ndarray, shapes (3, 3) and (3, 2)
        The model, for its steady state at the pooled inputs.

    Returns
    -------
    dict
        ``experiments``: per experiment its ``name``, ``window`` [s],
        ``samples``, ``u`` = mean (omega_r, omega_l) [rad/s] and ``y`` = mean
        (vx, vy, yaw) [m/s, m/s, rad/s], None where not measured; ``pooled``:
        the same over all windows, sample-weighted; ``model_steady_state``:
        -inv(A) B u at the pooled u, the model's own outputs there.

    Examples
    --------
    A steady circle at 12 and 8 rad/s with a yaw rate of 0.4 rad/s:

    >>> import numpy as np
    >>> from bayes_jackal.io import Experiment
    >>> from bayes_jackal.dem import operating_point
    >>> t = np.arange(720) / 72
    >>> run = Experiment(t=t, yaw_rate=np.full_like(t, 0.4), omega_r=np.full_like(t, 12.0),
    ...                  omega_l=np.full_like(t, 8.0), name="circle", steady_window=(2.0, 8.0))
    >>> point = operating_point([run], steady=True, A=-np.eye(3), B=np.ones((3, 2)))
    >>> point["pooled"]["u"], point["pooled"]["y"], point["pooled"]["samples"]
    ([12.0, 8.0], [None, None, 0.4], 433)
    >>> point["model_steady_state"]
    [20.0, 20.0, 20.0]
    """
    windows = [e.steady() if steady else e for e in experiments]
    rows = [_window_means(window) for window in windows]
    samples = np.array([row["samples"] for row in rows], float)
    u = np.average([row["u"] for row in rows], axis=0, weights=samples)
    y = []
    for c in range(len(CHANNELS)):
        measured = [(row["y"][c], n) for row, n in zip(rows, samples, strict=True)]
        measured = [pair for pair in measured if pair[0] is not None]
        if measured:
            values, weights = zip(*measured, strict=True)
            y.append(float(np.average(values, weights=weights)))
        else:
            y.append(None)
    return {
        "window": "steady" if steady else "run",
        "experiments": rows,
        "pooled": {"samples": int(samples.sum()), "u": u.tolist(), "y": y},
        "model_steady_state": (-np.linalg.solve(A, B @ u)).tolist(),
    }


def _pick(
    matrices: Sequence[np.ndarray], names: Sequence[str], cells: Sequence[list]
) -> tuple[list[str], np.ndarray]:
    """Labels (``A[i,j]``) and values (..., entries) of the chosen cells of each matrix."""
    labels, values = [], []
    for M, name, chosen in zip(matrices, names, cells, strict=True):
        rows, cols = np.array(chosen).T
        labels += [f"{name}[{i},{j}]" for i, j in chosen]
        values.append(M[..., rows, cols])
    return labels, np.concatenate(values, axis=-1)


def matrix_prior(robot: RobotProfile, d_lat: np.ndarray, d_long: np.ndarray, dt: float) -> dict:
    """The damping's posterior as a prior on the entries of A, B and Ad, Bd.

    A and B are linear in (d_lat, d_long) (thesis eq. 4-32), so the entries
    that depend on the damping have, over the draws, mean A(mean d) and
    covariance J cov(d) J' with the Jacobian J = d(entries) / d(d_lat, d_long),
    a rank-2 covariance. Ad, Bd (zero-order hold at dt) are not linear:
    their moments are the draws'.

    Parameters
    ----------
    robot : RobotProfile
    d_lat, d_long : ndarray, shape (draws,)
        Posterior draws [N s/m].
    dt : float
        Sample time [s].

    Returns
    -------
    dict
        ``continuous``: ``entries`` (names such as ``A[2,2]``), ``mean``,
        ``covariance`` and ``jacobian`` (entries x 2, per N s/m);
        ``discrete``: ``entries``, ``mean``, ``covariance``. The other
        entries of A, B are 0 whatever the damping.

    Examples
    --------
    The longitudinal pole A[0,0] = -4 d_long / m has derivative -4 / m:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.dem import matrix_prior
    >>> robot = bj.load_profile()
    >>> rng = np.random.default_rng(0)
    >>> prior = matrix_prior(robot, rng.normal(110, 5, 50), rng.normal(30, 1, 50), robot.dt)
    >>> prior["continuous"]["entries"]
    ['A[0,0]', 'A[1,1]', 'A[2,2]', 'B[0,0]', 'B[0,1]', 'B[2,0]', 'B[2,1]']
    >>> bool(np.isclose(prior["continuous"]["jacobian"][0][1], -4 / robot.mass))
    True
    """
    d = np.column_stack([d_lat, d_long])
    mean = d.mean(axis=0)
    step = _STEP * mean
    shifts = [np.eye(2)[k] * step[k] for k in range(2)]
    plus = [continuous_matrices(robot, *(mean + s)) for s in shifts]
    minus = [continuous_matrices(robot, *(mean - s)) for s in shifts]
    slopes = [
        [(p[m] - q[m]) / (2 * step[k]) for m in range(2)]
        for k, (p, q) in enumerate(zip(plus, minus, strict=True))
    ]
    # The cells that move with either damper (the others stay 0).
    cells = [
        [tuple(map(int, c)) for c in np.argwhere((slopes[0][m] != 0) | (slopes[1][m] != 0))]
        for m in range(2)
    ]
    entries, values = _pick(continuous_matrices(robot, d[:, 0], d[:, 1]), "AB", cells)
    jacobian = np.column_stack([_pick(slopes[k], "AB", cells)[1] for k in range(2)])
    discrete, discrete_values = _pick(
        discrete_matrices(robot, d[:, 0], d[:, 1], dt), ("Ad", "Bd"), cells
    )
    return {
        "continuous": {
            "entries": entries,
            "mean": values.mean(axis=0).tolist(),
            "covariance": np.cov(values.T).tolist(),
            "jacobian": jacobian.tolist(),
        },
        "discrete": {
            "entries": discrete,
            "mean": discrete_values.mean(axis=0).tolist(),
            "covariance": np.cov(discrete_values.T).tolist(),
        },
    }


def channel_moments(values: np.ndarray, channels: Sequence[str]) -> dict:
    """Mean and sd over the draws of a quantity per channel.

    Parameters
    ----------
    values : ndarray, shape (draws, channels)
    channels : sequence of str

    Returns
    -------
    dict
        ``{channel: {"mean": float, "sd": float}}``.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.dem import channel_moments
    >>> channel_moments(np.array([[1.0, 10.0], [3.0, 10.0]]), ["yaw", "vx"])
    {'yaw': {'mean': 2.0, 'sd': 1.0}, 'vx': {'mean': 10.0, 'sd': 0.0}}
    """
    return {
        c: {"mean": float(values[:, k].mean()), "sd": float(values[:, k].std())}
        for k, c in enumerate(channels)
    }


def _derivative_scale(order: int, n: int, dt: float) -> np.ndarray:
    """dt^(i+j) for row i * n + c and column j * n + e: seconds <-> bins."""
    k = np.arange(order + 1)
    return np.kron(dt ** np.add.outer(k, k), np.ones((n, n)))


def check_sensor_smoothness(value: float) -> float:
    """The sensor smoothness [bins], validated: a finite number > 0."""
    if not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
        raise InputError(
            f"sensor smoothness must be a finite number of time bins > 0, got {value!r}",
            field="sensor_smoothness",
        )
    return float(value)


def _sensor_noise(
    sigma_n: np.ndarray, temporal_bins: np.ndarray, smoothness: float, dt: float, channels: list
) -> dict:
    """Pi_z and its parts, in seconds and in bins, at sensor smoothness ``smoothness`` [bins]."""
    order = len(temporal_bins) - 1
    inverse_bins = np.linalg.inv(temporal_bins)
    precision_bins = generalised_precision(inverse_bins, sigma_n)
    # inv(V)[i, j] in seconds is dt^(i+j) times the one in bins (an exact rescaling).
    precision = precision_bins * _derivative_scale(order, len(channels), dt)
    return {
        "channels": channels,
        "smoothness_bins": smoothness,
        "smoothness_seconds": smoothness * dt,
        "smoothness_choice": (
            "white sensor noise has no derivatives; it is given a Gaussian smoothness s_z "
            f"(default {SENSOR_SMOOTHNESS} bins, SPM's default E.s; then the derivative's "
            "variance, 1 / (2 s_z^2) = 2 sigma_n^2 per bin^2, is that of the one-step "
            "difference of white noise)"
        ),
        "sd": channel_moments(sigma_n, channels),
        "precision_per_channel": (1.0 / sigma_n**2).mean(axis=0).tolist(),
        "temporal_covariance": (temporal_bins / _derivative_scale(order, 1, dt)).tolist(),
        "temporal_covariance_bins": temporal_bins.tolist(),
        "temporal_precision_bins": inverse_bins.tolist(),
        "precision": precision.tolist(),
        "precision_bins": precision_bins.tolist(),
        "condition": float(np.linalg.cond(precision)),
        "condition_bins": float(np.linalg.cond(precision_bins)),
    }


def _smoothness(family: str, width: np.ndarray, dt: float, channels: list) -> dict:
    """The Gaussian smoothness per channel in seconds and bins, and the one to share."""
    s = gaussian_smoothness(family, width)
    if s is None:
        return {"channels": None, "shared_seconds": None, "shared_bins": None}
    shared = float(s.mean(axis=0).mean())
    return {
        "channels": {
            c: {"seconds": moments, "bins": {k: v / dt for k, v in moments.items()}}
            for c, moments in channel_moments(s, channels).items()
        },
        "shared_seconds": shared,
        "shared_bins": shared / dt,
    }


def prior_additions(
    *,
    family: str,
    channels: list,
    width: np.ndarray,
    sigma_c: np.ndarray,
    sigma_n: np.ndarray | None,
    continuous_sd: np.ndarray,
    temporal_bins: np.ndarray,
    sensor_temporal_bins: np.ndarray,
    sensor_smoothness: float,
    robot: RobotProfile,
    damping: np.ndarray,
    dt: float,
    A: np.ndarray,
    B: np.ndarray,
    experiments: Sequence[Experiment],
    steady: bool,
) -> dict:
    """The consumer-facing keys :func:`~bayes_jackal.dem.export_prior` adds (module docstring).

    ``width``, ``sigma_c``, ``sigma_n`` (None where it is not a parameter)
    and ``continuous_sd`` are draws shaped (draws, channels);
    ``temporal_bins`` is V in bins per draw and channel, and
    ``sensor_temporal_bins`` the sensor noise's V in bins. Keys that exist in
    the prior (``model``, ``damping``, ``generalised_coordinates``) gain fields.
    """
    inverse_bins = np.linalg.inv(temporal_bins)
    return {
        "model": {"A_bins": (A * dt).tolist(), "B_bins": (B * dt).tolist()},
        "damping": {"matrix_prior": matrix_prior(robot, damping[:, 0], damping[:, 1], dt)},
        "generalised_coordinates": {
            "temporal_covariance_bins": temporal_bins.mean(axis=0).tolist(),
            "temporal_precision_bins": inverse_bins.mean(axis=0).tolist(),
            "process_sd_bins": channel_moments(continuous_sd * dt, channels),
            "precision_bins": generalised_precision(inverse_bins, continuous_sd * dt).tolist(),
            "precision_mean_covariance_bins": mean_covariance_precision(
                temporal_bins, continuous_sd * dt
            ).tolist(),
        },
        "sensor_noise": None
        if sigma_n is None
        else _sensor_noise(sigma_n, sensor_temporal_bins, sensor_smoothness, dt, channels),
        "smoothness": _smoothness(family, width, dt, channels),
        "log_precision": {
            "channels": channels,
            "process": log_precision_moments(sigma_c),
            "process_continuous": log_precision_moments(continuous_sd),
            "process_bins": log_precision_moments(continuous_sd * dt),
            "sensor": None if sigma_n is None else log_precision_moments(sigma_n),
        },
        "operating_point": operating_point(experiments, steady=steady, A=A, B=B),
    }
