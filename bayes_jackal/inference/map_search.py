"""The start of the chain: the maximum a posteriori point and the walkers around it.

The MAP search starts from the likelihood profiled over each noise group
(:mod:`bayes_jackal.inference.starts`), climbs with bounded quasi-Newton
searches and line scans of the kernel widths, and the walkers are drawn from
the Laplace approximation at the MAP, or, where the posterior is not that
shape, from its moments or a mixture along its ridge (:func:`ridge_mixture`).
The priors and the log-posterior live in :mod:`bayes_jackal.likelihood.priors`, the
sampler in :mod:`bayes_jackal.inference.sampling`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import scipy.optimize
from scipy.special import logsumexp

from .._runtime import InputError, one_blas_thread
from ..likelihood import LogPosterior, Prior
from ._lockstep import lockstep_maxima, negative_with_gradient
from .moves import (
    JOINT_SHARE,
    MIN_MATCHED_EFFICIENCY,
    MIN_PROPOSAL_EFFICIENCY,
    Approximation,
    BlockT,
    BoundedLaplace,
    GroupGrid,
    IndependenceMove,
    LaplaceApproximation,
    MixtureApproximation,
    Start,
    as_laplace,
    as_mixture,
    joint_efficiency,
    moment_matched,
    proposal_efficiency,
)
from .starts import profile_starts

__all__ = [
    "block_proposals",
    "climb",
    "find_map",
    "laplace_walkers",
    "ridge_mixture",
    "scan_posterior",
]


#: Local searches of :func:`find_map`, from the best points of the profile.
_MAP_STARTS = 4
#: Points of a kernel width's coarse sweep over its prior range (log width).
SWEEP_POINTS = 64
#: Points of its refinement around the coarse best.
SWEEP_REFINE = 32
#: How much higher [nats] a start's sweep must find the posterior for the
#: unswept start to be dropped. On a 10-minute step sequence the profile's
#: yaw width sat at the prior's 1 s and the sweep gained 21,000-47,000 nats,
#: and the unswept searches ended within 1 nat of the swept ones after 45-73
#: costly evaluations; on motion-capture bags with dropouts the sweeps gained
#: 0.2-0.6 nats and two unswept searches found the best maximum, 22 nats
#: above every swept one.
SWEEP_GAIN = 10.0
#: Cells of a noise group's grid of its width (:func:`block_proposals`).
GRID_POINTS = 64
#: How far below the best cell [nats] the refined grid of a block still reaches.
GRID_DEPTH = 20.0
#: The most quadratics fitted to find the conditional mode of a group's other
#: parameters in each cell of its width; the most each moves it, and the step
#: below which a cell stops, in guessed sd. From the regression at the MAP the
#: mode at the width's prior floor was ~30 sd away (lidar poses at 5 Hz):
#: steps of 3 sd left those cells short, and walkers stuck there for
#: hundreds of steps.
CONDITIONAL_ITERATIONS = 12
CONDITIONAL_STEP = 10.0
CONDITIONAL_TOLERANCE = 0.05
#: Cells of the grid along a curved posterior's widest parameter (:func:`ridge_mixture`).
RIDGE_CELLS = 16
#: How far below the highest cell's conditional maximum [nats] a cell still gets a component.
RIDGE_DEPTH = 30.0
#: How close to a bound, in units of the prior's range, a MAP's column is on it
#: (:func:`laplace_walkers` expands the log-posterior that far inside).
BOUND_DISTANCE = 1e-3


def damping_design(design_points: int) -> int:
    """Damping points of :func:`find_map`'s profile: ``design_points / 16``, at least 16."""
    return max(16, design_points // 16)


@one_blas_thread()
def find_map(
    log_posterior: LogPosterior,
    rng: np.random.Generator,
    design_points: int = 1024,
    starts: np.ndarray | None = None,
) -> np.ndarray:
    """Maximum a posteriori point in sampling coordinates.

    The likelihood is a sum over noise groups, each depending on the damping
    and its own noise only, so its profile over each group's noise on a
    design over the damping (:func:`bayes_jackal.inference.profile_starts`,
    ``design_points / 16`` damping points) finds the basin where every
    channel's noise is right at once, which a design over the whole prior
    box does not. Its best points start the local searches and width
    sweeps of :func:`climb`. Given ``starts`` (a warm start: points of a
    posterior known to be close, e.g. the pooled one's best draws for a run
    left out), the searches start there instead, and the profile is skipped.

    Parameters
    ----------
    log_posterior : LogPosterior
    rng : numpy.random.Generator
        Scrambles the damping design: same seed, same result.
    design_points : int
        Sixteen times the size of the damping design (at least 16 points).
    starts : ndarray, shape (S, P), optional
        Parameter values theta the local searches start from (warm).

    Returns
    -------
    ndarray, shape (P,)
        z = log(theta) of the MAP.

    Raises
    ------
    InputError
        When the log-posterior is -inf at every start.

    Examples
    --------
    A simulated run (truth d_lat = 110, d_long = 30 N s/m, sigma_h =
    0.047 s) on the yaw and vx channels; about a second:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.inference import find_map
    >>> from bayes_jackal.likelihood import LogPosterior, Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, channels=("yaw", "vx"))
    >>> log_posterior = LogPosterior(likelihood, Prior.for_likelihood(likelihood, robot))
    >>> z = find_map(log_posterior, np.random.default_rng(1), design_points=64)
    >>> [f"{name} {value:.3g}" for name, value in zip(likelihood.parameter_names[:3], np.exp(z))]
    ['d_lat 112', 'd_long 29.8', 'sigma_h[yaw] 0.0473']
    """
    prior = log_posterior.prior
    # Noise far below the data's overflows the likelihood's terms: -inf, checked below.
    with np.errstate(over="ignore", divide="ignore"):
        if starts is None:
            theta, _ = profile_starts(
                log_posterior.likelihood,
                prior.low,
                prior.high,
                damping_points=damping_design(design_points),
                starts=_MAP_STARTS,
                rng=rng,
            )
            where = f"the best {len(theta)} points of the profile likelihood"
        else:
            theta, where = np.atleast_2d(starts), f"the {len(np.atleast_2d(starts))} given"
        z = np.log(theta)
        finite = np.isfinite(log_posterior(z))
    if not finite.any():
        raise InputError(
            f"the log-posterior is -inf at every start of the MAP search ({where}): the "
            "priors exclude every parameter value the data allow",
            field="priors",
        )
    layout = log_posterior.likelihood.layout
    widths = layout.names_of(layout.width_name) if layout.width_name else ()
    return climb(log_posterior, z, widths=widths)


def _best_local(log_posterior: LogPosterior, starts: np.ndarray) -> scipy.optimize.OptimizeResult:
    """The best of L-BFGS-B maximisations within the prior's box from each row of ``starts``.

    The searches run in lockstep (``bayes_jackal.inference._lockstep``):
    each of their rounds is one call of the log-posterior.
    """
    prior = log_posterior.prior
    ends = lockstep_maxima(log_posterior, starts, prior.z_low, prior.z_high)
    return max(ends, key=lambda result: -result.fun)


def scan_posterior(log_posterior: LogPosterior) -> LogPosterior:
    """The MAP search's quick scan of a log-posterior: the spectral engine, the scans' fallback.

    The likelihood's ``fast`` engine with ``fallback=False``: of the sets no
    spectral grid certifies, only those whose banded factor is cheap are
    evaluated (:data:`bayes_jackal.likelihood.SCAN_WORK`); the rest (long
    memory, e.g. a 1 s kernel over 1e-4 sensor noise, each the O(n^2)
    recursion) are -inf. Exact wherever it is finite.

    Parameters
    ----------
    log_posterior : LogPosterior
        Over a likelihood with ``engine`` and ``fallback`` fields.

    Returns
    -------
    LogPosterior

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.inference import scan_posterior
    >>> from bayes_jackal.likelihood import LogPosterior, Prior
    >>> from bayes_jackal.likelihood import SeriesLikelihood
    >>> values = np.random.default_rng(1).standard_normal(200)
    >>> likelihood = SeriesLikelihood(values=values, dt=0.01, family="exponential",
    ...                               engine="exact")
    >>> prior = Prior(likelihood.names, np.full(3, 0.001), np.full(3, 10.0), np.ones(3, bool))
    >>> scan = scan_posterior(LogPosterior(likelihood, prior)).likelihood
    >>> scan.engine, scan.fallback
    ('fast', False)
    """
    scan = replace(log_posterior.likelihood, engine="fast", fallback=False)
    return LogPosterior(scan, log_posterior.prior)


@one_blas_thread()
def climb(
    log_posterior: LogPosterior, starts: np.ndarray, *, widths: Sequence[str] = ()
) -> np.ndarray:
    """The best maximum reached from ``starts``, its kernel widths swept out of local optima.

    Bounded quasi-Newton (L-BFGS-B) searches within the prior's box on the
    quick scan of the posterior (:func:`scan_posterior`), from each start
    and from each start with its kernel widths swept (:func:`_sweep_widths`:
    a start's width can lie where its likelihood is far from the profile's,
    e.g. the Whittle profile's widest width for a triangular kernel, from
    which a local search ends in a corner of the prior; a start whose sweep
    gains more than :data:`SWEEP_GAIN` is searched from its swept point
    only). The searches run in lockstep, one evaluation per round. Sweeps then move
    the best end point out of a local optimum's basin and a search starts
    again from there, at most three times. With another engine than
    ``fast`` the result is polished on ``log_posterior`` itself; with
    ``fast`` the scan is ``log_posterior`` wherever it is finite, and a
    polish would only spend the exact time-domain fallback on the line
    searches' trial points (a second each on a run's pose channels).
    :func:`find_map` climbs from the best points
    of the profile likelihood, a noise series' fit from the best of a
    design over its prior.

    Parameters
    ----------
    log_posterior : LogPosterior
        Over a likelihood with ``engine`` and ``fallback`` fields.
    starts : ndarray, shape (S, k)
        Starts in z = log theta.
    widths : sequence of str
        The names of the kernel widths among the prior's parameters.

    Returns
    -------
    ndarray, shape (k,)
        z of the maximum.

    Examples
    --------
    A moving-average series of 8 samples: its likelihood in the width has
    a local maximum near 5 samples. A search started there stays; the
    sweep finds the best basin (0.2 s).

    >>> import numpy as np
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.inference import climb
    >>> from bayes_jackal.likelihood import LogPosterior, Prior
    >>> from bayes_jackal.likelihood import SeriesLikelihood
    >>> rng = np.random.default_rng(1)
    >>> values = get_family("moving-average").noise(0.08, 0.01, 400, rng=rng)
    >>> values += 0.3 * rng.standard_normal(400)
    >>> likelihood = SeriesLikelihood(values=values, dt=0.01, family="moving-average")
    >>> prior = Prior(likelihood.names, np.array([0.005, 0.01, 0.01]),
    ...               np.array([0.4, 10.0, 10.0]), np.ones(3, bool))
    >>> log_posterior = LogPosterior(likelihood, prior)
    >>> start = np.log([[0.04, 1.0, 0.3]])
    >>> stays = climb(log_posterior, start)  # no width to sweep
    >>> swept = climb(log_posterior, start, widths=[likelihood.width_name])
    >>> [round(float(np.exp(z[0]) / 0.01), 1) for z in (stays, swept)]
    [5.2, 8.0]
    """
    prior = log_posterior.prior
    scan = scan_posterior(log_posterior)
    columns = [column for column, name in enumerate(prior.names) if name in widths]
    starts = np.atleast_2d(starts)
    swept, gains = _sweep_widths(scan, starts, prior, columns)
    moved = np.any(swept != starts, axis=1)
    # A start whose sweep gained more than SWEEP_GAIN sits at a width the data
    # reject; its search would retrace the swept start's, at the price of the
    # long kernels it passes through.
    kept = ~(gains > SWEEP_GAIN)
    best = _best_local(scan, np.vstack([starts[kept], swept[moved]]))
    for _ in range(3):
        swept, _ = _sweep_widths(scan, best.x[None], prior, columns)
        if np.array_equal(swept[0], best.x):
            break
        best = _best_local(scan, swept)
    if log_posterior.likelihood.engine == "fast":
        return best.x
    polished = _best_local(log_posterior, best.x[None])
    return polished.x if np.isfinite(polished.fun) else best.x


def _sweep_widths(
    function: LogPosterior,
    z: np.ndarray,
    prior: Prior,
    width_columns: Sequence[int],
) -> tuple[np.ndarray, np.ndarray]:
    """Move each kernel width to the best of a grid over its prior range, the rest held.

    A kernel width can have separated optima: the moving-average family's
    likelihood in its width has local maxima at about half and 1.5 times
    the best width, hundreds of nats lower, and a local search started in
    their basins stays there. A line scan of each width finds the best
    basin: :data:`SWEEP_POINTS` over the prior's range of log width, then
    :data:`SWEEP_REFINE` within two of their steps of the best (a quarter
    of the evaluations of one fine grid, most of them saved at the wide
    widths, whose long predictors cost the most). The rows of ``z`` (S, P)
    are swept together, one call per line.

    Returns the swept points (S, P) and how much higher [nats] the function
    is at each than at its row of ``z`` (inf where it is -inf at ``z`` only,
    0 where nothing moved).
    """
    gains = np.zeros(len(z))
    for column in width_columns:
        low, high = prior.z_low[column], prior.z_high[column]
        coarse = np.linspace(low, high, SWEEP_POINTS)
        z, coarse_gains = _best_on_lines(function, z, column, coarse[None])
        reach = 2 * (coarse[1] - coarse[0])
        fine = np.linspace(
            np.maximum(low, z[:, column] - reach), np.minimum(high, z[:, column] + reach),
            SWEEP_REFINE, axis=1,
        )  # fmt: skip
        z, fine_gains = _best_on_lines(function, z, column, fine)
        gains += coarse_gains + fine_gains
    return z, gains


def _best_on_lines(
    function: LogPosterior, z: np.ndarray, column: int, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The best of each row of ``z`` (S, P) and it with ``column`` set to each of its
    ``values`` (S or 1, V), from one call; and the gains [nats]."""
    count, size = len(z), values.shape[1] + 1
    candidates = np.repeat(z[:, None], size, axis=1)
    candidates[:, 1:, column] = values
    scores = function(candidates.reshape(-1, z.shape[1])).reshape(count, size)
    best = np.argmax(scores, axis=1)
    rows = np.arange(count)
    top, start = scores[rows, best], scores[:, 0]
    with np.errstate(invalid="ignore"):  # -inf - -inf where nothing moved: gain 0 below
        gains = np.where(np.isfinite(start), top - start, np.inf)
    return candidates[rows, best], np.where(best == 0, 0.0, gains)


def laplace_walkers(
    log_posterior: LogPosterior, centre: np.ndarray, walkers: int, rng: np.random.Generator
) -> Start:
    """Walkers from the Laplace approximation at ``centre``, kept inside the prior.

    The approximation goes with them, for the chain's independence moves
    (:mod:`bayes_jackal.inference.moves`), where importance sampling from their
    proposal is efficient enough
    (:func:`~bayes_jackal.inference.proposal_efficiency`). Where it is not
    (a MAP on the prior's boundary: the damping ridge or a kernel width can
    run into it; a Hessian that is not positive definite, regularised to
    at most a quarter of each prior range), the approximation is moved to
    the posterior's mean and covariance by importance sampling
    (:func:`~bayes_jackal.inference.moment_matched`). Where no single t fits (a
    curved ridge: the damping's scale unidentified, the noise bending along
    it), the approximation is a mixture along the ridge
    (:func:`ridge_mixture`); block moves (:func:`block_proposals`) go beside
    either, at the approximation's mean and covariance. Where the MAP is
    on bounds of the prior, with the log-posterior rising towards them
    (a family that does not fit), the approximation is the expansion's
    tail inside them (:class:`~bayes_jackal.inference.BoundedLaplace`),
    tried last so that the other starts' chains stay as they were. Where
    that fails too, the walkers start in a small ball, and the chain moves by
    differential evolution, and by block moves at the Hessian's approximation
    where there is one.

    Examples
    --------
    Walkers around a point (here the truth of a simulated run), all inside
    the prior and of finite posterior:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.inference import laplace_walkers
    >>> from bayes_jackal.likelihood import LogPosterior, Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, channels=("yaw",))
    >>> log_posterior = LogPosterior(likelihood, Prior.for_likelihood(likelihood, robot))
    >>> centre = np.log([110.0, 30.0, 0.047, 0.01, 0.005])
    >>> start = laplace_walkers(log_posterior, centre, 12, np.random.default_rng(1))
    >>> start.walkers.shape
    (12, 5)

    Away from the MAP the Hessian is not the posterior's shape: importance
    sampling from it is inefficient, so the approximation is moved to the
    posterior's moments, from which it is efficient (measured 0.48):

    >>> from bayes_jackal.inference import MIN_PROPOSAL_EFFICIENCY, proposal_efficiency
    >>> efficiency = proposal_efficiency(
    ...     log_posterior, start.approximation, np.random.default_rng(2)
    ... )
    >>> bool(efficiency > MIN_PROPOSAL_EFFICIENCY)
    True
    >>> inside = log_posterior.prior.inside(start.walkers)
    >>> bool(inside.all() and np.isfinite(log_posterior(start.walkers)).all())
    True
    """
    prior = log_posterior.prior
    span = prior.z_high - prior.z_low
    step = BOUND_DISTANCE / 10 * span
    peak, centre = centre, np.clip(centre, prior.z_low + 10 * step, prior.z_high - 10 * step)
    gradient, hessian = _derivatives(log_posterior, centre, step)
    approximation, exact = _hessian_approximation(centre, gradient, hessian, span)
    points = None
    if exact:
        points = _walkers_inside(log_posterior, approximation, walkers, rng)
        if points is not None and (
            proposal_efficiency(log_posterior, approximation, rng) >= MIN_PROPOSAL_EFFICIENCY
        ):
            return Start(points, approximation)
    if approximation is not None:  # not the posterior's shape: its moments, by importance sampling
        matched = moment_matched(log_posterior, approximation, rng)
        start = _efficient_start(log_posterior, matched, walkers, rng)
        widest = approximation if matched is None else matched
        axis = _widest_axis(prior, widest.covariance)
        # A curved posterior, which no single t fits: a mixture along its
        # ridge, unless the ridge runs along a noise group's gridded column,
        # which the block moves draw from its conditional over the prior.
        if start is None and axis not in _gridded_columns(log_posterior):
            mixture = ridge_mixture(log_posterior, approximation.centre, widest.covariance)
            start = _efficient_start(log_posterior, mixture, walkers, rng)
        if start is not None:
            return _with_blocks(log_posterior, start)
    # A posterior piled against bounds of the prior: the tail of the expansion there.
    bounded = _bounded_approximation(prior, peak, gradient, hessian)
    start = _efficient_start(log_posterior, bounded, walkers, rng.spawn(1)[0])
    if start is not None:
        return _with_blocks(log_posterior, start)
    if points is None:  # no approximation of the posterior: a small ball
        ball = rng.multivariate_normal(centre, np.diag((1e-3 * span) ** 2), size=8 * walkers)
        points = ball[prior.inside(ball)][:walkers]
    # Differential evolution, and block moves of the damping and of each noise
    # group, a share of them every block at once where their product fits.
    if approximation is None:
        return Start(points, None)
    blocks = block_proposals(log_posterior, approximation)
    fits = bool(blocks) and (
        joint_efficiency(log_posterior, blocks, centre, rng) >= MIN_PROPOSAL_EFFICIENCY
    )
    return Start(points, None, blocks, JOINT_SHARE if fits else 0.0)


def block_proposals(
    log_posterior: LogPosterior, approximation: LaplaceApproximation
) -> tuple[BlockT | GroupGrid, ...]:
    """Proposals of the damping's block and of each noise group's (:class:`GroupMove`).

    The damping's (with the speed ratios and a width every group shares) is
    a t around its conditional Laplace approximation (the inverse of its
    block of the approximation's precision). Each noise group's is its
    joint conditional posterior at the centre: the width (sigma_c where
    the group has none) on a grid of :data:`GRID_POINTS` cells over the
    prior's box in z, and given each cell the others (sigma_c, which bends
    with the width along a banana, and the sensor sd, which moves with
    both) a t around their conditional mode there (:class:`GroupGrid`);
    or the group's conditional t where the grid's mass is in one cell.
    Measured on a 10-minute DRIVE-like step sequence (yaw at 20 Hz, lidar
    poses at 5 Hz, whose widths spread over two decades): 800 steps (tau
    10-16), where a grid of (width, sigma_c) at the sensor sd's centre, the
    sd drawn from its own t, took 6,300 (tau 114-124 in the vx channel: its
    sd moves with the others, correlation 0.5-0.6).

    Examples
    --------
    The yaw rate of a simulated run, around its truth: the damping's block,
    and the grid of the width with sigma_c and the sensor sd given it,
    which the 38 s run leaves spread along a curve at that narrow a
    covariance:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.inference import LaplaceApproximation, block_proposals
    >>> from bayes_jackal.likelihood import LogPosterior, Prior, ResidualLikelihood
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, channels=("yaw",))
    >>> log_posterior = LogPosterior(likelihood, Prior.for_likelihood(likelihood, robot))
    >>> z = np.log([110.0, 30.0, 0.047, 0.01, 0.005])
    >>> blocks = block_proposals(log_posterior, LaplaceApproximation(z, 1e-4 * np.eye(5)))
    >>> [(type(block).__name__, block.block_columns.tolist()) for block in blocks]
    [('BlockT', [0, 1]), ('GroupGrid', [2, 3, 4])]
    """
    layout = getattr(log_posterior.likelihood, "layout", None)
    if layout is None:  # a likelihood of other parameters than the package's: no blocks known
        return ()
    centre, precision = approximation.centre, np.linalg.inv(approximation.covariance)

    def conditional(columns: np.ndarray) -> BlockT:
        covariance = np.linalg.inv(precision[np.ix_(columns, columns)])
        return BlockT(columns, centre[columns], covariance)

    shared = layout.damping_bases + layout.shared_bases
    blocks: list[BlockT | GroupGrid] = [conditional(np.array([layout.column(b) for b in shared]))]
    for group, columns in _group_columns(layout):
        # The width (sigma_c where the group has none) gridded, the others
        # given it; the group's joint t where the grid's mass is in one cell.
        grid = _grid(log_posterior, group, approximation, columns[:1], columns[1:])
        if grid is None or np.max(grid.log_probability) > np.log(0.5):
            blocks.append(conditional(columns))
        else:
            blocks.append(grid)
    return tuple(blocks)


def _grid(
    log_posterior: LogPosterior,
    group: int,
    approximation: LaplaceApproximation,
    columns: np.ndarray,
    given: np.ndarray,
) -> GroupGrid | None:
    """The grid of noise group ``group``'s conditional posterior at the centre (None: none finite).

    ``columns`` (one) is gridded, :data:`GRID_POINTS` cells, twice: over
    the prior's box, then over the cells within :data:`GRID_DEPTH` nats
    of the best (and a cell and a half more on each side), where the
    conditional's mass is; the uniform part of the proposal keeps the
    prior's box. The columns ``given`` are not: in each cell they are at
    their conditional mode (:func:`_conditional_modes`, from the
    regression at the centre), and the cell's probability is the
    conditional's there times the root of its covariance's determinant
    (the Laplace approximation of the integral over them). The conditional
    is that of the group's terms alone (:meth:`~bayes_jackal.likelihood.LogPosterior.group_terms`).
    """
    prior, centre = log_posterior.prior, approximation.centre

    def terms(z: np.ndarray) -> np.ndarray:
        return log_posterior.group_terms(z, group)

    box_low, box_high = prior.z_low[columns], prior.z_high[columns]
    low, high, grid = box_low, box_high, None
    # The given columns' regression on the gridded one, and their conditional
    # covariance, at the centre: the first guess in every cell.
    precision = np.linalg.inv(approximation.covariance)
    covariance = np.linalg.inv(precision[np.ix_(given, given)])
    slope = -covariance @ precision[np.ix_(given, columns)]
    for _ in range(2):
        cell = (high - low) / GRID_POINTS
        cells = low + cell * (np.arange(GRID_POINTS)[:, None] + 0.5)
        candidates = np.repeat(centre[None], GRID_POINTS, axis=0)
        candidates[:, columns] = cells
        candidates[:, given] = centre[given] + (cells - centre[columns]) @ slope.T
        modes = {}
        if len(given):
            mean, spread, values = _conditional_modes(terms, candidates, given, covariance)
            modes = {
                "conditional_columns": given,
                "conditional_mean": mean,
                "conditional_covariance": spread,
            }
            values = values + 0.5 * np.linalg.slogdet(spread)[1]
        else:
            values = terms(candidates)
        if not np.isfinite(values).any():
            return grid
        grid = GroupGrid(
            columns, low, high, values - logsumexp(values), GRID_POINTS, box_low, box_high, **modes
        )
        kept = cells[values >= np.max(values) - GRID_DEPTH]
        low = np.maximum(kept.min(axis=0) - 1.5 * cell, box_low)
        high = np.minimum(kept.max(axis=0) + 1.5 * cell, box_high)
    return grid


def _conditional_modes(
    function: Callable[[np.ndarray], np.ndarray],
    candidates: np.ndarray,
    columns: np.ndarray,
    covariance: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mode and covariance of ``columns``' conditional at each row of ``candidates``.

    A quadratic through ``function`` at the row's values of ``columns`` (the
    guessed mode) and one guessed sd from it along each column and each
    pair of columns (1 + 2e + e (e - 1) / 2 points, 6 for two columns:
    exact for a quadratic),
    each around the last one's mode (its step at most
    :data:`CONDITIONAL_STEP` guessed sd), until the step is below
    :data:`CONDITIONAL_TOLERANCE` sd or after :data:`CONDITIONAL_ITERATIONS`
    (:func:`_quadratic_step`).

    Parameters
    ----------
    function : callable
        The log-density, vectorised over rows.
    candidates : ndarray, shape (n, k)
    columns : ndarray of int, shape (e,)
    covariance : ndarray, shape (e, e)
        The first guess of every row's covariance.

    Returns
    -------
    mean : ndarray, shape (n, e)
    covariance : ndarray, shape (n, e, e)
    peak : ndarray, shape (n,)
        ``function`` at the mode (the quadratic's maximum).
    """
    n, e = len(candidates), len(columns)
    mean = candidates[:, columns]
    covariance = np.broadcast_to(covariance, (n, e, e)).copy()
    peak = np.full(n, -np.inf)
    active = np.arange(n)
    for _ in range(CONDITIONAL_ITERATIONS):
        step, fitted, peak[active] = _quadratic_step(
            function, candidates[active], columns, mean[active], covariance[active]
        )
        sd = np.sqrt(np.diagonal(covariance[active], axis1=1, axis2=2))
        mean[active] += step * sd
        covariance[active] = fitted
        active = active[np.linalg.norm(step, axis=1) > CONDITIONAL_TOLERANCE]
        if not len(active):
            break
    return mean, covariance, peak


