"""The ensemble's moves: differential evolution, and independent draws near the Laplace fit.

A posterior of the robot model is close to Gaussian in the sampler's log
coordinates, so the Laplace approximation at the MAP
(:func:`bayes_jackal.map_search.laplace_walkers`) is a good proposal for a
Metropolis-Hastings independence sampler: a multivariate t around it (5
degrees of freedom, the covariance widened by 1.2^2, so that its tails are
heavier than the posterior's), accepted with the ratio p(new) q(old) /
(p(old) q(new)). It is mixed with emcee's differential-evolution moves,
which need no approximation and follow a curved ridge where it fails.

Measured on the thesis-like 38 s run (three channels, 11 parameters): tau
30 steps with differential evolution alone, 6 with
:data:`INDEPENDENCE_WEIGHT` of independence moves (acceptance 0.4). The
independence moves also spread the walkers: differential evolution alone,
started from half the Laplace width, kept every posterior sd about 15 %
too small after 3,500 steps (d_lat 13.6 against 15.9 N s/m by importance
sampling from the same t, 40,000 draws), though tau said it had converged.
A proposal far from the posterior costs at most the steps its share takes
from differential evolution.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import emcee
import numpy as np

__all__ = [
    "INDEPENDENCE_WEIGHT",
    "IndependenceMove",
    "LaplaceApproximation",
    "Start",
    "ensemble_moves",
    "proposal_efficiency",
]

#: The share of the steps that are independence moves, when there is an approximation.
INDEPENDENCE_WEIGHT = 0.6
#: Degrees of freedom of the t proposal: tails heavier than a Gaussian's.
PROPOSAL_DOF = 5.0
#: The t proposal's scale over the Laplace approximation's.
PROPOSAL_SCALE = 1.2
#: Draws of the importance-sampling check of an approximation (:func:`proposal_efficiency`).
EFFICIENCY_DRAWS = 500
#: The least importance-sampling efficiency (ESS / draws) of the t proposal for
#: independence moves to be used. Measured: 0.4-0.6 on 38 s runs of one to three
#: channels, where they cut tau 5x; 0.02 on four 8 s runs of the yaw channel,
#: a MAP near the prior's bound, where they were rarely accepted and doubled tau.
MIN_PROPOSAL_EFFICIENCY = 0.1
#: Of differential evolution's share, the snooker updates' (emcee's advice
#: for curved targets: 0.8 DE, 0.2 snooker).
SNOOKER_SHARE = 0.2


@dataclass(frozen=True)
class LaplaceApproximation:
    """A Gaussian approximation of the posterior in the sampler's coordinates.

    Attributes
    ----------
    centre : ndarray, shape (k,)
        The MAP, z = log(theta).
    covariance : ndarray, shape (k, k)
        The inverse of the negative Hessian of the log-posterior there.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.moves import LaplaceApproximation
    >>> LaplaceApproximation(np.zeros(2), np.eye(2)).covariance.shape
    (2, 2)
    """

    centre: np.ndarray
    covariance: np.ndarray


@dataclass(frozen=True)
class Start:
    """Where a chain starts: its walkers, and the approximation its moves may propose from.

    Attributes
    ----------
    walkers : ndarray, shape (walkers, k)
    approximation : LaplaceApproximation or None
        None: differential evolution alone (no Laplace approximation, e.g.
        a MAP on the prior's boundary).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.moves import Start
    >>> Start(np.zeros((8, 2))).approximation is None
    True
    """

    walkers: np.ndarray
    approximation: LaplaceApproximation | None = None


class IndependenceMove(emcee.moves.MHMove):
    """Metropolis-Hastings with independent draws from a multivariate t.

    Parameters
    ----------
    approximation : LaplaceApproximation
        The t's centre and, times ``scale``^2, its scale matrix.
    dof : float
    scale : float

    Examples
    --------
    Draws for three walkers, and log q(old) - log q(new), the correction
    emcee adds to the log-posterior ratio:

    >>> import numpy as np
    >>> from bayes_jackal.moves import IndependenceMove, LaplaceApproximation
    >>> move = IndependenceMove(LaplaceApproximation(np.zeros(2), np.eye(2)))
    >>> new, factors = move.get_proposal(np.zeros((3, 2)), np.random.RandomState(1))
    >>> new.shape, bool(np.allclose(factors, -move.log_density(new)))
    ((3, 2), True)
    """

    def __init__(
        self,
        approximation: LaplaceApproximation,
        *,
        dof: float = PROPOSAL_DOF,
        scale: float = PROPOSAL_SCALE,
    ):
        self.centre = np.asarray(approximation.centre, float)
        self.factor = scale * np.linalg.cholesky(approximation.covariance)
        self.dof = dof
        super().__init__(self._propose)

    def log_density(self, z: np.ndarray) -> np.ndarray:
        """The t's log-density at each row of ``z``, up to a constant."""
        whitened = np.linalg.solve(self.factor, (z - self.centre).T)
        k = len(self.centre)
        return -0.5 * (self.dof + k) * np.log1p(np.sum(whitened**2, axis=0) / self.dof)

    def _propose(self, z: np.ndarray, random: np.random.RandomState):
        """Draws for every walker of ``z``, and log q(old) - log q(new) (emcee's factors)."""
        count, k = z.shape
        normal = random.randn(count, k)
        mixing = random.chisquare(self.dof, size=count) / self.dof
        new = self.centre + (normal / np.sqrt(mixing)[:, None]) @ self.factor.T
        return new, self.log_density(z) - self.log_density(new)


def ensemble_moves(approximation: LaplaceApproximation | None) -> list:
    """emcee's (move, weight) list: differential evolution, with independence moves if possible.

    Differential evolution with snooker updates alone where there is no
    approximation (emcee's recommendation for curved targets: along the
    damping ridge the noise parameters bend with the damping scale).

    Examples
    --------
    Independence moves from a t around N(0, I) leave a standard normal
    target's draws standard normal:

    >>> import emcee
    >>> import numpy as np
    >>> from bayes_jackal.moves import LaplaceApproximation, ensemble_moves
    >>> moves = ensemble_moves(LaplaceApproximation(np.zeros(2), np.eye(2)))
    >>> [type(move).__name__ for move, _ in moves]
    ['DEMove', 'DESnookerMove', 'IndependenceMove']
    >>> sampler = emcee.EnsembleSampler(
    ...     8, 2, lambda z: -0.5 * np.sum(z**2, axis=-1), vectorize=True, moves=moves
    ... )
    >>> seeded = np.random.RandomState(1).get_state()
    >>> start = emcee.State(np.random.default_rng(1).standard_normal((8, 2)), random_state=seeded)
    >>> state = sampler.run_mcmc(start, 2000)
    >>> draws = sampler.get_chain(discard=100, flat=True)
    >>> bool(np.all(np.abs(draws.std(axis=0) - 1) < 0.1))
    True
    """
    evolution = 1.0 if approximation is None else 1.0 - INDEPENDENCE_WEIGHT
    moves = [
        (emcee.moves.DEMove(), evolution * (1.0 - SNOOKER_SHARE)),
        (emcee.moves.DESnookerMove(), evolution * SNOOKER_SHARE),
    ]
    if approximation is not None:
        moves.append((IndependenceMove(approximation), INDEPENDENCE_WEIGHT))
    return moves


def proposal_efficiency(
    log_posterior: Callable[[np.ndarray], np.ndarray],
    approximation: LaplaceApproximation,
    rng: np.random.Generator,
    draws: int = EFFICIENCY_DRAWS,
) -> float:
    """The effective fraction of importance-sampling draws from the independence moves' t.

    The normalised ESS, 1 / (draws sum w^2), of the self-normalised weights
    p / q of ``draws`` draws from the t: near 1 where the approximation is
    the posterior, near 0 where the independence moves would rarely be
    accepted (:data:`MIN_PROPOSAL_EFFICIENCY`).

    Examples
    --------
    A t around N(0, I) for a standard normal target, and for one shifted by
    5 sd:

    >>> import numpy as np
    >>> from bayes_jackal.moves import LaplaceApproximation, proposal_efficiency
    >>> approximation = LaplaceApproximation(np.zeros(2), np.eye(2))
    >>> rng = np.random.default_rng(1)
    >>> def normal(z):
    ...     return -0.5 * np.sum(z**2, axis=-1)
    >>> def shifted(z):
    ...     return -0.5 * np.sum((z - 5.0) ** 2, axis=-1)
    >>> round(proposal_efficiency(normal, approximation, rng), 1)
    0.8
    >>> proposal_efficiency(shifted, approximation, rng) < 0.1
    True
    """
    move = IndependenceMove(approximation)
    random = np.random.RandomState(int(rng.integers(2**32)))
    z, _ = move.get_proposal(np.zeros((draws, len(approximation.centre))), random)
    log_weights = log_posterior(z) - move.log_density(z)
    if not np.any(np.isfinite(log_weights)):
        return 0.0
    weights = np.exp(log_weights - np.max(log_weights))
    return float(np.sum(weights) ** 2 / np.sum(weights**2) / draws)
