"""Stage: every run's one-step residuals under the best posterior, one table (``residuals.csv``).

One row per residual: the run, the channel, the time its last sample was
taken [s] (:func:`bayes_jackal.likelihood.residual_times`) and the residual
in the channel's unit (eq. 7-3; [rad/s] for yaw, [m/s] for vx and vy), at
the posterior median of the damping, on the steady window where the
likelihood used it: the series the report's residual figures draw, for a
user's own plots or tests.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import dataclass

from ..._runtime import atomic_path
from ...io import CHANNEL_FIELDS, UNITS
from ...likelihood import residual_times
from ...posterior import Posterior, observed_residuals
from ..context import RunContext, StageResult, WrittenFile
from .family_comparison import Families

__all__ = ["ResidualTable", "residual_table"]

#: The table's columns.
COLUMNS = ("run", "channel", "unit", "t", "residual")


@dataclass(frozen=True)
class ResidualTable(WrittenFile):
    """Where the residual table was written (``files``' ``residuals``), and its rows."""

    rows: int


def residual_table(context: RunContext, done: Mapping[str, StageResult]) -> ResidualTable:
    """Write ``residuals.csv``: the best posterior's one-step residuals, every run and channel."""
    families: Families = done["families"]
    posterior = Posterior.of(families.posterior)
    steady, rows = posterior.metadata.steady, 0
    path = context.out / "residuals.csv"
    with atomic_path(path) as temporary, temporary.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(COLUMNS)
        for index, experiment in enumerate(posterior.experiments):
            for channel in posterior.metadata.channels:
                residuals = observed_residuals(families.posterior, index, channel)
                times = residual_times(experiment, channel, steady)
                unit = UNITS[CHANNEL_FIELDS[channel]]
                writer.writerows(
                    (experiment.name, channel, unit, f"{t:.6f}", f"{r:.9g}")
                    for t, r in zip(times, residuals, strict=True)
                )
                rows += len(residuals)
    return ResidualTable("residuals", path, rows)
