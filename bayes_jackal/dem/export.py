"""Priors for Active Inference (DEM) filters, exported from a posterior (docs/design.md §4).

A DEM filter needs the model (A, B, C = I, or its discrete Ad, Bd at the
sample time dt) and the precision of the process noise in generalised
coordinates: the noise and its first P time derivatives. For a stationary
noise of autocorrelation rho, the covariance of (w, w', ..., w^(P)) is
sigma^2 V with

    V[i, j] = (-1)^i rho^(i+j)(0)       (zero when i + j is odd),

and independent channels give the precision

    Pi = sum_c inv(V_c) kron e_c e_c' / s_c^2  ( = inv(V) kron inv(Sigma_w)
                                                 when all V_c are equal),

ordered derivative-major: row i * n_channels + c is derivative i of channel c.
V exists up to order P only when rho has 2P derivatives at 0, i.e. when the
noise is P times mean-square differentiable. Each family holds its highest
order and its rho^(n)(0) (:class:`bayes_jackal.model.Family`: ``max_order``,
``autocorrelation_derivatives``): every order for ``gaussian``, 1 for
``triangular``, 0 for ``exponential``, ``moving-average`` and ``white``
(rho has a corner at 0: their noise has no derivative).

These are the continuous-time autocorrelations of which the sampled
kernels' discrete ones are the samples (exactly so in the limit dt -> 0).
Everything is averaged over posterior draws, so the exported precision
carries the uncertainty of the widths, the noise levels and the damping.

The process noise of the fitted model is per step: x[k+1] = Ad x[k] + Bd
u[k] + w[k] with sd sigma_c. White noise with the diagonal sensor term
cannot tell process from sensor noise; its sigma_c is the total sd
(``noise.sigma_c_is = "total"``, no sigma_n), and Pi treats all of it as
process noise. Held constant over a step, a continuous-time
noise w~ in dx/dt = A x + B u + w~ gives w[k] = w~ (Ad - 1) / A, so
s_c = sigma_c A / (Ad - 1) [channel units / s] is its sd; ``Pi`` uses s_c.

Beside Pi the prior carries what DEM and Active Inference codes take as
well (:mod:`bayes_jackal.dem.consumer_keys`, docs/active_inference.md): the
same quantities in time bins, the sensor-noise precision Pi_z, the
smoothness per channel, log-precision hyperpriors, the operating point and
the damping prior on the entries of A and B.

A channel recorded as motion-capture poses (``noise.pose_channels``) is
measured through its travel, the integral of its velocity, with the pose
noise sigma_p per recorded pose: its Pi_z row in ``sensor_noise`` is that
of the travel, in m, at the sd sigma_p / sqrt(n) of a sample averaging n
poses (``noise.pose_samples``, the identification's), and
``sensor_noise.measured`` says which channels these are. Its process noise
is the velocity's, as any channel's: Pi holds the robot's smoothness, not
a smoother's.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .. import __version__
from .._runtime import (
    AUTO_ORDER,
    CHANNELS,
    SENSOR_SMOOTHNESS,
    DataError,
    InputError,
    az,
    require_file,
    thinned_indices,
    write_json,
)
from ..model import DAMPING, continuous_matrices, discrete_matrices, get_family
from ..posterior import ROBOT_CONSTANTS, Posterior, interval, summarize
from .consumer_keys import (
    channel_moments,
    check_sensor_smoothness,
    continuous_sd,
    generalised_precision,
    mean_covariance_precision,
    prior_additions,
)
from .prior import ActiveInferencePrior
from .prior_fields import PRIOR_FORMAT

__all__ = [
    "MAX_CONDITION",
    "MAX_DRAWS",
    "allowed_orders",
    "autocorrelation_derivatives",
    "checked_precision",
    "checked_sensor_smoothness",
    "export_prior",
    "read_prior",
    "temporal_covariance",
    "write_prior",
]

#: Largest condition number of an exported precision Pi, in each time unit
#: the file holds it in: seconds and time bins. Inverting V or solving
#: with Pi by Cholesky or LU loses about log10 of the condition number of
#: the Jacobi-scaled D Pi D (D = diag(Pi)^-1/2), the same in both units (a
#: change of unit scales derivative i by dt^i, a diagonal scaling) and
#: never much above Pi's own. A consumer's eigenvalues or singular values (a log-determinant,
#: a matrix square root, ``numpy.linalg.cond``) lose log10 of the matrix's own
#: condition number in the unit it works in, and absolute thresholds, as
#: SPM's ``spm_logdet`` keeps entries and singular values between 1e-16 and
#: 1e16, depend on the unit too. So Pi must be below the bound in seconds
#: and in bins: 1e12 leaves 4 of double precision's 16 digits. Where V
#: exists the bound limits the order: for the Gaussian family the condition
#: grows ~1000-fold per order in seconds at the thesis' sigma_h = 0.047 s
#: (order 4: 5e11, order 5: 1e15; in bins, 3.4 bins at 72 Hz, 1e4 and 6e4),
#: so order 99 is noise or NaN. A width of many bins is limited in bins
#: instead (0.5 s at dt = 0.01 s: 2e10 at order 3, 3e13 at order 4).
MAX_CONDITION = 1e12
#: Posterior draws written beside the averaged matrices.
MAX_DRAWS = 1000


def _temporal_precision(
    family: str, width: np.ndarray, continuous_sd: np.ndarray, order: int, dt: float | None
) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """V, inv(V) per draw and channel, and Pi's condition number at ``order`` per time unit.

    Pi's block of channel c is the draws' mean of inv(V_c) / s_c^2, in
    ``seconds`` and, with ``dt`` [s], in ``bins`` (entry (i, j) divided by
    dt^(i+j); a factor common to all entries, as the rate's dt^-2, changes
    no condition number). Each is the largest over channels, infinite when
    any number is not finite.
    """
    k = np.arange(order + 1)
    with np.errstate(all="ignore"):  # overflow is caught below, as a non-finite matrix
        scales = {"seconds": 1.0} | ({} if dt is None else {"bins": dt ** -np.add.outer(k, k)})
        V = temporal_covariance(family, width, order)  # (draws, channels, P+1, P+1)
        unusable = V, np.full_like(V, math.nan), dict.fromkeys(scales, math.inf)
        if not np.isfinite(V).all():  # LAPACK crawls through NaN (11 s at order 99)
            return unusable
        try:
            S = np.linalg.inv(V)
        except np.linalg.LinAlgError:  # exactly singular
            return unusable
        blocks = (S / continuous_sd[..., None, None] ** 2).mean(axis=0)
        finite = np.isfinite(V).all() and np.isfinite(S).all()
        conditions = {unit: _condition(blocks * scale, finite) for unit, scale in scales.items()}
    return V, S, conditions


def _condition(blocks: np.ndarray, finite: bool) -> float:
    """The largest condition number of the channels' blocks; infinite for a non-finite one."""
    if not (finite and np.isfinite(blocks).all()):
        return math.inf
    condition = float(np.linalg.cond(blocks).max())
    return condition if math.isfinite(condition) else math.inf