def _quadratic_step(
    function: Callable[[np.ndarray], np.ndarray],
    candidates: np.ndarray,
    columns: np.ndarray,
    mean: np.ndarray,
    covariance: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of :func:`_conditional_modes`: to the quadratic's maximum, in guessed sd.

    Returns the step (n, e), the quadratic's covariance (the guess where it
    is not concave) and its maximum (the value at ``mean`` there). Where the
    values are finite but not concave (the conditional's convex tail), the
    step is :data:`CONDITIONAL_STEP` along the gradient; where they are not
    finite, 0.
    """
    n, e = mean.shape
    # The points, in guessed sd: the mode, -1 and +1 along each column, +1 along each pair.
    unit = np.eye(e)
    cross = [(i, j) for i in range(e) for j in range(i + 1, e)]
    pairs = np.array([unit[i] + unit[j] for i, j in cross]).reshape(-1, e)
    offsets = np.concatenate([np.zeros((1, e)), -unit, unit, pairs])
    sd = np.sqrt(np.diagonal(covariance, axis1=1, axis2=2))  # (n, e)
    points = np.repeat(candidates, len(offsets), axis=0)
    points[:, columns] = (mean[:, None, :] + sd[:, None, :] * offsets).reshape(-1, e)
    values = function(points).reshape(n, len(offsets))
    middle, minus, plus = values[:, 0], values[:, 1 : 1 + e], values[:, 1 + e : 1 + 2 * e]
    with np.errstate(invalid="ignore"):  # -inf - -inf where a value is outside: not finite
        gradient = (plus - minus) / 2
        hessian = np.zeros((n, e, e))
        hessian[:, range(e), range(e)] = plus - 2 * middle[:, None] + minus
        for k, (i, j) in enumerate(cross):
            hessian[:, i, j] = hessian[:, j, i] = (
                values[:, 1 + 2 * e + k] - plus[:, i] - plus[:, j] + middle
            )
    finite = np.all(np.isfinite(values), axis=1)
    gradient = np.where(finite[:, None], gradient, 0.0)
    hessian = np.where(finite[:, None, None], hessian, -np.eye(e))
    concave = finite & np.all(np.linalg.eigvalsh(hessian) < 0, axis=1)
    hessian = np.where(concave[:, None, None], hessian, -np.eye(e))
    newton = np.linalg.solve(-hessian, gradient[..., None])[..., 0]
    # Uphill (a zero gradient, or values not finite: no step), at most CONDITIONAL_STEP sd.
    step = np.where(concave[:, None], newton, CONDITIONAL_STEP * gradient)
    length = np.linalg.norm(step, axis=1, keepdims=True)
    step = step * np.minimum(1.0, CONDITIONAL_STEP / np.maximum(length, 1e-300))
    rise = np.sum(step * gradient, 1) + 0.5 * np.einsum("ni,nij,nj->n", step, hessian, step)
    peak = middle + np.where(concave, rise, 0.0)
    fitted = sd[:, :, None] * np.linalg.inv(-hessian) * sd[:, None, :]
    return step, np.where(concave[:, None, None], fitted, covariance), peak


def _derivatives(
    log_posterior: LogPosterior, centre: np.ndarray, step: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference gradient and Hessian at ``centre``, one vectorised call over the stencil.

    The gradient comes from the Hessian's diagonal points, ``centre`` +- 2 ``step``.
    """
    ndim = len(centre)
    rows, cols = np.triu_indices(ndim)
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]])
    offsets = np.zeros((len(rows), 4, ndim))
    pairs = np.arange(len(rows))[:, None]
    offsets[pairs, np.arange(4), rows[:, None]] += signs[:, 0] * step[rows][:, None]
    offsets[pairs, np.arange(4), cols[:, None]] += signs[:, 1] * step[cols][:, None]
    values = log_posterior(centre + offsets.reshape(-1, ndim)).reshape(-1, 4)
    hessian = np.zeros((ndim, ndim))
    hessian[rows, cols] = values @ np.array([1, -1, -1, 1]) / (4 * step[rows] * step[cols])
    hessian[cols, rows] = hessian[rows, cols]
    diagonal = values[rows == cols]
    return (diagonal[:, 0] - diagonal[:, 3]) / (4 * step), hessian


