"""Stage 5: the filters on each run left out of the prior (``state_estimation/``)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from ..._runtime import NOT_CONVERGED
from ...filters import SUMMARY, LeaveOneOut, leave_one_out
from ...report import state_estimation_highlight, state_estimation_section
from ..context import RunContext, StageResult
from .family_comparison import Families
from .ingestion import Ingested

__all__ = ["StateEstimation", "state_estimation"]


@dataclass(frozen=True)
class StateEstimation(StageResult):
    """Each left-out run's filters and scores (:class:`~bayes_jackal.filters.LeaveOneOut`)."""

    left_out: LeaveOneOut
    summary_file: str

    def to_dict(self) -> dict:
        convergence = [
            {"kind": NOT_CONVERGED, "message": f"leaving out {run}: {message}", "left_out": run}
            for run, record in self.left_out.runs.items()
            for message in record["warnings"]
        ]
        return {"warnings": convergence, "state_estimation": self.left_out.to_dict()}

    def files(self) -> dict[str, str | None]:
        return {"state_estimation": self.summary_file if self.left_out.skipped is None else None}

    def report_section(self) -> Callable:
        return functools.partial(state_estimation_section, self.left_out)

    def highlight(self) -> str | None:
        return state_estimation_highlight(self.left_out)


def state_estimation(context: RunContext, done: Mapping[str, StageResult]) -> StateEstimation:
    """Each run's posterior without it, then its filters driven by that prior, scored.

    The best family's pooled posterior reweighted by PSIS, or refit where
    the reweighting's Pareto k-hat is above 0.7
    (:func:`bayes_jackal.filters.leave_one_out`); turned off by the context's
    ``state_estimation``.
    """
    ingested: Ingested = done["ingest"]
    families: Families = done["families"]
    summary_file = str(context.out / SUMMARY)
    if not context.state_estimation:
        skipped = LeaveOneOut(families.best, skipped="turned off (--no-state-estimation)")
        return StateEstimation(skipped, summary_file)
    left_out = leave_one_out(
        ingested.experiments,
        families.best,
        context.out,
        ingested.fit,
        pooled=families.posterior,
        pooled_source=str(families.paths[families.best]),
        executor=context.executor,
    )
    return StateEstimation(left_out, summary_file)
