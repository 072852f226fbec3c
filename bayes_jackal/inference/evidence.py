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
:mod:`bayes_jackal.inference.comparison`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.fft
import scipy.special
import scipy.stats

from .._runtime import BRIDGE_MIN_DRAWS, InputError, as_rng
from ..likelihood import Prior
from ..posterior import Evidence

__all__ = ["bridge_sampling", "evidence_strength", "integrated_time", "nested_sampling"]


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

    Examples
    --------
    A check against a closed form: the unnormalised density exp(-|x|^2 / 2) in
    two dimensions has Z = 2 pi, and a chain of independent draws from it
    recovers log Z = 1.838:

    >>> import numpy as np
    >>> from bayes_jackal.inference import bridge_sampling
    >>> chain = np.random.default_rng(1).normal(size=(200, 8, 2))  # (draws, walkers, P)
    >>> evidence = bridge_sampling(lambda x: -0.5 * np.sum(x**2, axis=-1), chain, rng=1)
    >>> round(evidence.log_evidence, 2), round(float(np.log(2 * np.pi)), 2), evidence.error < 0.01
    (1.84, 1.84, True)
    """
    chain = np.asarray(chain, float)
    if chain.ndim != 3 or chain.shape[0] < BRIDGE_MIN_DRAWS:
        raise InputError(
            f"need a chain of shape (draws >= {BRIDGE_MIN_DRAWS}, walkers, P), got {chain.shape}",
            field="chain",
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
    tau = integrated_time(f2.reshape(-1, walkers))
    relative_mse = (
        np.var(f1) / np.mean(f1) ** 2 / n2 + max(tau, 1.0) * np.var(f2) / np.mean(f2) ** 2 / n1
    )
    return Evidence(shift + log_r, float(np.sqrt(relative_mse)), "bridge sampling")


def integrated_time(series: np.ndarray) -> float:
    """emcee's integrated autocorrelation time of walkers' series, a stuck walker counted.

    The walkers' normalised autocorrelations are averaged and summed up to
    Sokal's window (the first lag beyond 5 tau), as
    :func:`emcee.autocorr.integrated_time` does. A walker that never moves
    through the series (seen in moving-average chains) has no defined
    autocorrelation (emcee divides by its zero variance); it is counted as
    fully correlated, 1 at every lag, the limit of a walker that moves
    ever less: its draws are one draw, so the time grows with the share of
    stuck walkers (all stuck: 2 m - 1 for m draws).

    Parameters
    ----------
    series : ndarray, shape (m, walkers)
        A function of the draws (bridge sampling's f2), one column per walker.

    Returns
    -------
    float
        tau [draws].

    Examples
    --------
    Independent draws have tau near 1; one stuck walker among 8 adds 1/8 at
    every lag, and the window never closes (tau ~ 1 + (m - 1) / 4 = 100.75):

    >>> import numpy as np
    >>> from bayes_jackal.inference import integrated_time
    >>> draws = np.random.default_rng(1).normal(size=(400, 8))
    >>> round(integrated_time(draws), 1)
    1.0
    >>> draws[:, 0] = 3.0
    >>> round(integrated_time(draws))
    100
    """
    m = len(series)
    size = 2 * scipy.fft.next_fast_len(m)  # >= 2m: the linear, not circular, correlation
    spectrum = scipy.fft.rfft(series - series.mean(axis=0), n=size, axis=0)
    autocovariance = scipy.fft.irfft(spectrum * spectrum.conj(), n=size, axis=0)[:m]
    stuck = np.ptp(series, axis=0) == 0
    scale = np.where(stuck, 1.0, autocovariance[0])
    autocorrelation = np.where(stuck, 1.0, autocovariance / scale)
    taus = 2.0 * np.cumsum(autocorrelation.mean(axis=1)) - 1.0
    # Sokal's window: the first lag beyond 5 tau; where none is (emcee's
    # auto_window then answers lag 0), the whole series.
    closed = np.arange(m) >= 5.0 * taus
    return float(taus[np.argmax(closed) if closed.any() else m - 1])


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

    Examples
    --------
    A check against a closed form: a normal likelihood (sd 0.3) inside a
    uniform prior on [1, 3]^2 has Z = 1/4 (to 0.2 %). 50 live points keep the
    example quick and the error large:

    >>> import numpy as np
    >>> from bayes_jackal.inference import nested_sampling
    >>> from bayes_jackal.likelihood import Prior
    >>> prior = Prior(("a", "b"), np.full(2, 1.0), np.full(2, 3.0), np.full(2, False))
    >>> def log_likelihood(theta):
    ...     z = (theta - 2) / 0.3
    ...     return np.sum(-0.5 * z**2 - np.log(0.3 * np.sqrt(2 * np.pi)), axis=-1)
    >>> evidence = nested_sampling(log_likelihood, prior, rng=1, live_points=50, dlogz=0.5)
    >>> bool(abs(evidence.log_evidence - np.log(1 / 4)) < 2 * evidence.error), evidence.method
    (True, 'nested sampling (dynesty)')
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
    """Kass & Raftery's (1995) words for a Bayes factor [nats], either direction.

    Examples
    --------
    >>> from bayes_jackal.inference import evidence_strength
    >>> evidence_strength(0.4), evidence_strength(-2.0), evidence_strength(22_100.0)
    ('not worth more than a bare mention', 'positive', 'very strong')
    """
    size = abs(log_bayes_factor)
    if size < 1:
        return "not worth more than a bare mention"
    return "positive" if size < 3 else "strong" if size < 5 else "very strong"
