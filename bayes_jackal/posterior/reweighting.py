"""The posterior without one run, from the posterior with every run: PSIS.

The log-likelihoods of runs add, so the posterior without run i is the
pooled one reweighted: p(theta | y_-i) / p(theta | y) is proportional to
1 / p(y_i | theta). :class:`PooledPosterior` gives each pooled draw theta_s
the log-weight -log p(y_i | theta_s), run i's own log-likelihood (a
:class:`~bayes_jackal.likelihood.ResidualLikelihood` over that run alone,
with the pooled posterior's likelihood options, at the pooled draws'
columns of that run's parameters, evaluated in chunks of draws), and
:func:`psis_weights` smooths the largest weights by arviz's generalised
Pareto fit (:func:`arviz.psislw`; Vehtari, Simpson, Gelman, Yao and Gabry
2024, JMLR 25(72)), told the chain's relative efficiency (the mean over
parameters of its autocorrelation ESS per kept draw). The fit's shape
k-hat says whether the weights can be trusted: at most
:data:`PARETO_K_THRESHOLD` (0.7, arviz's), the posterior without the run
is the pooled draws resampled with them
(:meth:`PooledPosterior.posterior_without`); above, the run moves the
posterior further than the pooled draws reach, and its posterior must be
sampled again (:mod:`bayes_jackal.filters.left_out` does).

Noise per run (``shared_noise=False``). Run i's own noise parameters
phi_i (its groups' width, sigma_c, sensor sd) enter its likelihood only:
the other runs do not inform them, so the posterior without run i holds
them at their prior, and its layout (the other runs') has no column for
them. What it must get right is the posterior of the shared parameters
theta (damping; a shared width) and of the other runs' noise given y_-i,
whose weight is 1 / p(y_i | theta), phi_i integrated over its prior.
Dropping phi_i from the joint weight 1 / p(y_i | theta, phi_i) would be
unbiased, but it is the harmonic-mean estimate of that integral: its
weights have a tail of k ~ 1 (measured: 0.71-0.83 on four 8 s runs of the
yaw channel), and nearly every run would be refit. Instead the target is
extended by a density q(phi_i | theta) of our choosing,
p(theta, phi_-i | y_-i) q(phi_i | theta), whose marginal is exactly the
posterior without run i whatever q is; the weight is
q(phi_i | theta) / (p(phi_i) p(y_i | theta, phi_i)).
:func:`conditional_log_density` makes q a Gaussian in the logit of phi_i's
place in its prior box, fitted to the pooled draws with a mean quadratic
in log theta: close to p(phi_i | theta, y_i) and a little narrower
(:data:`OWN_COVARIANCE_SCALE`), so the weights are close to
1 / p(y_i | theta) (measured on the same four runs: k-hat 0.29-0.49, the
weights' ESS 5-13 times the joint weights'). The resampled draws of phi_i
are then dropped.

Cost: one evaluation of one run's likelihood at each pooled draw
(walkers x kept steps, a few thousand): 0.7-1.4 s for 5,000 draws of a
38 s run's three channels (white to Gaussian noise), against a chain's
walkers x thousands of steps on the other runs.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.special

from .._runtime import REQUIRED, InputError, az, chunks
from ..io import Experiment
from ..likelihood import CHUNK_ELEMENTS, LikelihoodOptions, Prior, ResidualLikelihood
from ..model import ParameterLayout, RobotProfile
from .file_format import experiment_arrays, store_reweighting
from .posterior import Posterior, build_inference_data

__all__ = [
    "OWN_COVARIANCE_SCALE",
    "PARETO_K_THRESHOLD",
    "PooledPosterior",
    "RunWeights",
    "conditional_log_density",
    "psis_weights",
]

#: The pooled draws a refit of the posterior without a run climbs from
#: (:meth:`PooledPosterior.best_draws_without`), as many as the profile's.
_WARM_STARTS = 4
#: Largest Pareto shape k-hat at which a PSIS reweighting is used (arviz's
#: ``loo`` and Vehtari et al. 2024's threshold); above it the run is refit.
PARETO_K_THRESHOLD = 0.7
#: The covariance of q(phi_i | theta), the density a left-out run's own noise
#: parameters are given (noise per run), as a fraction of the residual
#: covariance of its fit to the pooled draws: narrower than their
#: conditional posterior, so that q / p(phi_i | theta, y_i) in the weights
#: stays bounded (a Gaussian q of r times the variance would give k = 1 - 1/r).
OWN_COVARIANCE_SCALE = 0.75


def psis_weights(log_ratios: np.ndarray, reff: float = 1.0) -> tuple[np.ndarray, float, float]:
    """Pareto-smoothed importance weights of draws, their shape k-hat and effective size.

    Parameters
    ----------
    log_ratios : ndarray, shape (S,)
        Log importance ratios of S draws (target over proposal, up to a
        constant), finite; for leaving data out, minus their log-likelihood.
    reff : float
        The draws' relative efficiency, effective sample size / S, in (0, 1]
        (:func:`arviz.psislw`'s ``reff``: it sets the length of the tail fitted).

    Returns
    -------
    weights : ndarray, shape (S,)
        The smoothed weights, normalised to sum to 1.
    pareto_k : float
        The shape of the generalised Pareto distribution fitted to the largest
        ratios (inf when the tail has too few draws to fit): at most
        :data:`PARETO_K_THRESHOLD`, the weighted draws can be trusted.
    ess : float
        Kish's effective sample size of the weights, 1 / sum(w^2), counting
        the draws as independent.

    Raises
    ------
    InputError
        For ratios that are not a finite vector of two or more, or ``reff``
        outside (0, 1].

    Examples
    --------
    Draws of N(0, 1) reweighted by exp(mu / 2) are draws of N(1/2, 1):

    >>> import numpy as np
    >>> from bayes_jackal.posterior import psis_weights
    >>> mu = np.random.default_rng(1).normal(0.0, 1.0, 4000)
    >>> weights, k, ess = psis_weights(0.5 * mu)
    >>> round(float(weights @ mu), 1), bool(k < 0.7), 3000 < ess < 4000
    (0.5, True, True)
    """
    log_ratios = np.asarray(log_ratios, dtype=float)
    if log_ratios.ndim != 1 or len(log_ratios) < 2 or not np.isfinite(log_ratios).all():
        raise InputError(
            f"log ratios must be a finite vector of two or more, got shape {log_ratios.shape}",
            field="log_ratios",
        )
    if not (isinstance(reff, int | float) and 0.0 < reff <= 1.0):
        raise InputError(f"must be in (0, 1], got {reff!r}", field="reff")
    smoothed, pareto_k = az.psislw(log_ratios, reff=float(reff))
    weights = np.exp(smoothed - scipy.special.logsumexp(smoothed))
    weights /= weights.sum()
    return weights, float(pareto_k), float(1.0 / np.sum(weights**2))


def _quadratic_features(values: np.ndarray) -> np.ndarray:
    """1, the standardised columns, and their products and squares: shape (S, 1 + a + a(a+1)/2)."""
    spread = values.std(axis=0)
    x = (values - values.mean(axis=0)) / np.where(spread > 0, spread, 1.0)
    products = [x[:, i] * x[:, j] for i in range(x.shape[1]) for j in range(i, x.shape[1])]
    return np.column_stack([np.ones(len(x)), x, *products])


def conditional_log_density(
    given: np.ndarray,
    own: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    *,
    scale: float = OWN_COVARIANCE_SCALE,
) -> np.ndarray:
    """log q(own | given) at each draw: a normalised density on a box, fitted to the draws.

    q is a Gaussian in u = logit((own - low) / (high - low)), the draws'
    place in the box, with a mean quadratic in ``given`` (least squares on
    the draws) and ``scale`` times the covariance of the fit's residuals,
    carried back to ``own`` by the Jacobian of u. It is a density over
    the box for every value of ``given``: :class:`PooledPosterior` gives it to
    a left-out run's own noise parameters (with ``own`` and the box in
    z = log theta, the prior's coordinates).

    Parameters
    ----------
    given : ndarray, shape (S, a)
        What q is conditioned on, at each of S draws.
    own : ndarray, shape (S, b)
        The variables q is a density of, strictly inside the box.
    low, high : ndarray, shape (b,)
        The box.
    scale : float
        The residual covariance's factor, > 0 (:data:`OWN_COVARIANCE_SCALE`).

    Returns
    -------
    ndarray, shape (S,)
        log q(own_s | given_s) [log of own's units^-b].

    Raises
    ------
    InputError
        For mismatched shapes, a draw outside the box, a non-positive
        ``scale``, or too few draws for the fit (more than the features
        plus b are needed).
    numpy.linalg.LinAlgError
        When the residuals' covariance is singular (a variable that does not
        vary given the others).

    Examples
    --------
    A variable that follows another closely, own = given / 2 + N(0, 0.1^2),
    in a box much wider than the draws, where the logit is nearly linear: q
    is, at a typical draw, the Gaussian N(given / 2, 0.75 x 0.1^2):

    >>> import numpy as np
    >>> import scipy.stats
    >>> from bayes_jackal.posterior import conditional_log_density
    >>> rng = np.random.default_rng(1)
    >>> given = rng.normal(size=(2000, 1))
    >>> own = 0.5 * given + 0.1 * rng.normal(size=(2000, 1))
    >>> log_q = conditional_log_density(given, own, np.array([-5.0]), np.array([5.0]))
    >>> expected = scipy.stats.norm.logpdf(own[:, 0], 0.5 * given[:, 0], 0.1 * np.sqrt(0.75))
    >>> log_q.shape, round(float(np.median(np.abs(log_q - expected))), 2)
    ((2000,), 0.02)
    """
    given = np.asarray(given, dtype=float)
    own = np.asarray(own, dtype=float)
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    if (
        given.ndim != 2
        or own.ndim != 2
        or len(given) != len(own)
        or low.shape != (own.shape[1],)
        or high.shape != low.shape
    ):
        raise InputError(
            f"given (S, a), own (S, b), low and high (b,) expected, got {given.shape}, "
            f"{own.shape}, {low.shape}, {high.shape}",
            field="own",
        )
    if not (isinstance(scale, int | float) and math.isfinite(scale) and scale > 0):
        raise InputError(f"must be a finite number > 0, got {scale!r}", field="scale")
    if not np.all((own > low) & (own < high)):
        raise InputError("draws must lie strictly inside the box", field="own")
    features = _quadratic_features(given)
    dof = len(own) - features.shape[1]
    if dof <= own.shape[1]:
        raise InputError(
            f"{len(own)} draws are too few to fit {features.shape[1]} features and a "
            f"{own.shape[1]}-dimensional covariance",
            field="own",
        )
    width = high - low
    position = (own - low) / width
    u = np.log(position) - np.log1p(-position)
    log_jacobian = np.sum(np.log(width) - np.log(own - low) - np.log(high - own), axis=1)
    coefficients, *_ = np.linalg.lstsq(features, u, rcond=None)
    residuals = u - features @ coefficients
    factor = np.linalg.cholesky(scale * residuals.T @ residuals / dof)
    standard = scipy.linalg.solve_triangular(factor, residuals.T, lower=True)
    return (
        -0.5 * np.sum(standard**2, axis=0)
        - np.sum(np.log(np.diag(factor)))
        - 0.5 * own.shape[1] * math.log(2 * math.pi)
        + log_jacobian
    )


@dataclass(frozen=True)
class RunWeights:
    """One run's PSIS weights of the pooled draws (:meth:`PooledPosterior.weights`).

    Attributes
    ----------
    left_out : str
        The run whose weights these are.
    log_likelihood : ndarray, shape (S,)
        The run's log-likelihood at each of the S pooled draws.
    weights : ndarray, shape (S,), or None
        The smoothed weights (sum 1); None when they cannot be used
        (``reason`` says why).
    pareto_k : float or None
        The Pareto shape k-hat; None where it was not estimated.
    ess : float or None
        The weights' effective sample size, 1 / sum(w^2).
    draws : int
        S.
    reff : float
        The pooled chain's relative efficiency (ESS per draw) given to PSIS.
    reason : str or None
        Why the weights cannot be used: k-hat above :data:`PARETO_K_THRESHOLD`,
        or no finite log-likelihood.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.posterior import RunWeights
    >>> refused = RunWeights("a", np.zeros(4000), None, 0.93, 57.0, 4000, 0.45, "k-hat 0.93 > 0.7")
    >>> refused.fields("refit")["pareto_k"], refused.fields("refit")["refit_reason"]
    (0.93, 'k-hat 0.93 > 0.7')
    """

    left_out: str
    log_likelihood: np.ndarray
    weights: np.ndarray | None
    pareto_k: float | None
    ess: float | None
    draws: int
    reff: float
    reason: str | None = None

    def fields(self, method: str) -> dict:
        """A left-out run's record of how its posterior was made, with ``method``.

        Keys ``method``, ``pareto_k``, ``weights_ess``, ``draws``,
        ``relative_efficiency`` and ``refit_reason``
        (:class:`bayes_jackal.filters.LeaveOneOut`).
        """
        return {
            "method": method,
            "pareto_k": self.pareto_k,
            "weights_ess": self.ess,
            "draws": self.draws,
            "relative_efficiency": self.reff,
            "refit_reason": self.reason,
        }


class PooledPosterior:
    """A pooled posterior's draws, ready to be reweighted to the posterior without a run.

    Parameters
    ----------
    idata : arviz.InferenceData
        The posterior of ``family`` on ``experiments`` (in their order).
    experiments : sequence of Experiment
        The runs it was fitted to (checked by name and data).
    robot : RobotProfile
    family : str
    options : LikelihoodOptions
        The likelihood options it was sampled with.
    prior_overrides : mapping, optional
        The prior ranges it was sampled under (as for
        :meth:`~bayes_jackal.likelihood.Prior.for_likelihood`).
    source : str, optional
        Where it was read from or saved, named in errors.

    Raises
    ------
    InputError
        When it is not the posterior of ``family`` on exactly these runs
        (names and data), with these likelihood options and priors.

    Examples
    --------
    Two 8 s runs of the yaw channel, the chain kept short (200 steps): one of
    two runs is half the data, too much for the reweighting (k-hat > 0.7):

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import PooledPosterior
    >>> from bayes_jackal.likelihood import LikelihoodOptions
    >>> from bayes_jackal.io import Series
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=seed, name=name)
    ...     for seed, name in [(1, "a"), (2, "b")]
    ... ]
    >>> posterior = bj.sample(runs, family="white", channels=["yaw"], max_steps=200, seed=1)
    >>> options = LikelihoodOptions(channels=["yaw"])
    >>> pooled = PooledPosterior(posterior, runs, robot, "white", options)
    >>> weights = pooled.weights(runs[0])
    >>> weights.draws == pooled.count, weights.weights is None, weights.pareto_k > 0.7
    (True, True, True)
    >>> weights.reason  # doctest: +ELLIPSIS
    'Pareto k-hat ... > 0.7: the PSIS reweighting of the pooled posterior is unreliable ...'
    """

    def __init__(
        self,
        idata: az.InferenceData,
        experiments: Sequence[Experiment],
        robot: RobotProfile,
        family: str,
        options: LikelihoodOptions,
        prior_overrides: Mapping | None = None,
        source: str | None = None,
    ) -> None:
        posterior = Posterior.of(idata)
        self.metadata = metadata = posterior.metadata
        self.source, self.robot, self.family = source, robot, family
        self.options = LikelihoodOptions.of(options)
        self.prior_overrides = prior_overrides
        self.experiments = list(experiments)
        names = [e.name for e in experiments]
        fitted = [e.name for e in metadata.experiments]
        if metadata.family != family or fitted != names:
            raise InputError(
                f"the pooled posterior is of {metadata.family} noise on {fitted}; "
                f"the {family} posterior on {names} was expected",
                source=source,
                field="pooled",
            )
        for index, experiment in enumerate(experiments):
            arrays = experiment_arrays(idata, index)
            if not all(np.array_equal(arrays[key], getattr(experiment, key)) for key in REQUIRED):
                raise InputError(
                    f"the pooled posterior's run {experiment.name} holds other data than the "
                    "run given",
                    source=source,
                    field="pooled",
                )
        self.layout = metadata.layout
        draws, lp = posterior.draws()
        self.shape = draws.shape[:2]  # (draws, walkers)
        self.theta = draws.reshape(-1, draws.shape[-1])
        self.lp = lp.reshape(-1)
        efficiency = [
            value / len(self.theta)
            for value in metadata.convergence.ess_autocorr.values()
            if isinstance(value, int | float) and math.isfinite(value) and value > 0
        ]
        self.reff = float(min(1.0, np.mean(efficiency))) if efficiency else 1.0
        self._likelihood(list(experiments[:1]))  # the likelihood options, checked at once
        # The priors these options give.
        expected = Prior.for_layout(self.layout, robot, prior_overrides)
        stored = metadata.prior
        if not (
            np.allclose(expected.low, stored.low)
            and np.allclose(expected.high, stored.high)
            and np.array_equal(expected.log_uniform, stored.log_uniform)
        ):
            raise InputError(
                "the prior ranges differ from the pooled posterior's: its reweighting cannot "
                "give the posteriors under these priors",
                source=source,
                field="prior_overrides",
            )

    @property
    def count(self) -> int:
        """The pooled draws."""
        return len(self.theta)

    def task(self, name: str, seed: int | None) -> dict | None:
        """What defines the reweighting without run ``name``, JSON-ready, for reuse.

        The pooled posterior's task (``compare``'s), the run, the seed of
        the resampling and this module's constants; None when the pooled
        posterior has no task.
        """
        if self.metadata.task is None:
            return None
        task = {
            "method": "psis",
            "pooled": self.metadata.task,
            "left_out": name,
            "seed": seed,
            "pareto_k_threshold": PARETO_K_THRESHOLD,
            "own_covariance_scale": OWN_COVARIANCE_SCALE,
        }
        return json.loads(json.dumps(task))

    def _likelihood(self, experiments: list[Experiment]) -> ResidualLikelihood:
        """The likelihood of ``experiments`` with the analysis' options, checked against ours."""
        likelihood = self.options.likelihood(experiments, self.robot, self.family)
        ours, theirs = likelihood.layout, self.layout
        settings = {
            name: (getattr(ours, name), getattr(theirs, name))
            for name in ("sensor", "channels", "shared_noise", "shared_width", "pose_channels")
        }
        settings |= {
            "engine": (likelihood.engine, self.metadata.engine),
            "steady": (likelihood.steady, self.metadata.steady),
        }
        differ = {name: pair for name, pair in settings.items() if pair[0] != pair[1]}
        if differ:
            raise InputError(
                "the likelihood options differ from the pooled posterior's: "
                + "; ".join(f"{n} {a!r}, the posterior's {b!r}" for n, (a, b) in differ.items()),
                source=self.source,
                field="likelihood_options",
            )
        return likelihood

    def _columns(self, layout: ParameterLayout) -> list[int]:
        """The pooled columns of each of ``layout``'s parameters (same groups by key)."""
        pooled = self.layout
        return [
            pooled.column(
                base, None if group is None else pooled.groups.index(layout.groups[group])
            )
            for base, group in zip(layout.bases, layout.column_groups, strict=True)
        ]

    def weights(self, run: Experiment) -> RunWeights:
        """The PSIS weights of the pooled draws for the posterior without ``run``.

        Unusable weights (``weights`` None) say why in ``reason``: k-hat
        above :data:`PARETO_K_THRESHOLD`, a log-likelihood that is not
        finite, or, with noise per run, draws of its own parameters that
        admit no conditional density.
        """
        likelihood = self._likelihood([run])
        theta = self.theta[:, self._columns(likelihood.layout)]
        log_likelihood = np.empty(len(theta))
        # Rows of parameter sets at a time: no array of draws x samples.
        for rows in chunks(len(theta), likelihood.n_residuals, budget=CHUNK_ELEMENTS):
            log_likelihood[rows] = likelihood(theta[rows])
        common = {
            "left_out": run.name,
            "log_likelihood": log_likelihood,
            "draws": self.count,
            "reff": self.reff,
        }
        bad = int(np.count_nonzero(~np.isfinite(log_likelihood)))
        if bad:
            reason = f"its log-likelihood is not finite at {bad} of the {self.count} pooled draws"
            return RunWeights(weights=None, pareto_k=None, ess=None, reason=reason, **common)
        log_ratios = -log_likelihood
        layout = self.layout
        own = [
            j
            for j, group in enumerate(layout.column_groups)
            if group is not None and layout.groups[group][1] == run.name
        ]
        if own:  # noise per run: its own parameters get q(phi_i | theta), not the prior
            prior = self.metadata.prior
            z = np.log(self.theta)
            given = [j for j, group in enumerate(layout.column_groups) if group is None]
            try:
                log_q = conditional_log_density(
                    z[:, given], z[:, own], prior.z_low[own], prior.z_high[own]
                )
            except (InputError, np.linalg.LinAlgError) as exc:
                reason = f"its own noise parameters' draws admit no conditional density ({exc})"
                return RunWeights(weights=None, pareto_k=None, ess=None, reason=reason, **common)
            own_prior = Prior(
                tuple(prior.names[j] for j in own),
                prior.low[own],
                prior.high[own],
                prior.log_uniform[own],
            )
            log_ratios = log_ratios + log_q - own_prior.log_density(z[:, own])
        weights, pareto_k, ess = psis_weights(log_ratios, self.reff)
        if not pareto_k <= PARETO_K_THRESHOLD:
            reason = (
                f"Pareto k-hat {pareto_k:.3f} > {PARETO_K_THRESHOLD}: the PSIS reweighting of "
                f"the pooled posterior is unreliable (weights ESS {ess:.0f} of "
                f"{self.count} draws)"
                if math.isfinite(pareto_k)
                else f"Pareto k-hat cannot be estimated from {self.count} pooled draws"
            )
            k = pareto_k if math.isfinite(pareto_k) else None
            return RunWeights(weights=None, pareto_k=k, ess=ess, reason=reason, **common)
        return RunWeights(weights=weights, pareto_k=pareto_k, ess=ess, **common)

    def best_draws_without(
        self, weights: RunWeights, others: Sequence[Experiment], count: int = _WARM_STARTS
    ) -> np.ndarray:
        """The pooled draws of highest density without the run, in the others' layout.

        log p(theta | y_-i) = log p(theta | y) - log p(y_i | theta) + c at
        each pooled draw: the ``count`` best distinct draws, where a refit
        of the posterior without the run starts its MAP search (``starts``
        of :func:`~bayes_jackal.inference.compare_groups`) instead of a
        profile over the whole prior box. ``weights`` are the run's.

        Returns
        -------
        ndarray, shape (count, P)
            Parameter values theta, columns as the likelihood of ``others``.
        """
        density = self.lp - weights.log_likelihood
        order = np.argsort(-np.where(np.isfinite(density), density, -np.inf), kind="stable")
        _, first = np.unique(self.theta[order], axis=0, return_index=True)
        best = order[np.sort(first)[:count]]
        return self.theta[best][:, self._columns(self._likelihood(list(others)).layout)]

    def posterior_without(
        self,
        name: str,
        weights: RunWeights,
        rng: np.random.Generator,
        record: dict,
    ) -> az.InferenceData:
        """The posterior without run ``name``: the pooled draws resampled with ``weights``.

        Parameters
        ----------
        name : str
            The run left out.
        weights : RunWeights
            Its usable weights (:meth:`weights`).
        rng : numpy.random.Generator
            Draws the resampling: as many draws as the pooled posterior
            has, with replacement, with probabilities ``weights.weights``.
        record : dict
            JSON-ready, kept as its ``reweighting`` attribute
            (:func:`~bayes_jackal.posterior.store_reweighting`).

        Returns
        -------
        arviz.InferenceData
            A posterior of the usual layout, that of the other runs' likelihood
            (with noise per run, the left-out run's own parameters are
            dropped); its ``lp`` is the other runs' log posterior at each
            draw, its convergence the pooled chain's with its ESS scaled by
            the weights' efficiency (ESS / S).

        Raises
        ------
        InputError
            For weights that cannot be used or are another run's, or a run
            not among the pooled.
        """
        if weights.weights is None or len(weights.weights) != self.count:
            raise InputError(f"no usable weights: {weights.reason}", field="weights")
        if weights.left_out != name:
            raise InputError(f"the weights are without {weights.left_out}, not {name}")
        others = [e for e in self.experiments if e.name != name]
        if len(others) != len(self.experiments) - 1:
            raise InputError(f"no run {name!r} among {[e.name for e in self.experiments]}")
        likelihood = self._likelihood(others)
        prior = Prior.for_likelihood(likelihood, self.robot, self.prior_overrides)
        columns = self._columns(likelihood.layout)
        pooled_prior = self.metadata.prior
        chosen = rng.choice(self.count, size=self.count, replace=True, p=weights.weights)
        z = np.log(self.theta[chosen])
        # log p(y_-i | theta) = log p(y | theta) - log p(y_i | theta): runs add.
        rest = self.lp[chosen] - pooled_prior.log_density(z) - weights.log_likelihood[chosen]
        lp = rest + prior.log_density(z[:, columns])
        convergence = self.metadata.convergence
        old_names = [self.layout.names[j] for j in columns]
        names = dict(zip(likelihood.layout.names, old_names, strict=True))
        efficiency = weights.ess / self.count
        diagnostics = {
            "converged": convergence.converged,
            "n_steps": convergence.n_steps,
            "walkers": convergence.walkers,
            "discard": convergence.discard,
            "thin": convergence.thin,
            "autocorr_time": {
                new: convergence.autocorr_time[old]
                for new, old in names.items()
                if old in convergence.autocorr_time
            },
            "ess_autocorr": {
                new: convergence.ess_autocorr[old] * efficiency
                for new, old in names.items()
                if old in convergence.ess_autocorr
            },
            "acceptance_fraction": convergence.acceptance_fraction,
            "seed": convergence.seed,
            "settings": convergence.settings,
        }
        idata = build_inference_data(
            likelihood,
            prior,
            z[:, columns].reshape(*self.shape, len(columns)),
            lp.reshape(self.shape),
            diagnostics,
        )
        store_reweighting(idata, record)
        return idata