def allowed_orders(
    family: str, width: np.ndarray, continuous_sd: np.ndarray, *, dt: float | None = None
) -> list[int]:
    """The embedding orders 0, 1, .. whose precision is finite and well conditioned.

    An order is allowed when the family's noise has that many derivatives
    (:attr:`~bayes_jackal.model.Family.max_order`) and Pi's condition number is below
    :data:`MAX_CONDITION` at these draws of the width [s] and the
    continuous-time sd ``continuous_sd``, both shaped (draws, channels):
    Pi in seconds and, given the sample time ``dt`` [s], in time bins too.
    The condition grows with the order, so the orders are counted up to the
    first one that fails.

    Examples
    --------
    At the thesis' sigma_h = 0.047 s the Gaussian family allows orders up to 4
    (order 5 is too ill-conditioned in seconds); the exponential family's
    noise has no derivative. A width of 0.5 s is limited by Pi in bins of
    0.01 s (50 bins) instead:

    >>> import numpy as np
    >>> from bayes_jackal.dem import allowed_orders
    >>> width, sd = np.full((10, 1), 0.047), np.full((10, 1), 0.1)  # (draws, channels)
    >>> allowed_orders("gaussian", width, sd), allowed_orders("exponential", width, sd)
    ([0, 1, 2, 3, 4], [0])
    >>> wide = np.full((10, 1), 0.5)
    >>> allowed_orders("gaussian", wide, sd)[-1], allowed_orders("gaussian", wide, sd, dt=0.01)
    (9, [0, 1, 2, 3])
    """
    limit = get_family(family).max_order
    orders = []
    while limit is None or len(orders) <= limit:
        conditions = _temporal_precision(family, width, continuous_sd, len(orders), dt)[2]
        if not max(conditions.values()) < MAX_CONDITION:
            break
        orders.append(len(orders))
    return orders


