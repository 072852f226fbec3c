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

:func:`compare_families` samples one posterior per family and ranks the
families by bridge-sampling evidence. Bayes factors are read on Kass &
Raftery's (1995) scale, in natural-log units: below 1 not worth more than a
bare mention, 1-3 positive, 3-5 strong, above 5 very strong.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import emcee
import numpy as np
import scipy.special
import scipy.stats

from .errors import DataError, InputError
from .executors import in_processes
from .experiment import Experiment
from .inference import ConvergenceWarning, SamplerSettings, run_identity, sample_posterior
from .kernels import FAMILIES, as_rng, get_family
from .likelihood import ResidualLikelihood
from .posterior import HDI_PROB, az, interval, load_posterior, parameter_draws, summarize
from .priors import LogPosterior, Prior
from .robot import RobotProfile

__all__ = [
    "Comparison",
    "Evidence",
    "bridge_sampling",
    "compare_families",
    "evidence_strength",
    "nested_sampling",
]

#: A family is called coloured when it beats white noise by more than this
#: (ln B, "strong" on Kass & Raftery's scale) after two standard errors.
COLOURED_LOG_BF = 3.0
#: ... and white noise wins when every coloured family loses by more than
#: this ("positive") after two standard errors.
WHITE_LOG_BF = 1.0


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


@dataclass
class Comparison:
    """Noise-filter families of one data set, each with its posterior and evidence.

    Attributes
    ----------
    experiments : list of str
        Names of the experiments (several when pooled).
    evidence : dict of str to Evidence
        Bridge-sampling evidence per family.
    posteriors : dict of str to arviz.InferenceData
    nested : dict of str to Evidence
        Nested-sampling evidence per family, when cross-checked.
    """

    experiments: list[str]
    evidence: dict[str, Evidence]
    posteriors: dict[str, az.InferenceData]
    nested: dict[str, Evidence] = field(default_factory=dict)

    @property
    def best(self) -> str:
        """The family of highest evidence."""
        return max(self.evidence, key=lambda name: self.evidence[name].log_evidence)

    def log_bayes_factor(self, family: str, other: str) -> tuple[float, float]:
        """ln B of ``family`` over ``other`` and its standard error [nats]."""
        a, b = self.evidence[family], self.evidence[other]
        return a.log_evidence - b.log_evidence, float(np.hypot(a.error, b.error))

    def verdict(self) -> tuple[str, str]:
        """Is the noise coloured? ('coloured' | 'not coloured' | 'inconclusive', sentence).

        The best coloured family is set against white noise. 'coloured' needs
        ln B - 2 se > 3 (strong), 'not coloured' needs ln B + 2 se < -1
        (white better by positive evidence); anything between is
        inconclusive, so a noisy estimate never gives a confident answer.
        """
        coloured = [name for name in self.evidence if name != "white"]
        if "white" not in self.evidence or not coloured:
            return "inconclusive", "white noise and a coloured family must both be compared"
        rival = max(coloured, key=lambda name: self.evidence[name].log_evidence)
        value, error = self.log_bayes_factor(rival, "white")
        words = f"ln B = {value:.1f} +- {error:.2f}, {evidence_strength(value)}"
        if value - 2 * error > COLOURED_LOG_BF:
            return "coloured", f"coloured: {rival} over white, {words}"
        if value + 2 * error < -WHITE_LOG_BF:
            return "not coloured", f"not coloured: white over {rival}, {words}"
        return "inconclusive", f"inconclusive: {rival} against white, {words}"

    def to_dict(self) -> dict:
        """The ``compare --json`` object (docs/design.md §6).

        Each family carries its model-criticism ``warnings``
        (:func:`bayes_jackal.criticism.criticise`); the top-level ``warnings``
        lists them all, each with its ``family``.
        """
        families = {}
        for name, evidence in self.evidence.items():
            entry = evidence.to_dict()
            entry["log_bayes_factor_vs_best"] = self.log_bayes_factor(name, self.best)[0]
            entry["log_bayes_factor_vs_white"] = (
                self.log_bayes_factor(name, "white")[0] if "white" in self.evidence else None
            )
            entry["width"] = _width_summary(self.posteriors[name], name)
            entry["converged"] = bool(self.posteriors[name].posterior.attrs["converged"])
            entry["warnings"] = summarize(self.posteriors[name])["warnings"]
            if name in self.nested:
                entry["log_evidence_nested"] = self.nested[name].log_evidence
                entry["log_evidence_nested_err"] = self.nested[name].error
            families[name] = entry
        label, sentence = self.verdict()
        return {
            "experiments": self.experiments,
            "families": families,
            "best": self.best,
            "log_bayes_factor_vs_white": families[self.best]["log_bayes_factor_vs_white"],
            "verdict": label,
            "verdict_text": sentence,
            "warnings": [
                {"family": name} | warning
                for name, entry in families.items()
                for warning in entry["warnings"]
            ],
        }