def _hessian_approximation(
    centre: np.ndarray, gradient: np.ndarray, hessian: np.ndarray, span: np.ndarray
) -> tuple[LaplaceApproximation | None, bool]:
    """The Laplace approximation at ``centre``, and whether it is exact (not regularised).

    Where the negative Hessian is not positive definite, or has a direction
    wider than a quarter of the prior (a MAP on the prior's boundary, a
    direction the likelihood does not see), each of its
    eigenvalues, in units of a quarter of each prior range, is raised to
    the squared gradient along its direction (the log-density of an
    exponential tail of scale 1 / |g| falls by |g| per unit), and to at
    least 1: no direction wider than a quarter of the prior. None where
    they are not finite.
    """
    if not (np.all(np.isfinite(hessian)) and np.all(np.isfinite(gradient))):
        return None, False
    if np.all(np.linalg.eigvalsh(-hessian * np.outer(span, span) / 16.0) >= 1.0):
        try:
            covariance = np.linalg.inv(-hessian)
            np.linalg.cholesky(covariance)
            return LaplaceApproximation(centre, covariance), True
        except np.linalg.LinAlgError:
            pass
    return LaplaceApproximation(centre, _bounded_covariance(gradient, hessian, span)), False


def _bounded_covariance(gradient: np.ndarray, hessian: np.ndarray, span: np.ndarray) -> np.ndarray:
    """The inverse negative Hessian, each eigenvalue raised to the squared slope along it and to 1.

    In units of a quarter of each prior range (``span``): a direction in
    which the log-density falls by |g| per unit is an exponential tail of
    scale 1 / |g| (a parameter piled against its bound), whatever the
    curvature says; none is wider than a quarter of the prior.
    """
    quarter = np.outer(span, span) / 16.0
    values, vectors = np.linalg.eigh(-hessian * quarter)
    slopes = (gradient * np.sqrt(np.diag(quarter))) @ vectors
    values = np.maximum(np.maximum(values, slopes**2), 1.0)
    return (vectors / values) @ vectors.T * quarter


