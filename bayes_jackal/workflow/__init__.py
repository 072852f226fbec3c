"""The whole analysis of a set of logs, and the demo on the embedded data."""

from .analysis import analyse_logs
from .context import RunContext, StageResult, WrittenFile, background_jobs, in_background
from .demo import DEMO_FAMILIES, DEMO_TRUTH, demo_folder, demo_labels, make_demo_bags, run_demo
from .pipeline import PIPELINE, Analysis, run_pipeline

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "PIPELINE",
    "Analysis",
    "RunContext",
    "StageResult",
    "analyse_logs",
    "demo_folder",
    "run_demo",
    "run_pipeline",
]