def checked_precision(
    family: str,
    width: np.ndarray,
    continuous_sd: np.ndarray,
    order: int | None,
    *,
    dt: float,
    source: str | None = None,
) -> tuple[int, np.ndarray, np.ndarray]:
    """The order, V and inv(V) per draw and channel, refusing an order that is not allowed.

    Parameters
    ----------
    family : str
    width, continuous_sd : ndarray, shape (draws, channels)
        As :func:`allowed_orders`: the width [s] and the noise's sd.
    order : int or None
        Embedding order P; None: the highest :func:`allowed_orders` gives,
        at most :data:`AUTO_ORDER`.
    dt : float
        The sample time [s]: Pi is checked in seconds and in time bins.
    source : str, optional
        Named in the error.

    Returns
    -------
    order : int
    V, inv_V : ndarray, shape (draws, channels, P + 1, P + 1)
        :func:`temporal_covariance` [s^-(i+j)] and its inverse.

    Raises
    ------
    InputError
        For an order the family's noise cannot give, or whose precision's
        condition number is above :data:`MAX_CONDITION` in seconds or in
        bins (naming both and the allowed orders).

    Examples
    --------
    At the thesis' sigma_h = 0.047 s and 72 Hz the Gaussian family gives the
    default order 2; the exponential family's noise has no derivative. At a
    width of 1 ms, order 2 is refused by Pi in seconds, though in bins of
    1 ms it is well conditioned:

    >>> import numpy as np
    >>> from bayes_jackal.dem import checked_precision
    >>> width, sd = np.full((10, 1), 0.047), np.full((10, 1), 0.1)  # (draws, channels)
    >>> order, V, inv_V = checked_precision("gaussian", width, sd, None, dt=1 / 72)
    >>> order, V.shape, bool(np.allclose(V[0, 0] @ inv_V[0, 0], np.eye(3)))
    (2, (10, 1, 3, 3), True)
    >>> try:
    ...     checked_precision("exponential", width, sd, 1, dt=1 / 72)
    ... except ValueError as error:
    ...     print(str(error).split(": ")[0], "|", str(error).split(": ")[-1])
    order | generalised coordinates exist up to order 0, got 1
    >>> try:
    ...     checked_precision("gaussian", np.full((10, 1), 0.001), sd, 2, dt=0.001)
    ... except ValueError as error:
    ...     print(str(error).split("number ")[1].split(" (")[0], "|", str(error).split("; ")[1])
    1.13e+12 in seconds, 3.87 in bins | the orders allowed here are 0, 1
    """
    if order is None:
        order = min(
            AUTO_ORDER, max(allowed_orders(family, width, continuous_sd, dt=dt), default=0)
        )
    V, S, conditions = _temporal_precision(family, width, continuous_sd, order, dt)
    if not max(conditions.values()) < MAX_CONDITION:
        allowed = allowed_orders(family, width, continuous_sd, dt=dt)
        numbers = ", ".join(f"{value:.3g} in {unit}" for unit, value in conditions.items())
        raise InputError(
            f"order {order} gives a precision with condition number {numbers} (above "
            f"{MAX_CONDITION:.0e} in one unit: it would keep fewer than 4 significant digits) "
            f"for this {family} noise; the orders allowed here are "
            f"{', '.join(map(str, allowed)) or 'none'}",
            source=source,
            field="order",
        )
    return order, V, S