def _with_blocks(log_posterior: LogPosterior, start: Start) -> Start:
    """``start`` with block moves beside its approximation, at its mean and covariance,
    for what the approximation spreads over."""
    blocks = block_proposals(log_posterior, as_laplace(start.approximation))
    return Start(start.walkers, start.approximation, blocks)


def _bounded_approximation(
    prior: Prior, centre: np.ndarray, gradient: np.ndarray, hessian: np.ndarray
) -> BoundedLaplace | None:
    """The :class:`~bayes_jackal.inference.BoundedLaplace` of a MAP on bounds of the prior.

    A column is bound where ``centre`` is within :data:`BOUND_DISTANCE` of
    its prior range from a bound and the ``gradient`` (at the clipped
    centre, inside) rises towards it. The expansion is
    g x + x' H x / 2 (x the offset from the clipped centre): given the
    bound columns B, the others I have precision -H_II and mean
    (-H_II)^-1 (g_I + H_IB x_B); integrated out, they leave the bound
    columns the slope g_B + H_BI (-H_II)^-1 g_I and the curvature of the
    Schur complement -(H_BB + H_BI (-H_II)^-1 H_IB), each column's
    diagonal taken alone. None where no column is bound, every one is,
    the others' precision is not positive definite, or a bound column's
    density would not fall inward.
    """
    span = prior.z_high - prior.z_low
    at_low = (centre - prior.z_low <= BOUND_DISTANCE * span) & (gradient < 0)
    at_high = (prior.z_high - centre <= BOUND_DISTANCE * span) & (gradient > 0)
    bound = np.flatnonzero(at_low | at_high)
    interior = np.flatnonzero(~(at_low | at_high))
    if not len(bound) or not len(interior):
        return None
    try:
        conditional = np.linalg.inv(-hessian[np.ix_(interior, interior)])
        np.linalg.cholesky(conditional)
    except np.linalg.LinAlgError:
        return None
    expanded_at = np.clip(
        centre, prior.z_low + BOUND_DISTANCE * span, prior.z_high - BOUND_DISTANCE * span
    )
    coupling = hessian[np.ix_(interior, bound)]
    gains = conditional @ coupling
    signs = np.where(at_low, 1.0, -1.0)[bound]
    edges = np.where(at_low, prior.z_low, prior.z_high)[bound]
    curvature = -(hessian[np.ix_(bound, bound)] + coupling.T @ gains)
    to_edges = edges - expanded_at[bound]
    slopes = signs * (gradient[bound] + gains.T @ gradient[interior] - curvature @ to_edges)
    curvatures = np.maximum(np.diag(curvature), 0.0)
    if not np.all(np.isfinite(slopes)) or np.any((slopes >= 0) & (curvatures == 0)):
        return None
    mode = expanded_at.copy()
    mode[bound] = edges
    mode[interior] += conditional @ (gradient[interior] + coupling @ to_edges)
    return BoundedLaplace(mode, bound, signs, span[bound], slopes, curvatures, gains, conditional)