def _width_summary(idata: az.InferenceData, family: str) -> dict | None:
    """Posterior mean, sd and HDI of a family's width(s) [s]; None for white noise."""
    width_name = get_family(family).width_name
    if width_name is None:
        return None
    summary = summarize(idata)
    return {
        label: interval(row) for label, row in summary.items() if label.split("[")[0] == width_name
    } | {"hdi_prob": HDI_PROB}


#: Sampler settings that only change the display, not a family's result.
_DISPLAY_SETTINGS = ("progress", "progress_label", "progress_line")


@dataclass(frozen=True)
class _FamilyRun:
    """Everything one family's posterior and evidence need (picklable for a process)."""

    experiments: list[Experiment]
    robot: RobotProfile
    settings: SamplerSettings | None
    seed: int | None
    prior_overrides: dict | None
    cross_check: bool
    likelihood_options: dict
    lines: int = 1

    def _model(self, family: str) -> tuple[ResidualLikelihood, Prior]:
        likelihood = ResidualLikelihood(
            self.experiments, self.robot, family=family, **self.likelihood_options
        )
        return likelihood, Prior.for_likelihood(likelihood, self.robot, self.prior_overrides)

    def task(self, family: str) -> dict:
        """Everything that defines ``family``'s result, part by part (JSON-ready).

        The chain's identity (:func:`bayes_jackal.inference.run_identity`),
        the sampler settings but the display, and the cross-check.
        """
        likelihood, prior = self._model(family)
        settings = self.settings or SamplerSettings()
        sampler = {
            key: value
            for key, value in dataclasses.asdict(settings).items()
            if key not in _DISPLAY_SETTINGS
        }
        walkers = settings.n_walkers(len(prior.names))
        identity = run_identity(likelihood, prior, walkers, self.seed)
        task = identity | {"sampler": sampler, "cross_check": self.cross_check}
        return json.loads(json.dumps(task))

    def __call__(self, job: tuple[int, str]):
        """(family, evidence, posterior, nested evidence or None, convergence warnings).

        ``job`` is (position, family): the position picks the progress line.
        The result, kept in the posterior's attributes, is that of
        :meth:`_stored`.
        """
        position, family = job
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            likelihood, prior = self._model(family)
            # One labelled progress line per family (processes share the terminal).
            settings = dataclasses.replace(
                self.settings or SamplerSettings(),
                progress_label=f"{family:>14s}",
                progress_line=position % self.lines,
            )
            idata = sample_posterior(
                likelihood, settings, self.seed, prior_overrides=self.prior_overrides
            )
            draws, lp = parameter_draws(idata)
            # Keyed on the family, not on which others are compared: results are reusable.
            key = list(FAMILIES).index(family)
            rng = np.random.default_rng(None if self.seed is None else [self.seed, key])
            evidence = bridge_sampling(LogPosterior(likelihood, prior), np.log(draws), lp, rng)
            nested = nested_sampling(likelihood, prior, rng) if self.cross_check else None
        messages = [str(w.message) for w in caught if issubclass(w.category, ConvergenceWarning)]
        idata.posterior.attrs |= {
            "evidence": json.dumps(evidence.to_dict()),
            "evidence_nested": json.dumps(nested and nested.to_dict()),
            "convergence_messages": json.dumps(messages),
            "task": json.dumps(self.task(family)),
        }
        return self._stored(family, idata)

    @staticmethod
    def _stored(family: str, idata: az.InferenceData):
        """(family, evidence, posterior, nested or None, messages) from the posterior's attrs."""
        attrs = idata.posterior.attrs
        nested = json.loads(attrs["evidence_nested"])
        return (
            family,
            Evidence.from_dict(json.loads(attrs["evidence"])),
            idata,
            None if nested is None else Evidence.from_dict(nested),
            json.loads(attrs["convergence_messages"]),
        )

    def reuse(self, family: str, path: Path, say: Callable[[str], None]):
        """The result saved in ``path`` when its task is this one's, else None (saying why)."""
        if not path.exists():
            return None
        try:
            idata = load_posterior(path)
            stored = json.loads(idata.posterior.attrs.get("task", "{}"))
        except (DataError, ValueError) as exc:
            say(f"  recomputing {family}: {exc}")
            return None
        if not stored:
            say(f"  recomputing {family}: {path} holds no record of its settings")
            return None
        task = self.task(family)
        differ = [part for part in task if stored.get(part) != task[part]]
        if differ:
            say(f"  recomputing {family}: {path} was computed with other {', '.join(differ)}")
            return None
        say(f"  reusing {family} from {path}")
        return self._stored(family, idata)


