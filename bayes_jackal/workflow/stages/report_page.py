"""The last stage: ``report.html``, the families' posteriors best first, the stages' sections."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ...report import write_report
from ..context import RunContext, StageResult
from .family_comparison import Families

__all__ = ["ReportFile", "report"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's


@dataclass(frozen=True)
class ReportFile(StageResult):
    """Where the report was written."""

    path: Path

    def files(self) -> dict[str, str | None]:
        return {"report": str(self.path)}


def report(context: RunContext, done: Mapping[str, StageResult]) -> ReportFile:
    """The report of the families' posteriors with the sections the stages before it add.

    A stage's :meth:`~bayes_jackal.workflow.StageResult.report_section` and
    :meth:`~bayes_jackal.workflow.StageResult.highlight` join the report in
    the order of their ``report_rank``, then of the pipeline.
    """
    _log.info("writing the report (figures as PNG and SVG)...")
    families: Families = done["families"]
    ranked = sorted(done.values(), key=lambda result: result.report_rank)  # stable
    return ReportFile(
        write_report(
            [families.paths[family] for family in families.ranked],
            context.out / "report.html",
            sections=[s for r in ranked if (s := r.report_section()) is not None],
            highlights=[h for r in ranked if (h := r.highlight())],
        )
    )