def _efficient_start(
    log_posterior: LogPosterior,
    approximation: Approximation | None,
    walkers: int,
    rng: np.random.Generator,
) -> Start | None:
    """Walkers from ``approximation`` where importance sampling from it is efficient enough.

    None without an approximation, or below :data:`~bayes_jackal.inference.MIN_MATCHED_EFFICIENCY`.
    """
    try:
        if approximation is None or (
            proposal_efficiency(log_posterior, approximation, rng) < MIN_MATCHED_EFFICIENCY
        ):
            return None
    except np.linalg.LinAlgError:  # a covariance that is not positive definite
        return None
    drawn = _walkers_inside(log_posterior, approximation, walkers, rng)
    return None if drawn is None else Start(drawn, approximation)


def _walkers_inside(
    log_posterior: LogPosterior,
    approximation: Approximation,
    walkers: int,
    rng: np.random.Generator,
) -> np.ndarray | None:
    """``walkers`` draws from half the approximation's width, inside the prior and finite.

    A mixture's draws come from its components by weight. None when fewer
    than ``walkers`` of 8 times as many draws are.
    """
    count = 8 * walkers
    if isinstance(approximation, BoundedLaplace):
        random = np.random.RandomState(int(rng.integers(2**32)))
        points = IndependenceMove(approximation, scale=0.5).draw(count, random)
        return _finite_inside(log_posterior, points, walkers)
    mixture = as_mixture(approximation)
    if len(mixture.weights) == 1:
        points = rng.multivariate_normal(
            mixture.centres[0], 0.25 * mixture.covariances[0], size=count
        )
    else:
        chosen = rng.choice(len(mixture.weights), size=count, p=mixture.weights)
        normal = rng.standard_normal((count, mixture.centres.shape[1]))
        factors = np.linalg.cholesky(mixture.covariances)[chosen]
        points = mixture.centres[chosen] + 0.5 * np.einsum("nij,nj->ni", factors, normal)
    return _finite_inside(log_posterior, points, walkers)


