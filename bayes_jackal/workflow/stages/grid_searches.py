"""Stage 2: the thesis' grid searches of the yaw channel, beside the families' chains."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..._runtime import GRID_METHODS, write_json
from ...inference import Pending
from ...io import Experiment
from ...model import RobotProfile
from ...report import save_grid_plot
from ...thesis import grid_search, prior_grid
from ..context import RunContext, StageResult, in_background
from .ingestion import Ingested

__all__ = ["Grids", "grid_searches", "grids"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's


@dataclass(frozen=True)
class Grids(StageResult):
    """Each method's grid summary (:meth:`~bayes_jackal.thesis.GridResult.summary`).

    The grids run beside the stages after them (:func:`grids`): their
    summaries, and the lines they tell, come where they are first taken.
    """

    pending: Pending

    @property
    def summaries(self) -> dict[str, dict]:
        """Method -> its summary (waiting for the grids)."""
        return self.pending.result()

    def to_dict(self) -> dict:
        return {"grids": self.summaries}


def grids(context: RunContext, done: Mapping[str, StageResult]) -> Grids:
    """The one-step and simulation grids (ch. 9-1-2 and 5): PNG surfaces, minima in grid.json.

    The grids span the robot's prior ranges of d_lat and d_long (with the
    context's damping overrides), log-spaced (:func:`bayes_jackal.thesis.prior_grid`).
    They need no other stage's result: they run in the background
    (:func:`~bayes_jackal.workflow.context.in_background`), beside the
    families' chains, on the core the chains leave between them; their
    lines are told when the pipeline ends (or their result is first taken).
    """
    ingested: Ingested = done["ingest"]
    return Grids(
        in_background(
            grid_searches,
            ingested.experiments,
            context.robot,
            context.prior_overrides,
            context.out,
            context.settings.progress,
        )
    )


def grid_searches(
    experiments: list[Experiment],
    robot: RobotProfile,
    prior_overrides: Mapping | None,
    out: Path,
    progress: bool = False,
) -> dict[str, dict]:
    """Each method's grid over the prior ranges: its surface plotted, its minimum told.

    Writes ``grid_<method>.png`` and ``grid.json`` in ``out``; returns each
    method's summary. ``progress``: a ticking line while each grid runs.
    """
    _log.info("thesis grid searches of the yaw channel (ch. 5 and 9-1-2) over the prior ranges:")
    summaries = {}
    for method in GRID_METHODS:
        axes = (prior_grid(robot, name, method, prior_overrides) for name in ("d_lat", "d_long"))
        result = grid_search(experiments, robot, *axes, method=method, progress=progress)
        best_lat, best_long, _ = result.argmin()
        save_grid_plot(result, out / f"grid_{method}.png")
        edges = ", ".join(f"{name} {side}" for name, side in result.edges().items())
        _log.info(
            f"  {method} MSE grid minimum: d_lat = {best_lat:.4g}, d_long = {best_long:.4g} N s/m"
            + (f" (on the grid's edge: {edges})" if edges else "")
            + (f"; {result.caveat}" if result.caveat else "")
        )
        summaries[method] = result.summary()
    write_json(out / "grid.json", {"truth": _common_truth(experiments), **summaries})
    return summaries


def _common_truth(experiments: list[Experiment]) -> dict | None:
    """The true damping all experiments share (simulated runs), else None."""
    truths = [{key: (e.truth or {}).get(key) for key in ("d_lat", "d_long")} for e in experiments]
    shared = truths[0]
    return shared if None not in shared.values() and all(t == shared for t in truths) else None
