"""``bayes-jackal noise``: each series' families, smoothness and evidence, one at a time."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .._runtime import InputError, each_input, silenced, write_json
from ..dem import write_prior
from ..inference import ProcessExecutor, SamplerSettings
from ..noise import (
    NoiseCharacterisation,
    characterise_noise,
    export_noise_prior,
    read_noise_series,
    series_prior_overrides,
)
from ..report import NOISE_HEADER, NOISE_REPORT, noise_rows, write_noise_report
from .output import Failures, Reporter, warn_not_converged
from .parser_types import prior_ranges


def cmd_noise(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    failures = Failures(args.debug)
    settings = SamplerSettings(max_steps=args.max_steps, progress=not args.no_progress)
    settings.check_evidence_steps()  # refused before any series is read
    priors = series_prior_overrides(prior_ranges(args.prior), field="--prior")
    results: dict[str, dict] = {}

    def characterise(path: str) -> NoiseCharacterisation:
        series = read_noise_series(path, column=args.column, time_column=args.time_column,
                                   rate=args.rate, topic=args.topic, field=args.field,
                                   max_gap=args.max_gap)  # fmt: skip
        if series.name in results:  # its results and file would replace the other's
            raise InputError(
                f"a series named {series.name!r} was read already: rename one file",
                source=path,
                field="series",
            )
        out.say(f"{series.name}: {len(series.values)} samples at {1 / series.dt:.4g} Hz")
        with ProcessExecutor(args.processes) as executor:
            result = characterise_noise(series, families=args.families, settings=settings,
                                        seed=args.seed, engine=args.engine,
                                        executor=executor, prior_overrides=priors)  # fmt: skip
        summary = result.to_dict()
        noise_table(summary, out)
        if args.out:
            path_out = Path(args.out) / f"{series.name}.noise.json"
            out.say(f"wrote {write_json(path_out, summary)}")
            _write_prior(result, args.order, Path(args.out), path, out)
        results[series.name] = summary
        return result

    found, failed = each_input(args.series, characterise, catch=Exception, on_failure=failures)
    out.result({"series": results, "failed": failed})  # out before the report, whatever it does
    if args.out and found:
        _write_report(list(found.values()), Path(args.out) / NOISE_REPORT, args, out, failures)
    return failures.code


def _write_report(
    found: list[NoiseCharacterisation],
    path: Path,
    args: argparse.Namespace,
    out: Reporter,
    failures: Failures,
) -> None:
    """``noise_report.html`` (``--seed``, ``--formats``); a failure is one line naming it.

    A failure also gives a non-zero exit code.

    The series' results are printed and written already: a report that
    cannot be drawn or written loses none of them.
    """
    try:
        with silenced("bayes_jackal.report"):  # no figure counts: the command says what it wrote
            report = write_noise_report(found, path, formats=args.formats, seed=args.seed or 0)
    except Exception as failed:  # an interrupt (not an Exception) still stops the run
        failures(str(path), failed)
        return
    out.say(f"wrote {report} and its figures in {report.parent / (report.stem + '_figures')}/")


def _write_prior(
    result: NoiseCharacterisation,
    order: int | None,
    folder: Path,
    source: str,
    out: Reporter,
) -> None:
    """``<series>.prior.json``, the DEM prior of the best family at ``order``.

    An order the family cannot give is a warning, not a failure: the
    series' characterisation stands (written already), only its prior is
    missing. A prior from a chain that did not converge is written with a warning.
    """
    try:
        prior = export_noise_prior(result, order=order, source=source)
    except InputError as refused:
        print(f"bayes-jackal: WARNING: no prior for {result.series.name}: {refused}",
              file=sys.stderr)  # fmt: skip
        return
    path = write_prior(prior, folder / f"{result.series.name}.prior.json")
    size = prior["generalised_coordinates"]["order"] + 1
    out.say(f"wrote {path}: {prior['family']} noise, embedding order {size - 1} "
        f"({size} x {size} precision)")  # fmt: skip
    if not prior["converged"]:
        warn_not_converged(f"{result.series.name}'s {prior['family']} fit")


def noise_table(summary: dict, out: Reporter) -> None:
    """Each family's evidence and width, the verdict, and the classical widths beside them.

    ``summary``: the series' ``NoiseCharacterisation.to_dict()``.
    """
    out.say(_text_row(NOISE_HEADER))
    for row, (name, entry) in zip(noise_rows(summary), summary["families"].items(), strict=True):
        out.say(_text_row(row))
        for warning in entry["warnings"]:
            out.say(f"  WARNING: {name}: {warning['message']}")
    out.say(f"verdict: {summary['verdict_text']}")
    classical = ", ".join(f"{k}: {v:.4g}" for k, v in summary["acf_least_squares"].items())
    out.say(f"ACF least-squares width [s] by lag count: {classical}")
    out.say(f"the thesis' fit (30 lags): {summary['thesis_fit']:.4g} s")


#: Characters of each column of :func:`noise_table` (``NOISE_HEADER``'s).
_COLUMNS = (15, 11, 6, 13, 10, 21, 8)


def _text_row(cells) -> str:
    """The first cell left-aligned, the others right-aligned, in :data:`_COLUMNS`."""
    first, *rest = cells
    aligned = [cell.rjust(width) for cell, width in zip(rest, _COLUMNS[1:], strict=True)]
    return " ".join([first.ljust(_COLUMNS[0]), *aligned])
