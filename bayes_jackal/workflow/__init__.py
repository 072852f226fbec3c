"""The whole analysis of a set of logs, and the demo on the embedded data."""

from .analysis import analyse_logs, ingest_logs, read_log
from .api import compare, load_experiments, read_logs, sample
from .demo import DEMO_FAMILIES, DEMO_TRUTH, demo_folder, demo_labels, make_demo_bags, run_demo

__all__ = [
    "DEMO_FAMILIES",
    "DEMO_TRUTH",
    "analyse_logs",
    "compare",
    "demo_folder",
    "demo_labels",
    "ingest_logs",
    "load_experiments",
    "make_demo_bags",
    "read_log",
    "read_logs",
    "run_demo",
    "sample",
]
