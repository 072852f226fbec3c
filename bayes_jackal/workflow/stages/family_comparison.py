"""Stage 3: the pooled posterior of every noise family, its evidence, and the best family."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from ..._runtime import NOT_CONVERGED, SHORT_MEMORY, az, write_json
from ...inference import Comparison, compare_families, keep_warnings
from ...posterior import Summary, criticise, save_posterior, summarize
from ..context import RunContext, StageResult
from .ingestion import Ingested

__all__ = ["Families", "families"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's


@dataclass(frozen=True)
class Families(StageResult):
    """The comparison and its JSON (``compare.json``), the best family's posterior and summary.

    ``compared`` are the families in the order compared, ``paths`` each
    one's posterior file (``posteriors/<family>.nc``), ``convergence`` the
    messages of the chains that did not converge.
    """

    comparison: Comparison
    comparison_json: dict
    compared: tuple[str, ...]
    summary: Summary
    paths: dict[str, Path]
    posterior_file: Path
    convergence: list[str] = field(default_factory=list)

    @property
    def best(self) -> str:
        return self.comparison.best

    @property
    def posterior(self) -> az.InferenceData:
        return self.comparison.posteriors[self.best]

    @property
    def ranked(self) -> list[str]:
        """The families compared, the best first."""
        return [self.best, *(family for family in self.compared if family != self.best)]

    def to_dict(self) -> dict:
        convergence = [{"kind": NOT_CONVERGED, "message": m} for m in self.convergence]
        return {
            "comparison": self.comparison_json,
            "best": self.best,
            "posterior": self.summary.to_dict(),
            "warnings": convergence + self.comparison_json["warnings"],
        }

    def files(self) -> dict[str, str | None]:
        return {"posterior": str(self.posterior_file)}


def families(context: RunContext, done: Mapping[str, StageResult]) -> Families:
    """Compare the families; save each posterior as it finishes, then the best one's files.

    With the default families, the short-memory exponential family is
    compared too where white beats gaussian, as gaussian's smooth kernel
    fits colour of a few samples worse than white does.
    """
    ingested: Ingested = done["ingest"]
    requested = context.requested_families
    channels = ingested.fit.likelihood_options.channels
    _log.info(
        f"posterior and evidence of {', '.join(requested)} noise on {', '.join(channels)}, "
        f"pooled over {len(ingested.experiments)} experiment(s):"
    )
    paths = {f: context.out / "posteriors" / f"{f}.nc" for f in (*requested, SHORT_MEMORY)}
    compared = requested
    try:
        with keep_warnings() as kept:
            comparison = _compare(context, ingested, compared, paths)
            if (
                context.families is None
                and comparison.best == "white"
                and SHORT_MEMORY not in compared
            ):
                _log.info(f"  white beat gaussian: {SHORT_MEMORY} (short-memory colour) is "
                          "compared too, as gaussian's smooth kernel fits colour of a few "
                          "samples worse than white does")  # fmt: skip
                compared = (*compared, SHORT_MEMORY)
                comparison = _compare(context, ingested, compared, paths)
    finally:
        # The convergence warnings go into the result; the others reach the user,
        # also those raised before the comparison failed.
        kept.issue()
    idata = comparison.posteriors[comparison.best]
    save_posterior(idata, posterior_file := context.out / "posterior.nc")
    summary = summarize(idata)
    write_json(context.out / "posterior.json", summary)
    write_json(context.out / "compare.json", comparison_json := comparison.to_dict())
    return Families(
        comparison, comparison_json, compared, summary, paths, posterior_file, kept.convergence
    )


def _compare(
    context: RunContext, ingested: Ingested, families: tuple[str, ...], paths: dict[str, Path]
) -> Comparison:
    def finished(family, evidence, idata) -> None:
        criticise(idata)  # cached in its attrs: the saved file and the report reuse it
        save_posterior(idata, paths[family])  # kept if interrupted, reused on a rerun
        _log.info(f"  {family}: log evidence {evidence.log_evidence:.2f} +- {evidence.error:.3f}")

    return compare_families(
        ingested.experiments,
        ingested.fit,
        families=families,
        executor=context.executor,
        reuse=paths,
        on_family=finished,
    )
