"""The commands of ``bayes-jackal``: command-line arguments in, library calls, text out."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import logging
import sys
import warnings
from collections.abc import Callable
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

from .._runtime import POSE_NOISE, InputError, chain_path, each_input, silenced, write_json
from ..dem import export_prior, read_prior, write_prior
from ..filters import estimate_columns, estimate_each, score_estimates, write_estimates
from ..inference import (
    ConvergenceWarning,
    Executor,
    FitOptions,
    SamplerSettings,
    compare_groups,
    executor_for,
    keep_warnings,
    population_posterior,
    sample_posterior,
)
from ..io import (
    Experiment,
    NoiseSettings,
    ReadOptions,
    bag_truth,
    ingest_logs,
    simulate_series,
    write_bag,
    write_csv,
    write_netcdf,
)
from ..likelihood import LikelihoodOptions, resolve_channels
from ..model import FAMILIES, RobotProfile, mass_scaled_damping, prior_overrides
from ..posterior import criticise, load_posterior, save_posterior, summarize
from ..report import read_posteriors, save_grid_plot, save_population_plot, save_report
from ..thesis import analyse, damping_grid, grid_search, prior_grid
from ..workflow import DEMO_TRUTH, analyse_logs, run_demo
from .exits import EXIT_BAD_INPUT, EXIT_OK
from .output import (
    Failures,
    Reporter,
    analysis_text,
    comparison_table,
    family_warnings,
    filter_table,
    grid_table,
    grid_warnings,
    population_text,
    posterior_table,
    print_criticism,
    residual_table,
    warn_not_converged,
)
from .parser_types import prior_ranges
from .paths import check_named_outputs, family_files, group_name, summary_file
from .reading import each_experiment, load_logs, read_options, robot_profile, robot_with_topics

#: The commands' own messages (sampling one experiment, maybe in a worker).
_log = logging.getLogger(__package__)


def _damping(args: argparse.Namespace, robot: RobotProfile) -> tuple[float, float]:
    """``--d-lat``, ``--d-long``, by default the thesis' Jackal damping scaled to the robot."""
    scaled = mass_scaled_damping(robot.mass)
    given = (args.d_lat, args.d_long)
    return tuple(float(d) if d is not None else s for d, s in zip(given, scaled, strict=True))