def autocorrelation_derivatives(family: str, width: np.ndarray, order: int) -> np.ndarray:
    """rho^(n)(0), n = 0 .. 2 ``order``, of the family named ``family`` [1/s^n].

    :meth:`bayes_jackal.model.Family.autocorrelation_derivatives` of
    :func:`~bayes_jackal.model.get_family` ``(family)``: parameters, shape
    and errors are documented there.

    Examples
    --------
    The Gaussian filter's autocorrelation is exp(-t^2 / (4 sigma_h^2)), so
    rho''(0) = -1 / (2 sigma_h^2):

    >>> import numpy as np
    >>> from bayes_jackal.dem import autocorrelation_derivatives
    >>> rho = autocorrelation_derivatives("gaussian", np.array(0.047), 1)
    >>> rho.shape, np.allclose(rho, [1.0, 0.0, -1 / (2 * 0.047**2)])
    ((3,), True)
    """
    return get_family(family).autocorrelation_derivatives(width, order)


def checked_sensor_smoothness(smoothness: float, order: int, *, dt: float) -> float:
    """The sensor smoothness [bins], refused when its Pi_z at ``order`` is ill conditioned.

    Pi_z's temporal part is the inverse of the Gaussian family's V at width
    s_z = ``smoothness`` bins, held to :data:`MAX_CONDITION` in bins: the
    unit the smoothness is given in and SPM's ``spm_DEM_R`` works in. (In
    seconds a white sensor's Pi_z spans dt^-2p whatever s_z: SPM's default
    0.5 bins at 72 Hz gives 5e8 at order 2 and 2e18 at order 4; the export
    reports it as ``sensor_noise.condition``.)

    Raises
    ------
    InputError
        Naming the condition numbers and the smoothnesses this order allows.

    Examples
    --------
    >>> from bayes_jackal.dem import checked_sensor_smoothness
    >>> checked_sensor_smoothness(0.5, 2, dt=1 / 72)
    0.5
    >>> try:
    ...     checked_sensor_smoothness(0.01, 4, dt=1 / 72)
    ... except ValueError as error:
    ...     print(str(error).split("; ")[1])
    order 4 allows 0.045 to 32 bins
    """
    smoothness = check_sensor_smoothness(smoothness)

    def condition(bins: float) -> float:
        width = np.array([[bins * dt]])
        return _temporal_precision("gaussian", width, np.ones_like(width), order, dt)[2]["bins"]

    found = condition(smoothness)
    if found < MAX_CONDITION:
        return smoothness
    allowed = [s for s in np.geomspace(1e-3, 1e3, 121) if condition(s) < MAX_CONDITION]
    span = f"{allowed[0]:.2g} to {allowed[-1]:.2g} bins" if allowed else "none"
    raise InputError(
        f"a sensor smoothness of {smoothness:g} bins gives Pi_z the condition number "
        f"{found:.3g} in bins (above {MAX_CONDITION:.0e}: it would keep fewer than 4 "
        f"significant digits); order {order} allows {span}",
        field="sensor_smoothness",
    )


