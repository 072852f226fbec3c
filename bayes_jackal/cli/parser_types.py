"""argparse types of the command line's flags: names, families, bounded numbers, priors.

They load no numpy (the family registry is read only when a family flag is
given), so ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

from .._runtime import CHANNELS, FAMILY, FIGURE_FORMATS, REPORT_FORMATS, InputError

__all__ = [
    "bounded",
    "channel_list",
    "count",
    "family",
    "family_list",
    "finite",
    "name_list",
    "natural",
    "non_negative",
    "positive",
    "prior_ranges",
    "registered_families",
]


def name_list(allowed, what: str) -> Callable[[str], tuple[str, ...]]:
    """argparse type of a comma-separated list of names, e.g. ``--channels yaw,vx``."""

    def parse(text: str) -> tuple[str, ...]:
        names = tuple(name.strip() for name in text.split(",") if name.strip())
        unknown = [name for name in names if name not in allowed]
        if unknown or not names:
            raise argparse.ArgumentTypeError(
                f"unknown {what} {unknown or text!r}; use some of {','.join(allowed)}"
            )
        return names

    return parse


channel_list = name_list(CHANNELS, "channel(s)")


def registered_families() -> tuple[str, ...]:
    """The keys of ``kernels.FAMILIES``, imported when a family flag is given.

    The registry is the one list of families (docs/families.md), and reading it
    loads numpy: so ``--help`` does not, and a family flag is checked here.
    """
    from ..model import FAMILIES  # imported with a family given: the command runs

    return tuple(FAMILIES)


def family_list(text: str) -> tuple[str, ...]:
    """argparse type of ``--families white,gaussian``: registered families."""
    return name_list(registered_families(), "families")(text)


def family(text: str) -> str:
    """argparse type of ``--family gaussian``: a registered family.

    argparse converts a string default too: the default family, registered
    (tests/test_cli.py), is taken without loading the registry, so that a
    refused output is said before numpy loads.
    """
    if text == FAMILY:
        return text
    families = registered_families()
    if text not in families:
        raise argparse.ArgumentTypeError(
            f"unknown family {text!r}; use one of {','.join(families)}"
        )
    return text


def bounded(convert: type, what: str, *, minimum: float, strict: bool = False) -> Callable:
    """argparse type of a finite number (``convert``: int or float) >= ``minimum`` (> if strict).

    ``what`` states the allowed range in the message, e.g. "an integer >= 0".
    Checked while parsing, so a bad flag is refused before any work.
    """

    def parse(text: str) -> float:
        try:
            value = convert(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and (value > minimum if strict else value >= minimum)):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    return parse


#: Counts and seeds (numpy's seeds are >= 0), counts of at least one, and
#: physical quantities: positive, or non-negative (a noise sd of 0 is none).
natural = bounded(int, "an integer >= 0", minimum=0)
count = bounded(int, "an integer >= 1", minimum=1)
positive = bounded(float, "a finite number > 0", minimum=0.0, strict=True)
non_negative = bounded(float, "a finite number >= 0", minimum=0.0)
finite = bounded(float, "a finite number", minimum=-math.inf)


def add_formats_flag(parser: argparse.ArgumentParser) -> None:
    """``--formats``: the figure files beside a report (report, analyse, demo and noise)."""
    parser.add_argument(
        "--formats",
        type=name_list(FIGURE_FORMATS, "figure formats"),
        default=REPORT_FORMATS,
        metavar="png,svg",
        help=f"figure files written beside the report, from {','.join(FIGURE_FORMATS)} "
        f"(default {','.join(REPORT_FORMATS)}; add svg for vector figures)",
    )


def add_prior_flag(parser: argparse.ArgumentParser, help: str) -> None:
    """``--prior NAME LOW HIGH``, repeatable: the flag of sample, compare, analyse and noise.

    :func:`prior_ranges` reads what it collects.
    """
    parser.add_argument(
        "--prior",
        nargs=3,
        action="append",
        default=[],
        metavar=("NAME", "LOW", "HIGH"),
        help=help,
    )


def prior_ranges(items: list[list[str]]) -> dict[str, tuple[str, str]]:
    """``--prior NAME LOW HIGH`` items (sample, compare, analyse, noise) as {name: (low, high)}.

    A name given twice is refused (the last would silently win); the command
    validates the ranges and names (:func:`bayes_jackal.model.prior_overrides`).

    Raises
    ------
    InputError
        Naming ``--prior`` and the repeated name.
    """
    ranges: dict[str, tuple[str, str]] = {}
    for name, low, high in items:
        if name in ranges:
            raise InputError(
                f"{name} is given twice ({' '.join(ranges[name])} and {low} {high}): give it once",
                field="--prior",
            )
        ranges[name] = (low, high)
    return ranges
