"""Stage 1: every log ingested into ``experiments/<name>.nc``, and the runs a model can take."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..._runtime import DataError, describe
from ...inference import FitOptions, plan_units
from ...io import Experiment, ingest_logs
from ...likelihood import resolve_channels
from ..context import RunContext, StageResult

__all__ = ["Ingested", "ingest"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's


@dataclass(frozen=True)
class Ingested(StageResult):
    """The experiments every later stage takes, and the inputs that could not be used.

    ``fit`` are the context's fit options, the likelihood's channels
    resolved (every channel all experiments measure, by default): the
    options of every later chain.
    """

    experiments: list[Experiment]
    failed: dict[str, str]
    fit: FitOptions
    folder: Path

    def to_dict(self) -> dict:
        return {
            "experiments": {
                e.name: {
                    "file": str(self.folder / f"{e.name}.nc"),
                    "source": e.source,
                    "samples": len(e.t),
                    "rate": 1.0 / e.dt,
                    "channels": list(e.channels),
                    "steady_window": e.steady_window,
                }
                for e in self.experiments
            },
            "failed": self.failed,
            "channels": list(self.fit.likelihood_options.channels),
        }


def ingest(context: RunContext, done: Mapping[str, StageResult]) -> Ingested:
    """Read every input, keep those a likelihood of the first family can take.

    A log no model can use (poses that do not cover its samples, a channel
    too short) is named and skipped before the grids, not found after
    minutes of work; none usable is a :class:`DataError` naming each reason.
    """
    folder = context.out / "experiments"
    experiments, failed = ingest_logs(
        context.inputs,
        context.robot,
        folder,
        read_options=context.read_options,
        progress=context.settings.progress,
        labels=context.labels,
    )
    _refuse_none(experiments, failed)
    options = context.likelihood_options
    experiments, unusable = _usable(experiments, context)
    _refuse_none(experiments, failed := failed | unusable)
    options = dataclasses.replace(
        options, channels=resolve_channels(experiments, options.channels)
    )
    if context.groups is not None:  # runs the groups do not name refused before any work
        plan_units(experiments, context.groups, noise=options.noise)
    fit = dataclasses.replace(FitOptions.of(context), likelihood_options=options)
    return Ingested(experiments, failed, fit, folder)


def _refuse_none(experiments: list[Experiment], failed: dict[str, str]) -> None:
    if not experiments:
        raise DataError(
            f"none of the {len(failed)} inputs could be used: " + "; ".join(failed.values()),
            field="inputs",
        )


def _usable(
    experiments: list[Experiment], context: RunContext
) -> tuple[list[Experiment], dict[str, str]]:
    """The experiments a likelihood can take, each alone; the others' reasons, by source."""
    usable, failed = [], {}
    for experiment in experiments:
        try:
            context.likelihood_options.likelihood(
                [experiment], context.robot, context.requested_families[0]
            )
        except DataError as exc:
            failed[experiment.source] = describe(exc, experiment.source)
            _log.info(f"  skipped {failed[experiment.source]}")
        else:
            usable.append(experiment)
    return usable, failed
