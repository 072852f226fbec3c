"""The report stage: ``report.html``, the families' posteriors best first, the stages' sections."""

from __future__ import annotations

import logging
from collections.abc import Mapping

from ...report import formats_text, write_report
from ..context import RunContext, StageResult, WrittenFile
from .family_comparison import Families

__all__ = ["report"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's


def report(context: RunContext, done: Mapping[str, StageResult]) -> WrittenFile:
    """The report of the families' posteriors with the sections the stages before it add.

    A stage's :meth:`~bayes_jackal.workflow.StageResult.report_section` and
    :meth:`~bayes_jackal.workflow.StageResult.highlight` join the report in
    the order of their ``report_rank``, then of the pipeline.
    """
    files = formats_text(context.figure_formats)
    _log.info(f"writing the report (figures as {files or 'embedded images only'})...")
    families: Families = done["families"]
    ranked = sorted(done.values(), key=lambda result: result.report_rank)  # stable
    return WrittenFile(
        "report",
        write_report(
            [families.paths[family] for family in families.ranked],
            context.out / "report.html",
            formats=context.figure_formats,
            sections=[s for r in ranked if (s := r.report_section()) is not None],
            highlights=[h for r in ranked if (h := r.highlight())],
        ),
    )