def compare_families(
    experiments: list[Experiment],
    robot: RobotProfile,
    families: tuple[str, ...] = tuple(FAMILIES),
    settings: SamplerSettings | None = None,
    seed: int | None = None,
    prior_overrides: dict | None = None,
    on_family: Callable[[str, Evidence, az.InferenceData], None] | None = None,
    cross_check: bool = False,
    processes: int = 1,
    reuse: Mapping[str, str | Path] | None = None,
    say: Callable[[str], None] = lambda text: None,
    **likelihood_options,
) -> Comparison:
    """Sample each family's posterior and estimate its evidence by bridge sampling.

    Parameters
    ----------
    experiments : list of Experiment
        Pooled into one likelihood (shared damping).
    robot : RobotProfile
    families : tuple of str
        Names from :data:`bayes_jackal.kernels.FAMILIES`.
    settings : SamplerSettings, optional
        With progress on, each family's bar is labelled and, with several
        processes, kept on a line of its own.
    seed : int, optional
        Seeds every family's chain and the bridge's proposal draws; the
        results do not depend on ``processes``.
    prior_overrides : dict, optional
        As in :func:`bayes_jackal.inference.sample_posterior`.
    on_family : callable, optional
        Called with (family, evidence, posterior) as each family finishes,
        e.g. to save it at once.
    cross_check : bool
        Also estimate each evidence by :func:`nested_sampling` (slow).
    processes : int
        Families sampled at once, each in its own process (one per core).
    reuse : mapping of str to path, optional
        Where finished families were saved (family -> posterior file, e.g.
        by ``on_family`` in a run that was interrupted). A family whose
        saved task (data, robot, family, likelihood options, priors,
        sampler settings but the display, seed, cross-check) equals this
        one's is read back, not recomputed, and ``on_family`` is not
        called for it.
    say : callable
        Told which families are reused, and why others are recomputed.
    **likelihood_options
        ``channels``, ``shared_noise``, ``sensor``, ``engine`` of
        :class:`ResidualLikelihood`. Without ``channels`` (or with None)
        every family sees every channel measured in all experiments
        (:func:`~bayes_jackal.likelihood.resolve_channels`).

    Returns
    -------
    Comparison
        Each posterior carries in its attributes its evidence
        (``evidence``, ``evidence_nested``), its ``task`` and its
        ``convergence_messages``. Families that hit the step cap re-issue their
        :class:`~bayes_jackal.inference.ConvergenceWarning` here.
    """
    unknown = [name for name in families if name not in FAMILIES]
    if unknown or not families or len(set(families)) != len(families):
        raise InputError(
            f"families must be distinct names from {list(FAMILIES)}, got {list(families)}",
            field="families",
        )
    if processes < 1:
        raise InputError(f"processes must be >= 1, got {processes}", field="processes")
    run = _FamilyRun(
        experiments,
        robot,
        settings,
        seed,
        prior_overrides,
        cross_check,
        likelihood_options,
    )
    results = {}
    for family in families:
        if reuse is not None and family in reuse:
            reused = run.reuse(family, Path(reuse[family]), say)
            if reused is not None:
                results[family] = reused[1:]
    jobs = list(enumerate(family for family in families if family not in results))
    parallel = processes > 1 and len(jobs) > 1
    workers = min(processes, len(jobs)) if parallel else 1
    run = dataclasses.replace(run, lines=workers)
    # With more families than processes every core stays busy (one BLAS thread
    # each); with as many, the longest family runs alone at the end and keeps
    # its threads.
    with (
        in_processes(run, jobs, workers=workers, single_threaded=len(jobs) > processes)
        if parallel
        else contextlib.nullcontext(map(run, jobs))
    ) as finished:
        for family, evidence, idata, nested, messages in finished:
            results[family] = evidence, idata, nested, messages
            if on_family is not None:
                on_family(family, evidence, idata)
    for family in families:
        for message in results[family][3]:
            warnings.warn(ConvergenceWarning(f"{family}: {message}"), stacklevel=2)
    ordered = [(family, *results[family][:3]) for family in families]
    return Comparison(
        [e.name for e in experiments],
        {family: evidence for family, evidence, _, _ in ordered},
        {family: idata for family, _, idata, _ in ordered},
        {family: nested for family, _, _, nested in ordered if nested is not None},
    )