def temporal_covariance(family: str, width: np.ndarray, order: int) -> np.ndarray:
    """V[i, j] = (-1)^i rho^(i+j)(0), the covariance of (w, w', .., w^(P)) / sigma^2.

    Returns
    -------
    ndarray, shape (..., P + 1, P + 1)

    Examples
    --------
    The covariance of the Gaussian noise and its derivative, per unit variance:
    the derivative's variance is -rho''(0) = 1 / (2 sigma_h^2) [1/s^2]:

    >>> import numpy as np
    >>> from bayes_jackal.dem import temporal_covariance
    >>> V = temporal_covariance("gaussian", np.array(0.047), 1)
    >>> V.shape, np.allclose(V, [[1.0, 0.0], [0.0, 1 / (2 * 0.047**2)]])
    ((2, 2), True)
    """
    derivatives = autocorrelation_derivatives(family, width, order)
    i, j = np.indices((order + 1, order + 1))
    return (-1.0) ** i * derivatives[..., i + j]


def export_prior(
    idata: az.InferenceData,
    *,
    order: int | None = AUTO_ORDER,
    source: str | None = None,
    sensor_smoothness: float = SENSOR_SMOOTHNESS,
) -> ActiveInferencePrior:
    """The Active Inference prior of a posterior.

    Parameters
    ----------
    idata : arviz.InferenceData
        A posterior of ``bayes-jackal sample`` or :func:`bayes_jackal.sample`,
        in memory or read by :func:`~bayes_jackal.posterior.load_posterior`
        (shared noise: one noise group per channel).
    order : int or None
        Embedding order P of the generalised coordinates (P + 1 of them);
        by default :data:`AUTO_ORDER` (2, as ``export-prior --order``).
        None: the highest order :func:`allowed_orders` gives for this
        posterior, at most :data:`AUTO_ORDER`.
    source : str, optional
        Where the posterior was read from (written into the prior).
    sensor_smoothness : float
        Gaussian smoothness given to the white sensor noise in its precision
        Pi_z [time bins]; by default :data:`SENSOR_SMOOTHNESS` (0.5 bins,
        :mod:`bayes_jackal.dem.consumer_keys` says why).

    Returns
    -------
    ActiveInferencePrior
        The schema ``bayes_jackal.prior/1`` (docs/guide/prior.md, "The file"):
        :meth:`~ActiveInferencePrior.to_json` is the JSON of ``prior.json``.

    Raises
    ------
    InputError
        For an order the family cannot give, noise per experiment, or a
        sensor smoothness that is not a finite number > 0.

    Examples
    --------
    The prior of a simulated run's posterior, written for a DEM filter. The
    chain is capped at 20 steps to keep the example quick, far from
    converged on purpose (a ConvergenceWarning); real use takes the default cap.

    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="gaussian", channels=["yaw"], max_steps=20, seed=1)
    >>> prior = bj.export_prior(posterior, order=2)
    >>> prior
    ActiveInferencePrior(family='gaussian', channels=('yaw',), order=2, dt=0.013888888889,
                         source=None)
    >>> prior.noise["sigma_c_is"], prior["generalised_coordinates"]["order"]  # fields, or keys
    ('process', 2)
    >>> bj.write_prior(prior, "prior.json")  # doctest: +SKIP
    PosixPath('prior.json')
    """
    fitted = Posterior.of(idata)
    metadata = fitted.metadata
    layout = metadata.layout
    family, channels, names = layout.family, list(layout.channels), layout.names
    if order is not None:
        get_family(family).check_order(order)
    sensor_smoothness = check_sensor_smoothness(sensor_smoothness)
    width_name = layout.width_name
    if len(layout.groups) != len(channels):
        raise InputError(
            "noise parameters per experiment have no single prior: sample with shared noise",
            source=source,
            field="shared_noise",
        )
    robot = metadata.robot
    dts = {round(e.dt, 12) for e in metadata.experiments}
    if len(dts) != 1:
        raise InputError(f"experiments differ in sample time: {sorted(dts)} s", source=source)
    dt = dts.pop()
    draws, _ = fitted.draws()
    draws = draws.reshape(-1, len(names))
    d = draws[:, :2]
    # Shared noise: group c is channel c; white noise has unit widths.
    width, sigma_c, sensor = np.stack(
        [layout.noise_parameters(draws, group) for group in range(len(channels))], axis=-1
    )
    poses = _pose_samples(metadata)
    sensor_sd = sensor / np.sqrt([poses if c in layout.pose_channels else 1 for c in channels])
    every_sensor = all(layout.sensor_parameter(g) for g in range(len(channels)))
    process_sd = continuous_sd(robot, d, dt, channels, sigma_c)
    order, V, S = checked_precision(family, width, process_sd, order, dt=dt, source=source)
    if every_sensor:
        checked_sensor_smoothness(sensor_smoothness, order, dt=dt)
    mean_d = d.mean(axis=0)
    A, B = continuous_matrices(robot, *mean_d)
    Ad, Bd = discrete_matrices(robot, *mean_d, dt)
    summary = summarize(idata)
    kept = thinned_indices(len(draws), MAX_DRAWS)
    noise_stats = {name: interval(summary[name]) for name in names[len(DAMPING) :]}
    prior = {
        "format": PRIOR_FORMAT,
        "bayes_jackal_version": __version__,
        "source": source,
        "converged": metadata.convergence.converged,
        "experiments": [e.name for e in metadata.experiments],
        "robot": {key: getattr(robot, key) for key in ROBOT_CONSTANTS},
        "dt": dt,
        "states": list(CHANNELS),
        "inputs": ["omega_r", "omega_l"],
        "model": {
            "at": "posterior mean of (d_lat, d_long)",
            "A": A.tolist(),
            "B": B.tolist(),
            "C": np.eye(len(CHANNELS)).tolist(),
            "Ad": Ad.tolist(),
            "Bd": Bd.tolist(),
        },
        "damping": {
            "names": ["d_lat", "d_long"],
            "units": "N s/m",
            "mean": mean_d.tolist(),
            "covariance": np.cov(d.T).tolist(),
            "d_lat": interval(summary["d_lat"]),
            "d_long": interval(summary["d_long"]),
            "ratio": interval(summary["ratio"]),
        },
        "noise": {
            "family": family,
            "width_name": width_name,
            "shared_width": bool(layout.shared_bases),
            "channels": channels,
            "parameters": noise_stats,
            "sigma_c_is": "process" if every_sensor else "total",
            "process_sd_continuous": channel_moments(process_sd, channels),
            "sensor": layout.sensor,
            "pose_channels": list(layout.pose_channels),
            "pose_samples": poses,
        },
        "generalised_coordinates": {
            "order": order,
            "channels": channels,
            "layout": "derivative-major: row i * len(channels) + c is derivative i of channel c",
            "temporal_covariance": V.mean(axis=0).tolist(),
            "temporal_precision": S.mean(axis=0).tolist(),
            "noise_covariance": np.diag((process_sd**2).mean(axis=0)).tolist(),
            "precision": generalised_precision(S, process_sd).tolist(),
            "precision_mean_covariance": mean_covariance_precision(V, process_sd).tolist(),
        },
        "draws": {
            "count": len(kept),
            **{name: draws[kept, j].tolist() for j, name in enumerate(names)},
        },
    }
    additions = prior_additions(
        family=family,
        channels=channels,
        width=width,
        sigma_c=sigma_c,
        sigma_n=sensor_sd if every_sensor else None,
        continuous_sd=process_sd,
        temporal_bins=temporal_covariance(family, width / dt, order),
        sensor_temporal_bins=temporal_covariance("gaussian", np.array(sensor_smoothness), order),
        sensor_smoothness=sensor_smoothness,
        robot=robot,
        damping=d,
        dt=dt,
        A=A,
        B=B,
        experiments=fitted.experiments,
        steady=metadata.steady,
    )
    for key, value in additions.items():
        if key in prior:
            prior[key].update(value)
        else:
            prior[key] = value
    if prior["sensor_noise"] is not None:
        prior["sensor_noise"]["measured"] = {
            c: "pose" if c in layout.pose_channels else "rate" for c in channels
        }
    return ActiveInferencePrior(**prior)


