"""The result of a comparison of noise-filter families: evidence, posteriors, verdict.

A :class:`Comparison` holds each family's posterior and log evidence for one
data set (:func:`bayes_jackal.inference.compare_families` makes it), names
the best family, gives Bayes factors between any two, and answers whether
the noise is coloured. Bayes factors are read on Kass & Raftery's (1995)
scale, in natural-log units: below 1 not worth more than a bare mention,
1-3 positive, 3-5 strong, above 5 very strong.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .._runtime.arviz_quiet import az
from .._runtime.defaults import HDI_PROB
from ..posterior.posterior import Posterior
from ..posterior.records import Evidence
from ..posterior.summary import interval, summarize
from .evidence import evidence_strength

__all__ = ["COLOURED_LOG_BF", "WHITE_LOG_BF", "Comparison", "colour_verdict"]

#: A family is called coloured when it beats white noise by more than this
#: (ln B, "strong" on Kass & Raftery's scale) after two standard errors.
COLOURED_LOG_BF = 3.0
#: ... and white noise wins when every coloured family loses by more than
#: this ("positive") after two standard errors.
WHITE_LOG_BF = 1.0


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

    Examples
    --------
    Two families' evidence as bridge sampling would give it (the
    posteriors, which :meth:`to_dict` reads, left out here):

    >>> from bayes_jackal.inference import Comparison
    >>> from bayes_jackal.posterior import Evidence
    >>> comparison = Comparison(
    ...     ["v1_01"],
    ...     {
    ...         "white": Evidence(7778.5, 0.03, "bridge sampling"),
    ...         "gaussian": Evidence(7790.5, 0.04, "bridge sampling"),
    ...     },
    ...     posteriors={},
    ... )
    >>> comparison.best
    'gaussian'
    >>> value, error = comparison.log_bayes_factor("gaussian", "white")
    >>> round(value, 2), round(error, 2)
    (12.0, 0.05)
    >>> comparison.verdict()
    ('coloured', 'coloured: gaussian over white, ln B = 12.0 +- 0.05, very strong')
    """

    experiments: list[str]
    evidence: dict[str, Evidence]
    posteriors: dict[str, az.InferenceData]
    nested: dict[str, Evidence] = field(default_factory=dict)

    @property
    def best(self) -> str:
        """The family of highest evidence."""
        return max(self.evidence, key=lambda name: self.evidence[name].log_evidence)

    def convergence_messages(self) -> list[str]:
        """Each family's chain that hit its step cap, as ``"<family>: <message>"``.

        Read from the posteriors' ``convergence_messages`` attributes (kept
        by :func:`compare_groups`, also in a saved and reused posterior).
        """
        return [
            f"{family}: {message}"
            for family, idata in self.posteriors.items()
            for message in Posterior.of(idata).metadata.convergence_messages
        ]

    def log_bayes_factor(self, family: str, other: str) -> tuple[float, float]:
        """ln B of ``family`` over ``other`` and its standard error [nats]."""
        a, b = self.evidence[family], self.evidence[other]
        return a.log_evidence - b.log_evidence, float(np.hypot(a.error, b.error))

    def verdict(self) -> tuple[str, str]:
        """Is the noise coloured? :func:`colour_verdict` of the families' evidence."""
        return colour_verdict(self.evidence)

    def to_dict(self) -> dict:
        """The ``compare --json`` object (docs/design.md §6).

        Each family carries its model-criticism ``warnings``
        (:func:`bayes_jackal.posterior.criticise`); the top-level ``warnings``
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
            entry["converged"] = Posterior.of(self.posteriors[name]).metadata.convergence.converged
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
    layout = Posterior.of(idata).metadata.layout
    if layout.width_name is None:
        return None
    summary = summarize(idata)
    widths = layout.names_of(layout.width_name)
    return {name: interval(summary[name]) for name in widths} | {"hdi_prob": HDI_PROB}


def colour_verdict(evidence: Mapping[str, Evidence]) -> tuple[str, str]:
    """Is the noise coloured? ('coloured' | 'not coloured' | 'inconclusive', sentence).

    The best coloured family is set against white noise. 'coloured' needs
    ln B - 2 se > 3 (strong), 'not coloured' needs ln B + 2 se < -1
    (white better by positive evidence); anything between is
    inconclusive, so a noisy estimate never gives a confident answer.

    Parameters
    ----------
    evidence : mapping of str to Evidence
        Each family's log evidence.

    Examples
    --------
    >>> from bayes_jackal.inference import colour_verdict
    >>> from bayes_jackal.posterior import Evidence
    >>> colour_verdict({"white": Evidence(-10.0, 0.1, "bridge"),
    ...                 "gaussian": Evidence(-9.5, 0.1, "bridge")})[0]
    'inconclusive'
    """
    coloured = [name for name in evidence if name != "white"]
    if "white" not in evidence or not coloured:
        return "inconclusive", "white noise and a coloured family must both be compared"
    rival = max(coloured, key=lambda name: evidence[name].log_evidence)
    value = evidence[rival].log_evidence - evidence["white"].log_evidence
    error = float(np.hypot(evidence[rival].error, evidence["white"].error))
    words = f"ln B = {value:.1f} +- {error:.2f}, {evidence_strength(value)}"
    if value - 2 * error > COLOURED_LOG_BF:
        return "coloured", f"coloured: {rival} over white, {words}"
    if value + 2 * error < -WHITE_LOG_BF:
        return "not coloured", f"not coloured: white over {rival}, {words}"
    return "inconclusive", f"inconclusive: {rival} against white, {words}"
