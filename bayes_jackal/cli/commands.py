"""The commands of ``bayes-jackal``: command-line arguments in, library calls, text out."""

from __future__ import annotations

import argparse
import signal
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

from .._files import write_json
from ..bag_writer import write_bag
from ..criticism import criticise
from ..demo import DEMO_TRUTH, run_demo
from ..errors import InputError
from ..evidence import compare_families
from ..experiment import write_netcdf
from ..export import export_prior, write_prior
from ..gridsearch import damping_grid, grid_search
from ..inference import ConvergenceWarning, SamplerSettings, sample_posterior
from ..likelihood import ResidualLikelihood, resolve_channels
from ..noise import analyse
from ..plots import save_grid_plot
from ..posterior import load_posterior, save_posterior, summarize
from ..report import write_report
from ..robot import DEFAULT_PRIORS, RobotProfile, load_profile
from ..simulate import NoiseSettings, simulate_series
from ..tables import check_column_roles, load_experiments, write_csv
from ..workflow import analyse_logs, ingest_logs
from .output import (
    EXIT_BAD_INPUT,
    EXIT_OK,
    Reporter,
    analysis_text,
    comparison_table,
    grid_table,
    posterior_table,
    print_criticism,
    residual_table,
)


def _robot(args: argparse.Namespace) -> RobotProfile:
    return load_profile(args.robot)


def cmd_simulate(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
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
    out = Reporter(args.json)
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
    out = Reporter(args.json)
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
    grid_table(result, out.say)
    if args.plot:
        out.say(f"wrote {save_grid_plot(result, args.plot)}")
    if args.out:
        out.say(f"wrote {result.to_netcdf(args.out)}")
    out.result(result.summary())
    return EXIT_OK


def cmd_residuals(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    robot = _robot(args)
    experiments = _load(args)
    result = analyse(experiments, robot, args.d_lat, args.d_long, args.channels, args.lags)
    residual_table(result, out.say)
    out.result(result)
    return EXIT_OK


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
    posterior_table(summary, say)
    for warning in caught:
        if issubclass(warning.category, ConvergenceWarning):
            print(f"bayes-jackal: WARNING: {warning.message}", file=sys.stderr)
    print_criticism(summary["warnings"])
    return summary


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
    out = Reporter(args.json)
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


def cmd_compare(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
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
        comparison_table(results[name], out.say)
        print_criticism(results[name]["warnings"])
        if folder is not None:
            write_json(folder / f"{name}.compare.json", results[name])
            out.say(f"wrote {folder}/{name}.<family>.nc and {name}.compare.json")
    out.result(results.popitem()[1] if len(results) == 1 else {"experiments": results})
    return EXIT_OK


def cmd_export_prior(args: argparse.Namespace) -> int:
    out = Reporter(False)
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


def cmd_analyse(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
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
    return analysis_text(result, out)


def cmd_demo(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    signal.signal(signal.SIGTERM, _interrupt)
    result = run_demo(args.out, out.say, progress=not args.no_progress)
    out.say(
        f"Truth (simulated): d_lat={DEMO_TRUTH['d_lat']:g}, d_long={DEMO_TRUTH['d_long']:g} "
        f"N s/m, sigma_h={NoiseSettings().width} s. The bags' vx and vy are derived from "
        "noise-free motion-capture poses by a smoothing derivative: they carry no sensor "
        "noise (sigma_n at its prior bound) and a wider kernel (sigma_h) than the simulator's."
    )
    return analysis_text(result, out)


def cmd_report(args: argparse.Namespace) -> int:
    out = Reporter(False)
    path = write_report(args.posteriors, args.out, args.formats)
    out.say(f"wrote {path} and its figures in {path.parent / (path.stem + '_figures')}/")
    return EXIT_OK


def _read_options(args: argparse.Namespace) -> dict:
    """Keywords of load_experiment(s) from the input flags."""
    return {"columns": check_column_roles(dict(args.column), field="--column"), "rate": args.rate}


def _load(args: argparse.Namespace) -> list:
    """The experiments named on the command line, read with the input flags."""
    return load_experiments(args.experiments, **_read_options(args))
