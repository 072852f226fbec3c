"""The argument parser of ``bayes-jackal``: commands, flags and their defaults.

It loads no numpy, so that every ``--help`` answers at once: the names and
defaults are the library's own, from :mod:`bayes_jackal._runtime.defaults`, and
:func:`bayes_jackal.cli.main` imports the commands (:mod:`.commands`) only
to run one, ``cmd_<command>``.
"""

from __future__ import annotations

import argparse
import os

from .. import __version__
from .._runtime import (
    AUTO_ORDER,
    BAG_FORMATS,
    CHANNELS,
    CONVERSIONS,
    D_LAT,
    D_LONG,
    DAMPING_MODEL,
    DAMPING_MODELS,
    DEFAULT_CHANNEL_ORDER,
    DEFAULT_FAMILIES,
    DISCRETISATION,
    DISCRETISATIONS,
    ENGINE,
    ENGINES,
    EXPERIMENT_FORMATS,
    FAMILY,
    FILTER_PARAMETERS,
    FILTERS,
    GRID_METHODS,
    GRID_POINTS,
    LOOKAHEAD,
    MAX_GAP,
    MAX_GAP_STEPS,
    MAX_STEPS,
    METHOD,
    NOISE,
    NOISE_SHARING,
    POSE_NOISE,
    RESIDUAL_CHANNELS,
    RESIDUAL_LAGS,
    ROLES,
    SENSOR,
    SENSOR_MODELS,
    SENSOR_PRECISIONS,
    SENSOR_SMOOTHNESS,
    SERIES_COUNTS,
    SHORT_MEMORY,
    SIMULATED_NOISE,
    STATE_ESTIMATION,
    THESIS_CHANNEL,
    VELOCITIES,
    WALKERS,
    InputError,
)
from .noise_parser import add_noise_parser
from .parser_types import add_formats_flag, add_prior_flag
from .parser_types import channel_list as _channel_list
from .parser_types import count as _count
from .parser_types import family as _family
from .parser_types import family_list as _family_list
from .parser_types import finite as _finite
from .parser_types import name_list as _name_list
from .parser_types import natural as _natural
from .parser_types import non_negative as _non_negative
from .parser_types import positive as _positive


class _Grid(argparse.Action):
    """``--d-lat START STOP STEP``: checked by the grid's own rule (``damping_grid``)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from ..thesis import damping_grid  # imported with a grid given: the command runs

        try:
            damping_grid(*values, name=option_string)
        except InputError as exc:
            message = str(exc).removeprefix(f"{option_string}: ")
            raise argparse.ArgumentError(self, message) from None
        setattr(namespace, self.dest, values)


class _Window(argparse.Action):
    """``--window T0 T1`` [s]: T0 < T1."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        start, stop = values
        if not start < stop:
            raise argparse.ArgumentError(self, f"expected T0 < T1 [s], got {start:g} {stop:g}")
        setattr(namespace, self.dest, values)


#: The default of a damping flag of simulate and residuals (model.mass_scaled_damping).
_SCALED = "{:g} for the Jackal, scaled with the robot's mass as its prior is"

#: What grid, residuals, sample and compare read (as bj.load_experiments does).
_EXP_HELP = "experiment files (.csv, .mat, .nc) and bags (.bag, .mcap, .db3, bag folders)"


def _add_common(parser: argparse.ArgumentParser, json_flag: bool = True) -> None:
    parser.add_argument(
        "--robot", metavar="PROFILE", help="profile: jackal (default), husky, warthog or TOML file"
    )
    if json_flag:
        parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


#: Set (to anything but "" or "0") to show tracebacks as ``--debug`` does,
#: e.g. where a script or CI job runs the command.
DEBUG_VARIABLE = "BAYES_JACKAL_DEBUG"


