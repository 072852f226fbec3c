"""Stage 4: the Active Inference prior of the best family, ``prior.json``."""

from __future__ import annotations

from collections.abc import Mapping

from ...dem import export_prior, write_prior
from ..context import RunContext, StageResult, WrittenFile
from .family_comparison import Families

__all__ = ["prior"]


def prior(context: RunContext, done: Mapping[str, StageResult]) -> WrittenFile:
    """The prior of the best family's posterior, at the highest order it allows.

    Order 2 or the highest the family and the precision's conditioning
    allow (:data:`bayes_jackal.dem.export.AUTO_ORDER`,
    :func:`bayes_jackal.dem.allowed_orders`; 0 for white noise).
    """
    families: Families = done["families"]
    source = str(families.paths[families.best])
    exported = export_prior(families.posterior, order=None, source=source)
    return WrittenFile("prior", write_prior(exported, context.out / "prior.json"))
