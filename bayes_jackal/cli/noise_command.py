"""``bayes-jackal noise``: each series' families, smoothness and evidence, one at a time."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from .._files import write_json
from ..chains import SamplerSettings
from ..errors import InputError, each_input
from ..executors import ProcessExecutor
from ..noise_characterisation import NoiseCharacterisation, characterise_noise
from ..noise_series import read_noise_series
from .output import Failures, Reporter


def cmd_noise(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    failures = Failures(args.debug)
    settings = SamplerSettings(max_steps=args.max_steps, progress=not args.no_progress)
    results: dict[str, dict] = {}

    def characterise(path: str) -> NoiseCharacterisation:
        series = read_noise_series(path, column=args.column, rate=args.rate, topic=args.topic,
                                   field=args.field, max_gap=args.max_gap)  # fmt: skip
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
                                        executor=executor)  # fmt: skip
        noise_table(result, out.say)
        summary = result.to_dict()
        if args.out:
            path_out = Path(args.out) / f"{series.name}.noise.json"
            out.say(f"wrote {write_json(path_out, summary)}")
        results[series.name] = summary
        return result

    _, failed = each_input(args.series, characterise, catch=Exception, on_failure=failures)
    out.result({"series": results, "failed": failed})
    return failures.code


def noise_table(result: NoiseCharacterisation, say: Callable[[str], None]) -> None:
    """Each family's evidence and width, the verdict, and the classical widths beside them."""
    summary = result.to_dict()
    say(f"{'family':15s} {'ln Z':>11s} {'+-':>6s} {'ln B vs white':>13s} "
        f"{'width [s]':>10s} {'94 % HDI':>21s} {'[bins]':>8s}")  # fmt: skip
    for name, entry in summary["families"].items():
        width = entry["width"]
        bayes = entry["log_bayes_factor_vs_white"]
        seconds = width["seconds"] if width else None
        say(
            f"{name:15s} {entry['log_evidence']:11.2f} {entry['log_evidence_err']:6.2f} "
            f"{'-' if bayes is None else format(bayes, '.2f'):>13s} "
            f"{'-' if width is None else format(seconds['mean'], '.4g'):>10s} "
            + (
                f"{'-':>21s} {'-':>8s}"
                if width is None
                else f"[{seconds['hdi_3%']:.4g}, {seconds['hdi_97%']:.4g}]".rjust(21)
                + f" {width['bins']['mean']:8.3g}"
            )
        )
        for warning in entry["warnings"]:
            say(f"  WARNING: {name}: {warning['message']}")
    say(f"verdict: {summary['verdict_text']}")
    classical = ", ".join(f"{k}: {v:.4g}" for k, v in summary["acf_least_squares"].items())
    say(f"ACF least-squares width [s] by lag count: {classical}")
    say(f"the thesis' fit (30 lags): {summary['thesis_fit']:.4g} s")
