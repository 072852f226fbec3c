"""The commands of ``bayes-jackal``: command-line arguments in, library calls, text out."""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .._files import write_json
from ..bag_writer import write_bag
from ..criticism import criticise
from ..demo import DEMO_TRUTH, run_demo
from ..errors import InputError, each_input
from ..evidence import compare_families
from ..experiment import Experiment, write_netcdf
from ..export import export_prior, write_prior
from ..gridsearch import damping_grid, grid_search
from ..inference import ConvergenceWarning, SamplerSettings, chain_path, sample_posterior
from ..likelihood import ResidualLikelihood, resolve_channels
from ..noise import analyse
from ..plots import save_grid_plot
from ..posterior import load_posterior, save_posterior, summarize
from ..report import read_posteriors, save_report
from ..robot import DEFAULT_PRIORS, RobotProfile, load_profile
from ..simulate import NoiseSettings, simulate_series
from ..tables import check_column_roles, load_experiments, read_experiments, write_csv
from ..workflow import analyse_logs, ingest_logs
from .output import (
    EXIT_BAD_INPUT,
    EXIT_OK,
    Failures,
    Reporter,
    analysis_text,
    comparison_table,
    grid_table,
    posterior_table,
    print_criticism,
    residual_table,
)
from .paths import check_named_outputs


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
        if "renamed_from" in experiment.provenance:  # two inputs of one name (ingest_logs)
            out.say(f"  renamed: {experiment.provenance['renamed_from']} was another input's name")
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

    def residuals(experiments: list) -> dict:
        return analyse(experiments, robot, args.d_lat, args.d_long, args.channels, args.lags)

    if len(args.experiments) == 1:
        experiments, failed, code = _load(args), {}, EXIT_OK
    else:  # each on its own first: a bad one is named, the others analysed together
        done, failed, code = _each_experiment(args, out.say, lambda e: residuals([e]))
        experiments = [e for e, _ in done]
    if not experiments:  # every input named on stderr already
        out.result({"experiments": {}, "failed": failed})
        return code
    result = residuals(experiments)
    residual_table(result, out.say)
    out.result(result | {"failed": failed})
    return code


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
            chain_file=chain_path(out_path),
            prior_overrides=prior_overrides,
            say=say,
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


def _each_experiment(
    args: argparse.Namespace,
    say: Callable[[str], None],
    work: Callable[[Experiment], Any],
    outputs: Callable[[Experiment], list[Path]] | None = None,
) -> tuple[list[tuple[Experiment, Any]], dict[str, str], int]:
    """Without pooling: read and process each experiment on its own.

    A bad input is reported on stderr as it is met, and the others finish.
    ``outputs`` gives the files an experiment's work writes: they are checked
    for every experiment before any work (:func:`.paths.check_named_outputs`).

    Returns
    -------
    done : list of (Experiment, result)
    failed : dict of str to str
        Input -> reason.
    code : int
        The exit code: 2 when an input was bad, 1 when one failed otherwise.
    """
    failures = Failures(args.debug)
    loaded, failed = read_experiments(args.experiments, **_read_options(args), on_failure=failures)
    if outputs is not None:
        checked, refused = each_input(
            loaded,
            lambda given: check_named_outputs(args, outputs(loaded[given])),
            on_failure=failures,
        )
        loaded, failed = {given: loaded[given] for given in checked}, failed | refused
    done, crashed = each_input(
        loaded, lambda given: work(loaded[given]), catch=Exception, on_failure=failures
    )
    failed |= crashed
    if failed:
        total = len(args.experiments)
        say(f"{len(done)} of {total} experiments done; failed: {', '.join(failed)}")
    return [(loaded[given], result) for given, result in done.items()], failed, failures.code


def _print_each(
    args: argparse.Namespace,
    out: Reporter,
    work: Callable[[Experiment], Any],
    outputs: Callable[[Experiment], list[Path]],
) -> int:
    """:func:`_each_experiment`; JSON: ``experiments`` (name -> result) and ``failed``."""
    done, failed, code = _each_experiment(args, out.say, work, outputs)
    out.result({"experiments": {e.name: result for e, result in done}, "failed": failed})
    return code


