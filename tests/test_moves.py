"""The independence moves' proposal at a prior bound, and the approximation by moments.

A posterior piled against a prior bound (a kernel width at its prior's end,
the damping against its floor) has no Laplace approximation: the tests here
build such targets in closed form and check that the approximation by
importance sampling finds their moments, and that the independence moves,
whose proposal is truncated to the prior, still sample the target.
"""

from __future__ import annotations

from dataclasses import dataclass

import emcee
import numpy as np
import scipy.stats

from bayes_jackal.map_search import laplace_walkers
from bayes_jackal.moves import (
    MIN_MATCHED_EFFICIENCY,
    IndependenceMove,
    LaplaceApproximation,
    moment_matched,
    proposal_efficiency,
)
from bayes_jackal.priors import LogPosterior, Prior


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
