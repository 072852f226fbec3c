"""Starting points of the MAP search: the likelihood profiled over each noise group.

The log-likelihood is a sum over noise groups (a channel, or a channel of
one experiment), and each group depends only on the damping and on its own
noise parameters: vx's coefficients on d_long, vy's on d_lat, yaw's on both
(:func:`bayes_jackal.model.channel_coefficients`). So a design over the
damping alone, crossed with a grid over each group's noise, finds for every
damping point the best noise of every group: the profile likelihood. With
three channels that is a 2-D search followed by three searches over one
group's noise, where a design over the whole 11-D prior box cannot find a
point at which every channel's noise is right at once.

The profile uses the debiased Whittle likelihood
(:func:`bayes_jackal.likelihood.debiased_whittle_loglike`), whose expected
periodogram is linear in the autocovariance. With rho = sigma_n / sigma_c
(sigma_p / sigma_c for a channel recorded as poses),

    E[I] = sigma_c^2 S,    S = E_R(width) + rho^2 E_M(alpha),

E_R the expected periodogram of the kernel's autocorrelation (one FFT per
width; for a pose channel through its two-tap filter, which depends on
alpha too) and E_M that of the sensor term (``ma1``: lags 0 and 1 only;
a pose channel's MA(2)). A damping point changes the periodogram
I = c^T P c of the block's cross-periodograms P and the pole alpha in E_M. Past 4,096 residuals the
periodogram is averaged onto 4,096 frequencies (the spectra of the model
are smooth on that scale), so the work does not grow with the run. For a fixed
shape S the group's Whittle log-likelihood

    -1/2 [A log sigma_c^2 + sum E log S + Q / sigma_c^2] - A/2 log(2 pi),

A the number of residuals and Q = sum I / S (sums over the blocks' Fourier
frequencies), is largest at sigma_c^2 = Q / A, kept inside the prior box.
So only the width and the ratio are gridded. The Whittle likelihood is off
the exact one by tens of nats for the Gaussian family, which does not move
a basin hundreds of nats better; the local searches that follow use the
exact engine. Where a kernel's spectrum has nulls (triangular, boxcar) and
the width is long, it can be off by thousands (measured: 11,600 nats at a
1 s triangle on a simulated yaw-rate run), and its best width there is
spurious; the MAP search sweeps each start's widths on the quick scan of
the exact likelihood (:func:`bayes_jackal.inference.climb`).

A bare noise series (:class:`bayes_jackal.likelihood.SeriesLikelihood`)
is one such group with no damping: :func:`series_profile` profiles its
Whittle likelihood over (width, rho) on a fine grid of the width's whole
prior range, so that the exact likelihood, whose long-memory sets cost up
to a second each, is only evaluated near the profile's best widths.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.fft
import scipy.stats

from ..likelihood import (
    MEASUREMENT_MODELS,
    ResidualBlock,
    ResidualLikelihood,
    SeriesLikelihood,
    expected_periodogram,
    frequency_weights,
)
from ..model import SPEED_RATIOS, Family, get_family

__all__ = ["profile_starts", "series_profile"]

#: Points per sd of the exact profile of a group observed at its own times only.
EXACT_GRID = 7
#: Coarse grid of one group's kernel width (log-spaced over its prior range)
#: and of rho = sigma_n / sigma_c (log-spaced over the range the box allows),
#: then ZOOMS refinements: around each damping point's best, a 5 x 5 grid
#: with half the previous spacing.
WIDTHS = 16
RATIOS = 10
ZOOMS = 5
#: Frequencies of the profile's spectral grid: a longer series' periodogram
#: is averaged onto it, so the profile's cost does not grow with the run
#: (only the starting points of the MAP search depend on it).
PROFILE_FREQUENCIES = 4096
#: A residual group's grid is coarser where its widest kernel allows: at least
#: KERNEL_RESOLUTION points per the widest kernel's length in samples, and
#: never fewer than LEAST_PROFILE_FREQUENCIES (nor more than the above). On a
#: 10-minute step sequence at 20 Hz (1 s widest width: 121 taps) 1024 points
#: instead of 3018-4096 gave the same four starts to four digits in a quarter
#: of the time (1.5 s against 6.1 s); at 1 kHz the grid stays at 4096.
KERNEL_RESOLUTION = 4
LEAST_PROFILE_FREQUENCIES = 1024
#: Largest array of the profile, in elements (~64 MB of float64): the
#: damping design is processed in chunks of at most this size.
_MAX_ELEMENTS = 8_000_000
#: A series' profile (:func:`series_profile`): widths of its grid over the
#: width's prior range (log-spaced: a step of 14 % over the default range
#: of 4,000 samples, finer than the moving-average family's basins, whose
#: local optima lie at half and 1.5 times the best width) and ratios rho
#: (log-spaced over the range the box allows: a factor 1.8 per step over
#: the default 1e-4..1e4).
SERIES_WIDTHS = 64
SERIES_RATIOS = 33
_LOG_2PI = np.log(2.0 * np.pi)


def profile_starts(
    likelihood: ResidualLikelihood,
    low: np.ndarray,
    high: np.ndarray,
    *,
    damping_points: int,
    starts: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """The best points of the profile likelihood over a damping design.

    Parameters
    ----------
    likelihood : ResidualLikelihood
    low, high : ndarray, shape (P,)
        Prior box in natural units, ordered as ``likelihood.parameter_names``.
    damping_points : int
        Size of the scrambled Sobol design over (log d_lat, log d_long).
    starts : int
        Number of points returned.
    rng : numpy.random.Generator
        Scrambles the design.

    Returns
    -------
    theta : ndarray, shape (starts, P)
        Damping points with every group's best noise, best first (natural
        units, inside the box). A width every group shares
        (``shared_width``) is the geometric mean of the groups' best ones.
    profile : ndarray, shape (starts,)
        Their Whittle log-likelihoods (-inf where no noise setting of some
        group is valid); with a shared width, the sum of each group's best,
        an upper bound of the likelihood at ``theta``.

    Examples
    --------
    Starting points on a simulated run (truth d_lat = 110, d_long = 30 N s/m,
    sigma_h = 0.047 s), from a coarse design of 64 damping points: the best
    lies on the ridge of the truth's ratio d_lat / d_long ~ 3.7, and its value
    is the Whittle likelihood there, to the periodogram's averaging onto
    :data:`KERNEL_RESOLUTION` points per the widest kernel's tap;
    :func:`bayes_jackal.inference.find_map` refines it.

    >>> from dataclasses import replace
    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.inference import profile_starts
    >>> from bayes_jackal.likelihood import Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, channels=("yaw", "vx"))
    >>> prior = Prior.for_likelihood(likelihood, robot)
    >>> rng = np.random.default_rng(1)
    >>> theta, profile = profile_starts(
    ...     likelihood, prior.low, prior.high, damping_points=64, starts=3, rng=rng
    ... )
    >>> [f"{name} {value:.3g}" for name, value in zip(likelihood.parameter_names[:3], theta[0])]
    ['d_lat 49.2', 'd_long 11.9', 'sigma_h[yaw] 0.041']
    >>> whittle = replace(likelihood, engine="whittle")(theta)
    >>> bool(np.max(np.abs(whittle - profile)) < 0.2)  # of 20,000 nats: the binned periodogram
    True
    """
    if likelihood.damping != "constant":
        return _constant_starts(likelihood, low, high, damping_points, starts, rng)
    unit = scipy.stats.qmc.Sobol(2, scramble=True, seed=rng).random(damping_points)
    damping = low[:2] * (high[:2] / low[:2]) ** unit
    theta = np.repeat(np.sqrt(low * high)[None], damping_points, axis=0)
    theta[:, :2] = damping
    total = np.zeros(damping_points)
    layout = likelihood.layout
    shared = [layout.column(base) for base in layout.shared_bases]
    log_shared = np.zeros((damping_points, len(shared)))
    regular = {block.noise_group for block in likelihood.blocks}
    for group in sorted(regular):
        columns = layout.noise_columns(group)
        loglike, noise = _group_profile(likelihood, group, damping, low[columns], high[columns])
        total += loglike
        theta[:, columns] = noise
        log_shared += np.log(theta[:, shared])
    theta[:, shared] = np.exp(log_shared / max(len(regular), 1))
    order = np.argsort(np.where(np.isnan(total), -np.inf, total))[::-1][:starts]
    theta, total = np.clip(theta[order], low, high), total[order]
    for group in sorted(set(range(len(layout.groups))) - regular):
        loglike, theta = _exact_profile(likelihood, group, theta, low, high)
        total = total + loglike
    return theta, total


def _constant_starts(
    likelihood: ResidualLikelihood,
    low: np.ndarray,
    high: np.ndarray,
    damping_points: int,
    starts: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Starts of a damping that depends on the speed: the constant damping's, its ratios 1.

    The same likelihood with one damping (most of its channels on the
    Toeplitz engines) is profiled, and each start gets the speed ratios 1:
    the speed model's local searches climb from the constant model's best.
    Its profile values are the constant model's.
    """
    constant = dataclasses.replace(likelihood, damping="constant")
    extra = [likelihood.layout.column(base) for base in SPEED_RATIOS]
    keep = np.setdiff1d(np.arange(len(low)), extra)
    theta, profile = profile_starts(
        constant, low[keep], high[keep], damping_points=damping_points, starts=starts, rng=rng
    )
    out = np.ones((len(theta), len(low)))
    out[:, keep] = theta
    return np.clip(out, low, high), profile


