"""The stages of an analysis, each a function of the run context and the results before it.

Each module is one stage and its typed result: :mod:`.ingestion`,
:mod:`.grid_searches`, :mod:`.family_comparison`, :mod:`.prior_export`, :mod:`.left_out`,
:mod:`.groups` and :mod:`.report_page`. The pipeline
(:data:`bayes_jackal.workflow.PIPELINE`) runs them in order.
"""

from .family_comparison import Families, families
from .grid_searches import Grids, grids
from .groups import GroupsPopulation, groups_population
from .ingestion import Ingested, ingest
from .left_out import StateEstimation, state_estimation
from .prior_export import PriorFile, prior
from .report_page import ReportFile, report

__all__ = [
    "Families",
    "Grids",
    "GroupsPopulation",
    "Ingested",
    "PriorFile",
    "ReportFile",
    "StateEstimation",
    "families",
    "grids",
    "groups_population",
    "ingest",
    "prior",
    "report",
    "state_estimation",
]