def _pose_samples(metadata) -> float:
    """The recorded poses per sample of a posterior's pose channels: 1 / mean(1 / n_e).

    A sample's pose noise has the variance sigma_p^2 / n_e in experiment e;
    this n gives their mean. 1 without pose channels.
    """
    counts = [e.pose_samples for e in metadata.experiments]
    if not metadata.layout.pose_channels:
        return 1.0
    return float(1.0 / np.mean(1.0 / np.asarray(counts, float)))


def write_prior(prior: ActiveInferencePrior | Mapping, path: str | Path) -> Path:
    """Write an exported prior as JSON, atomically; return the path.

    Parameters
    ----------
    prior : ActiveInferencePrior or mapping
        A prior (:func:`export_prior`), written as its
        :meth:`~ActiveInferencePrior.to_json`. A mapping of its format,
        ``bayes_jackal.prior/1``, is checked first
        (:meth:`ActiveInferencePrior.from_json`), so that the file is one
        :func:`read_prior` reads; a mapping of another format (the prior of
        a noise series, :func:`bayes_jackal.noise.export_noise_prior`) is
        written as it is.
    path : str or Path
        The file (``prior.json``); a number that is not finite is written as null.

    Returns
    -------
    Path

    Raises
    ------
    InputError
        For a mapping of the format ``bayes_jackal.prior/1`` with a field
        the filters read missing or of the wrong type, naming it.
    OutputError
        When the file cannot be written.

    Examples
    --------
    The prior of a posterior, written as JSON. The 20-step chain is short on
    purpose:

    >>> import json
    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> prior = bj.export_prior(posterior, order=0)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = bj.write_prior(prior, Path(folder) / "prior.json")
    ...     stored = json.loads(path.read_text())
    >>> path.name, stored["format"], stored["noise"]["family"], stored == prior.to_json()
    ('prior.json', 'bayes_jackal.prior/1', 'white', True)
    """
    if not isinstance(prior, ActiveInferencePrior) and prior.get("format") == PRIOR_FORMAT:
        prior = ActiveInferencePrior.from_json(prior)
    payload = prior.to_json() if isinstance(prior, ActiveInferencePrior) else prior
    return write_json(path, payload, indent=1)


