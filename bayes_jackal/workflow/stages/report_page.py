"""The report: each family's section drawn while the filters run, then ``report.html``.

:func:`report_sections` starts drawing the families' sections (their
criticism and figures) in the background as soon as their posteriors are
saved (:func:`~bayes_jackal.workflow.context.in_background`); :func:`report`
writes the page around them with the sections the other stages add.
Drawn beside the state estimation, the figures cost the demo little of its
wall time (they were a quarter of it, drawn after).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

from ..._runtime import refuse
from ...inference import Pending
from ...report import draw_posterior_sections, formats_text, read_posteriors, save_report
from ..context import RunContext, StageResult, WrittenFile, in_background
from .family_comparison import Families

__all__ = ["REPORT", "DrawnSections", "report", "report_sections"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's

#: The report's file name in the analysis folder.
REPORT = "report.html"


@dataclass(frozen=True)
class DrawnSections(StageResult):
    """The families' sections of the report, best first, drawn beside the stages after it."""

    pending: Pending

    def sections(self) -> list[str]:
        """The sections' HTML (waiting for them); their messages told here."""
        return self.pending.result()


def _ranked_paths(done: Mapping[str, StageResult]) -> list:
    families: Families = done["families"]
    return [families.paths[family] for family in families.ranked]


def report_sections(context: RunContext, done: Mapping[str, StageResult]) -> DrawnSections:
    """Start drawing each family's section of the report, the best first."""
    return DrawnSections(
        in_background(
            draw_posterior_sections,
            _ranked_paths(done),
            context.out / REPORT,
            context.figure_formats,
        )
    )


def report(context: RunContext, done: Mapping[str, StageResult]) -> WrittenFile:
    """The report of the families' posteriors with the sections the stages before it add.

    A stage's :meth:`~bayes_jackal.workflow.StageResult.report_section` and
    :meth:`~bayes_jackal.workflow.StageResult.highlight` join the report in
    the order of their ``report_rank``, then of the pipeline. The families'
    own sections are :func:`report_sections`'s where it ran, else drawn here.
    """
    files = formats_text(context.figure_formats)
    _log.info(f"writing the report (figures as {files or 'embedded images only'})...")
    paths = _ranked_paths(done)
    drawn = done["report_sections"].sections() if "report_sections" in done else None
    posteriors, failed = read_posteriors(paths)
    refuse(failed, len(paths))
    ranked = sorted(done.values(), key=lambda result: result.report_rank)  # stable
    return WrittenFile(
        "report",
        save_report(
            posteriors,
            context.out / REPORT,
            context.figure_formats,
            sections=[s for r in ranked if (s := r.report_section()) is not None],
            highlights=[h for r in ranked if (h := r.highlight())],
            drawn=drawn,
        ),
    )
