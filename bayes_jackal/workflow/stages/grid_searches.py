"""Stage 2: the thesis' grid searches of the yaw channel over the prior ranges."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

from ..._runtime import GRID_METHODS, write_json
from ...io import Experiment
from ...report import save_grid_plot
from ...thesis import grid_search, prior_grid
from ..context import RunContext, StageResult
from .ingestion import Ingested

__all__ = ["Grids", "grids"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's


@dataclass(frozen=True)
class Grids(StageResult):
    """Each method's grid summary (:meth:`~bayes_jackal.thesis.GridResult.summary`)."""

    summaries: dict[str, dict]

    def to_dict(self) -> dict:
        return {"grids": self.summaries}


def grids(context: RunContext, done: Mapping[str, StageResult]) -> Grids:
    """The one-step and simulation grids (ch. 9-1-2 and 5): PNG surfaces, minima in grid.json.

    The grids span the robot's prior ranges of d_lat and d_long (with the
    context's damping overrides), log-spaced (:func:`bayes_jackal.thesis.prior_grid`).
    """
    ingested: Ingested = done["ingest"]
    experiments, robot = ingested.experiments, context.robot
    _log.info("thesis grid searches of the yaw channel (ch. 5 and 9-1-2) over the prior ranges:")
    summaries = {}
    for method in GRID_METHODS:
        axes = (
            prior_grid(robot, name, method, context.prior_overrides)
            for name in ("d_lat", "d_long")
        )
        result = grid_search(
            experiments, robot, *axes, method=method, progress=context.settings.progress
        )
        best_lat, best_long, _ = result.argmin()
        save_grid_plot(result, context.out / f"grid_{method}.png")
        edges = ", ".join(f"{name} {side}" for name, side in result.edges().items())
        _log.info(
            f"  {method} MSE grid minimum: d_lat = {best_lat:.4g}, d_long = {best_long:.4g} N s/m"
            + (f" (on the grid's edge: {edges})" if edges else "")
            + (f"; {result.caveat}" if result.caveat else "")
        )
        summaries[method] = result.summary()
    write_json(context.out / "grid.json", {"truth": _common_truth(experiments), **summaries})
    return Grids(summaries)


def _common_truth(experiments: list[Experiment]) -> dict | None:
    """The true damping all experiments share (simulated runs), else None."""
    truths = [{key: (e.truth or {}).get(key) for key in ("d_lat", "d_long")} for e in experiments]
    shared = truths[0]
    return shared if None not in shared.values() and all(t == shared for t in truths) else None
