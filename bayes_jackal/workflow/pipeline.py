"""The analysis as a pipeline of stages, and its typed result.

:data:`PIPELINE` lists the stages in the order they run, each a function
``stage(context, done)`` of the :class:`~bayes_jackal.workflow.RunContext`
and the results of the stages before it (by name), returning a
:class:`~bayes_jackal.workflow.StageResult`. Adding a stage is one module
in :mod:`bayes_jackal.workflow.stages` and one line here: its result's
``to_dict()`` joins the analysis' JSON, its ``files()`` the files, and its
``report_section()`` and ``highlight()`` the report (a stage before it). A
stage that only writes files of its own (the residual table) runs after
the report, so that its failure cannot cost the report.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from .._runtime import InputError
from .context import RunContext, StageResult, background_jobs
from .stages.family_comparison import families
from .stages.grid_searches import grids
from .stages.groups import groups_population
from .stages.ingestion import ingest
from .stages.left_out import state_estimation
from .stages.prior_export import prior
from .stages.report_page import report, report_sections
from .stages.residual_table import residual_table

__all__ = ["PIPELINE", "Analysis", "run_pipeline"]

#: A stage: the run context and the results before it (by name) -> its result.
Stage = Callable[[RunContext, Mapping[str, StageResult]], StageResult]

#: The stages of an analysis, in the order they run.
PIPELINE: tuple[Stage, ...] = (
    ingest,
    grids,
    families,
    prior,
    report_sections,
    state_estimation,
    groups_population,
    report,
    residual_table,
)


@dataclass(frozen=True)
class Analysis:
    """The result of an analysis: each stage's typed result, by the stage's name.

    Examples
    --------
    >>> from bayes_jackal.workflow import Analysis, StageResult
    >>> class Counted(StageResult):
    ...     def to_dict(self):
    ...         return {"count": 3, "warnings": [{"kind": "k", "message": "m"}]}
    >>> Analysis("out", {"counted": Counted()}).to_dict()
    {'count': 3, 'warnings': [{'kind': 'k', 'message': 'm'}], 'files': {'folder': 'out'}}
    """

    folder: str
    results: Mapping[str, StageResult]

    def __getitem__(self, stage: str) -> StageResult:
        return self.results[stage]

    @property
    def best(self) -> str:
        """The noise family of highest evidence."""
        return self.results["families"].best

    def to_dict(self) -> dict:
        """The ``--json`` object of ``analyse``: each stage's part in order, then ``files``.

        A stage's ``warnings`` join those of the stages before it. ``files``
        names the report first (the file to open), then each stage's files
        in order, then the folder.
        """
        payload: dict = {}
        files: dict[str, str | None] = {}
        for result in self.results.values():
            for key, value in result.to_dict().items():
                joined = key == "warnings" and key in payload
                payload[key] = [*payload[key], *value] if joined else value
            files |= result.files()
        report = {"report": files.pop("report")} if "report" in files else {}
        return {**payload, "files": {**report, **files, "folder": self.folder}}


def run_pipeline(context: RunContext, stages: tuple[Stage, ...] = PIPELINE) -> Analysis:
    """Run ``stages`` in order on ``context``; each sees the results before it.

    Parameters
    ----------
    context : RunContext
        The options every stage takes.
    stages : tuple of callables
        Each ``stage(context, done) -> StageResult``; its result is kept under
        the function's name. Default: :data:`PIPELINE`, the whole analysis.

    Returns
    -------
    Analysis

    Examples
    --------
    A pipeline of one stage of one's own, which counts the inputs:

    >>> from dataclasses import dataclass
    >>> from bayes_jackal.inference import SerialExecutor
    >>> from bayes_jackal.workflow import RunContext, StageResult, run_pipeline
    >>> @dataclass(frozen=True)
    ... class Counted(StageResult):
    ...     inputs: int
    ...
    ...     def to_dict(self):
    ...         return {"inputs": self.inputs}
    >>> def count_inputs(context, done):
    ...     return Counted(len(context.inputs))
    >>> context = RunContext(inputs=["a.bag", "b.bag"], out="out", executor=SerialExecutor())
    >>> analysis = run_pipeline(context, (count_inputs,))
    >>> analysis["count_inputs"].inputs, analysis.to_dict()
    (2, {'inputs': 2, 'files': {'folder': 'out'}})
    """
    names = [getattr(stage, "__name__", "<lambda>") for stage in stages]
    for stage, name in zip(stages, names, strict=True):  # refused before any stage runs
        if name == "<lambda>" or names.count(name) > 1:
            raise InputError(
                f"stages: {stage!r} needs a name of its own (a def), to keep its result by",
                field="stages",
            )
    done: dict[str, StageResult] = {}
    with background_jobs(context):
        for stage, name in zip(stages, names, strict=True):
            done[name] = stage(context, done)
    return Analysis(str(context.out), done)
