"""Evidence of a posterior run, and noise-filter families compared by it (docs/design.md §4).

The evidence (log marginal likelihood) of a model M on data y is
log Z = log of the integral of p(y | theta, M) p(theta | M) d theta. Two
independent estimators:

- :func:`bridge_sampling`, the main one: Meng & Wong's (1996) optimal bridge
  between the emcee chain and a multivariate normal fitted to its first
  half (the "normal" method of Gronau et al. 2017), with the relative error
  of Fruehwirth-Schnatter (2004), which counts the chain's autocorrelation.
  It costs one vectorised likelihood evaluation per proposal draw.
- :func:`nested_sampling`, the cross-check: dynesty's nested sampler run on
  the same likelihood and priors from scratch (optional extra
  ``bayes-jackal[evidence]``); slower, sharing nothing with the chain.

:func:`evidence_strength` words a Bayes factor on Kass & Raftery's (1995)
scale. Families are compared by these evidences in
:mod:`bayes_jackal.comparison`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import emcee
import numpy as np
import scipy.special
import scipy.stats

from .errors import InputError
from .kernels import as_rng
from .priors import Prior

__all__ = ["Evidence", "bridge_sampling", "evidence_strength", "nested_sampling"]


@dataclass(frozen=True)
class Evidence:
    """A log-evidence estimate.

    Attributes
    ----------
    log_evidence : float
        log Z [nats].
    error : float
        Its standard error [nats].
    method : str
        The estimator.
    """

    log_evidence: float
    error: float
    method: str

    def to_dict(self) -> dict:
        """JSON-ready fields (the keys of ``compare --json``)."""
        return {
            "log_evidence": self.log_evidence,
            "log_evidence_err": self.error,
            "method": self.method,
        }

    @classmethod
    def from_dict(cls, fields: dict) -> Evidence:
        """The inverse of :meth:`to_dict`."""
        return cls(fields["log_evidence"], fields["log_evidence_err"], fields["method"])


def _bridge_ratio(l1: np.ndarray, l2: np.ndarray, tol: float, max_iterations: int) -> float:
    """Meng & Wong's fixed point for log r = log Z - median(l1), in log space.

    l1 = log q(theta) - log g(theta) at the posterior draws, l2 the same at
    the proposal draws (q the unnormalised posterior, g the proposal).
    """
    n1, n2 = len(l1), len(l2)
    log_s1, log_s2 = np.log(n1 / (n1 + n2)), np.log(n2 / (n1 + n2))
    log_r = 0.0
    for _ in range(max_iterations):
        numerator = scipy.special.logsumexp(l2 - np.logaddexp(log_s1 + l2, log_s2 + log_r))
        denominator = scipy.special.logsumexp(-np.logaddexp(log_s1 + l1, log_s2 + log_r))
        updated = numerator - denominator + np.log(n1 / n2)
        if abs(updated - log_r) < tol:
            return float(updated)
        log_r = updated
    raise RuntimeError(f"bridge sampling did not converge in {max_iterations} iterations")


def bridge_sampling(
    log_density: Callable[[np.ndarray], np.ndarray],
    chain: np.ndarray,
    log_prob: np.ndarray | None = None,
    rng: np.random.Generator | int | None = None,
    tol: float = 1e-10,
    max_iterations: int = 1000,
) -> Evidence:
    """Log evidence from an MCMC chain by bridge sampling.

    Parameters
    ----------
    log_density : callable
        Unnormalised log posterior (log-likelihood + log prior density, the
        prior normalised), vectorised: (B, P) -> (B,), in the coordinates
        of ``chain``; -inf outside the prior.
    chain : ndarray, shape (draws, walkers, P)
        Posterior draws, burn-in removed. The first half of the draws fits
        the normal proposal, the second half enters the bridge.
    log_prob : ndarray, shape (draws, walkers), optional
        ``log_density`` at ``chain``, when already known.
    rng : numpy.random.Generator, int or None
        Source of the proposal draws.
    tol : float
        Convergence tolerance of the fixed-point iteration [nats].
    max_iterations : int

    Returns
    -------
    Evidence
        The error is the square root of the relative mean square error of
        Z (Fruehwirth-Schnatter 2004; the error measure of Gronau et al.
        2017), with the chain's part scaled
        by the integrated autocorrelation time of the bridge function.
    """
    chain = np.asarray(chain, float)
    if chain.ndim != 3 or chain.shape[0] < 8:
        raise InputError(
            f"need a chain of shape (draws >= 8, walkers, P), got {chain.shape}", field="chain"
        )
    draws, walkers, ndim = chain.shape
    half = draws // 2
    fitted = chain[:half].reshape(-1, ndim)
    posterior = chain[half:].reshape(-1, ndim)
    proposal = scipy.stats.multivariate_normal(fitted.mean(axis=0), np.cov(fitted.T))
    proposal_draws = proposal.rvs(len(posterior), random_state=as_rng(rng)).reshape(-1, ndim)
    at_posterior = (
        log_density(posterior) if log_prob is None else np.asarray(log_prob)[half:].ravel()
    )
    l1 = at_posterior - proposal.logpdf(posterior)
    l2 = log_density(proposal_draws) - proposal.logpdf(proposal_draws)
    if not np.all(np.isfinite(l1)):
        raise InputError("the log density is not finite at every posterior draw", field="chain")
    shift = float(np.median(l1))
    log_r = _bridge_ratio(l1 - shift, l2 - shift, tol, max_iterations)
    n1, n2 = len(l1), len(l2)
    s1, s2 = n1 / (n1 + n2), n2 / (n1 + n2)
    # Fruehwirth-Schnatter's f1 (proposal draws, independent) and f2 (chain).
    f1 = np.exp(l2 - shift - log_r - np.logaddexp(np.log(s1) + l2 - shift - log_r, np.log(s2)))
    f2 = np.exp(-np.logaddexp(np.log(s1) + l1 - shift - log_r, np.log(s2)))
    tau = emcee.autocorr.integrated_time(f2.reshape(-1, walkers), tol=0)[0]
    relative_mse = (
        np.var(f1) / np.mean(f1) ** 2 / n2 + max(tau, 1.0) * np.var(f2) / np.mean(f2) ** 2 / n1
    )
    return Evidence(shift + log_r, float(np.sqrt(relative_mse)), "bridge sampling")


def nested_sampling(
    log_likelihood: Callable[[np.ndarray], np.ndarray],
    prior: Prior,
    rng: np.random.Generator | int | None = None,
    live_points: int = 500,
    dlogz: float = 0.1,
) -> Evidence:
    """Log evidence by dynesty's nested sampler, independent of any chain.

    Parameters
    ----------
    log_likelihood : callable
        Vectorised log-likelihood in natural units, (B, P) -> (B,).
    prior : Prior
        The priors; dynesty draws from them through :meth:`Prior.from_unit`.
    rng : numpy.random.Generator, int or None
    live_points : int
        More live points, smaller error (it falls as 1 / sqrt(live_points)).
    dlogz : float
        Stop when the live points can add less than this to log Z.

    Raises
    ------
    ImportError
        Without dynesty (``pip install 'bayes-jackal[evidence]'``).
    """
    try:
        import dynesty
    except ImportError:
        raise ImportError(
            "nested sampling needs dynesty: pip install 'bayes-jackal[evidence]'"
        ) from None

    def point_log_likelihood(z: np.ndarray) -> float:
        return float(log_likelihood(prior.to_natural(z)[None])[0])

    sampler = dynesty.NestedSampler(
        point_log_likelihood,
        prior.from_unit,
        len(prior.names),
        nlive=live_points,
        sample="rwalk",
        rstate=as_rng(rng),
    )
    sampler.run_nested(dlogz=dlogz, print_progress=False)
    results = sampler.results
    return Evidence(
        float(results.logz[-1]), float(results.logzerr[-1]), "nested sampling (dynesty)"
    )


def evidence_strength(log_bayes_factor: float) -> str:
    """Kass & Raftery's (1995) words for a Bayes factor [nats], either direction."""
    size = abs(log_bayes_factor)
    if size < 1:
        return "not worth more than a bare mention"
    return "positive" if size < 3 else "strong" if size < 5 else "very strong"
