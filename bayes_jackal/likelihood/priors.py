"""Priors and the log-posterior in sampling coordinates (docs/design.md §4).

Priors: every parameter log-uniform on the profile's ranges: d_lat, d_long,
every kernel width, sigma_c, sigma_n and sigma_p (the pose noise of vx, vy
recorded as poses). The damping's is scale-invariant on purpose: runs that
fix the skid ratio d_lat / d_long but not the damping's scale leave the
posterior where the prior puts it, and a uniform prior (the thesis' grid, 5-1)
puts it at the top of its range (docs/design.md §4). The sampler works in
z = log(theta), where the damping ridge d_lat / d_long ~ const is straight
(see :class:`Prior`).
The MAP search uses them in :mod:`bayes_jackal.inference.map_search`, the sampler in
:mod:`bayes_jackal.inference.sampling`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.stats

from ..model import (
    SPEED_RATIO,
    SPEED_RATIO_PRIOR,
    ParameterLayout,
    RobotProfile,
    prior_overrides,
    prior_range,
)
from .residual_likelihood import ResidualLikelihood

__all__ = ["LogPosterior", "Prior"]


@dataclass(frozen=True)
class Prior:
    """Independent uniform or log-uniform priors on a box.

    The sampler works in z = log(theta) for every parameter: the ridge of
    the damping, d_lat / d_long ~ const, is a straight line there, which
    affine-invariant moves cross easily. A prior uniform in theta has
    log-density z - log(high - low) in z; a log-uniform one is constant.
    New priors are all log-uniform (:meth:`for_likelihood`); a uniform one
    is the damping's of a posterior file written by an earlier version, read
    back as it was sampled.

    Attributes
    ----------
    names : tuple of str
        Parameter names (:attr:`bayes_jackal.model.ParameterLayout.names`).
    low, high : ndarray, shape (P,)
        Bounds in natural units.
    log_uniform : ndarray of bool, shape (P,)
        Log-uniform (True) or uniform (False) in natural units.

    Examples
    --------
    The priors of a likelihood's parameters, one range overridden; the density
    of z = log(theta) of a log-uniform prior is 1 / log(high / low):

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.likelihood import Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="gaussian", channels=("yaw",))
    >>> prior = Prior.for_likelihood(likelihood, robot, {"d_lat": (50, 500)})
    >>> prior.names
    ('d_lat', 'd_long', 'sigma_h', 'sigma_c', 'sigma_n')
    >>> prior.low.tolist(), prior.log_uniform.tolist()
    ([50.0, 10.0, 0.001, 1e-05, 0.0001], [True, True, True, True, True])
    >>> theta = np.array([110.0, 30.0, 0.047, 0.01, 0.005])
    >>> expected = -np.log(np.log(prior.high / prior.low)).sum()
    >>> bool(np.isclose(prior.log_density(np.log(theta)), expected))
    True
    """

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    log_uniform: np.ndarray

    @classmethod
    def for_likelihood(
        cls,
        likelihood: ResidualLikelihood,
        robot: RobotProfile,
        overrides: Mapping[str, Sequence[float]] | None = None,
    ) -> Prior:
        """Priors of every parameter of ``likelihood`` from the robot profile.

        ``overrides`` maps a prior key (``d_lat``, ``d_long``, ``sigma_h``,
        ``sigma_c``, ``sigma_n``, ``sigma_p``; ``width`` or a family's own
        width name for ``sigma_h``) to a (low, high) pair that replaces the profile's,
        validated by :func:`~bayes_jackal.model.prior_overrides`: an
        unknown key is an :class:`InputError` naming the keys allowed. Every
        noise family's width takes the ``sigma_h`` range.
        """
        return cls.for_layout(likelihood.layout, robot, overrides)

    @classmethod
    def for_layout(
        cls,
        layout: ParameterLayout,
        robot: RobotProfile,
        overrides: Mapping[str, Sequence[float]] | None = None,
    ) -> Prior:
        """Priors of every parameter of ``layout``: as :meth:`for_likelihood`."""
        ranges = {SPEED_RATIO: SPEED_RATIO_PRIOR, **robot.priors, **prior_overrides(overrides)}
        keys = [layout.prior_key(base) for base in layout.bases]
        low, high = np.array([prior_range(key, ranges[key]) for key in keys]).T
        return cls(layout.names, low, high, np.ones(len(keys), bool))

    @property
    def z_low(self) -> np.ndarray:
        """Lower bounds of z = log(theta)."""
        return np.log(self.low)

    @property
    def z_high(self) -> np.ndarray:
        """Upper bounds of z = log(theta)."""
        return np.log(self.high)

    def log_density(self, z: np.ndarray) -> np.ndarray:
        """Log prior density of z = log(theta) inside the box, shape (...)."""
        uniform = np.where(self.log_uniform, 0.0, z - np.log(self.high - self.low))
        log_uniform = np.where(self.log_uniform, -np.log(self.z_high - self.z_low), 0.0)
        return np.sum(uniform + log_uniform, axis=-1)

    @staticmethod
    def to_natural(z: np.ndarray) -> np.ndarray:
        """Natural units from sampling coordinates."""
        return np.exp(z)

    def inside(self, z: np.ndarray) -> np.ndarray:
        """Whether each point lies in the prior's support."""
        return np.all((z >= self.z_low) & (z <= self.z_high), axis=-1)

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """z of the prior quantiles ``u`` in [0, 1]^P: maps uniform draws to prior draws."""
        uniform = np.log(self.low + u * (self.high - self.low))
        return np.where(self.log_uniform, self.z_low + u * (self.z_high - self.z_low), uniform)

    def draw(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` prior draws in z from a scrambled Sobol design, shape (n, P)."""
        return self.from_unit(
            scipy.stats.qmc.Sobol(len(self.names), scramble=True, seed=rng).random(n)
        )


@dataclass(frozen=True)
class LogPosterior:
    """Vectorised log-posterior in sampling coordinates (for emcee, vectorize=True).

    Examples
    --------
    The log-likelihood plus the log prior in z = log(theta); -inf outside the
    prior:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.likelihood import ResidualLikelihood
    >>> from bayes_jackal.likelihood import LogPosterior, Prior
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
    >>> likelihood = ResidualLikelihood([run], robot, family="gaussian", channels=("yaw",))
    >>> prior = Prior.for_likelihood(likelihood, robot)
    >>> log_posterior = LogPosterior(likelihood, prior)
    >>> theta = np.array([[110.0, 30.0, 0.047, 0.01, 0.005], [2000.0, 30.0, 0.047, 0.01, 0.005]])
    >>> z = np.log(theta)
    >>> values = log_posterior(z)
    >>> bool(np.isclose(values[0], likelihood(theta[:1])[0] + prior.log_density(z[0])))
    True
    >>> float(values[1])  # d_lat = 2000 is outside [10, 1000]
    -inf
    """

    likelihood: ResidualLikelihood
    prior: Prior

    def __call__(self, z: np.ndarray) -> np.ndarray:
        return self._with_prior(z, self.likelihood)

    def group_terms(self, z: np.ndarray, group: int) -> np.ndarray:
        """The log-prior plus noise group ``group``'s log-likelihood alone, at rows of ``z``.

        The likelihood's other groups depend on the damping and their own
        noise only, so between rows that differ in this group's noise alone
        it differs from the log-posterior by a constant: the group's
        conditional, at a third of the cost with three channels.

        Examples
        --------
        >>> import numpy as np
        >>> import bayes_jackal as bj
        >>> from bayes_jackal.likelihood import LogPosterior, Prior, ResidualLikelihood
        >>> robot = bj.load_profile()
        >>> run = bj.simulate_experiment(robot, 110.0, 30.0, "v1", rng=1)
        >>> likelihood = ResidualLikelihood([run], robot, channels=("yaw", "vx"))
        >>> log_posterior = LogPosterior(likelihood, Prior.for_likelihood(likelihood, robot))
        >>> z = np.log([[110.0, 30.0, 0.047, 0.01, 0.005, 0.047, 0.01, 0.005]] * 2)
        >>> z[1, 2] += 0.1  # the yaw group's width
        >>> change = np.diff(log_posterior(z))[0]
        >>> bool(np.isclose(change, np.diff(log_posterior.group_terms(z, 0))[0]))
        True
        """
        return self._with_prior(z, lambda theta: self.likelihood.group_loglike(theta, group))

    def _with_prior(
        self, z: np.ndarray, loglike: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """``loglike`` of the rows of ``z`` inside the prior plus the log-prior; -inf elsewhere."""
        z = np.atleast_2d(z)
        out = np.full(len(z), -np.inf)
        inside = self.prior.inside(z)
        if inside.any():
            out[inside] = loglike(self.prior.to_natural(z[inside])) + self.prior.log_density(
                z[inside]
            )
        return np.where(np.isnan(out), -np.inf, out)