def read_prior(path: str | Path) -> ActiveInferencePrior:
    """Read a prior written by :func:`write_prior` (``prior.json``).

    Parameters
    ----------
    path : str or Path
        A ``prior.json`` (format ``bayes_jackal.prior/1``).

    Returns
    -------
    ActiveInferencePrior
        As :func:`export_prior` made it (:meth:`ActiveInferencePrior.from_json`).

    Raises
    ------
    DataError
        For a file that is missing or not a regular file, not JSON, not an
        exported prior (its ``format``), or a field the filters read that
        is missing or of the wrong type
        (:func:`bayes_jackal.dem.check_prior_fields`), naming the
        file and the field.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.dem import read_prior
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "prior.json"
    ...     _ = path.write_text('{"format": "bayes_jackal.posterior/1"}')
    ...     try:
    ...         read_prior(path)
    ...     except ValueError as error:
    ...         print(str(error).split(": ", 2)[2])
    not a prior this version reads: 'bayes_jackal.posterior/1' (expected bayes_jackal.prior/1)
    """
    source = str(path)
    require_file(path, source)
    try:
        prior = json.loads(Path(path).read_text())
    except OSError as error:
        raise DataError(f"cannot read: {error.strerror}", source=source) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise DataError(f"not JSON: {error}", source=source) from None
    except RecursionError:  # json's parser recurses per level: no prior nests that deep
        raise DataError(
            "not a prior: its JSON nests deeper than Python parses", source=source
        ) from None
    return ActiveInferencePrior.from_json(prior, source=source)