def _finite_inside(
    log_posterior: LogPosterior, points: np.ndarray, walkers: int
) -> np.ndarray | None:
    """The first ``walkers`` of ``points`` inside the prior and finite; None if fewer are."""
    points = points[log_posterior.prior.inside(points)]
    points = points[np.isfinite(log_posterior(points))]
    return points[:walkers] if len(points) >= walkers else None


def ridge_mixture(
    log_posterior: LogPosterior, centre: np.ndarray, covariance: np.ndarray
) -> MixtureApproximation | None:
    """A mixture of Gaussians along the posterior's ridge: its profile over its widest parameter.

    Where the damping's scale is not identified (one channel, short runs
    at a low rate), the posterior is a ridge along it, and the noise
    parameters bend with the scale (a banana). No single Gaussian fits it;
    differential evolution crawls along it (tau of 130 steps on eight 48 s
    runs at 10 Hz, yaw, the Gaussian family: 6,600 steps, 10 times the other
    families' time). The parameter along which ``covariance`` is widest
    (in units of its prior range) is cut into :data:`RIDGE_CELLS` cells;
    in each, the log-posterior is maximised over the other parameters
    (bounded quasi-Newton, started from the neighbouring cell's maximum,
    outwards from the MAP's cell). Each cell within :data:`RIDGE_DEPTH`
    nats of the best gives a component: centred at the cell's maximum, a
    cell's width along the path's tangent, and across it the inverse
    negative Hessian of the other parameters (an exponential tail's scale
    along a direction in which the posterior is piled against its bound),
    weighted by its Laplace mass (the maximum's height and the covariance's
    volume). The independence moves then propose from the mixture
    (:class:`~bayes_jackal.inference.IndependenceMove`).

    Parameters
    ----------
    log_posterior : LogPosterior
    centre : ndarray, shape (k,)
        Where the path starts (the MAP), in z.
    covariance : ndarray, shape (k, k)
        An approximation's covariance (the moments by importance sampling,
        which have spread along the ridge), which picks the widest parameter.

    Returns
    -------
    MixtureApproximation or None
        None where fewer than two cells have a finite maximum.

    Examples
    --------
    A banana in two log-uniform parameters: z2 = 0.5 z1^2 within 0.05, z1
    uniform over [-2, 2]. A Gaussian at z1 = -1.8 (a MAP at the end of the
    ridge) covers none of it; the mixture follows it, and importance
    sampling from it is efficient:

    >>> import numpy as np
    >>> from bayes_jackal.inference import ridge_mixture
    >>> from bayes_jackal.inference import proposal_efficiency
    >>> from bayes_jackal.likelihood import LogPosterior, Prior
    >>> def banana(theta):
    ...     z = np.log(theta)
    ...     return -0.5 * ((z[:, 1] - 0.5 * z[:, 0] ** 2) / 0.05) ** 2
    >>> prior = Prior(("a", "b"), np.exp([-2.0, -1.0]), np.exp([2.0, 3.0]), np.full(2, True))
    >>> log_posterior = LogPosterior(banana, prior)
    >>> mixture = ridge_mixture(log_posterior, np.array([-1.8, 1.62]), np.diag([0.5, 0.01]))
    >>> len(mixture.weights), np.round(mixture.centres[[0, -1]], 2).tolist()
    (16, [[-1.88, 1.76], [1.88, 1.76]])
    >>> bool(proposal_efficiency(log_posterior, mixture, np.random.default_rng(1)) > 0.5)
    True
    """
    prior = log_posterior.prior
    span = prior.z_high - prior.z_low
    axis = _widest_axis(prior, covariance)
    width = span[axis] / RIDGE_CELLS
    cells = prior.z_low[axis] + width * (np.arange(RIDGE_CELLS) + 0.5)
    path, heights = _conditional_maxima(log_posterior, centre, axis, cells)
    finite = np.flatnonzero(np.isfinite(heights))
    if len(finite) < 2:
        return None
    tangents = np.gradient(path[finite], cells[finite], axis=0)
    kept = heights[finite] > np.max(heights[finite]) - RIDGE_DEPTH
    cells_kept = zip(path[finite][kept], tangents[kept], heights[finite][kept], strict=True)
    components = [
        (point, component[0], height + component[1])
        for point, tangent, height in cells_kept
        if (component := _cell_component(log_posterior, point, tangent, axis, width))
    ]
    if not components:
        return None
    log_masses = np.array([log_mass for _, _, log_mass in components])
    weights = np.exp(log_masses - np.max(log_masses))
    used = weights > 1e-12  # a component of no weight would never be drawn
    return MixtureApproximation(
        weights[used] / np.sum(weights[used]),
        np.array([point for point, _, _ in components])[used],
        np.array([covariance for _, covariance, _ in components])[used],
    )


