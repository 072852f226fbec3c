"""Stage 4: the Active Inference prior of the best family, ``prior.json``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ...dem import export_prior, write_prior
from ..context import RunContext, StageResult
from .family_comparison import Families

__all__ = ["PriorFile", "prior"]


@dataclass(frozen=True)
class PriorFile(StageResult):
    """Where the exported prior was written."""

    path: Path

    def files(self) -> dict[str, str | None]:
        return {"prior": str(self.path)}


def prior(context: RunContext, done: Mapping[str, StageResult]) -> PriorFile:
    """The prior of the best family's posterior, at the highest order it allows.

    Order 2 or the highest the family and the precision's conditioning
    allow (:data:`bayes_jackal.dem.export.AUTO_ORDER`,
    :func:`bayes_jackal.dem.allowed_orders`; 0 for white noise).
    """
    families: Families = done["families"]
    source = str(families.paths[families.best])
    exported = export_prior(families.posterior, order=None, source=source)
    return PriorFile(write_prior(exported, context.out / "prior.json"))
