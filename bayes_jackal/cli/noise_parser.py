"""The flags of ``bayes-jackal noise`` (a bare noise series), apart from the main parser.

Like :mod:`.parser` it loads no numpy: the names and defaults are the
library's, from :mod:`bayes_jackal._runtime.defaults`.
"""

from __future__ import annotations

import argparse
import os

from .._runtime import (
    AUTO_ORDER,
    MAX_GAP_STEPS,
    MIN_EVIDENCE_STEPS,
    NOISE_MAX_STEPS,
    SERIES_ENGINES,
)
from .parser_types import add_formats_flag, add_prior_flag, count, family_list, natural, positive


def add_noise_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``noise SERIES... [flags]`` to the subcommands."""
    noise = commands.add_parser(
        "noise", help="a bare noise series: families, smoothness and evidence"
    )
    noise.add_argument(
        "series", nargs="+", metavar="SERIES", help="CSV, MATLAB (.mat) or bag (.bag, .mcap, .db3)"
    )
    noise.add_argument("--column", metavar="NAME", help="the series' column (CSV, .mat)")
    noise.add_argument(
        "--time-column",
        metavar="NAME",
        help="the time stamps' column [s] (CSV, .mat; default the one named t or time)",
    )
    noise.add_argument(
        "--rate",
        type=positive,
        metavar="HZ",
        help="sampling rate [Hz] of a file without a time column",
    )
    noise.add_argument("--topic", metavar="NAME", help="a bag's topic, e.g. /imu/data")
    noise.add_argument(
        "--field", metavar="PATH", help="the topic's field, e.g. angular_velocity.z"
    )
    noise.add_argument(
        "--max-gap",
        type=positive,
        default=None,
        help=f"longest dropout filled [s] (default {MAX_GAP_STEPS} sample steps)",
    )
    noise.add_argument(
        "--families",
        type=family_list,
        metavar="white,gaussian,...",
        help="comma-separated families (every registered family)",
    )
    noise.add_argument(
        "--out",
        metavar="DIR",
        help="write <series>.noise.json, <series>.prior.json and noise_report.html here",
    )
    noise.add_argument(
        "--order",
        type=natural,
        default=None,
        help="embedding order P of <series>.prior.json, the best family's DEM prior "
        f"(default {AUTO_ORDER}, or the highest the family allows)",
    )
    noise.add_argument("--seed", type=natural, default=None, help="seed: same seed, same answer")
    noise.add_argument(
        "--max-steps",
        type=count,
        default=NOISE_MAX_STEPS,
        help=f"step cap per family ({NOISE_MAX_STEPS}; bridge sampling needs "
        f"{MIN_EVIDENCE_STEPS})",
    )
    add_prior_flag(
        noise,
        "replace a prior range: sigma_h (or width, the width [s]), sigma_c, sigma_n, sigma "
        "(white noise's sd), e.g. --prior width 0.001 2",
    )
    add_formats_flag(noise)
    noise.add_argument(
        "--engine",
        choices=SERIES_ENGINES,
        default=SERIES_ENGINES[0],
        help=f"likelihood engine ({SERIES_ENGINES[0]})",
    )
    noise.add_argument(
        "--processes",
        type=count,
        default=os.cpu_count() or 1,
        help="families sampled at once, one per process (default: the number of cores)",
    )
    noise.add_argument("--no-progress", action="store_true", help="no progress bar")
    noise.add_argument("--json", action="store_true", help="print one JSON object on stdout")