def _add_debug(parser: argparse.ArgumentParser, default: object) -> None:
    parser.add_argument(
        "--debug",
        action="store_true",
        default=default,
        help=f"show the traceback of a failure (or set {DEBUG_VARIABLE}=1)",
    )


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
        type=_positive,
        metavar="HZ",
        help="declared sampling rate [Hz] (default: detected from the time stamps)",
    )
    parser.add_argument(
        "--velocities",
        choices=VELOCITIES,
        default=VELOCITIES[0],
        help="what a file's vx, vy columns are when it has no pose columns (x, y, heading): "
        "measured by a sensor (the model's assumption), or derived from poses, which the "
        "posterior then warns of (default: %(default)s)",
    )


def _add_bag_flags(parser: argparse.ArgumentParser, max_gap: float | None = MAX_GAP) -> None:
    """Flags of reading bags (every command that reads them): window, gaps, topics."""
    parser.add_argument(
        "--window",
        type=_finite,
        nargs=2,
        action=_Window,
        metavar=("T0", "T1"),
        help="steady-state window [s; in bags from the first IMU stamp] instead of detecting it",
    )
    parser.add_argument(
        "--max-gap",
        type=_positive,
        default=max_gap,
        help="longest tolerated dropout [s] "
        + (
            f"({max_gap:g})"
            if max_gap
            else f"(bags {MAX_GAP:g}, experiment files {MAX_GAP_STEPS} sample steps)"
        ),
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
        default=SENSOR,
        help=f"sensor-noise footprint: ma1 or a diagonal nugget ({SENSOR})",
    )
    if pooling:
        parser.add_argument(
            "--pooled", action="store_true", help="one posterior for all experiments (shared d)"
        )
    parser.add_argument(
        "--noise",
        choices=NOISE_SHARING,
        default=NOISE,
        help="noise parameters: shared by pooled experiments, per experiment, or shared "
        f"with one width (smoothness) for every channel ({NOISE})",
    )
    parser.add_argument(
        "--engine", choices=ENGINES, default=ENGINE, help=f"likelihood engine ({ENGINE})"
    )
    parser.add_argument(
        "--steady",
        action="store_true",
        help="fit each run's steady window only, as the thesis (default: every sample, "
        "transients included)",
    )
    parser.add_argument(
        "--damping",
        choices=DAMPING_MODELS,
        default=DAMPING_MODEL,
        help="one damping, or one that depends on each segment's speed (speed ratios "
        f"across the runs' speeds) ({DAMPING_MODEL})",
    )
    parser.add_argument("--seed", type=_natural, default=None, help="seed: same seed, same chain")
    parser.add_argument(
        "--walkers",
        type=_natural,
        default=WALKERS,
        help=f"ensemble size (default {WALKERS}: max(32, 4 x parameters))",
    )
    parser.add_argument(
        "--max-steps", type=_count, default=MAX_STEPS, help=f"step cap ({MAX_STEPS})"
    )
    add_prior_flag(parser, "override a prior range, e.g. --prior d_lat 10 2000")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the tasks (each experiment's posterior; for compare and analyse each "
        "family) on a Dask cluster, e.g. tcp://127.0.0.1:8786 (`dask scheduler` and "
        "`dask worker`; pip install 'bayes-jackal[cluster]'); no progress bars there. "
        "Default: this machine",
    )


