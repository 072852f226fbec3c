"""Stage 6, with groups: each group's damping and their population (``population.json``)."""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from ..._runtime import write_json
from ...inference import population_posterior
from ...report import population_highlight, population_section, save_population_plot
from ..context import RunContext, StageResult
from .ingestion import Ingested

__all__ = ["GroupsPopulation", "groups_population"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__.removesuffix(".stages"))  # the workflow's


@dataclass(frozen=True)
class GroupsPopulation(StageResult):
    """The population's JSON (:meth:`bayes_jackal.inference.Population.to_dict`), or None."""

    summary: dict | None
    path: str | None
    #: A campaign's groups come first in the report, before its state estimation.
    report_rank = -1

    def to_dict(self) -> dict:
        return {"population": self.summary}

    def files(self) -> dict[str, str | None]:
        return {"population": self.path}

    def report_section(self) -> Callable | None:
        if self.summary is None:
            return None
        return functools.partial(population_section, self.summary)

    def highlight(self) -> str | None:
        return None if self.summary is None else population_highlight(self.summary)


def groups_population(context: RunContext, done: Mapping[str, StageResult]) -> GroupsPopulation:
    """With the context's groups, the population of the best family (else nothing).

    Saved as ``population.json``, ``population.png`` and ``population/units/``.
    """
    if context.groups is None:
        return GroupsPopulation(None, None)
    ingested: Ingested = done["ingest"]
    best = done["families"].best
    _log.info(f"each group's damping and their population ({best} noise):")
    summary = population_posterior(
        ingested.experiments,
        ingested.fit,
        groups=context.groups,
        family=best,
        executor=context.executor,
        out=context.out / "population",
    ).to_dict()
    write_json(path := context.out / "population.json", summary)
    save_population_plot(summary, context.out / "population.png")
    return GroupsPopulation(summary, str(path))
