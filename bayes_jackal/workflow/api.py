"""The workflow's front door: ``import bayes_jackal as bj`` is enough for all of it.

Logs in, posteriors, evidence, priors and reports out, with keyword-only
options whose defaults are the command line's (the constants of
:mod:`bayes_jackal._runtime.defaults`, which ``bayes-jackal``'s flags read)::

    runs = bj.load_experiments(["run1.csv", "run2.bag"])
    posterior = bj.sample(runs, seed=1)  # bayes-jackal sample --pooled
    comparison = bj.compare(runs, families=("white", "gaussian"), seed=1)
    prior = bj.export_prior(comparison.posteriors[comparison.best], order=None)  # up to 2
    bj.write_report(comparison.posteriors, "report.html")

:func:`bayes_jackal.dem.export_prior` and
:func:`bayes_jackal.report.write_report` are exported as they are. Where a
library is better quiet than a command, the defaults differ: no progress
display (``progress=True`` shows it), and :func:`compare` runs its families
one after the other in this process (``processes``; ``bayes-jackal
compare`` takes one per core). Several experiments make one pooled
posterior (``sample --pooled``); call :func:`sample` on each for one per
experiment.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from .._runtime.arviz_quiet import az
from .._runtime.defaults import (
    ENGINE,
    FAMILY,
    MAX_STEPS,
    NOISE,
    SENSOR,
    VELOCITIES,
    WALKERS,
)
from .._runtime.errors import each_input, refuse
from ..inference.chains import SamplerSettings
from ..inference.comparison import compare_families
from ..inference.comparison_result import Comparison
from ..inference.executors import Executor
from ..inference.sampling import sample_posterior
from ..io.experiment import Experiment
from ..io.tables import (
    check_column_roles,
    check_columns_apply,
    check_declared_rate,
    check_unique_names,
)
from ..likelihood.residual_likelihood import LikelihoodOptions
from ..model.kernels import FAMILIES
from ..model.robot import RobotProfile, load_profile
from .analysis import read_log

__all__ = ["compare", "load_experiments", "read_logs", "sample"]


def _profile(robot: RobotProfile | str | Path | None) -> RobotProfile:
    """A robot profile as given, or read from its TOML file (None: the Jackal's)."""
    return robot if isinstance(robot, RobotProfile) else load_profile(robot)


def _experiments(experiments: Experiment | Sequence[Experiment]) -> list[Experiment]:
    """One experiment, or several, as a list."""
    return [experiments] if isinstance(experiments, Experiment) else list(experiments)


def load_experiments(
    paths: str | Path | Sequence[str | Path],
    *,
    robot: RobotProfile | str | Path | None = None,
    columns: Mapping[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    window: tuple[float, float] | None = None,
    progress: bool = False,
    velocities: str = VELOCITIES[0],
) -> list[Experiment]:
    """Read logs as experiments: CSV, MATLAB ``.mat``, NetCDF ``.nc`` files and ROS bags.

    Each input is read as ``bayes-jackal analyse`` reads it
    (:func:`bayes_jackal.workflow.read_log`): a bag (``.bag``, ``.mcap``,
    ``.db3`` or a ROS2 bag folder) as ``ingest`` does, an experiment file
    by :func:`bayes_jackal.io.load_experiment`. All or none: a bad
    input stops the call, and the error names every bad one.

    Parameters
    ----------
    paths : str, Path or sequence of them
        The logs.
    robot : RobotProfile, str or Path, optional
        A profile or its TOML file; the Jackal's by default (``--robot``).
        Its topics and wheel joints read bags; an experiment file's sample
        rate is checked against its rate unless ``rate`` is given
        (:func:`~bayes_jackal.io.check_sample_time`: a time unit slip is
        refused, another plausible rate said).
    columns : mapping of str to str, optional
        CSV and MATLAB files: the file's column for a role, e.g.
        ``{"yaw_rate": "gyro_z"}`` (``--column``).
    rate : float, optional
        CSV and MATLAB files: the declared sample rate [Hz]; detected from
        the stamps by default (``--rate``).
    velocities : {"measured", "derived"}
        CSV and MATLAB files without pose columns: whether their vx, vy
        were measured or derived from poses (``--velocities``;
        :func:`bayes_jackal.io.read_csv`).
    max_gap : float, optional
        Longest tolerated dropout [s]; by default 0.25 s in bags and 5
        sample steps in files (``--max-gap``).
    window : (float, float), optional
        The steady window [s; in bags from the first IMU stamp]; by default
        detected in bags, the whole run in files (``--window``).
    progress : bool
        Show each bag's progress on stderr.

    Returns
    -------
    list of Experiment
        In the order given; their names are unique.

    Raises
    ------
    DataError
        Naming every input that cannot be read and why, or experiments that
        share a name.
    InputError
        For an unknown column role.

    Examples
    --------
    A CSV of a simulated run (time in s, yaw rate and wheel speeds in
    rad/s, vx and vy in m/s), read back:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1, name="v1_01")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     csv = bj.write_csv(run, Path(folder) / "v1_01.csv")
    ...     [loaded] = bj.load_experiments([csv])
    >>> loaded.name, loaded.channels, round(1 / loaded.dt)
    ('v1_01', ('vx', 'vy', 'yaw'), 72)
    """
    paths = _paths(paths)
    experiments, failed = read_logs(
        paths,
        robot=robot,
        columns=columns,
        rate=rate,
        max_gap=max_gap,
        window=window,
        progress=progress,
        velocities=velocities,
    )
    refuse(failed, len(paths))
    return list(experiments.values())


def read_logs(
    paths: str | Path | Sequence[str | Path],
    *,
    robot: RobotProfile | str | Path | None = None,
    columns: Mapping[str, str] | None = None,
    rate: float | None = None,
    max_gap: float | None = None,
    window: tuple[float, float] | None = None,
    progress: bool = False,
    on_failure: Callable[[str, Exception], None] | None = None,
    velocities: str = VELOCITIES[0],
) -> tuple[dict[str, Experiment], dict[str, str]]:
    """Read each log on its own, past the bad ones (:func:`load_experiments`: all or none).

    The reader of ``bayes-jackal sample``, ``compare``, ``grid`` and
    ``residuals``, which go on with the good inputs when they process each
    on its own.

    Parameters
    ----------
    paths, robot, columns, rate, max_gap, window, progress, velocities
        As in :func:`load_experiments`.
    on_failure : callable, optional
        ``on_failure(path, exception)``, called as each bad input is met.

    Returns
    -------
    experiments : dict of str to Experiment
        By path as given, in order.
    failed : dict of str to str
        Why each bad input cannot be used (the reason names it), by path.

    Raises
    ------
    DataError
        When two experiments that could be read share a name.
    InputError
        For an unknown column role, or a column mapping none of the paths
        can use (:func:`~bayes_jackal.io.check_columns_apply`).

    Examples
    --------
    A simulated run written as CSV, and a file that is not there:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.workflow import read_logs
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1, name="v1_01")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     csv = str(bj.write_csv(run, Path(folder) / "v1_01.csv"))
    ...     experiments, failed = read_logs([csv, "missing.nc"])
    >>> [e.name for e in experiments.values()], list(failed)
    (['v1_01'], ['missing.nc'])
    """
    robot = _profile(robot)
    options = {
        "columns": check_column_roles(columns),
        "rate": check_declared_rate(rate),
        "velocities": velocities,
    }
    paths = _paths(paths)
    check_columns_apply(paths, columns)
    experiments, failed = each_input(
        paths,
        lambda path: read_log(
            path, robot, window=window, max_gap=max_gap, progress=progress, read_options=options
        ),
        on_failure=on_failure,
    )
    check_unique_names(experiments.values())
    return experiments, failed


def _paths(paths: str | Path | Sequence[str | Path]) -> list[str | Path]:
    """One path, or several, as a list."""
    return [paths] if isinstance(paths, str | Path) else list(paths)


def sample(
    experiments: Experiment | Sequence[Experiment],
    *,
    family: str = FAMILY,
    channels: Sequence[str] | None = None,
    noise: str = NOISE,
    sensor: str = SENSOR,
    engine: str = ENGINE,
    seed: int | None = None,
    max_steps: int = MAX_STEPS,
    walkers: int = WALKERS,
    priors: Mapping[str, tuple[float, float]] | None = None,
    robot: RobotProfile | str | Path | None = None,
    chain_file: str | Path | None = None,
    progress: bool = True,
) -> az.InferenceData:
    """The posterior of the damping and the noise, sampled with emcee (``bayes-jackal sample``).

    The same likelihood, sampler settings and seed as ``bayes-jackal sample
    --pooled`` with the same options, so the same chain.

    Parameters
    ----------
    experiments : Experiment or sequence of them
        Several are pooled into one posterior: one damping (d_lat, d_long)
        for all.
    family : str
        Process-noise family, a key of :data:`bayes_jackal.FAMILIES`
        (``--family``; :data:`FAMILY`).
    channels : sequence of {"yaw", "vx", "vy"}, optional
        By default every channel all experiments measure (``--channels``).
    noise : {"shared", "per-experiment", "one-width"}
        Pooled experiments' noise parameters (``--noise``; :data:`NOISE`):
        "one-width" shares them too, with one width for every channel.
    sensor : {"ma1", "diagonal"}
        Sensor-noise footprint (``--sensor-noise``; :data:`SENSOR`).
    engine : {"fast", "exact", "whittle"}
        Likelihood engine (``--engine``; :data:`ENGINE`).
    seed : int, optional
        Same seed, same chain (``--seed``).
    max_steps : int
        Step cap of the chain (``--max-steps``; :data:`MAX_STEPS`). A chain
        that reaches it before converging warns
        (:class:`~bayes_jackal.inference.ConvergenceWarning`).
    walkers : int
        Ensemble size; 0: max(32, 4 x parameters) (``--walkers``).
    priors : mapping of str to (float, float), optional
        (low, high) ranges over the profile's, e.g. ``{"d_lat": (10, 2000)}``
        [N s/m; s for ``sigma_h``/``width``; rad/s or m/s for ``sigma_c``,
        ``sigma_n``] (``--prior``).
    robot : RobotProfile, str or Path, optional
        A profile or its TOML file; the Jackal's by default (``--robot``).
    chain_file : str or Path, optional
        HDF5 file of the chain: a run with the same file and options resumes
        it (``sample`` keeps it beside the posterior as ``*.chain.h5``).
    progress : bool
        Show the chain's progress on stderr (by default: a bar on a terminal, a
        line every 10 s elsewhere, with the steps the chain expects to need and
        the time left); False for silence.

    Returns
    -------
    arviz.InferenceData
        As :func:`bayes_jackal.inference.sample_posterior`; save it with
        :func:`bayes_jackal.save_posterior`.

    Raises
    ------
    InputError
        Naming an unknown family, channel, noise sharing, sensor model,
        engine or prior, or a bad count.
    DataError
        For a channel an experiment does not measure.

    Examples
    --------
    A quick chain of 20 steps, far from converged (a ConvergenceWarning);
    real use takes the default step cap:

    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> sorted(posterior.posterior.data_vars)[:4]
    ['Ad', 'Bd', 'd_lat', 'd_long']
    >>> summary = bj.summarize(posterior)
    >>> summary["family"], summary["channels"], summary["converged"]
    ('white', ['yaw'], False)
    """
    options = LikelihoodOptions(channels=channels, noise=noise, sensor=sensor, engine=engine)
    likelihood = options.likelihood(_experiments(experiments), _profile(robot), family)
    return sample_posterior(
        likelihood,
        SamplerSettings(walkers=walkers, max_steps=max_steps, progress=progress),
        seed=seed,
        chain_file=chain_file,
        prior_overrides=priors,
    )


def compare(
    experiments: Experiment | Sequence[Experiment],
    *,
    families: Sequence[str] | None = None,
    channels: Sequence[str] | None = None,
    noise: str = NOISE,
    sensor: str = SENSOR,
    engine: str = ENGINE,
    seed: int | None = None,
    max_steps: int = MAX_STEPS,
    walkers: int = WALKERS,
    priors: Mapping[str, tuple[float, float]] | None = None,
    robot: RobotProfile | str | Path | None = None,
    nested: bool = False,
    processes: int = 1,
    executor: Executor | None = None,
    progress: bool = True,
) -> Comparison:
    """Noise-filter families ranked by evidence (``bayes-jackal compare --pooled``).

    Samples each family's posterior as :func:`sample` does and estimates
    its log evidence by bridge sampling
    (:func:`bayes_jackal.inference.compare_families`).

    Parameters
    ----------
    experiments : Experiment or sequence of them
        Several are pooled: one damping for all.
    families : sequence of str, optional
        Keys of :data:`bayes_jackal.FAMILIES`, distinct (``--families``);
        None: every registered family, in the registry's order.
    channels, noise, sensor, engine, seed, max_steps, walkers, priors, robot, progress
        As in :func:`sample`; the seed seeds every family's chain and the
        bridges' proposal draws.
    nested : bool
        Cross-check each evidence by nested sampling (slow; ``--nested``,
        ``pip install 'bayes-jackal[evidence]'``).
    processes : int
        Families sampled at once, each in its own worker process; a script
        that asks for more than 1 needs an ``if __name__ == "__main__":``
        guard. The numbers do not depend on it.
    executor : Executor, optional
        Where the families run instead (:mod:`bayes_jackal.inference.executors`),
        e.g. ``DaskExecutor("tcp://host:8786")`` (``--scheduler``).

    Returns
    -------
    Comparison
        ``best`` (the family of highest evidence), ``posteriors`` (family ->
        arviz.InferenceData, each with its evidence), ``verdict()`` and
        ``to_dict()`` (the ``compare --json`` object).

    Raises
    ------
    InputError
        For families that are not distinct known names, and as :func:`sample`.

    Examples
    --------
    Two families on a quick budget (20 steps, the fewest bridge sampling
    takes are 16; far from converged: real use takes the default step cap):

    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> comparison = bj.compare(
    ...     [run], families=("white", "exponential"), channels=["yaw"], max_steps=20, seed=1
    ... )
    >>> sorted(comparison.posteriors), comparison.best in comparison.posteriors
    (['exponential', 'white'], True)
    >>> sorted(comparison.to_dict()["families"]["white"])[:3]
    ['converged', 'log_bayes_factor_vs_best', 'log_bayes_factor_vs_white']
    """
    return compare_families(
        _experiments(experiments),
        _profile(robot),
        families=tuple(FAMILIES if families is None else families),
        settings=SamplerSettings(walkers=walkers, max_steps=max_steps, progress=progress),
        seed=seed,
        prior_overrides=priors,
        cross_check=nested,
        processes=processes,
        executor=executor,
        likelihood_options=LikelihoodOptions(
            channels=channels, noise=noise, sensor=sensor, engine=engine
        ),
    )