def _add_state_estimation(parser: argparse.ArgumentParser) -> None:
    """``--state-estimation`` / ``--no-state-estimation`` of analyse and demo."""
    parser.add_argument(
        "--state-estimation",
        action=argparse.BooleanOptionalAction,
        default=STATE_ESTIMATION,
        help="with two or more runs, score the filters on each run left out of the best "
        "family's prior fitted to the others: the pooled posterior reweighted by PSIS, one "
        "more posterior per run whose Pareto k-hat is above 0.7 "
        f"(default: {'on' if STATE_ESTIMATION else 'off'})",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``bayes-jackal``."""
    parser = argparse.ArgumentParser(
        prog="bayes-jackal",
        description="Bayesian system identification of skid-steer robots (thesis: The Noisy "
        "Jackal).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    _add_debug(parser, default=os.environ.get(DEBUG_VARIABLE, "0") not in ("", "0"))
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
        default=None,
        metavar="white,gaussian,...",
        help=f"noise families to compare ({','.join(DEFAULT_FAMILIES)}, and {SHORT_MEMORY} "
        "where white beats gaussian)",
    )
    analysis.add_argument(
        "--processes",
        type=_count,
        default=os.cpu_count() or 1,
        help="families sampled at once (default: the number of cores; not with --scheduler)",
    )
    analysis.add_argument(
        "--groups",
        metavar="GROUPS.csv",
        help="CSV of each run's group (run, group, numeric covariates such as speed): also "
        "each group's damping, their population and its speed dependence (as `population`)",
    )
    _add_state_estimation(analysis)
    add_formats_flag(analysis)
    _add_bag_flags(analysis, max_gap=None)
    _add_input_flags(analysis)
    _add_model_flags(analysis, pooling=False)
    _add_common(analysis)

    demo = commands.add_parser(
        "demo", help="analyse on the shipped simulated bags (embedded default data)"
    )
    demo.add_argument("--out", default="bayes-jackal-demo", help="output folder")
    demo.add_argument("--no-progress", action="store_true", help="no progress display")
    demo.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    _add_state_estimation(demo)
    add_formats_flag(demo)

    sim = commands.add_parser("simulate", help="write thesis-like experiments with known truth")
    sim.add_argument("--out", required=True, help="output folder")
    sim.add_argument("--seed", type=_natural, default=None, help="random seed (reproducible runs)")
    for label, default in SERIES_COUNTS.items():
        sim.add_argument(
            f"--{label}",
            type=_natural,
            default=default,
            help=f"runs of series {label} ({default})",
        )
    for name, value in (("d_lat", D_LAT), ("d_long", D_LONG)):
        sim.add_argument(
            f"--{name.replace('_', '-')}",
            type=_positive,
            default=None,
            help=f"true {name} [N s/m] ({_SCALED.format(value)})",
        )
    sim.add_argument(
        "--family", type=_family, default=FAMILY, help=f"process-noise filter ({FAMILY})"
    )
    sim.add_argument(
        "--width",
        "--sigma-h",
        dest="width",
        type=_positive,
        default=SIMULATED_NOISE["width"],
        help=f"kernel width [s] (sigma_h of the Gaussian; {SIMULATED_NOISE['width']})",
    )
    for name, help_text in (("c", "process"), ("n", "sensor")):
        sim.add_argument(
            f"--sigma-{name}",
            type=_non_negative,
            nargs=3,
            metavar=("VX", "VY", "YAW"),
            default=SIMULATED_NOISE[f"sigma_{name}"],
            help=f"{help_text} noise sd of vx, vy [m/s] and yaw [rad/s]",
        )
    sim.add_argument("--conversion", choices=CONVERSIONS, help="cmd_vel -> wheel speeds")
    sim.add_argument(
        "--format",
        choices=EXPERIMENT_FORMATS,
        default=EXPERIMENT_FORMATS[0],
        help=f"file format ({EXPERIMENT_FORMATS[0]})",
    )
    sim.add_argument(
        "--bag", choices=BAG_FORMATS, help="also write each run as a ROS1 or ROS2 bag"
    )
    sim.add_argument(
        "--pose-noise",
        type=_non_negative,
        nargs=2,
        metavar=("POSITION", "HEADING"),
        default=POSE_NOISE,
        help="the bags' motion-capture noise: position sd per axis [m] and heading sd [rad] "
        f"({POSE_NOISE[0]:g} {POSE_NOISE[1]:g}); vx, vy of a bag are seen through its poses",
    )
    _add_common(sim)

    grid = commands.add_parser("grid", help="thesis grid search over (d_lat, d_long)")
    grid.add_argument("experiments", nargs="+", metavar="EXP", help=_EXP_HELP)
    grid.add_argument(
        "--method", choices=GRID_METHODS, default=METHOD, help=f"criterion ({METHOD})"
    )
    counts = ", ".join(f"{count} for {method}" for method, count in GRID_POINTS.items())
    for name in ("d-lat", "d-long"):
        grid.add_argument(
            f"--{name}",
            type=_finite,
            nargs=3,
            action=_Grid,
            default=None,
            metavar=("START", "STOP", "STEP"),
            help="grid values [N s/m], STOP included (default: the profile's prior range of "
            f"{name.replace('-', '_')}, log-spaced: {counts}; the thesis': 1 1000 1)",
        )
    grid.add_argument(
        "--channel", choices=CHANNELS, default=THESIS_CHANNEL, help=f"channel ({THESIS_CHANNEL})"
    )
    grid.add_argument(
        "--discretisation",
        choices=DISCRETISATIONS,
        default=DISCRETISATION,
        help=f"zero-order hold or forward Euler ({DISCRETISATION})",
    )
    grid.add_argument("--plot", metavar="FILE", help="save the MSE surface (png, svg, pdf)")
    grid.add_argument("--out", metavar="FILE.nc", help="save all MSE surfaces as NetCDF")
    _add_bag_flags(grid, max_gap=None)
    _add_input_flags(grid)
    _add_common(grid)

    ingest = commands.add_parser("ingest", help="ROS1/ROS2 bags to experiment files")
    ingest.add_argument("bags", nargs="+", metavar="BAG", help=".bag, .mcap, .db3 or bag folder")
    ingest.add_argument("--out", required=True, help="output folder (one .nc per bag)")
    _add_bag_flags(ingest)
    _add_common(ingest)

    res = commands.add_parser("residuals", help="thesis ch. 7 residual analysis and sigma_h fit")
    res.add_argument("experiments", nargs="+", metavar="EXP", help=_EXP_HELP)
    for name, value in (("d_lat", D_LAT), ("d_long", D_LONG)):
        res.add_argument(
            f"--{name.replace('_', '-')}",
            type=_positive,
            default=None,
            help=f"{name} of the model [N s/m] ({_SCALED.format(value)})",
        )
    res.add_argument(
        "--channels",
        type=_channel_list,
        default=RESIDUAL_CHANNELS,
        metavar="yaw,vx,vy",
        help=f"comma-separated channels to analyse ({','.join(RESIDUAL_CHANNELS)})",
    )
    res.add_argument(
        "--lags",
        type=_count,
        default=RESIDUAL_LAGS,
        help=f"lags of the Ljung-Box test and sigma_h fit ({RESIDUAL_LAGS})",
    )
    _add_bag_flags(res, max_gap=None)
    _add_input_flags(res)
    _add_common(res)

    sample = commands.add_parser("sample", help="posterior of damping and noise with emcee")
    sample.add_argument("experiments", nargs="+", metavar="EXP", help=_EXP_HELP)
    sample.add_argument("--out", required=True, metavar="POSTERIOR.nc", help="posterior file")
    sample.add_argument("--family", type=_family, default=FAMILY, help=f"noise family ({FAMILY})")
    _add_bag_flags(sample, max_gap=None)
    _add_input_flags(sample)
    _add_model_flags(sample)
    _add_common(sample)

    compare = commands.add_parser("compare", help="noise-filter families ranked by evidence")
    compare.add_argument("experiments", nargs="+", metavar="EXP", help=_EXP_HELP)
    compare.add_argument(
        "--families",
        type=_family_list,
        metavar="white,gaussian,...",
        help="comma-separated families (every registered family)",
    )
    compare.add_argument("--out", metavar="DIR", help="save each family's posterior here")
    compare.add_argument(
        "--processes",
        type=_count,
        default=os.cpu_count() or 1,
        help="tasks sampled at once, one per process (default: the number of cores; not "
        "with --scheduler)",
    )
    compare.add_argument(
        "--nested",
        action="store_true",
        help="cross-check each evidence by nested sampling (dynesty; slow)",
    )
    _add_bag_flags(compare, max_gap=None)
    _add_input_flags(compare)
    _add_model_flags(compare)
    _add_common(compare)

    population = commands.add_parser(
        "population",
        help="each group's damping, their population and its dependence on speed",
    )
    population.add_argument("experiments", nargs="+", metavar="EXP", help=_EXP_HELP)
    population.add_argument(
        "--groups",
        metavar="GROUPS.csv",
        help="CSV of each run's group: columns run, group and numeric covariates such as "
        "speed (default: the experiments' own 'group')",
    )
    population.add_argument(
        "--covariate",
        metavar="NAME",
        help="covariate of the state dependence log d = a + b (x - x0) (default: speed, "
        "when every run has one)",
    )
    population.add_argument(
        "--out", required=True, metavar="DIR", help="population.json, the forest plot, units/"
    )
    population.add_argument(
        "--family", type=_family, default=FAMILY, help=f"noise family of every unit ({FAMILY})"
    )
    population.add_argument(
        "--processes",
        type=_count,
        default=os.cpu_count() or 1,
        help="units sampled at once (default: the number of cores; not with --scheduler)",
    )
    _add_bag_flags(population, max_gap=None)
    _add_input_flags(population)
    _add_model_flags(population, pooling=False)
    _add_common(population)

    export = commands.add_parser("export-prior", help="Active Inference (DEM) prior as JSON")
    export.add_argument("posterior", metavar="POSTERIOR.nc", help="posterior file from sample")
    export.add_argument("--out", required=True, metavar="prior.json", help="output JSON")
    export.add_argument(
        "--order",
        type=_natural,
        default=AUTO_ORDER,
        help=f"embedding order P of generalised coordinates ({AUTO_ORDER})",
    )
    export.add_argument(
        "--sensor-smoothness",
        type=_positive,
        default=SENSOR_SMOOTHNESS,
        metavar="BINS",
        help="Gaussian smoothness of the white sensor noise in Pi_z [time bins] "
        f"({SENSOR_SMOOTHNESS}, SPM's default)",
    )
    _add_common(export, json_flag=False)

    filters = commands.add_parser("filter", help="state estimates of the filters a prior drives")
    filters.add_argument("experiments", nargs="+", metavar="EXP", help=_EXP_HELP)
    filters.add_argument(
        "--prior",
        dest="prior_file",
        required=True,
        metavar="prior.json",
        help="prior file from export-prior",
    )
    filters.add_argument(
        "--out", required=True, metavar="estimates.csv", help="columns t and FILTER.STATE"
    )
    filters.add_argument(
        "--filters",
        type=_name_list(FILTERS, "filter(s)"),
        default=FILTERS,
        metavar=",".join(FILTERS),
        help=f"comma-separated filters ({','.join(FILTERS)})",
    )
    filters.add_argument(
        "--order",
        type=_natural,
        default=None,
        help="embedding order P of the generalised filter (the prior's)",
    )
    filters.add_argument(
        "--parameters",
        choices=FILTER_PARAMETERS,
        default=FILTER_PARAMETERS[0],
        help="noise parameters at the posterior means, or averaged over the prior's draws "
        f"({FILTER_PARAMETERS[0]})",
    )
    filters.add_argument(
        "--sensor-precision",
        choices=SENSOR_PRECISIONS,
        default=SENSOR_PRECISIONS[0],
        help="the generalised filter's Pi_z: embedded white noise, or the prior's sensor "
        f"smoothness ({SENSOR_PRECISIONS[0]})",
    )
    filters.add_argument(
        "--lookahead",
        type=_natural,
        default=LOOKAHEAD,
        help=f"samples after t_k in the generalised filter's embedding ({LOOKAHEAD}: causal)",
    )
    _add_bag_flags(filters, max_gap=None)
    _add_input_flags(filters)
    _add_common(filters)

    add_noise_parser(commands)

    report = commands.add_parser("report", help="HTML report with figures of posteriors")
    report.add_argument(
        "posteriors", nargs="+", metavar="POSTERIOR.nc", help="posterior files or folders"
    )
    report.add_argument("--out", required=True, metavar="report.html", help="output HTML")
    add_formats_flag(report)
    for command in commands.choices.values():
        _add_debug(command, default=argparse.SUPPRESS)  # keeps a --debug given before COMMAND
    return parser
