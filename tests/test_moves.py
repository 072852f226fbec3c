"""The independence moves' proposal at a prior bound and on a curved ridge.

A posterior piled against a prior bound (a kernel width at its prior's end,
the damping against its floor) has no Laplace approximation, and a curved
ridge (the damping's scale unidentified, the noise bending along it) no
Gaussian one: the tests here build such targets in closed form and check
that the approximations by importance sampling and along the ridge find
their moments, and that the independence moves, whose proposal is
truncated to the prior, still sample the target.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import emcee
import lab_simulator as lab
import numpy as np
import pytest
import scipy.optimize
import scipy.stats
from scipy.special import logsumexp

from bayes_jackal import load_experiments, load_profile, simulate_experiment
from bayes_jackal.inference import map_search
from bayes_jackal.inference.chains import (
    BufferedHDFBackend,
    _store_approximation,
    _stored_approximation,
)
from bayes_jackal.inference.map_search import (
    _bounded_approximation,
    _conditional_modes,
    find_map,
    laplace_walkers,
)
from bayes_jackal.inference.moves import (
    JOINT_SHARE,
    MIN_MATCHED_EFFICIENCY,
    MIN_PROPOSAL_EFFICIENCY,
    PROPOSAL_DOF,
    SHARED_WEIGHT,
    BlockT,
    BoundedLaplace,
    GroupGrid,
    GroupMove,
    IndependenceMove,
    LaplaceApproximation,
    MixtureApproximation,
    as_laplace,
    ensemble_moves,
    joint_efficiency,
    moment_matched,
    proposal_efficiency,
)
from bayes_jackal.likelihood import ResidualLikelihood
from bayes_jackal.likelihood.priors import LogPosterior, Prior
from bayes_jackal.workflow import demo_folder


@dataclass(frozen=True)
class ClosedForm:
    """A log-likelihood of theta (natural units) given in closed form of z = log theta."""

    slope: float  # d loglike / d z[0]: an exponential tail against z[0]'s upper bound
    scale: float  # sd of z[1] around 0 (a Gaussian, inside the prior)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        z = np.log(np.atleast_2d(theta))
        return self.slope * z[:, 0] - 0.5 * (z[:, 1] / self.scale) ** 2


def piled_posterior(slope: float = 20.0, scale: float = 0.3) -> LogPosterior:
    """z[0] piled against its upper bound log(10): exponential, of scale 1 / slope, from it."""
    prior = Prior(("width", "sigma_c"), np.array([0.01, 0.01]), np.array([10.0, 100.0]),
                  np.array([True, True]))  # fmt: skip
    return LogPosterior(ClosedForm(slope, scale), prior)


def test_walkers_at_a_bound_get_the_posterior_moments():
    # Log-uniform priors are flat in z: z[0]'s posterior is log(10) - Exp(20),
    # mean log(10) - 0.05 and sd 0.05 (the prior's other end, 13.8 sd away, is
    # negligible); z[1]'s is N(0, 0.3^2). The Hessian is zero along z[0] at
    # the bound: no Laplace approximation. 4 rounds of 500 draws estimate
    # the moments to a few per cent (ESS ~ 200 a round): 20 % tolerances.
    log_posterior = piled_posterior()
    centre = np.array([np.log(10.0), 0.0])
    start = laplace_walkers(log_posterior, centre, 32, np.random.default_rng(1))
    approximation = start.approximation
    assert approximation is not None
    sd = np.sqrt(np.diag(approximation.covariance))
    assert abs(approximation.centre[0] - (np.log(10.0) - 0.05)) < 0.2 * 0.05
    assert abs(sd[0] - 0.05) < 0.2 * 0.05
    assert abs(sd[1] - 0.3) < 0.2 * 0.3
    assert log_posterior.prior.inside(start.walkers).all()
    efficiency = proposal_efficiency(log_posterior, approximation, np.random.default_rng(2))
    assert efficiency >= MIN_MATCHED_EFFICIENCY


def test_moments_of_a_truncated_correlated_gaussian():
    # N((0.5, 0), [[1, 0.8], [0.8, 1]]) truncated to z0 > 0, from a start
    # at the origin far too wide; reference moments by quadrature on a grid
    # of step 0.01. Monte Carlo error of 4,000 draws a round: ~0.02.
    mean, covariance = np.array([0.5, 0.0]), np.array([[1.0, 0.8], [0.8, 1.0]])
    target = scipy.stats.multivariate_normal(mean, covariance)

    def log_density(z):
        return np.where(z[:, 0] > 0, target.logpdf(z), -np.inf)

    grid = np.stack(np.meshgrid(np.arange(0.005, 6, 0.01), np.arange(-6, 6, 0.01)), -1)
    points = grid.reshape(-1, 2)
    weights = np.exp(log_density(points))
    weights /= weights.sum()
    expected_mean = weights @ points
    expected_cov = (weights[:, None] * (points - expected_mean)).T @ (points - expected_mean)
    start = LaplaceApproximation(np.zeros(2), 9.0 * np.eye(2))
    matched = moment_matched(log_density, start, np.random.default_rng(3), draws=4000)
    assert np.allclose(matched.centre, expected_mean, atol=0.05)
    assert np.allclose(matched.covariance, expected_cov, atol=0.06)


def test_truncated_independence_moves_sample_the_target():
    # Independence moves alone, from a t centred on the bound z0 = 0 of the
    # box [0, 3] x [-3, 3], on N(0, I) restricted to the box: a proposal is
    # outside only if 11 draws in a row were (0.56 of them are: the t's half
    # below 0 and its tails past 3; a share 0.56^11 = 0.0017, under 0.005
    # with 10,000 proposals at 5 sd), and the draws have the truncated normal's mean in z0,
    # scipy's truncnorm(0, 3).mean() = 0.7909; sd of the mean over ~3,000
    # effective draws ~0.011: 0.05 is over 4 sd.
    box = (np.array([0.0, -3.0]), np.array([3.0, 3.0]))

    def log_density(z):
        inside = np.all((z > box[0]) & (z < box[1]), axis=1)
        return np.where(inside, -0.5 * np.sum(z**2, axis=1), -np.inf)

    move = IndependenceMove(LaplaceApproximation(np.zeros(2), np.eye(2)), box=box)
    proposals, _ = move.get_proposal(np.zeros((10_000, 2)), np.random.RandomState(4))
    outside = np.any((proposals <= box[0]) | (proposals >= box[1]), axis=1)
    assert outside.mean() < 0.005
    sampler = emcee.EnsembleSampler(16, 2, log_density, vectorize=True, moves=[move])
    start = np.random.default_rng(5).uniform([0.1, -1.0], [1.0, 1.0], (16, 2))
    sampler.run_mcmc(emcee.State(start, random_state=np.random.RandomState(6).get_state()), 400)
    draws = sampler.get_chain(discard=50, flat=True)
    assert abs(draws[:, 0].mean() - scipy.stats.truncnorm(0.0, 3.0).mean()) < 0.05
    assert abs(draws[:, 1].mean()) < 0.05


def banana_posterior() -> LogPosterior:
    """z[1] = z[0]^2 / 2 within 0.01 (Gaussian), z[0] uniform over its prior [0, 2].

    The shape of a damping scale that yaw alone leaves unidentified: flat
    along the ridge, its MAP anywhere on it, the noise bending with it.
    Log-uniform priors are flat in z. The moments in closed form: z[0] is
    U(0, 2), mean 1 and variance 1/3; z[1] has mean E[z0^2] / 2 = 2/3 and
    variance Var(z0^2) / 4 + 0.01^2 = (16/5 - 16/9) / 4 + 0.0001 = 0.3557
    (z[1]'s prior [-1, 3] cuts nothing: the ridge is 100 sd inside it).
    """

    def banana(theta: np.ndarray) -> np.ndarray:
        z = np.log(np.atleast_2d(theta))
        return -0.5 * ((z[:, 1] - 0.5 * z[:, 0] ** 2) / 0.01) ** 2

    prior = Prior(("d_long", "sigma_c"), np.exp([0.0, -1.0]), np.exp([2.0, 3.0]),
                  np.array([True, True]))  # fmt: skip
    return LogPosterior(banana, prior)


def test_a_curved_ridge_gets_a_mixture_along_it_and_the_chain_its_moments():
    # The MAP search ends anywhere on the flat ridge, here at its floor. No
    # single t fits a banana this thin: its moments by importance sampling
    # fall short of MIN_MATCHED_EFFICIENCY (measured 0.04-0.19, or none),
    # and the walkers start from the mixture along the ridge (0.62-0.68).
    # 32 walkers x 1,500 steps, tau under 10: over 4,500 effective draws.
    # The errors of z[0]'s mean and variance are sqrt((1/3) / 4500) = 0.009
    # and sqrt((1/5 - 1/9) / 4500) = 0.004 (U(0, 2)'s centred 4th moment is
    # 1/5), z[1]'s sqrt(0.3557 / 4500) = 0.009 and ~0.012: tolerances of
    # 0.05 are over 4 sd.
    log_posterior = banana_posterior()
    prior = log_posterior.prior
    centre = np.array([0.05, 0.00125])
    start = laplace_walkers(log_posterior, centre, 32, np.random.default_rng(1))
    assert isinstance(start.approximation, MixtureApproximation)
    assert len(start.approximation.weights) > 1
    efficiency = proposal_efficiency(log_posterior, start.approximation, np.random.default_rng(2))
    assert efficiency >= MIN_MATCHED_EFFICIENCY
    moves = ensemble_moves(start.approximation, box=(prior.z_low, prior.z_high))
    sampler = emcee.EnsembleSampler(32, 2, log_posterior, vectorize=True, moves=moves)
    seeded = emcee.State(start.walkers, random_state=np.random.RandomState(3).get_state())
    sampler.run_mcmc(seeded, 1500)
    assert np.max(sampler.get_autocorr_time(discard=100, quiet=True)) < 10
    draws = sampler.get_chain(discard=100, flat=True)
    np.testing.assert_allclose(draws.mean(axis=0), [1.0, 2.0 / 3.0], atol=0.05)
    np.testing.assert_allclose(draws.var(axis=0), [1.0 / 3.0, 0.3557], atol=0.05)


def test_a_one_component_mixture_moves_as_its_laplace_approximation():
    # The same draws and the same Metropolis-Hastings factors, bit for bit:
    # a chain's proposals do not change with the type its approximation has.
    covariance = np.array([[1.0, 0.3], [0.3, 0.5]])
    single = IndependenceMove(LaplaceApproximation(np.ones(2), covariance))
    mixture = IndependenceMove(MixtureApproximation(np.ones(1), np.ones((1, 2)), covariance[None]))
    walkers = np.random.default_rng(1).standard_normal((8, 2))
    drawn = [move.get_proposal(walkers, np.random.RandomState(2)) for move in (single, mixture)]
    np.testing.assert_array_equal(drawn[0][0], drawn[1][0])
    np.testing.assert_array_equal(drawn[0][1], drawn[1][1])


def test_a_mixture_density_is_its_weighted_sum_of_t_densities():
    # Against scipy's multivariate t (5 degrees of freedom, scale matrices
    # 1.2^2 times the covariances): the log-density up to one constant.
    weights = np.array([0.3, 0.7])
    centres = np.array([[0.0, 0.0], [2.0, 1.0]])
    covariances = np.array([np.eye(2), [[0.5, 0.2], [0.2, 0.4]]])
    move = IndependenceMove(MixtureApproximation(weights, centres, covariances))
    z = np.random.default_rng(1).standard_normal((50, 2)) * 2
    reference = np.log(sum(
        w * scipy.stats.multivariate_t(c, 1.44 * s, df=5).pdf(z)
        for w, c, s in zip(weights, centres, covariances, strict=True)
    ))  # fmt: skip
    difference = move.log_density(z) - reference
    np.testing.assert_allclose(difference, difference[0], atol=1e-10)


def test_a_chain_file_keeps_a_mixture_for_the_resumed_chain(tmp_path):
    # 16 components of 30 parameters: 115 kB of covariances, more than an
    # HDF5 attribute holds (64 kB), e.g. eight runs' noise per experiment.
    rng = np.random.default_rng(1)
    factors = rng.standard_normal((16, 30, 30))
    mixture = MixtureApproximation(
        np.full(16, 1 / 16), rng.standard_normal((16, 30)), factors @ factors.transpose(0, 2, 1)
    )
    backend = BufferedHDFBackend(str(tmp_path / "chain.h5"), flush_every=100)
    backend.reset(64, 30)
    _store_approximation(backend, mixture)
    kept = _stored_approximation(backend)[0]
    assert isinstance(kept, MixtureApproximation)
    for field in ("weights", "centres", "covariances"):
        np.testing.assert_array_equal(getattr(kept, field), getattr(mixture, field))


def test_block_moves_go_beside_an_approximation_moved_to_the_moments():
    # Away from the MAP (at the truth of a 38 s run, yaw alone) the Hessian is
    # not the posterior's shape and the start moves it to the moments (the
    # laplace_walkers example): block moves of the damping and of the yaw
    # group go beside it, the two sharing SHARED_WEIGHT each of the steps.
    robot = load_profile()
    run = simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    likelihood = ResidualLikelihood([run], robot, channels=("yaw",))
    log_posterior = LogPosterior(likelihood, Prior.for_likelihood(likelihood, robot))
    centre = np.log([110.0, 30.0, 0.047, 0.01, 0.005])
    start = laplace_walkers(log_posterior, centre, 12, np.random.default_rng(1))
    assert start.approximation is not None and start.groups
    assert {0, 1} <= {int(c) for block in start.groups for c in block.columns}
    moves = ensemble_moves(start.approximation, groups=start.groups)
    weights = {type(move): weight for move, weight in moves}
    assert weights[IndependenceMove] == weights[GroupMove] == SHARED_WEIGHT
    assert np.isclose(sum(weights.values()), 1.0)  # the rest differential evolution


def conditional_grid() -> GroupGrid:
    """x on 32 cells of [-3, 3] by N(0, 1); y given x's cell by N(x^2 / 2, (0.03 + 0.02 |x|)^2).

    The mean and sd of y are those at each cell's centre, so the proposal is
    not the target of :func:`curved_target`, and its sd varies between cells.
    """
    edges = np.linspace(-3.0, 3.0, 33)
    centres = (edges[:-1] + edges[1:]) / 2
    log_p = -0.5 * centres**2
    return GroupGrid(
        np.array([0]), edges[:1], edges[-1:], log_p - logsumexp(log_p), 32, edges[:1], edges[-1:],
        conditional_columns=np.array([1]),
        conditional_mean=(centres**2 / 2)[:, None],
        conditional_covariance=((0.03 + 0.02 * np.abs(centres)) ** 2)[:, None, None],
    )  # fmt: skip


def curved_target(z: np.ndarray) -> np.ndarray:
    """x ~ N(0, 1) on [-3, 3], y | x ~ N(x^2 / 2, (0.03 + 0.02 |x|)^2): log-density of rows."""
    x, y = z[:, 0], z[:, 1]
    sd = 0.03 + 0.02 * np.abs(x)
    inside = np.abs(x) < 3.0
    return np.where(inside, -0.5 * x**2 - 0.5 * ((y - x**2 / 2) / sd) ** 2 - np.log(sd), -np.inf)


def test_a_grid_with_a_conditional_column_draws_from_its_density():
    # The draws' histogram over (x cell, standardised y) against the density
    # integrated over the same bins by quadrature (its t's constant put
    # back): the draw and the log-density are one proposal. 200,000 draws: a bin of probability p
    # has a relative sd of sqrt((1 - p) / (200,000 p)), 2.2 % at p = 0.01;
    # bins of at least that mass agree within 10 % (4.5 sd).
    grid = conditional_grid()
    draws = grid.draw(200_000, np.random.RandomState(3))
    assert grid.block_columns.tolist() == [0, 1]
    x_edges = np.linspace(-3.0, 3.0, 7)
    y_edges = np.linspace(-1.0, 5.0, 13)
    counts, _, _ = np.histogram2d(draws[:, 0], draws[:, 1], (x_edges, y_edges))
    x, y = np.meshgrid(
        np.linspace(-3, 3, 1201)[:-1] + 0.0025, np.linspace(-1, 5, 2401)[:-1] + 0.00125
    )
    density = np.exp(grid.log_density(np.column_stack([x.ravel(), y.ravel()])))
    expected, _, _ = np.histogram2d(
        x.ravel(), y.ravel(), (x_edges, y_edges), weights=density * 0.005 * 0.0025
    )
    expected *= scipy.stats.t(PROPOSAL_DOF).pdf(0.0)  # the constant log_density leaves out
    assert abs(expected.sum() - 1.0) < 0.01
    big = expected > 0.01
    np.testing.assert_allclose(counts[big] / len(draws), expected[big], rtol=0.1)


def test_block_moves_with_a_conditional_column_sample_a_curved_target():
    # Metropolis-Hastings with the grid's block moves alone leaves the target
    # invariant, though the proposal is not the target: E[y] = E[x^2] / 2 =
    # 0.4865 for N(0, 1) on [-3, 3] (1 - 6 phi(3) / (2 Phi(3) - 1), halved);
    # 32 walkers x 1,500 steps with tau ~ 2 give ~20,000 draws, the sd of
    # E[y] (sd of y ~0.5) ~0.004 and of E[x] ~0.007: 0.03 is over 4 sd. A
    # density that left out its sd's normalisation (varying between cells)
    # shifts E[y] by ~0.05.
    grid = conditional_grid()
    truncated = scipy.stats.truncnorm(-3.0, 3.0)
    sampler = emcee.EnsembleSampler(
        32, 2, curved_target, vectorize=True, moves=[(GroupMove((grid,)), 1.0)]
    )
    x = np.random.default_rng(8).uniform(-1.0, 1.0, 32)
    start = np.column_stack([x, x**2 / 2])
    state = emcee.State(start, random_state=np.random.RandomState(7).get_state())
    sampler.run_mcmc(state, 1500)
    draws = sampler.get_chain(discard=100, flat=True)
    assert abs(draws[:, 0].mean()) < 0.03
    assert abs(draws[:, 1].mean() - truncated.moment(2) / 2) < 0.03
    assert np.mean(sampler.acceptance_fraction) > 0.5  # a good proposal: most moves taken


def test_block_moves_drawing_every_block_at_once_sample_a_correlated_target():
    # Two blocks of a correlated Gaussian (correlation 0.6), each proposal a
    # t around 0 of its marginal's sd: drawn one at a time or, for 70 % of
    # the walkers, both at once (an independence proposal from their
    # product, which ignores the correlation), Metropolis-Hastings leaves
    # the target invariant. 32 walkers x 2,000 steps with tau of a few
    # steps give ~15,000 effective draws: the sd of E[x0 x1] (var ~1.4)
    # is ~0.01, of E[x0^2] ~0.012; 0.05 is over 4 sd.
    covariance = np.array([[1.0, 0.6], [0.6, 1.0]])
    precision = np.linalg.inv(covariance)

    def target(z):
        return -0.5 * np.einsum("ni,ij,nj->n", z, precision, z)

    blocks = tuple(BlockT(np.array([c]), np.zeros(1), np.eye(1)) for c in (0, 1))
    sampler = emcee.EnsembleSampler(
        32, 2, target, vectorize=True, moves=[(GroupMove(blocks, joint=0.7), 1.0)]
    )
    start = np.random.default_rng(3).standard_normal((32, 2))
    sampler.run_mcmc(emcee.State(start, random_state=np.random.RandomState(4).get_state()), 2000)
    draws = sampler.get_chain(discard=100, flat=True)
    np.testing.assert_allclose(draws.T @ draws / len(draws), covariance, atol=0.05)
    assert abs(np.mean(draws)) < 0.05


def test_the_efficiency_of_the_blocks_product_is_its_closed_form():
    # A grid of the uniform density on [-1, 1]: for a target uniform there
    # every draw weighs the same (efficiency 1); for a normal of sd 0.3 a
    # uniform proposal's efficiency is E[p]^2 / E[p^2] = 0.53 over [-1, 1]
    # (500 draws: Monte Carlo sd ~0.03, so it rounds to 0.5).
    grid = GroupGrid(np.array([0]), np.array([-1.0]), np.array([1.0]),
                     np.log(np.full(8, 1 / 8)), 8)  # fmt: skip

    def flat(z):
        return np.where(np.abs(z[:, 0]) < 1.0, 0.0, -np.inf)

    def normal(z):
        return -0.5 * (z[:, 0] / 0.3) ** 2

    rng = np.random.default_rng(1)
    assert round(joint_efficiency(flat, (grid,), np.zeros(1), rng), 2) == 1.0
    assert round(joint_efficiency(normal, (grid,), np.zeros(1), rng), 1) == 0.5


def test_a_joint_share_outside_zero_to_one_is_refused():
    with pytest.raises(ValueError, match=r"joint share 1\.5"):
        GroupMove((conditional_grid(),), joint=1.5)


def test_conditional_modes_are_a_gaussians_mean_and_covariance_from_a_far_guess():
    # A Gaussian in columns 1 and 2 (column 0 carried along): the quadratic
    # fits are exact, so from a guess 60 sd away with a covariance 4 times
    # too small the steps (at most CONDITIONAL_STEP sd each) reach the mean,
    # and the fit is the covariance, to rounding.
    mean = np.array([0.3, -1.2])
    covariance = np.array([[0.04, 0.018], [0.018, 0.01]])
    precision = np.linalg.inv(covariance)

    def log_density(z):
        deviation = z[:, 1:] - mean
        return -0.5 * np.einsum("ni,ij,nj->n", deviation, precision, deviation) + z[:, 0]

    candidates = np.array([[0.0, 0.3 + 60 * 0.2, -1.2], [1.0, 0.3, -1.2 - 60 * 0.1]])
    found, fitted, peak = _conditional_modes(
        log_density, candidates, np.array([1, 2]), covariance / 4
    )
    np.testing.assert_allclose(found, np.stack([mean, mean]), atol=1e-6)
    np.testing.assert_allclose(fitted, np.stack([covariance, covariance]), rtol=1e-6)
    np.testing.assert_allclose(peak, candidates[:, 0], atol=1e-6)


@pytest.fixture(scope="module")
def drive_like_start(tmp_path_factory):
    """A DRIVE-like step sequence's log-posterior and its chain's start (ridge mixture refused).

    Its widest direction is a pose channel's width, piled at its prior's
    floor: the block moves' grid draws it, so no ridge mixture is built.
    """
    path = tmp_path_factory.mktemp("drive") / "drive.csv"
    run = lab.write_drive_run(path, icp_layout="sparse", n_steps=20, rng=36)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the held encoders, said and replaced
        experiments = load_experiments([run.path], robot="husky", columns=lab.DRIVE_ALL_ROLES)
    robot = load_profile("husky")
    likelihood = ResidualLikelihood(experiments, robot)
    log_posterior = LogPosterior(likelihood, Prior.for_likelihood(likelihood, robot))
    rng = np.random.default_rng(1)

    def refused(*args):
        raise AssertionError("a ridge mixture along a gridded width")

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(map_search, "ridge_mixture", refused)
        start = laplace_walkers(log_posterior, find_map(log_posterior, rng), 44, rng)
    return log_posterior, start


def test_a_drive_like_start_draws_every_block_at_once_where_their_product_fits(
    drive_like_start,
):
    # No approximation of the whole posterior (widths piled at their
    # floor), so block moves alone; the importance-sampling efficiency of
    # their product is above the threshold (0.35 on the 10-minute sequence),
    # so a share of the walkers draws all blocks at once.
    log_posterior, start = drive_like_start
    assert start.approximation is None and len(start.groups) == 4
    efficiency = joint_efficiency(
        log_posterior, start.groups, start.walkers[0], np.random.default_rng(2)
    )
    assert efficiency >= MIN_PROPOSAL_EFFICIENCY
    assert start.joint == JOINT_SHARE


def test_a_drive_like_groups_conditional_modes_are_its_conditional_maxima(drive_like_start):
    # The grids of a DRIVE-like step sequence (yaw at 20 Hz, ICP poses at
    # 5 Hz): in cells across each group's width, including the prior's
    # floor, where the Hessian's regression at the MAP is tens of sd off, the
    # stored mode of (sigma_c, sensor sd) is where scipy's Nelder-Mead finds
    # the group's conditional maximum, within 0.1 of the conditional sd, and
    # its value within 0.01 nats (the quadratics stop at steps of 0.05 sd).
    log_posterior, start = drive_like_start
    likelihood = log_posterior.likelihood
    damping, *groups = start.groups
    grids = [block for block in groups if isinstance(block, GroupGrid)]
    assert len(grids) >= 2 and all(len(grid.conditional_columns) == 2 for grid in grids)
    for grid in grids:
        group = likelihood.layout.column_groups[int(grid.columns[0])]
        for cell in (0, grid.points // 3, grid.points - 1):
            z = np.array(start.walkers[0])
            z[damping.columns] = damping.centre  # the grids' damping
            z[grid.columns] = grid.low + (cell + 0.5) * (grid.high - grid.low) / grid.points
            given = grid.conditional_columns

            def negative(values, z=z, given=given, group=group):
                point = z.copy()
                point[given] = values
                return -log_posterior.group_terms(point, group)[0]

            found = grid.conditional_mean[cell]
            best = scipy.optimize.minimize(negative, found, method="Nelder-Mead",
                                           options={"xatol": 1e-6, "fatol": 1e-8})  # fmt: skip
            sd = np.sqrt(np.diag(grid.conditional_covariance[cell]))
            assert np.all(np.abs(best.x - found) < 0.1 * sd), (group, cell)
            assert negative(found) - best.fun < 0.01, (group, cell)


def test_a_chain_file_keeps_a_grids_conditional_columns_and_reads_one_without(tmp_path):
    # The resumed chain proposes as the first did; a file written before
    # grids had conditional columns (no such datasets) or a joint share
    # reads as a grid without, and a share of 0.
    grid = conditional_grid()
    backend = BufferedHDFBackend(str(tmp_path / "chain.h5"), flush_every=100)
    backend.reset(8, 2)
    _store_approximation(backend, None, (grid,), JOINT_SHARE)
    _, (kept,), joint = _stored_approximation(backend)
    assert joint == JOINT_SHARE
    for field in ("columns", "log_probability", "conditional_columns", "conditional_mean",
                  "conditional_covariance"):  # fmt: skip
        np.testing.assert_array_equal(getattr(kept, field), getattr(grid, field))
    with backend.open("a") as stored:
        for field in ("conditional_columns", "conditional_mean", "conditional_covariance"):
            del stored[backend.name][f"block_0_{field}"]
        del stored[backend.name].attrs["block_joint"]
    _, (old,), joint = _stored_approximation(backend)
    assert joint == 0.0
    assert old.block_columns.tolist() == [0]


#: A Gaussian in z piled against z0's lower bound 0 (mean -0.3, sd 0.2: the
#: bound 1.5 sd above it), z1 correlated with z0 (0.5), z2 independent.
PILED_MEAN = np.array([-0.3, 0.4, -0.2])
PILED_COVARIANCE = np.array([[0.04, 0.03, 0.0], [0.03, 0.09, 0.0], [0.0, 0.0, 0.25]])


def piled_gaussian() -> tuple[Prior, scipy.stats._multivariate.multivariate_normal_frozen]:
    """:data:`PILED_MEAN` and :data:`PILED_COVARIANCE` inside the box z0 in [0, 3], z1, z2 in
    [-5, 5] (log-uniform priors: flat in z)."""
    prior = Prior(("d_long", "sigma_c", "sigma_n"), np.exp([0.0, -5.0, -5.0]),
                  np.exp([3.0, 5.0, 5.0]), np.array([True, True, True]))  # fmt: skip
    return prior, scipy.stats.multivariate_normal(PILED_MEAN, PILED_COVARIANCE)


def piled_bounded() -> BoundedLaplace:
    """The :class:`BoundedLaplace` of :func:`piled_gaussian`, from its exact derivatives at
    the point laplace_walkers expands at (the MAP moved inside the bound)."""
    prior = piled_gaussian()[0]
    precision = np.linalg.inv(PILED_COVARIANCE)
    gains = PILED_COVARIANCE[1:, :1] / PILED_COVARIANCE[0, 0]
    peak = np.concatenate([[0.0], PILED_MEAN[1:] + gains[:, 0] * (0.0 - PILED_MEAN[0])])
    expanded = peak + np.array([1e-3 * 3.0, 0.0, 0.0])
    return _bounded_approximation(prior, peak, -precision @ (expanded - PILED_MEAN), -precision)


def test_a_bounded_laplace_of_a_piled_gaussian_is_its_marginal_and_conditional():
    # For a Gaussian the quadratic expansion is exact: z0's distance from its
    # bound is N(-0.3, 0.2^2) truncated to [0, 3] (slope at the bound
    # -0.3 / 0.04 = -7.5 per unit, curvature 1 / 0.04 = 25), and (z1, z2)
    # given z0 is N(mu + S_I0 / S_00 (z0 + 0.3), S_II - S_I0 S_0I / S_00):
    # gains (0.75, 0), variances (0.0675, 0.25). Rounding only: 1e-9. The
    # moments of as_laplace are the truncated normal's (scipy) carried
    # through the conditional, in closed form.
    bounded = piled_bounded()
    assert bounded.columns.tolist() == [0] and bounded.signs.tolist() == [1.0]
    np.testing.assert_allclose(bounded.slopes, [-7.5], rtol=1e-9)
    np.testing.assert_allclose(bounded.curvatures, [25.0], rtol=1e-9)
    np.testing.assert_allclose(bounded.gains, [[0.75], [0.0]], atol=1e-9)
    np.testing.assert_allclose(bounded.conditional, np.diag([0.0675, 0.25]), atol=1e-9)
    np.testing.assert_allclose(bounded.centre, [0.0, 0.4 + 0.75 * 0.3, -0.2], atol=1e-9)
    z0 = scipy.stats.truncnorm(1.5, 16.5, loc=-0.3, scale=0.2)
    moments = as_laplace(bounded)
    np.testing.assert_allclose(
        moments.centre, [z0.mean(), 0.4 + 0.75 * (z0.mean() + 0.3), -0.2], atol=1e-9
    )
    expected = np.diag([z0.var(), 0.0675 + 0.75**2 * z0.var(), 0.25])
    expected[0, 1] = expected[1, 0] = 0.75 * z0.var()
    np.testing.assert_allclose(moments.covariance, expected, atol=1e-9)


def test_a_bounded_laplaces_proposal_is_its_target_where_the_target_is_gaussian():
    # Unwidened (scale 1) and with the t's degrees of freedom at 1e9 (a
    # normal to 1e-9), the proposal's density is the truncated Gaussian's
    # up to one constant (the box's other bounds are over 9 sd away): its
    # draws would be exact importance samples. The chain's proposal, widened
    # (t, 5 degrees of freedom, scale 1.2), stays efficient: 0.5 is the
    # truncated Gaussian's 0.77-0.82 (measured, 8 seeds) less over 10 of their sd.
    prior, target = piled_gaussian()
    bounded = piled_bounded()
    exact = IndependenceMove(bounded, dof=1e9, scale=1.0)
    z = exact.draw(2000, np.random.RandomState(1))
    assert np.all(z[:, 0] > 0.0)
    difference = exact.log_density(z) - target.logpdf(z)
    np.testing.assert_allclose(difference, difference[0], atol=1e-6)

    def log_density(z):
        return np.where(prior.inside(z), target.logpdf(z), -np.inf)

    assert proposal_efficiency(log_density, bounded, np.random.default_rng(2)) > 0.5


def test_independence_and_de_moves_from_a_bounded_laplace_sample_the_piled_target():
    # The chain's moves (the widened t-proposal at INDEPENDENCE_WEIGHT, the
    # rest differential evolution), started from the approximation: 32
    # walkers x 1,500 steps, tau under 5 (checked), over 9,000 effective
    # draws. The truncated Gaussian's moments in closed form (above): the
    # sd of each mean under 0.3 / sqrt(9000) = 0.003, of each variance
    # under 0.002: tolerances of 0.015 are over 5 sd.
    prior, target = piled_gaussian()
    bounded = piled_bounded()

    def log_density(z):
        return np.where(prior.inside(z), target.logpdf(z), -np.inf)

    moves = ensemble_moves(bounded, box=(prior.z_low, prior.z_high))
    sampler = emcee.EnsembleSampler(32, 3, log_density, vectorize=True, moves=moves)
    walkers = IndependenceMove(bounded, scale=0.5).draw(32, np.random.RandomState(4))
    sampler.run_mcmc(emcee.State(walkers, random_state=np.random.RandomState(5).get_state()), 1500)
    assert np.max(sampler.get_autocorr_time(discard=100, quiet=True)) < 5
    draws = sampler.get_chain(discard=100, flat=True)
    moments = as_laplace(bounded)
    np.testing.assert_allclose(draws.mean(axis=0), moments.centre, atol=0.015)
    np.testing.assert_allclose(np.cov(draws.T), moments.covariance, atol=0.015)


def test_a_chain_file_keeps_a_bounded_laplace_for_the_resumed_chain(tmp_path):
    bounded = piled_bounded()
    backend = BufferedHDFBackend(str(tmp_path / "chain.h5"), flush_every=100)
    backend.reset(32, 3)
    _store_approximation(backend, bounded)
    kept = _stored_approximation(backend)[0]
    assert isinstance(kept, BoundedLaplace)
    for field in ("centre", "columns", "signs", "lengths", "slopes", "curvatures", "gains",
                  "conditional"):  # fmt: skip
        np.testing.assert_array_equal(getattr(kept, field), getattr(bounded, field))


def test_a_family_that_does_not_fit_starts_from_the_tail_at_its_bounds():
    # The demo's two bags (coloured noise) under the white family: the MAP
    # puts d_long and the yaw sensor sd on their floors (10 N s/m, 1e-4
    # rad/s). The Laplace t is 0.06 efficient and its moments cannot be
    # matched; the bounded approximation is 0.42 efficient (measured, 500
    # draws: sd ~0.03), so the walkers start from it and the chain's
    # independence moves propose from it (4,800 steps with differential
    # evolution and block moves alone, 500 with it).
    robot = load_profile()
    experiments = load_experiments(sorted(demo_folder().glob("*.bag")))
    likelihood = ResidualLikelihood(experiments, robot, family="white")
    log_posterior = LogPosterior(likelihood, Prior.for_likelihood(likelihood, robot))
    rng = np.random.default_rng(1)
    start = laplace_walkers(log_posterior, find_map(log_posterior, rng), 32, rng)
    assert isinstance(start.approximation, BoundedLaplace)
    bound = [log_posterior.prior.names[c] for c in start.approximation.columns]
    assert bound == ["d_long", "sigma_n[yaw]"]
    assert start.groups  # block moves beside it
    efficiency = proposal_efficiency(log_posterior, start.approximation, np.random.default_rng(2))
    assert efficiency >= MIN_MATCHED_EFFICIENCY
