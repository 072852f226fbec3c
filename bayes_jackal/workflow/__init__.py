"""The whole analysis of a set of logs, and the demo on the embedded data."""

from .analysis import analyse_logs
from .demo import DEMO_FAMILIES, DEMO_TRUTH, demo_folder, demo_labels, make_demo_bags, run_demo

__all__ = [
    "DEMO_FAMILIES",
    "DEMO_TRUTH",
    "analyse_logs",
    "demo_folder",
    "demo_labels",
    "make_demo_bags",
    "run_demo",
]
