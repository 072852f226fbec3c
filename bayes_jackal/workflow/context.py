"""What every stage of an analysis takes, and what each gives.

:class:`RunContext` is one frozen object of the options a whole analysis
shares (the robot, the families, the sampler, the seed, the priors, the
likelihood and read options, the executor, the groups, the output folder),
validated on construction, so that a bad option is refused before a log is
read. A stage (:mod:`bayes_jackal.workflow.stages`) is a function of the
context and the results of the stages before it, and returns a
:class:`StageResult`: its part of the analysis' JSON (``to_dict``), the
files it wrote, and what it adds to the report. A stage may start work
that a later stage takes (:func:`in_background`: the grids run beside the
families' chains, the report's figures are drawn while the filters run).
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._runtime import (
    DEFAULT_FAMILIES,
    REPORT_FORMATS,
    STATE_ESTIMATION,
)
from ..inference import Background, Executor, FitOptions, Pending
from ..io import ReadOptions, RunGroups, as_run_groups
from ..report import figure_formats

__all__ = ["RunContext", "StageResult", "WrittenFile", "background_jobs", "in_background"]

#: Where the running pipeline's background jobs go (:func:`background_jobs`).
_BACKGROUND: contextvars.ContextVar[Background | None] = contextvars.ContextVar(
    "bayes_jackal_background", default=None
)


@dataclass(frozen=True, kw_only=True)
class RunContext(FitOptions):
    """The options of one analysis, which every stage takes.

    A :class:`~bayes_jackal.inference.FitOptions` (the robot, likelihood
    options, priors, sampler settings and seed that every chain of the
    analysis shares), with what the analysis adds.

    Parameters
    ----------
    inputs : tuple of str or Path
        Bags and experiment files (:func:`bayes_jackal.io.ingest_logs`).
    out : Path
        The output folder.
    executor : Executor
        Where the families, the left-out runs and the population's units run.
    robot, likelihood_options, prior_overrides, settings, seed
        As in :class:`~bayes_jackal.inference.FitOptions`.
    families : tuple of str, optional
        The noise families compared; None (default): white and gaussian,
        and the short-memory exponential family too where white wins.
    read_options : ReadOptions, optional
        How the logs are read (window, longest gap, columns, rate, velocities).
    labels : mapping, optional
        Per input path, Experiment fields to set (the demo's truth).
    state_estimation : bool
        Score the filters on each run left out of the prior.
    groups : RunGroups, optional
        Each run's group: the population stage runs with it. A mapping, a
        CSV's path or a RunGroups is read on construction.
    figure_formats : tuple of str
        The figure files written beside the report, from
        :data:`~bayes_jackal._runtime.defaults.FIGURE_FORMATS` (default PNG
        alone; ``("png", "svg")`` for vector figures too).

    Examples
    --------
    >>> from pathlib import Path
    >>> from bayes_jackal.inference import SerialExecutor
    >>> from bayes_jackal.workflow import RunContext
    >>> context = RunContext(
    ...     inputs=["run1.bag"], out=Path("analysis"), executor=SerialExecutor(), seed=1
    ... )
    >>> context.families, context.robot.name, context.likelihood_options.noise
    (None, 'jackal', 'shared')
    >>> context.requested_families
    ('white', 'gaussian')
    """

    inputs: tuple[str | Path, ...]
    out: Path
    executor: Executor
    families: tuple[str, ...] | None = None
    read_options: ReadOptions | None = None
    labels: Mapping[str, Mapping] | None = None
    state_estimation: bool = STATE_ESTIMATION
    groups: RunGroups | None = None
    figure_formats: tuple[str, ...] = REPORT_FORMATS

    def __post_init__(self) -> None:
        super().__post_init__()
        # Refused before a log is read or a grid written.
        self.settings.check_evidence_steps()
        set_field = object.__setattr__  # normalised once, as the frozen fields they are
        set_field(self, "inputs", tuple(self.inputs))
        set_field(self, "out", Path(self.out))
        if self.families is not None:
            set_field(self, "families", tuple(self.families))
        if self.groups is not None:  # a bad groups file refused before a log is read
            set_field(self, "groups", as_run_groups(self.groups))
        formats = figure_formats(self.figure_formats, field="figure_formats")
        set_field(self, "figure_formats", formats)

    @property
    def requested_families(self) -> tuple[str, ...]:
        """The families to compare first (the defaults without ``families``)."""
        return tuple(DEFAULT_FAMILIES) if self.families is None else self.families


class StageResult:
    """What a stage of the analysis gives (a base of the stages' typed results).

    ``to_dict()`` is its part of the analysis' JSON (the ``--json`` object of
    ``analyse``): its keys join the object's in the pipeline's order, a
    ``warnings`` list joins the list before it. ``files()`` names the files
    it wrote (the object's ``files``); ``report_section()`` (a function of
    the report's figures, returning HTML) and ``highlight()`` (a line of the
    report's summary) are what it adds to the report, if anything; the
    report orders them by ``report_rank`` (lower first), then by the
    pipeline's order.

    Examples
    --------
    >>> from bayes_jackal.workflow import StageResult
    >>> class Nothing(StageResult):
    ...     pass
    >>> Nothing().to_dict(), Nothing().files(), Nothing().report_section()
    ({}, {}, None)
    """

    #: Where the stage's section and highlight go in the report (lower: earlier).
    report_rank: int = 0

    def to_dict(self) -> dict:
        return {}

    def files(self) -> dict[str, str | None]:
        return {}

    def report_section(self) -> Callable | None:
        return None

    def highlight(self) -> str | None:
        return None


@dataclass(frozen=True)
class WrittenFile(StageResult):
    """The result of a stage that writes one file: the file, under its key in ``files``.

    Examples
    --------
    >>> from pathlib import Path
    >>> from bayes_jackal.workflow import WrittenFile
    >>> WrittenFile("prior", Path("analysis/prior.json")).files()
    {'prior': 'analysis/prior.json'}
    """

    key: str
    path: Path

    def files(self) -> dict[str, str | None]:
        return {self.key: str(self.path)}


@contextlib.contextmanager
def background_jobs(context: RunContext) -> Iterator[None]:
    """While the block runs, :func:`in_background` jobs go to one more local process.

    Where the context's executor runs jobs side by side (local processes,
    a cluster), the machine has a core for them; a serial analysis runs
    each where its result is taken. Leaving the block takes every result
    not taken yet (its lines told, its error raised), or on an exception
    (an interrupt) stops the jobs (:class:`~bayes_jackal.inference.Background`).
    """
    with Background(local=context.executor.slots(2) > 1) as background:
        token = _BACKGROUND.set(background)
        try:
            yield
        finally:
            _BACKGROUND.reset(token)


def in_background(work: Callable[..., Any], *args) -> Pending:
    """Start ``work(*args)`` beside the stages that follow; a later stage takes its result.

    ``work`` and ``args`` are picklable (a module-level function and data).
    Outside :func:`background_jobs` (a stage called on its own) the job
    runs where its result is taken.

    Examples
    --------
    >>> from bayes_jackal.workflow.context import in_background
    >>> in_background(sum, [1, 2, 3]).result()
    6
    """
    return (_BACKGROUND.get() or Background(local=False)).submit(work, *args)
