"""The ``bayes-jackal`` command line: a thin layer over the library.

Commands, flags, JSON keys and exit codes follow docs/design.md §6. Exit codes:
0 success, 2 bad input (the message names file, field and value), 1 any
other failure; no traceback reaches the user.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

from . import __version__
from ._files import write_json
from .bag_writer import write_bag
from .criticism import criticise
from .demo import DEMO_TRUTH, run_demo
from .errors import InputError
from .evidence import compare_families
from .experiment import write_netcdf
from .export import export_prior, write_prior
from .gridsearch import METHODS, GridResult, damping_grid, grid_search
from .inference import ConvergenceWarning, SamplerSettings, sample_posterior
from .kernels import FAMILIES
from .likelihood import (
    DEFAULT_CHANNEL_ORDER,
    ENGINES,
    SENSOR_MODELS,
    ResidualLikelihood,
    resolve_channels,
)
from .noise import analyse
from .physics import CHANNELS
from .plots import save_grid_plot
from .posterior import load_posterior, save_posterior, summarize
from .report import FIGURE_FORMATS, write_report
from .robot import CONVERSIONS, DEFAULT_PRIORS, RobotProfile, load_profile
from .simulate import SERIES, NoiseSettings, simulate_series
from .tables import ROLES, check_column_roles, load_experiments, write_csv
from .workflow import DEFAULT_FAMILIES, analyse_logs, ingest_logs

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2


class _Reporter:
    """Human text to stdout, or to stderr when stdout carries JSON."""

    def __init__(self, json_mode: bool):
        self.json_mode = json_mode

    def say(self, text: str = "") -> None:
        print(text, file=sys.stderr if self.json_mode else sys.stdout)

    def result(self, payload: dict) -> None:
        if self.json_mode:
            json.dump(payload, sys.stdout, indent=2)
            sys.stdout.write("\n")


def _robot(args: argparse.Namespace) -> RobotProfile:
    return load_profile(args.robot)


def _grid_table(result: GridResult, say: Callable[[str], None]) -> None:
    summary = result.summary()
    say(
        f"{result.method} MSE of the {result.channel} channel over "
        f"d_lat {result.d_lat[0]:g}..{result.d_lat[-1]:g} ({len(result.d_lat)} values) x "
        f"d_long {result.d_long[0]:g}..{result.d_long[-1]:g} ({len(result.d_long)} values)"
    )
    say(f"{'':12s} {'runs':>5s} {'d_lat':>8s} {'d_long':>8s} {'ratio':>7s} {'MSE':>11s}")
    rows = [(label, len(s["experiments"]), s) for label, s in summary["series"].items()]
    rows.append(("total (5-3)", sum(n for _, n, _ in rows), summary))
    for label, runs, s in rows:
        say(
            f"{label:12s} {runs:5d} {s['d_lat']:8g} {s['d_long']:8g} "
            f"{s['d_lat'] / s['d_long']:7.3f} {s['mse']:11.4g}"
        )


def cmd_simulate(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    robot = _robot(args)
    noise = NoiseSettings(args.width, tuple(args.sigma_c), tuple(args.sigma_n), args.family)
    counts = {"v1": args.v1, "v2": args.v2}
    experiments = simulate_series(
        robot, args.d_lat, args.d_long, counts, noise, args.seed, args.conversion
    )
    writer, suffix = (write_csv, ".csv") if args.format == "csv" else (write_netcdf, ".nc")
    paths = [str(writer(e, Path(args.out) / f"{e.name}{suffix}")) for e in experiments]
    if args.bag:
        bag_suffix = ".bag" if args.bag == "ros1" else ".mcap"
        paths += [
            str(write_bag(e, Path(args.out) / f"{e.name}{bag_suffix}", robot, args.bag, args.seed))
            for e in experiments
        ]
    for path in paths:
        out.say(f"wrote {path}")
    out.say(
        f"{len(experiments)} simulated experiments "
        f"(truth d_lat={args.d_lat}, d_long={args.d_long})"
    )
    out.result({"experiments": paths, "truth": experiments[0].truth if experiments else None})
    return EXIT_OK


def _robot_with_topics(args: argparse.Namespace) -> RobotProfile:
    """The profile with ``--topic ROLE NAME`` overrides applied."""
    robot = _robot(args)
    unknown = [role for role, _ in args.topic if role not in robot.topics]
    if unknown:
        raise InputError(
            f"unknown topic role(s) {unknown}; use {sorted(robot.topics)}", field="--topic"
        )
    return robot.replace(topics={**robot.topics, **dict(args.topic)})


def cmd_ingest(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    folder = Path(args.out)
    experiments, failed = ingest_logs(
        args.bags,
        _robot_with_topics(args),
        folder,
        window=args.window,
        max_gap=args.max_gap,
        progress=not args.json,
    )
    for reason in failed.values():
        print(f"bayes-jackal: error: {reason}", file=sys.stderr)
    out.say(
        f"{'bag':24s} {'duration':>9s} {'imu Hz':>7s} {'pose Hz':>7s} "
        f"{'steady window [s]':>18s} {'repairs':>7s}"
    )
    written = {}
    for experiment in experiments:
        start, stop = experiment.steady_window or (float("nan"), float("nan"))
        row = written[experiment.name] = {
            "file": str(folder / f"{experiment.name}.nc"),
            "duration": float(experiment.t[-1] - experiment.t[0]),
            "rate": 1.0 / experiment.dt,
            "pose_rate": experiment.provenance.get("pose_rate"),
            "steady_window": experiment.steady_window,
            "repairs": experiment.provenance.get("repairs", []),
        }
        out.say(
            f"{experiment.name:24s} {row['duration']:8.1f}s {row['rate']:7.1f} "
            f"{row['pose_rate'] or float('nan'):7.1f} {start:8.2f} - {stop:7.2f} "
            f"{len(row['repairs']):7d}"
        )
    out.say(f"{len(written)} of {len(args.bags)} bags ingested into {folder}/")
    out.result({"experiments": written, "failed": failed})
    return EXIT_BAD_INPUT if failed else EXIT_OK


def cmd_grid(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    robot = _robot(args)
    experiments = _load(args)
    result = grid_search(
        experiments,
        robot,
        damping_grid(*args.d_lat, name="d_lat"),
        damping_grid(*args.d_long, name="d_long"),
        method=args.method,
        channel=args.channel,
        discretisation=args.discretisation,
    )
    _grid_table(result, out.say)
    if args.plot:
        out.say(f"wrote {save_grid_plot(result, args.plot)}")
    if args.out:
        out.say(f"wrote {result.to_netcdf(args.out)}")
    out.result(result.summary())
    return EXIT_OK


def _residual_table(result: dict, say: Callable[[str], None]) -> None:
    say(
        f"one-step residuals (eq. 7-3) of the steady-state window at d_lat={result['d_lat']:g}, "
        f"d_long={result['d_long']:g} N s/m; Ljung-Box and sigma_h fit over {result['lags']} lags"
    )
    say(
        f"{'experiment':12s} {'channel':7s} {'n':>6s} {'sd':>10s} {'LB p':>9s} "
        f"{'r1':>7s} {'sigma_h [s]':>11s}"
    )
    for name, channels in result["experiments"].items():
        for channel, row in channels.items():
            r1 = row["autocorrelation"][0]
            say(
                f"{name:12s} {channel:7s} {row['n']:6d} {row['sd']:10.4g} "
                f"{row['ljung_box_p']:9.3g} {r1:7.3f} {row['sigma_h']:11.3f}"
            )
    say()
    say("sigma_h of the yaw channel (thesis table 7-1: v1 0.051, v2 0.041, all 0.047 s)")
    say(f"{'series':12s} {'runs':>5s} {'sigma_h [s]':>11s}")
    members = result["series"]
    for label, value in result["sigma_h"].items():
        runs = len(result["experiments"]) if label == "all" else len(members[label])
        say(f"{label:12s} {runs:5d} {value:11.4f}")


def cmd_residuals(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    robot = _robot(args)
    experiments = _load(args)
    result = analyse(experiments, robot, args.d_lat, args.d_long, args.channels, args.lags)
    _residual_table(result, out.say)
    out.result(result)
    return EXIT_OK


def _name_list(allowed, what: str) -> Callable[[str], tuple[str, ...]]:
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


_channel_list = _name_list(CHANNELS, "channel(s)")
_family_list = _name_list(tuple(FAMILIES), "families")


def _posterior_table(summary: dict, say: Callable[[str], None]) -> None:
    say(
        f"{'':16s} {'mean':>10s} {'sd':>10s} {'hdi_3%':>10s} {'hdi_97%':>10s} "
        f"{'ess_tau':>8s} {'r_hat':>6s}"
    )
    for name, row in summary.items():
        if isinstance(row, dict) and "mean" in row:
            say(
                f"{name:16s} {row['mean']:10.4g} {row['sd']:10.3g} {row['hdi_3%']:10.4g} "
                f"{row['hdi_97%']:10.4g} {row.get('ess_autocorr', float('nan')):8.0f} "
                f"{row['r_hat']:6.3f}"
            )
    ratio = summary["ratio"]
    say(
        f"corr(d_lat, d_long) = {summary['corr_d_lat_d_long']:.3f}; d_lat/d_long 94 % HDI "
        f"[{ratio['hdi_3%']:.3f}, {ratio['hdi_97%']:.3f}] (thesis: {ratio['thesis']:.4f})"
    )
    taus = summary["autocorr_time"]
    status = "converged" if summary["converged"] else "NOT CONVERGED"
    say(
        f"{status}: {summary['n_steps']} steps, max autocorrelation time "
        f"{max(taus.values()):.0f} steps ({summary['n_steps'] / max(taus.values()):.0f} tau)"
    )


def _run_sample(
    likelihood: ResidualLikelihood,
    settings: SamplerSettings,
    seed: int | None,
    out_path: Path,
    say: Callable[[str], None],
    prior_overrides: dict | None = None,
) -> dict:
    """Sample, save the posterior (chain beside it), print and return the summary."""
    say(
        f"sampling {', '.join(e.name for e in likelihood.experiments)} on channels "
        f"{', '.join(likelihood.channels)} -> {out_path}"
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        idata = sample_posterior(
            likelihood,
            settings,
            seed=seed,
            chain_file=out_path.with_suffix(".chain.h5"),
            prior_overrides=prior_overrides,
        )
    save_posterior(idata, out_path)
    summary = summarize(idata)
    _posterior_table(summary, say)
    for warning in caught:
        if issubclass(warning.category, ConvergenceWarning):
            print(f"bayes-jackal: WARNING: {warning.message}", file=sys.stderr)
    _print_criticism(summary["warnings"])
    return summary


def _print_criticism(findings: list[dict]) -> None:
    """Model-criticism warnings on stderr, as ConvergenceWarning (compare: with the family)."""
    for finding in findings:
        family = f"{finding['family']}: " if "family" in finding else ""
        print(f"bayes-jackal: WARNING: {family}{finding['message']}", file=sys.stderr)


def _sampler_settings(args: argparse.Namespace) -> SamplerSettings:
    return SamplerSettings(
        walkers=args.walkers, max_steps=args.max_steps, progress=not args.no_progress
    )


def _likelihood_options(args: argparse.Namespace) -> dict:
    """ResidualLikelihood keywords from the shared modelling flags."""
    return {
        "channels": args.channels,
        "shared_noise": args.noise == "shared",
        "sensor": args.sensor_noise,
        "engine": args.engine,
    }


def _data_sets(args: argparse.Namespace, experiments: list) -> dict[str, list]:
    """One pooled data set, or one per experiment (keyed by experiment name)."""
    if args.pooled or len(experiments) == 1:
        return {"pooled" if len(experiments) > 1 else experiments[0].name: experiments}
    return {e.name: [e] for e in experiments}


def cmd_sample(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    robot = _robot(args)
    experiments = _load(args)
    out_path = Path(args.out)
    settings = _sampler_settings(args)
    overrides = _prior_overrides(args.prior)
    signal.signal(signal.SIGTERM, _interrupt)
    data_sets = _data_sets(args, experiments)

    def run(group: list, path: Path) -> dict:
        likelihood = ResidualLikelihood(
            group, robot, family=args.family, **_likelihood_options(args)
        )
        return _run_sample(likelihood, settings, args.seed, path, out.say, overrides)

    if len(data_sets) == 1:
        result = run(experiments, out_path)
    else:
        result = {
            "experiments": {
                name: run(group, out_path.with_name(f"{out_path.stem}.{name}.nc"))
                for name, group in data_sets.items()
            }
        }
    out.result(result)
    return EXIT_OK


def _comparison_table(result: dict, say: Callable[[str], None]) -> None:
    say(
        f"{'family':16s} {'log Z':>12s} {'+-':>6s} {'lnB best':>9s} {'lnB white':>10s}  "
        "width mean [94 % HDI] (s)"
    )
    for name, row in result["families"].items():
        widths = "; ".join(
            f"{label} {w['mean']:.4g} [{w['hdi_3%']:.4g}, {w['hdi_97%']:.4g}]"
            for label, w in (row["width"] or {}).items()
            if label != "hdi_prob"
        )
        versus_white = row["log_bayes_factor_vs_white"]
        say(
            f"{name:16s} {row['log_evidence']:12.2f} {row['log_evidence_err']:6.3f} "
            f"{row['log_bayes_factor_vs_best']:9.2f} "
            f"{'' if versus_white is None else f'{versus_white:10.2f}':>10s}  {widths or '-'}"
            + ("" if row["converged"] else "  NOT CONVERGED")
        )
        if "log_evidence_nested" in row:
            say(
                f"{'':16s} {row['log_evidence_nested']:12.2f} "
                f"{row['log_evidence_nested_err']:6.3f}  (nested sampling)"
            )
    say(f"best: {result['best']}. Verdict: {result['verdict_text']}")


def cmd_compare(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    robot = _robot(args)
    experiments = _load(args)
    folder = Path(args.out) if args.out else None
    overrides = _prior_overrides(args.prior)
    signal.signal(signal.SIGTERM, _interrupt)
    results = {}
    for name, group in _data_sets(args, experiments).items():
        channels = resolve_channels(group, args.channels)
        out.say(
            f"comparing {', '.join(args.families)} on {name}, channels {', '.join(channels)} "
            "(bridge sampling)"
        )

        def finished(family, evidence, idata, name=name) -> None:
            out.say(f"  {family}: log Z = {evidence.log_evidence:.2f} +- {evidence.error:.3f}")
            if folder is not None:  # saved at once: an interruption keeps it
                criticise(idata)  # cached in its attrs: the file carries it
                save_posterior(idata, folder / f"{name}.{family}.nc")

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            comparison = compare_families(
                group,
                robot,
                args.families,
                _sampler_settings(args),
                args.seed,
                overrides,
                finished,
                cross_check=args.nested,
                processes=args.processes,
                **_likelihood_options(args) | {"channels": channels},
            )
        for warning in caught:
            if issubclass(warning.category, ConvergenceWarning):
                print(f"bayes-jackal: WARNING: {warning.message}", file=sys.stderr)
        results[name] = comparison.to_dict() | {"channels": list(channels)}
        _comparison_table(results[name], out.say)
        _print_criticism(results[name]["warnings"])
        if folder is not None:
            write_json(folder / f"{name}.compare.json", results[name])
            out.say(f"wrote {folder}/{name}.<family>.nc and {name}.compare.json")
    out.result(results.popitem()[1] if len(results) == 1 else {"experiments": results})
    return EXIT_OK


def cmd_export_prior(args: argparse.Namespace) -> int:
    out = _Reporter(False)
    idata = load_posterior(args.posterior)
    prior = export_prior(idata, args.order, source=args.posterior)
    path = write_prior(prior, args.out)
    noise = prior["noise"]
    size = len(prior["generalised_coordinates"]["precision"])
    out.say(
        f"wrote {path}: {noise['family']} noise on {', '.join(noise['channels'])}, "
        f"embedding order {args.order} ({size} x {size} precision), "
        f"{prior['draws']['count']} posterior draws"
    )
    if not prior["converged"]:
        print(
            f"bayes-jackal: WARNING: {args.posterior} is NOT CONVERGED; the prior inherits that",
            file=sys.stderr,
        )
    return EXIT_OK


def _prior_overrides(items: list[list[str]]) -> dict[str, tuple[float, float]]:
    """``--prior NAME LOW HIGH`` items as {name: (low, high)}, validated."""
    overrides = {}
    for name, low, high in items:
        if name not in DEFAULT_PRIORS:
            raise InputError(
                f"unknown prior {name!r}; use one of {list(DEFAULT_PRIORS)}", field="--prior"
            )
        try:
            overrides[name] = (float(low), float(high))
        except ValueError:
            raise InputError(
                f"{name}: LOW and HIGH must be numbers, got {low!r} {high!r}", field="--prior"
            ) from None
    return overrides


def _interrupt(signum, frame) -> None:
    """SIGTERM handler: unwind like Ctrl-C so that the chain is flushed."""
    raise KeyboardInterrupt


def _analysis_text(result: dict, out: _Reporter) -> int:
    """Print what analyse_logs found; warnings and bad inputs on stderr; the exit code."""
    out.say(
        f"\n{result['best']}-noise posterior (the best family by evidence), pooled over "
        f"{len(result['experiments'])} experiment(s), channels {', '.join(result['channels'])}:"
    )
    _posterior_table(result["posterior"], out.say)
    out.say(f"Is the noise coloured? {result['comparison']['verdict_text']}")
    files = result["files"]
    out.say(
        f"Open {files['report']} in a browser. Also written: {files['prior']} (Active "
        f"Inference prior), {files['posterior']}, posteriors/, experiments/, grid_*.png, *.json."
    )
    _print_criticism(result["warnings"])
    for reason in result["failed"].values():
        print(f"bayes-jackal: error: {reason}", file=sys.stderr)
    out.result(result)
    return EXIT_BAD_INPUT if result["failed"] else EXIT_OK


def cmd_analyse(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    robot = _robot_with_topics(args)
    signal.signal(signal.SIGTERM, _interrupt)
    options = _likelihood_options(args)
    result = analyse_logs(
        args.inputs,
        args.out,
        robot=robot,
        families=args.families,
        channels=options.pop("channels"),
        settings=_sampler_settings(args),
        seed=args.seed,
        processes=args.processes,
        prior_overrides=_prior_overrides(args.prior),
        likelihood_options=options,
        window=args.window,
        max_gap=args.max_gap,
        read_options=_read_options(args),
        say=out.say,
    )
    return _analysis_text(result, out)


def cmd_demo(args: argparse.Namespace) -> int:
    out = _Reporter(args.json)
    signal.signal(signal.SIGTERM, _interrupt)
    result = run_demo(args.out, out.say, progress=not args.no_progress)
    out.say(
        f"Truth (simulated): d_lat={DEMO_TRUTH['d_lat']:g}, d_long={DEMO_TRUTH['d_long']:g} "
        f"N s/m, sigma_h={NoiseSettings().width} s. The bags' vx and vy are derived from "
        "noise-free motion-capture poses by a smoothing derivative: they carry no sensor "
        "noise (sigma_n at its prior bound) and a wider kernel (sigma_h) than the simulator's."
    )
    return _analysis_text(result, out)


def _add_common(parser: argparse.ArgumentParser, json_flag: bool = True) -> None:
    parser.add_argument(
        "--robot", metavar="PROFILE", help="robot profile TOML (default: models/jackal.toml)"
    )
    if json_flag:
        parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def cmd_report(args: argparse.Namespace) -> int:
    out = _Reporter(False)
    path = write_report(args.posteriors, args.out, args.formats)
    out.say(f"wrote {path} and its figures in {path.parent / (path.stem + '_figures')}/")
    return EXIT_OK


def _add_input_flags(parser: argparse.ArgumentParser) -> None:
    """Flags of reading experiment files (CSV, MATLAB): column names and the rate."""
    parser.add_argument(
        "--column",
        nargs=2,
        action="append",
        default=[],
        metavar=("ROLE", "NAME"),
        help=f"the file's column for a role ({', '.join(ROLES)}), e.g. --column yaw_rate gyro_z",
    )
    parser.add_argument(
        "--rate",
        type=float,
        metavar="HZ",
        help="declared sampling rate [Hz] (default: detected from the time stamps)",
    )


def _read_options(args: argparse.Namespace) -> dict:
    """Keywords of load_experiment(s) from the input flags."""
    return {"columns": check_column_roles(dict(args.column), field="--column"), "rate": args.rate}


def _load(args: argparse.Namespace) -> list:
    """The experiments named on the command line, read with the input flags."""
    return load_experiments(args.experiments, **_read_options(args))


def _add_bag_flags(parser: argparse.ArgumentParser, max_gap: float | None = 0.25) -> None:
    """Flags of reading bags, shared by ingest and analyse: window, gaps, topics."""
    parser.add_argument(
        "--window",
        type=float,
        nargs=2,
        metavar=("T0", "T1"),
        help="steady-state window [s; in bags from the first IMU stamp] instead of detecting it",
    )
    parser.add_argument(
        "--max-gap",
        type=float,
        default=max_gap,
        help="longest tolerated dropout [s] "
        + (f"({max_gap:g})" if max_gap else "(bags 0.25, experiment files 5 sample steps)"),
    )
    parser.add_argument(
        "--topic",
        nargs=2,
        action="append",
        default=[],
        metavar=("ROLE", "NAME"),
        help="override a profile topic, e.g. --topic pose /vrpn_client_node/jackal/pose",
    )


def _add_model_flags(parser: argparse.ArgumentParser, *, pooling: bool = True) -> None:
    """Flags of sample, compare and analyse: channels, noise model, pooling, sampler, priors.

    ``pooling=False`` (analyse, always pooled) leaves out ``--pooled``.
    """
    parser.add_argument(
        "--channels",
        type=_channel_list,
        default=None,
        help="comma-separated subset of "
        f"{','.join(DEFAULT_CHANNEL_ORDER)} (default: every one all experiments measure)",
    )
    parser.add_argument(
        "--sensor-noise",
        choices=SENSOR_MODELS,
        default="ma1",
        help="sensor-noise footprint: ma1 (default) or a diagonal nugget",
    )
    if pooling:
        parser.add_argument(
            "--pooled", action="store_true", help="one posterior for all experiments (shared d)"
        )
    parser.add_argument(
        "--noise",
        choices=("shared", "per-experiment"),
        default="shared",
        help="pooled: noise parameters shared or per experiment",
    )
    parser.add_argument(
        "--engine", choices=ENGINES, default="fast", help="likelihood engine (fast)"
    )
    parser.add_argument("--seed", type=int, default=None, help="seed: same seed, same chain")
    parser.add_argument("--walkers", type=int, default=0, help="ensemble size (default 32+)")
    parser.add_argument("--max-steps", type=int, default=20_000, help="step cap (20000)")
    parser.add_argument(
        "--prior",
        nargs=3,
        action="append",
        default=[],
        metavar=("NAME", "LOW", "HIGH"),
        help="override a prior range, e.g. --prior d_lat 10 2000",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``bayes-jackal``."""
    parser = argparse.ArgumentParser(
        prog="bayes-jackal",
        description="Bayesian system identification of skid-steer robots (thesis: The Noisy "
        "Jackal).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    analysis = commands.add_parser(
        "analyse", help="the whole analysis of your logs: ingest, grids, compare, prior, report"
    )
    analysis.add_argument(
        "inputs",
        nargs="+",
        metavar="BAG|EXP",
        help="bags (.bag, .mcap, .db3, bag folders) and experiment files (.csv, .mat, .nc)",
    )
    analysis.add_argument("--out", required=True, metavar="DIR", help="output folder")
    analysis.add_argument(
        "--families",
        type=_family_list,
        default=DEFAULT_FAMILIES,
        metavar="white,gaussian,...",
        help=f"noise families to compare ({','.join(DEFAULT_FAMILIES)})",
    )
    analysis.add_argument(
        "--processes",
        type=int,
        default=os.cpu_count() or 1,
        help="families sampled at once (default: the number of cores)",
    )
    _add_bag_flags(analysis, max_gap=None)
    _add_input_flags(analysis)
    _add_model_flags(analysis, pooling=False)
    _add_common(analysis)
    analysis.set_defaults(func=cmd_analyse)

    demo = commands.add_parser(
        "demo", help="analyse on the shipped simulated bags (embedded default data)"
    )
    demo.add_argument("--out", default="bayes-jackal-demo", help="output folder")
    demo.add_argument("--no-progress", action="store_true", help="no progress display")
    demo.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    demo.set_defaults(func=cmd_demo)

    sim = commands.add_parser("simulate", help="write thesis-like experiments with known truth")
    sim.add_argument("--out", required=True, help="output folder")
    sim.add_argument("--seed", type=int, default=None, help="random seed (reproducible runs)")
    for label in SERIES:
        default = 10 if label == "v1" else 5
        sim.add_argument(
            f"--{label}", type=int, default=default, help=f"runs of series {label} ({default})"
        )
    sim.add_argument("--d-lat", type=float, default=110.0, help="true d_lat [N s/m] (110)")
    sim.add_argument("--d-long", type=float, default=30.0, help="true d_long [N s/m] (30)")
    defaults = NoiseSettings()
    sim.add_argument(
        "--family", choices=list(FAMILIES), default=defaults.family, help="process-noise filter"
    )
    sim.add_argument(
        "--width",
        "--sigma-h",
        dest="width",
        type=float,
        default=defaults.width,
        help=f"kernel width [s] (sigma_h of the Gaussian; {defaults.width})",
    )
    for name, help_text in (("c", "process"), ("n", "sensor")):
        sim.add_argument(
            f"--sigma-{name}",
            type=float,
            nargs=3,
            metavar=("VX", "VY", "YAW"),
            default=getattr(defaults, f"sigma_{name}"),
            help=f"{help_text} noise sd of vx, vy [m/s] and yaw [rad/s]",
        )
    sim.add_argument("--conversion", choices=CONVERSIONS, help="cmd_vel -> wheel speeds")
    sim.add_argument("--format", choices=("nc", "csv"), default="nc", help="file format (nc)")
    sim.add_argument(
        "--bag", choices=("ros1", "ros2"), help="also write each run as a ROS1 or ROS2 bag"
    )
    _add_common(sim)
    sim.set_defaults(func=cmd_simulate)

    grid = commands.add_parser("grid", help="thesis grid search over (d_lat, d_long)")
    grid.add_argument("experiments", nargs="+", metavar="EXP", help="experiment .csv, .mat or .nc")
    grid.add_argument("--method", choices=METHODS, default="onestep")
    for name in ("d-lat", "d-long"):
        grid.add_argument(
            f"--{name}",
            type=float,
            nargs=3,
            default=(10.0, 1000.0, 10.0),
            metavar=("START", "STOP", "STEP"),
            help="grid values [N s/m], STOP included (10 1000 10)",
        )
    grid.add_argument("--channel", choices=CHANNELS, default="yaw")
    grid.add_argument("--discretisation", choices=("zoh", "euler"), default="zoh")
    grid.add_argument("--plot", metavar="FILE", help="save the MSE surface (png, svg, pdf)")
    grid.add_argument("--out", metavar="FILE.nc", help="save all MSE surfaces as NetCDF")
    _add_input_flags(grid)
    _add_common(grid)
    grid.set_defaults(func=cmd_grid)

    ingest = commands.add_parser("ingest", help="ROS1/ROS2 bags to experiment files")
    ingest.add_argument("bags", nargs="+", metavar="BAG", help=".bag, .mcap, .db3 or bag folder")
    ingest.add_argument("--out", required=True, help="output folder (one .nc per bag)")
    _add_bag_flags(ingest)
    _add_common(ingest)
    ingest.set_defaults(func=cmd_ingest)

    res = commands.add_parser("residuals", help="thesis ch. 7 residual analysis and sigma_h fit")
    res.add_argument("experiments", nargs="+", metavar="EXP", help="experiment .csv, .mat or .nc")
    res.add_argument("--d-lat", type=float, default=110.0, help="d_lat of the model [N s/m] (110)")
    res.add_argument("--d-long", type=float, default=30.0, help="d_long of the model [N s/m] (30)")
    res.add_argument(
        "--channels",
        type=_channel_list,
        default=("yaw",),
        metavar="yaw,vx,vy",
        help="comma-separated channels to analyse (yaw)",
    )
    res.add_argument(
        "--lags", type=int, default=30, help="lags of the Ljung-Box test and sigma_h fit (30)"
    )
    _add_input_flags(res)
    _add_common(res)
    res.set_defaults(func=cmd_residuals)

    sample = commands.add_parser("sample", help="posterior of damping and noise with emcee")
    sample.add_argument(
        "experiments", nargs="+", metavar="EXP", help="experiment .csv, .mat or .nc"
    )
    sample.add_argument("--out", required=True, metavar="POSTERIOR.nc", help="posterior file")
    sample.add_argument("--family", choices=list(FAMILIES), default="gaussian")
    _add_input_flags(sample)
    _add_model_flags(sample)
    _add_common(sample)
    sample.set_defaults(func=cmd_sample)

    compare = commands.add_parser("compare", help="noise-filter families ranked by evidence")
    compare.add_argument(
        "experiments", nargs="+", metavar="EXP", help="experiment .csv, .mat or .nc"
    )
    compare.add_argument(
        "--families",
        type=_family_list,
        default=tuple(FAMILIES),
        metavar="white,gaussian,...",
        help=f"comma-separated families ({','.join(FAMILIES)})",
    )
    compare.add_argument("--out", metavar="DIR", help="save each family's posterior here")
    compare.add_argument(
        "--processes",
        type=int,
        default=os.cpu_count() or 1,
        help="families sampled at once, one per process (default: the number of cores)",
    )
    compare.add_argument(
        "--nested",
        action="store_true",
        help="cross-check each evidence by nested sampling (dynesty; slow)",
    )
    _add_input_flags(compare)
    _add_model_flags(compare)
    _add_common(compare)
    compare.set_defaults(func=cmd_compare)

    export = commands.add_parser("export-prior", help="Active Inference (DEM) prior as JSON")
    export.add_argument("posterior", metavar="POSTERIOR.nc", help="posterior file from sample")
    export.add_argument("--out", required=True, metavar="prior.json", help="output JSON")
    export.add_argument(
        "--order", type=int, default=2, help="embedding order P of generalised coordinates (2)"
    )
    _add_common(export, json_flag=False)
    export.set_defaults(func=cmd_export_prior)

    report = commands.add_parser("report", help="HTML report with figures of posteriors")
    report.add_argument(
        "posteriors", nargs="+", metavar="POSTERIOR.nc", help="posterior files or folders"
    )
    report.add_argument("--out", required=True, metavar="report.html", help="output HTML")
    report.add_argument(
        "--formats",
        type=_name_list(FIGURE_FORMATS, "figure formats"),
        default=FIGURE_FORMATS,
        metavar="png,svg",
        help="figure files written beside the report (png,svg)",
    )
    report.set_defaults(func=cmd_report)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``bayes-jackal``; return the exit code."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # usage errors (2) and --help/--version (0)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        return args.func(args)
    except InputError as exc:
        print(f"bayes-jackal: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("bayes-jackal: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        print(f"bayes-jackal: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