def cmd_sample(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    robot = _robot(args)
    out_path = Path(args.out)
    settings = _sampler_settings(args)
    overrides = _prior_overrides(args.prior)

    def run(group: list, path: Path) -> dict:
        likelihood = ResidualLikelihood(
            group, robot, family=args.family, **_likelihood_options(args)
        )
        return _run_sample(likelihood, settings, args.seed, path, out.say, overrides)

    if args.pooled or len(args.experiments) == 1:
        out.result(run(_load(args), out_path))
        return EXIT_OK

    def path(experiment: Experiment) -> Path:
        return out_path.with_name(f"{out_path.stem}.{experiment.name}.nc")

    return _print_each(
        args,
        out,
        lambda e: run([e], path(e)),
        lambda e: [path(e), chain_path(path(e))],
    )


def cmd_compare(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    robot = _robot(args)
    folder = Path(args.out) if args.out else None
    overrides = _prior_overrides(args.prior)

    def compare(name: str, group: list) -> dict:
        channels = resolve_channels(group, args.channels)
        out.say(
            f"comparing {', '.join(args.families)} on {name}, channels {', '.join(channels)} "
            "(bridge sampling)"
        )

        def finished(family, evidence, idata) -> None:
            out.say(f"  {family}: log Z = {evidence.log_evidence:.2f} +- {evidence.error:.3f}")
            if folder is not None:  # saved at once: an interruption keeps it
                criticise(idata)  # cached in its attrs: the file carries it
                save_posterior(idata, _family_files(folder, name, [family])[family])

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
                reuse=None if folder is None else _family_files(folder, name, args.families),
                say=out.say,
                **_likelihood_options(args) | {"channels": channels},
            )
        for warning in caught:
            if issubclass(warning.category, ConvergenceWarning):
                print(f"bayes-jackal: WARNING: {warning.message}", file=sys.stderr)
        result = comparison.to_dict() | {"channels": list(channels)}
        comparison_table(result, out.say)
        print_criticism(result["warnings"])
        if folder is not None:
            write_json(_summary_file(folder, name), result)
            out.say(f"wrote {folder}/{name}.<family>.nc and {name}.compare.json")
        return result

    def outputs(name: str) -> list[Path]:
        if folder is None:
            return []
        return [*_family_files(folder, name, args.families).values(), _summary_file(folder, name)]

    if args.pooled or len(args.experiments) == 1:
        experiments = _load(args)
        name = "pooled" if len(experiments) > 1 else experiments[0].name
        check_named_outputs(args, outputs(name))
        out.result(compare(name, experiments))
        return EXIT_OK
    return _print_each(args, out, lambda e: compare(e.name, [e]), lambda e: outputs(e.name))


def _family_files(folder: Path, name: str, families) -> dict[str, Path]:
    """Where ``compare --out`` keeps each family's posterior (and finds it on a rerun)."""
    return {family: folder / f"{name}.{family}.nc" for family in families}


def _summary_file(folder: Path, name: str) -> Path:
    """Where ``compare --out`` writes the comparison of ``name``."""
    return folder / f"{name}.compare.json"


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


def cmd_analyse(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    robot = _robot_with_topics(args)
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
    failures = Failures(args.debug)
    posteriors, _ = read_posteriors(args.posteriors, on_failure=failures)
    if not posteriors:  # every input named on stderr already
        return failures.code
    path = save_report(posteriors, args.out, args.formats)
    out.say(f"wrote {path} and its figures in {path.parent / (path.stem + '_figures')}/")
    return failures.code


def _read_options(args: argparse.Namespace) -> dict:
    """Keywords of load_experiment(s) from the input flags (and ``--robot``: its rate)."""
    return {
        "columns": check_column_roles(dict(args.column), field="--column"),
        "rate": args.rate,
        "robot": _robot(args),
    }


def _load(args: argparse.Namespace) -> list:
    """The experiments named on the command line, read with the input flags."""
    return load_experiments(args.experiments, **_read_options(args))