def _widest_axis(prior: Prior, covariance: np.ndarray) -> int:
    """The parameter along which ``covariance`` is widest, in units of the prior's range."""
    span = prior.z_high - prior.z_low
    scaled = covariance / np.outer(span, span)
    return int(np.argmax(np.abs(np.linalg.eigh(scaled)[1][:, -1])))


def _group_columns(layout) -> list[tuple[int, np.ndarray]]:
    """Each noise group with parameters of its own, and their columns (its width first)."""
    columns = [
        (g, np.array([layout.column(base, g) for base in layout.group_bases_of(g)], int))
        for g in range(len(layout.groups))
    ]
    return [(g, c) for g, c in columns if len(c)]


def _gridded_columns(log_posterior: LogPosterior) -> set[int]:
    """The columns :func:`block_proposals` grids: each noise group's first (its width)."""
    layout = getattr(log_posterior.likelihood, "layout", None)
    return set() if layout is None else {int(c[0]) for _, c in _group_columns(layout)}


def _conditional_maxima(
    log_posterior: LogPosterior, centre: np.ndarray, axis: int, cells: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each cell's maximum over the parameters but ``axis`` (fixed at the cell), and its height.

    Each search starts from the neighbouring cell's maximum, outwards from
    the cell nearest ``centre``.
    """
    path = np.repeat(centre[None], len(cells), axis=0)
    path[:, axis] = cells
    heights = np.full(len(cells), -np.inf)
    first = int(np.argmin(np.abs(cells - centre[axis])))
    for index in [*range(first, len(cells)), *range(first - 1, -1, -1)]:
        neighbour = index - 1 if index > first else index + 1 if index < first else index
        start = centre.copy() if index == first else path[neighbour].copy()
        start[axis] = cells[index]
        path[index], heights[index] = _conditional_maximum(log_posterior, start, axis)
    return path, heights


def _conditional_maximum(
    log_posterior: LogPosterior, start: np.ndarray, axis: int
) -> tuple[np.ndarray, float]:
    """The maximum over every parameter but ``axis`` from ``start`` (L-BFGS-B in the prior box)."""
    prior = log_posterior.prior
    others = np.flatnonzero(np.arange(len(start)) != axis)

    def conditional(u: np.ndarray) -> np.ndarray:
        points = np.repeat(start[None], len(u), axis=0)
        points[:, others] = u
        return log_posterior(points)

    low, high = prior.z_low[others], prior.z_high[others]
    with np.errstate(invalid="ignore"):  # differences beside a -inf region, as in _best_local
        result = scipy.optimize.minimize(
            negative_with_gradient(conditional, high), np.clip(start[others], low, high),
            method="L-BFGS-B", jac=True, bounds=list(zip(low, high, strict=True)),
        )  # fmt: skip
    point = start.copy()
    point[others] = result.x
    height = -float(result.fun)
    return point, height if np.isfinite(height) else -np.inf


def _cell_component(
    log_posterior: LogPosterior, point: np.ndarray, tangent: np.ndarray, axis: int, width: float
) -> tuple[np.ndarray, float] | None:
    """A cell's covariance (its width along ``tangent``, the bounded inverse Hessian across)
    and the log-volume of the part across (half the log-determinant).

    None where the derivatives are not finite (the maximum against a region
    where the posterior is -inf) or the covariance is not positive definite.
    """
    prior = log_posterior.prior
    span = prior.z_high - prior.z_low
    step = 1e-4 * span
    inside = np.clip(point, prior.z_low + 10 * step, prior.z_high - 10 * step)
    gradient, hessian = _derivatives(log_posterior, inside, step)
    if not (np.all(np.isfinite(gradient)) and np.all(np.isfinite(hessian))):
        return None
    others = np.flatnonzero(np.arange(len(point)) != axis)
    across = _bounded_covariance(gradient[others], hessian[np.ix_(others, others)], span[others])
    covariance = width**2 * np.outer(tangent, tangent)
    covariance[np.ix_(others, others)] += across
    sign, log_determinant = np.linalg.slogdet(across)
    if sign <= 0 or not np.all(np.isfinite(covariance)):
        return None
    return covariance, 0.5 * float(log_determinant)