def _exact_profile(
    likelihood: ResidualLikelihood,
    group: int,
    theta: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """A group observed at its own times only: its best sd's on a grid, on the exact likelihood.

    Channels of the irregular engine (poses slower than the samples) have no
    Whittle profile: at each start, their width is the geometric centre of
    its prior and sigma_c and the sensor sd the best of
    :data:`EXACT_GRID` x :data:`EXACT_GRID` log-spaced points of their box;
    the MAP search's local searches and width sweeps take it from there.
    Returns the group's log-likelihood at each start and the starts.
    """
    layout = likelihood.layout
    sds = [layout.column("sigma_c", group)]
    sensor = layout.sensor_parameter(group)
    if sensor is not None:
        sds.append(layout.column(sensor, group))
    unit = np.stack(np.meshgrid(*[np.linspace(0, 1, EXACT_GRID)] * len(sds)), -1).reshape(
        -1, len(sds)
    )
    grid = low[sds] * (high[sds] / low[sds]) ** unit  # (G, 1 or 2)
    candidates = np.repeat(theta, len(grid), axis=0)
    candidates[:, sds] = np.tile(grid, (len(theta), 1))
    loglike = likelihood.group_loglike(candidates, group).reshape(len(theta), len(grid))
    best = np.argmax(loglike, axis=1)
    out = theta.copy()
    out[:, sds] = grid[best]
    return loglike[np.arange(len(theta)), best], out


def _group_profile(
    likelihood: ResidualLikelihood,
    group: int,
    damping: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Best Whittle log-likelihood of one group at each damping point, and its noise.

    The coarse grid of (log width, log rho) is shared by all damping points;
    each zoom evaluates a 5 x 5 grid around every point's best so far with
    half the spacing (one value where the family has no width or the group
    no sensor parameter).

    Parameters
    ----------
    damping : ndarray, shape (D, 2)
        (d_lat, d_long) [N s/m].
    low, high : ndarray, shape (K,)
        The group's prior box, in ``layout.noise_bases_of(group)`` order.

    Returns
    -------
    loglike : ndarray, shape (D,)
    noise : ndarray, shape (D, K)
        The best (width,) sigma_c(, sensor sd), in that order.
    """
    layout = likelihood.layout
    names = layout.noise_bases_of(group)
    bounds = dict(zip(names, zip(low, high, strict=True), strict=True))
    family = get_family(likelihood.family)
    sensor_name = layout.sensor_parameter(group)
    # Log-width and log-ratio ranges; a single value where not a parameter.
    ranges = np.zeros((2, 2))
    if family.has_width:
        ranges[0] = np.log(bounds[family.width_name])
    if sensor_name is not None:
        ranges[1] = np.log(bounds[sensor_name]) - np.log(bounds["sigma_c"])[::-1]
    sensor = 0.0 if sensor_name is None else 1.0  # rho = 0 without a sensor parameter
    sizes = np.where(ranges[:, 1] > ranges[:, 0], (WIDTHS, RATIOS), 1)
    axes = [np.linspace(*r, s)[None] for r, s in zip(ranges, sizes, strict=True)]
    steps = np.ptp(ranges, axis=1) / np.maximum(sizes - 1, 1)
    rows = np.arange(len(damping))
    best = None
    for zoom in range(ZOOMS + 1):
        if zoom:
            offsets = [np.arange(-2, 3) * h / 2**zoom if h else np.zeros(1) for h in steps]
            axes = [
                np.clip(centre[:, None] + o, r[0], r[1])
                for centre, o, r in zip(best, offsets, ranges, strict=True)
            ]
        loglike, variance = _grid_loglike(
            likelihood,
            group,
            damping,
            np.exp(axes[0]),
            sensor * np.exp(axes[1]),
            bounds,
            sensor_name,
        )
        flat = loglike.reshape(len(damping), -1)
        index = np.unravel_index(np.argmax(flat, axis=1), loglike.shape[1:])
        best = [axis[rows if len(axis) > 1 else 0, i] for axis, i in zip(axes, index, strict=True)]
        sigma_c = np.sqrt(variance[(rows, *index)])
        top = loglike[(rows, *index)]
    width, ratio = np.exp(best) * [[1.0], [sensor]]
    values = {"sigma_c": sigma_c, sensor_name: ratio * sigma_c, family.width_name: width}
    return top, np.column_stack([values[name] for name in names])


def _grid_loglike(
    likelihood: ResidualLikelihood,
    group: int,
    damping: np.ndarray,
    widths: np.ndarray,
    ratios: np.ndarray,
    bounds: dict[str, tuple[float, float]],
    sensor_name: str | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Whittle log-likelihood of one group, maximised over sigma_c, on a grid.

    Parameters
    ----------
    damping : ndarray, shape (D, 2)
    widths : ndarray, shape (1 or D, W)
        Kernel widths [s], shared by all damping points or one row each.
    ratios : ndarray, shape (1 or D, R)
        rho = sensor sd / sigma_c (0 where the group has no sensor parameter).
    bounds : dict
        The group's prior box by base name.
    sensor_name : str or None
        The group's sensor parameter (``sigma_n``, ``sigma_p``).

    Returns
    -------
    loglike, variance : ndarray, shape (D, W, R)
        The log-likelihood at the best sigma_c^2 = Q / A inside the box
        (-inf where the box allows none), and that sigma_c^2.
    """
    blocks = [b for b in likelihood.blocks if b.noise_group == group]
    count = sum(b.regressors.shape[0] * b.regressors.shape[1] for b in blocks)
    cells = len(damping) * widths.shape[1] * ratios.shape[1]
    family = get_family(likelihood.family)
    widest = bounds[family.width_name][1] if family.has_width else 1.0
    lags = [_profile_lags(block, family, widest) for block in blocks]
    frequencies = sum(points // 2 + 1 for points in lags)
    chunks = np.array_split(
        np.arange(len(damping)), int(np.ceil(cells * frequencies / _MAX_ELEMENTS))
    )
    log_det, quadratic = (
        np.concatenate(parts)
        for parts in zip(
            *(
                _chunk_terms(
                    likelihood, blocks, lags, damping[i], _rows(widths, i), _rows(ratios, i)
                )
                for i in chunks
            ),
            strict=True,
        )
    )
    ratios = ratios[:, None, :]
    c_low, c_high = bounds["sigma_c"]
    if sensor_name is not None:
        # The sensor sd rho sigma_c must be inside its box too.
        c_low = np.maximum(c_low, bounds[sensor_name][0] / ratios)
        c_high = np.minimum(c_high, bounds[sensor_name][1] / ratios)
    variance = np.clip(quadratic / count, c_low**2, c_high**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        loglike = -0.5 * (count * (np.log(variance) + _LOG_2PI) + log_det + quadratic / variance)
    valid = np.isfinite(loglike) & (c_low <= c_high)
    return np.where(valid, loglike, -np.inf), variance


def _rows(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Rows ``index`` of a per-damping-point grid; a shared one-row grid as is."""
    return values if len(values) == 1 else values[index]


def _profile_lags(block: ResidualBlock, family: Family, widest: float) -> int:
    """Points of a block's profile grid: :data:`KERNEL_RESOLUTION` per the widest kernel."""
    support = KERNEL_RESOLUTION * family.taps(widest, block.dt).shape[-1]
    return min(block.n, PROFILE_FREQUENCIES, max(LEAST_PROFILE_FREQUENCIES, support))


def _chunk_terms(
    likelihood: ResidualLikelihood,
    blocks: list,
    block_lags: list[int],
    damping: np.ndarray,
    widths: np.ndarray,
    ratios: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """sum E log S and Q = sum I / S over a group's blocks, each (D, W, R)."""
    log_det, quadratic = 0.0, 0.0
    for block, lags in zip(blocks, block_lags, strict=True):
        count = block.regressors.shape[0]
        binned, weights = _binned_periodogram(block, lags)
        c, alpha = MEASUREMENT_MODELS[block.measurement].coefficients(
            likelihood.robot, damping[:, 0], damping[:, 1], block.channel, block.dt,
            clock=block.clock,
        )  # fmt: skip
        periodogram = (c[:, :, None] * c[:, None, :]).reshape(len(c), -1) @ binned.T

        # E_R: the kernel through the channel's filter, for each width, and
        # for each damping point where that filter depends on alpha (poses).
        if block.measurement == "pose":
            grid = np.broadcast_to(widths, (len(alpha), widths.shape[1]))
            poles = np.broadcast_to(alpha[:, None], grid.shape)
        else:  # alpha enters the sensor term only
            grid, poles = widths, np.ones(widths.shape)
        unit = np.ones(grid.size)
        kernel = _expected(likelihood, block, lags, grid.ravel(), unit, 0 * unit, poles.ravel())
        kernel = kernel.reshape(*grid.shape, -1)
        unit = np.ones(len(alpha))
        sensor = _expected(likelihood, block, lags, unit, 0 * unit, unit, alpha)
        # S (D, W, R, F) = E_R(width) + rho^2 E_M(alpha).
        shape = kernel[:, :, None, :] + ratios[:, None, :, None] ** 2 * sensor[:, None, None, :]
        with np.errstate(invalid="ignore", divide="ignore"):
            log_det = log_det + count * (np.log(shape) @ weights)
            quadratic = quadratic + (periodogram[:, None, None, :] / shape) @ weights
    return log_det, quadratic


def _expected(
    likelihood: ResidualLikelihood, block: ResidualBlock, lags: int, *noise: np.ndarray
) -> np.ndarray:
    """Expected periodogram of a block's residual at rows (width, sigma_c, sensor sd, alpha).

    On the rfft frequencies of ``lags`` points, each (B, lags // 2 + 1).
    """
    acov = MEASUREMENT_MODELS[block.measurement].autocovariance(
        get_family(likelihood.family),
        *noise,
        block.dt,
        lags,
        sensor=likelihood.sensor,
        samples=block.samples,
        clock=block.clock,
    )
    return expected_periodogram(acov, block.n)


def _binned_periodogram(block: ResidualBlock, points: int) -> tuple[np.ndarray, np.ndarray]:
    """The block's cross-periodogram averaged onto the rfft frequencies of ``points`` points.

    Each of the n Fourier frequencies goes to the nearest of the coarse
    ones, weighted by its multiplicity; with points = n that is the
    periodogram itself.

    Returns
    -------
    periodogram : ndarray, shape (points // 2 + 1, K^2)
        Weighted mean over each coarse frequency's bin.
    weights : ndarray, shape (points // 2 + 1,)
        Multiplicity of each bin among the n Fourier frequencies.
    """
    multiplicity, bins = _frequency_bins(block.n, points)
    if points == block.n:  # the periodogram itself
        return block.periodogram, multiplicity
    return _bin(block.periodogram.T, multiplicity, bins).T, np.bincount(bins, multiplicity)


def series_profile(
    likelihood: SeriesLikelihood, low: np.ndarray, high: np.ndarray, *, starts: int
) -> tuple[np.ndarray, np.ndarray]:
    """The best local maxima of a noise series' Whittle likelihood profiled over its sds.

    The debiased Whittle likelihood of the centred series (the mean's
    frequency 0 left out, as the exact likelihood integrates the mean out:
    n - 1 frequencies), profiled over sigma_c as in :func:`profile_starts`:
    with rho = sigma_n / sigma_c the expected periodogram is sigma_c^2
    (E_R(width) + rho^2), E_R the debiased periodogram of the kernel's
    autocorrelation at every lag of the series, so sigma_c^2 = Q / (n - 1)
    (kept inside the box). On :data:`SERIES_WIDTHS` widths by
    :data:`SERIES_RATIOS` ratios; the local maxima of the profile along the
    width (the best rho at each width) are the candidates, the ``starts``
    best of them refined by :data:`ZOOMS` 5 x 5 grids of half the previous
    spacing. Past :data:`PROFILE_FREQUENCIES` samples the periodogram and
    E_R are averaged onto that many frequencies. White noise has one
    point: its sd.

    Parameters
    ----------
    likelihood : SeriesLikelihood
    low, high : ndarray, shape (k,)
        Prior box in natural units, ordered as ``likelihood.names``.
    starts : int
        Most points returned.

    Returns
    -------
    theta : ndarray, shape (S, k), S <= starts
        The candidates, best first, in natural units inside the box.
    profile : ndarray, shape (S,)
        Their Whittle log-likelihoods, up to a constant [nats] (-inf where
        the box allows no sd).

    Examples
    --------
    A moving-average series of duration 8 samples over a white floor: the
    best candidate is the truth, and the next sits in the local optimum
    near half of it.

    >>> import numpy as np
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.inference import series_profile
    >>> from bayes_jackal.likelihood import SeriesLikelihood
    >>> rng = np.random.default_rng(1)
    >>> values = get_family("moving-average").noise(0.08, 0.01, 2000, rng=rng)
    >>> values += 0.3 * rng.standard_normal(2000)
    >>> likelihood = SeriesLikelihood(values=values, dt=0.01, family="moving-average")
    >>> low, high = np.array([0.0025, 1e-3, 1e-3]), np.array([2.0, 10.0, 10.0])
    >>> theta, profile = series_profile(likelihood, low, high, starts=4)
    >>> [round(float(w / 0.01), 1) for w in theta[:2, 0]]
    [8.0, 4.3]
    >>> bool(np.all(np.diff(profile) <= 0))
    True
    """
    low, high = np.asarray(low, float), np.asarray(high, float)
    family = get_family(likelihood.family)
    n = likelihood.n
    points = min(n, PROFILE_FREQUENCIES)
    multiplicity, bins = _frequency_bins(n, points)
    multiplicity[0] = 0.0  # the mean's: the likelihood integrates it out
    weights = np.bincount(bins, multiplicity)
    periodogram = np.abs(scipy.fft.rfft(likelihood.values - likelihood.centre)) ** 2 / n
    periodogram = _bin(periodogram[None], multiplicity, bins)[0]
    count = n - 1
    names = likelihood.names
    if not family.has_width:
        quadratic = periodogram @ weights
        variance = np.clip(quadratic / count, low[0] ** 2, high[0] ** 2)
        loglike = -0.5 * (count * np.log(variance) + quadratic / variance)
        return np.sqrt(variance)[None, None], np.array([loglike])
    c_bounds = low[names.index("sigma_c")], high[names.index("sigma_c")]
    n_bounds = low[names.index("sigma_n")], high[names.index("sigma_n")]
    ranges = np.log([[low[0], high[0]], [n_bounds[0] / c_bounds[1], n_bounds[1] / c_bounds[0]]])

    def shapes(widths: np.ndarray) -> np.ndarray:
        """E_R of each width on the profile's frequencies, shape (W, F)."""
        out = np.empty((len(widths), len(weights)))
        for rows in np.array_split(np.arange(len(widths)), -(-len(widths) * n // _MAX_ELEMENTS)):
            expected = expected_periodogram(
                family.autocorrelation(widths[rows], likelihood.dt, n), n
            )
            out[rows] = _bin(expected, multiplicity, bins)
        return out

    def grid(kernel: np.ndarray, log_ratios: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Profile log-likelihood and sigma_c^2 at kernels (..., F) x ratios (..., R)."""
        ratios = np.exp(log_ratios)
        shape = kernel[..., None, :] + ratios[..., None] ** 2
        with np.errstate(invalid="ignore", divide="ignore"):
            log_det = np.log(shape) @ weights
            quadratic = (periodogram / shape) @ weights
        c_low = np.maximum(c_bounds[0], n_bounds[0] / ratios)
        c_high = np.minimum(c_bounds[1], n_bounds[1] / ratios)
        variance = np.clip(quadratic / count, c_low**2, c_high**2)
        with np.errstate(invalid="ignore", divide="ignore"):
            loglike = -0.5 * (count * np.log(variance) + log_det + quadratic / variance)
        valid = np.isfinite(loglike) & (c_low <= c_high)
        return np.where(valid, loglike, -np.inf), variance

    log_widths = np.linspace(*ranges[0], SERIES_WIDTHS)
    log_ratios = np.linspace(*ranges[1], SERIES_RATIOS)
    loglike, _ = grid(shapes(np.exp(log_widths)), log_ratios)
    curve = loglike.max(axis=1)
    # Local maxima along the width; of a plateau (e.g. sigma_c at its floor), its narrowest.
    padded = np.concatenate([[-np.inf], curve, [-np.inf]])
    peaks = np.flatnonzero((curve > padded[:-2]) & (curve >= padded[2:]) & np.isfinite(curve))
    if not len(peaks):
        peaks = np.array([0])
    peaks = peaks[np.argsort(-curve[peaks], kind="stable")][:starts]
    centre = np.column_stack([log_widths[peaks], log_ratios[np.argmax(loglike[peaks], axis=1)]])
    steps = np.ptp(ranges, axis=1) / (np.array([SERIES_WIDTHS, SERIES_RATIOS]) - 1)
    offsets = np.arange(-2, 3)
    for zoom in range(1, ZOOMS + 1):
        axes = [
            np.clip(centre[:, [i]] + offsets * steps[i] / 2**zoom, *ranges[i]) for i in range(2)
        ]
        kernel = shapes(np.exp(axes[0]).ravel()).reshape(len(peaks), len(offsets), -1)
        loglike, variance = grid(kernel, axes[1][:, None, :])
        flat = loglike.reshape(len(peaks), -1)
        best = np.unravel_index(np.argmax(flat, axis=1), loglike.shape[1:])
        rows = np.arange(len(peaks))
        centre = np.column_stack([axes[0][rows, best[0]], axes[1][rows, best[1]]])
        top, sigma_c = flat[rows, np.argmax(flat, axis=1)], np.sqrt(variance[(rows, *best)])
    order = np.argsort(-top, kind="stable")
    width, ratio = np.exp(centre[order]).T
    theta = np.column_stack([width, sigma_c[order], ratio * sigma_c[order]])
    return np.clip(theta, low, high), top[order]


def _frequency_bins(n: int, points: int) -> tuple[np.ndarray, np.ndarray]:
    """Each of a series' n // 2 + 1 rfft frequencies' multiplicity and bin.

    The bins are the nearest of the rfft frequencies of ``points`` points
    (each its own where points = n).
    """
    return frequency_weights(n), np.rint(np.arange(n // 2 + 1) * points / n).astype(int)


def _bin(values: np.ndarray, multiplicity: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """Rows of values at the rfft frequencies averaged over each bin, weighted by multiplicity.

    One bincount over every row (each row's bins offset by its index): the
    sums of a row's bin add in the same order as a bincount of that row.
    """
    size = bins[-1] + 1
    if size == len(bins):  # a bin per frequency
        return values
    offsets = size * np.arange(len(values))[:, None]
    sums = np.bincount(
        (bins + offsets).ravel(), (multiplicity * values).ravel(), size * len(values)
    )
    weights = np.bincount(bins, multiplicity, size)
    return sums.reshape(len(values), size) / np.where(weights > 0, weights, 1.0)