def cmd_simulate(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    robot = robot_profile(args)
    noise = NoiseSettings(args.width, tuple(args.sigma_c), tuple(args.sigma_n), args.family)
    counts = {"v1": args.v1, "v2": args.v2}
    d_lat, d_long = _damping(args, robot)
    experiments = simulate_series(robot, d_lat, d_long, counts, noise, args.seed, args.conversion)
    writer, suffix = (write_csv, ".csv") if args.format == "csv" else (write_netcdf, ".nc")
    paths = [str(writer(e, Path(args.out) / f"{e.name}{suffix}")) for e in experiments]
    pose_noise = tuple(args.pose_noise)
    result: dict = {"truth": experiments[0].truth if experiments else None}
    if args.bag:
        bag_suffix = ".bag" if args.bag == "ros1" else ".mcap"
        paths += [
            str(write_bag(e, Path(args.out) / f"{e.name}{bag_suffix}", robot, args.bag,
                          args.seed, pose_noise=pose_noise))
            for e in experiments
        ]  # fmt: skip
        result["bag_truth"] = bag_truth(experiments[0], pose_noise) if experiments else None
    for path in paths:
        out.say(f"wrote {path}")
    out.say(f"{len(experiments)} simulated experiments (truth d_lat={d_lat:g}, d_long={d_long:g})")
    out.result({"experiments": paths, **result})
    return EXIT_OK


def cmd_ingest(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    folder = Path(args.out)
    with silenced("bayes_jackal.io"):  # the table below says what each bag gave
        experiments, failed = ingest_logs(
            args.bags,
            robot_with_topics(args),
            folder,
            read_options=ReadOptions(window=args.window, max_gap=args.max_gap),
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
    robot = robot_profile(args)
    experiments = load_logs(args)
    # A grid given is the thesis' kind (START STOP STEP); the default spans the prior.
    d_lat, d_long = (
        damping_grid(*given, name=name) if given else prior_grid(robot, name, args.method)
        for name, given in (("d_lat", args.d_lat), ("d_long", args.d_long))
    )
    result = grid_search(
        experiments,
        robot,
        d_lat,
        d_long,
        method=args.method,
        channel=args.channel,
        discretisation=args.discretisation,
        progress=True,
    )
    grid_table(result, out)
    grid_warnings(result.edge_warnings(), "--{option} START STOP STEP")
    if args.plot:
        out.say(f"wrote {save_grid_plot(result, args.plot)}")
    if args.out:
        out.say(f"wrote {result.to_netcdf(args.out)}")
    out.result(result.summary())
    return EXIT_OK


def cmd_residuals(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    robot = robot_profile(args)

    d_lat, d_long = _damping(args, robot)

    def residuals(experiments: list) -> dict:
        return analyse(experiments, robot, d_lat, d_long, args.channels, args.lags)

    if len(args.experiments) == 1:
        experiments, failed, code = load_logs(args), {}, EXIT_OK
    else:  # each on its own first: a bad one is named, the others analysed together
        done, failed, code = each_experiment(args, out, lambda e: residuals([e]))
        experiments = [e for e, _ in done]
    if not experiments:  # every input named on stderr already
        out.result({"experiments": {}, "failed": failed})
        return code
    result = residuals(experiments)
    residual_table(result, out)
    out.result(result | {"failed": failed})
    return code


@dataclasses.dataclass(frozen=True)
class _Sampling:
    """One posterior of ``sample`` (picklable: a job of an executor).

    Called with the experiments of one posterior; returns the posterior, or
    the exception that stopped it (so that one experiment's failure does not
    stop the others on a cluster), with the warnings raised on the way
    (:class:`~bayes_jackal.inference.KeptWarnings`: a worker's would be lost).
    """

    fit: FitOptions
    family: str
    out: Path
    each: bool  # one posterior per experiment, named after it
    chain: bool = True  # the chain file beside the posterior (not on a cluster)

    def path(self, group: list[Experiment]) -> Path:
        """The posterior file of ``group``."""
        if not self.each:
            return self.out
        return self.out.with_name(f"{self.out.stem}.{group[0].name}.nc")

    def __call__(self, group: list[Experiment]):
        """(posterior, kept warnings, None) or (None, kept warnings, the exception)."""
        path = self.path(group)
        with keep_warnings() as kept:
            try:
                fit = self.fit
                likelihood = fit.likelihood_options.likelihood(group, fit.robot, self.family)
                _log.info(
                    f"sampling {', '.join(e.name for e in group)} on channels "
                    f"{', '.join(likelihood.channels)} -> {path}"
                )
                idata = sample_posterior(
                    likelihood,
                    fit.settings,
                    seed=fit.seed,
                    chain_file=chain_path(path) if self.chain else None,
                    prior_overrides=fit.prior_overrides,
                )
            except Exception as exc:  # raised again where the result is used
                return None, kept, exc
        return idata, kept, None


def _save_sample(result: tuple, path: Path, out: Reporter) -> dict:
    """Save a :class:`_Sampling` result (the chain is beside it), print and return its summary."""
    idata, kept, error = result
    kept.issue()  # raised where it ran (maybe a worker), shown here
    if error is not None:
        raise error
    save_posterior(idata, path)
    out.say(f"wrote {path}; the summary and the posterior-predictive checks of the fit:")
    summary = summarize(idata)
    posterior_table(summary, out)
    for message in kept.convergence:
        print(f"bayes-jackal: WARNING: {message}", file=sys.stderr)
    print_criticism(summary["warnings"])
    return summary


def _sampler_settings(args: argparse.Namespace) -> SamplerSettings:
    """Walkers, step cap and progress (none on a cluster: its workers have no terminal)."""
    return SamplerSettings(
        walkers=args.walkers,
        max_steps=args.max_steps,
        progress=not args.no_progress and args.scheduler is None,
    )


def _executor(args: argparse.Namespace, processes: int = 1) -> Executor:
    """``--scheduler``'s Dask cluster, else local processes (``processes`` at once).

    Use it as a context manager: the cluster is reached (or refused, exit 2)
    before any work, and the connection closed after.
    """
    return executor_for(args.scheduler, processes=processes)


def _likelihood_options(args: argparse.Namespace) -> LikelihoodOptions:
    """The likelihood options of the shared modelling flags."""
    return LikelihoodOptions(
        channels=args.channels,
        noise=args.noise,
        sensor=args.sensor_noise,
        engine=args.engine,
        steady=args.steady,
        damping=args.damping,
    )


def _fit_options(args: argparse.Namespace) -> FitOptions:
    """The fit options of the shared modelling flags."""
    return FitOptions(
        robot=robot_profile(args),
        likelihood_options=_likelihood_options(args),
        prior_overrides=_prior_overrides(args.prior),
        settings=_sampler_settings(args),
        seed=args.seed,
    )


@dataclasses.dataclass(frozen=True)
class _Labelled:
    """(input, ``job([experiment])``) of an (input, experiment) pair (picklable)."""

    job: Callable[[list[Experiment]], Any]

    def __call__(self, item: tuple[str, Experiment]) -> tuple[str, Any]:
        given, experiment = item
        return given, self.job([experiment])


def _print_each(
    args: argparse.Namespace,
    out: Reporter,
    work: Callable[..., Any],
    outputs: Callable[[Experiment], list[Path]],
    **options,
) -> int:
    """:func:`each_experiment`; JSON: ``experiments`` (name -> result) and ``failed``."""
    done, failed, code = each_experiment(args, out, work, outputs, **options)
    out.result({"experiments": {e.name: result for e, result in done}, "failed": failed})
    return code


def cmd_sample(args: argparse.Namespace) -> int:
    """Without ``--pooled``, one posterior per experiment: one job each on the executor.

    Locally they run one after the other in this process, the chain file
    beside each posterior; on a cluster (``--scheduler``) all at once, with
    no chain file (the workers need not share this file system). Each
    posterior is saved as it finishes.
    """
    out = Reporter(args.json)
    local = args.scheduler is None
    sampling = _Sampling(
        _fit_options(args),
        args.family,
        Path(args.out),
        each=not args.pooled and len(args.experiments) > 1,
        chain=local,
    )
    with _executor(args) as executor:
        if not local:
            out.say(f"sampling on the Dask cluster at {args.scheduler}")
        if not sampling.each:
            group = load_logs(args)
            with executor.run(sampling, [group]) as finished:
                out.result(_save_sample(next(finished), sampling.path(group), out))
            return EXIT_OK

        def outputs(experiment: Experiment) -> list[Path]:
            path = sampling.path([experiment])
            return [path, chain_path(path)]

        return _print_each(
            args,
            out,
            lambda e, result: _save_sample(result, sampling.path([e]), out),
            outputs,
            results=lambda loaded, _: executor.run(_Labelled(sampling), list(loaded.items())),
        )


def cmd_compare(args: argparse.Namespace) -> int:
    """Every (experiment, family) a job of the executor, all at once (``--pooled``: one group).

    With ``--out``, each family's posterior is saved as it finishes (and
    reused on a rerun), each experiment's summary as soon as its families
    are done.
    """
    out = Reporter(args.json)
    folder = Path(args.out) if args.out else None
    executor = _executor(args, args.processes)
    families = args.families or tuple(FAMILIES)  # None: every registered family

    def announce(group: list[Experiment]) -> None:
        channels = resolve_channels(group, args.channels)
        out.say(
            f"comparing {', '.join(families)} on {group_name(group)}, channels "
            f"{', '.join(channels)} (bridge sampling)"
        )

    @contextlib.contextmanager
    def comparisons(groups: dict[str, list[Experiment]], on_failure=None):
        names = {key: group_name(group) for key, group in groups.items()}

        def finished(key: str, family: str, evidence, idata) -> None:
            label = f"{names[key]} {family}" if len(groups) > 1 else family
            out.say(f"  {label}: log Z = {evidence.log_evidence:.2f} +- {evidence.error:.3f}")
            if folder is not None:  # saved at once: an interruption keeps it
                criticise(idata)  # cached in its attrs: the file carries it
                save_posterior(idata, family_files(folder, names[key], [family])[family])

        reuse = folder and {k: family_files(folder, n, families) for k, n in names.items()}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)  # report() prints them
            each = compare_groups(
                groups,
                _fit_options(args),
                families=families,
                cross_check=args.nested,
                executor=executor,
                reuse=reuse,
                on_family=finished,
                on_failure=on_failure,
            )
            with contextlib.closing(each):
                yield each

    def report(group: list[Experiment], comparison) -> dict:
        for message in comparison.convergence_messages():
            print(f"bayes-jackal: WARNING: {message}", file=sys.stderr)
        result = comparison.to_dict() | {"channels": list(resolve_channels(group, args.channels))}
        comparison_table(result, out)
        name = group_name(group)
        saved = "" if folder is None else f" and {summary_file(folder, name)}"
        family_warnings(result["warnings"], result, where=f"--json{saved}")
        if folder is not None:
            write_json(summary_file(folder, name), result)
            files = ", ".join(
                path.name for path in family_files(folder, name, result["families"]).values()
            )
            out.say(f"wrote {files} and {summary_file(folder, name).name} in {folder}/")
        return result

    def each_experiment(loaded: dict[str, Experiment], fail) -> AbstractContextManager:
        announced, _ = each_input(
            loaded, lambda given: announce([loaded[given]]), catch=Exception, on_failure=fail
        )
        return comparisons({given: [loaded[given]] for given in announced}, fail)

    def outputs(name: str) -> list[Path]:
        if folder is None:
            return []
        return [*family_files(folder, name, families).values(), summary_file(folder, name)]

    with executor:  # a cluster is reached (or refused) before any work
        if args.pooled or len(args.experiments) == 1:
            experiments = load_logs(args)
            check_named_outputs(args, outputs(group_name(experiments)))
            announce(experiments)
            with comparisons({"pooled": experiments}) as each:
                [(_, comparison)] = each
            out.result(report(experiments, comparison))
            return EXIT_OK
        return _print_each(
            args,
            out,
            lambda e, comparison: report([e], comparison),
            lambda e: outputs(e.name),
            results=each_experiment,
        )


def cmd_population(args: argparse.Namespace) -> int:
    """Each unit's posterior saved under ``--out``/units as it finishes (reused on a rerun),
    then population.json and the forest plot."""
    out = Reporter(args.json)
    folder = Path(args.out)
    experiments = load_logs(args)
    with _executor(args, args.processes) as executor:
        result = population_posterior(
            experiments,
            _fit_options(args),
            groups=args.groups,
            covariate=args.covariate,
            family=args.family,
            executor=executor,
            out=folder,
        )
    summary = result.to_dict()
    write_json(folder / "population.json", summary)
    save_population_plot(summary, folder / "population.png")
    population_text(summary, out)
    out.say(f"wrote {folder}/population.json, population.png and units/")
    out.result(summary)
    return EXIT_OK


def cmd_export_prior(args: argparse.Namespace) -> int:
    out = Reporter(False)
    idata = load_posterior(args.posterior)
    prior = export_prior(
        idata, order=args.order, source=args.posterior, sensor_smoothness=args.sensor_smoothness
    )
    path = write_prior(prior, args.out)
    size = len(prior.generalised_coordinates["precision"])
    out.say(
        f"wrote {path}: {prior.family} noise on {', '.join(prior.channels)}, "
        f"embedding order {args.order} ({size} x {size} precision), "
        f"{prior.draws['count']} posterior draws"
    )
    if not prior.converged:
        warn_not_converged(args.posterior)
    return EXIT_OK


def cmd_filter(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    prior, robot = read_prior(args.prior_file), robot_with_topics(args)
    trained = set(prior.experiments or ())  # the runs the prior was sampled on
    options = {
        "filters": args.filters,
        "order": args.order,
        "parameters": args.parameters,
        "sensor_precision": args.sensor_precision,
        "lookahead": args.lookahead,
        "robot": robot,
    }

    def estimate(experiment: Experiment) -> tuple[dict, dict, dict]:
        try:
            estimates, refused = estimate_each(experiment, prior, **options)
        except InputError as exc:  # name the prior beside the experiment
            if exc.source is not None:
                raise
            named = type(exc)(str(exc), source=f"{args.prior_file} on {experiment.source}")
            named.field = exc.field
            raise named from exc
        for name, reason in refused.items():
            out.say(f"{experiment.name}: {name} cannot run with this prior: {reason}")
        if experiment.name in trained:
            out.say(
                f"note: {experiment.name} is a run the prior was sampled on ({args.prior_file}'s "
                "experiments): its scores are in-sample, not a test on a run it has not seen"
            )
        columns = estimate_columns(experiment, estimates)
        return columns, score_estimates(experiment, estimates), refused

    done, failed, code = each_experiment(args, out, estimate)
    if done:
        write_estimates(args.out, {e.name: columns for e, (columns, _, _) in done})
        out.say(f"wrote {args.out}")
    for experiment, (_, scores, _) in done:
        filter_table(experiment.name, scores, out)
    out.result(
        {
            "prior": args.prior_file,
            "out": args.out if done else None,
            "experiments": {e.name: scores for e, (_, scores, _) in done},
            "filters_failed": {e.name: refused for e, (_, _, refused) in done if refused},
            "in_sample": [e.name for e, _ in done if e.name in trained],
            "failed": failed,
        }
    )
    return code


def _prior_overrides(items: list[list[str]]) -> dict[str, tuple[float, float]]:
    """``--prior NAME LOW HIGH`` items as {name: (low, high)}, validated by the library."""
    return prior_overrides(prior_ranges(items), field="--prior")


def cmd_analyse(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    robot = robot_with_topics(args)
    with _executor(args, args.processes) as executor:
        result = analyse_logs(
            args.inputs,
            args.out,
            robot=robot,
            families=args.families,
            settings=_sampler_settings(args),
            seed=args.seed,
            executor=executor,
            prior_overrides=_prior_overrides(args.prior),
            likelihood_options=_likelihood_options(args),
            read_options=read_options(args),
            state_estimation=args.state_estimation,
            groups=args.groups,
            figure_formats=args.formats,
        )
    return analysis_text(result, out)


def cmd_demo(args: argparse.Namespace) -> int:
    out = Reporter(args.json)
    result = run_demo(
        args.out,
        progress=not args.no_progress,
        state_estimation=args.state_estimation,
        figure_formats=args.formats,
    )
    noise = NoiseSettings()
    (sigma_c_vx, sigma_c_vy, sigma_c_yaw), sigma_n_yaw = noise.sigma_c, noise.sigma_n[2]
    out.say(
        f"Truth (simulated): d_lat={DEMO_TRUTH['d_lat']:g}, d_long={DEMO_TRUTH['d_long']:g} "
        f"N s/m, sigma_h={noise.width} s on every channel, sigma_c={sigma_c_yaw:g} rad/s "
        f"(yaw), {sigma_c_vx:g} and {sigma_c_vy:g} m/s (vx, vy), sigma_n[yaw]={sigma_n_yaw:g} "
        f"rad/s; vx and vy are recorded as motion-capture poses, sigma_p={POSE_NOISE[0]:g} m "
        f"(and {POSE_NOISE[1]:g} rad of heading noise)."
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
