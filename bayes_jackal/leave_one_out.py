"""State estimation with the analysis' prior on runs it has not seen: leave one out.

Does the identified noise model help estimation? A prior scored on the
runs it was fitted to would flatter it. With N >= 2 runs,
:func:`leave_one_out` fits, for each run i, the posterior of one noise
family (the analysis' best) on the N - 1 other runs, exports its Active
Inference prior (:func:`bayes_jackal.export.export_prior`, at the highest
order the family allows up to :data:`~bayes_jackal.export.AUTO_ORDER`, as
the analysis' ``prior.json``), and runs every filter of
:mod:`bayes_jackal.state_estimation` on run i, scoring each
(:func:`~bayes_jackal.state_estimation.score_estimates`).

Cost: N more posteriors of the family, each on N - 1 runs, with the
analysis' sampler settings, seed, priors and likelihood options (in all
about N - 1 times that family's posterior on every run), run at once on the
analysis' executor (:func:`bayes_jackal.comparison.compare_groups`, whose
bridge-sampling evidence adds a few per cent); the filters take well under a
second per run. ``analyse --no-state-estimation`` skips it.

Files, under the analysis folder ``out``:

- ``state_estimation/posteriors/<run>.nc``: the posterior without ``<run>``,
  saved as it finishes and reused by a rerun with the same task;
- ``state_estimation/<run>.prior.json``: its prior (``experiments`` names
  the runs it was fitted to);
- ``state_estimation/<run>.csv``: the filters' estimates on ``<run>``
  (:func:`~bayes_jackal.state_estimation.write_estimates`);
- ``state_estimation.json``: :meth:`LeaveOneOut.to_dict`, rewritten as each
  run is done, so an interruption keeps the runs finished.

A filter that cannot run on a prior (the generalised filter needs a
sensor-noise sd) is named with its reason and the others are scored; a run
whose posterior or prior fails, or where no filter runs, is named in
``failed`` with its reason, and the other runs go on.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ._files import write_json
from .comparison import compare_groups
from .errors import describe
from .executors import Executor
from .experiment import Experiment
from .export import export_prior, write_prior
from .inference import SamplerSettings, keep_warnings
from .kalman import StateEstimate
from .posterior import save_posterior
from .robot import RobotProfile
from .state_estimation import (
    FILTERS,
    estimate_columns,
    estimate_each,
    score_estimates,
    write_estimates,
)

__all__ = ["FOLDER", "SUMMARY", "LeaveOneOut", "leave_one_out"]

#: The folder of the left-out runs' files, in the analysis folder.
FOLDER = "state_estimation"
#: The scores of every left-out run, in the analysis folder.
SUMMARY = "state_estimation.json"


@dataclass
class LeaveOneOut:
    """The filters' scores on each run left out, with a prior fitted to the others.

    Attributes
    ----------
    family : str
        The noise family of every left-out posterior.
    runs : dict of str to dict
        Per run left out, in the analysis' order: ``trained_on`` (the runs
        its prior was fitted to), ``order`` (the prior's embedding order),
        ``converged``, ``warnings`` (its chain's convergence messages),
        ``scores`` (:func:`~bayes_jackal.state_estimation.score_estimates`)
        of the filters that ran, ``filters_failed`` (the reason for each
        filter that could not run on this prior) and ``files``.
    failed : dict of str to str
        The reason for each run whose posterior, prior or filters failed.
    skipped : str or None
        Why nothing was run (fewer than two runs, or turned off).
    estimates : dict of str to (Experiment, estimates)
        Per run done, in the analysis' order, the run and its filters'
        estimates (``[filter][channel]``), for the report's figures.

    Examples
    --------
    >>> from bayes_jackal.leave_one_out import LeaveOneOut
    >>> LeaveOneOut("white", skipped="needs two or more runs").to_dict()
    {'family': 'white', 'runs': {}, 'failed': {}, 'skipped': 'needs two or more runs'}
    """

    family: str
    runs: dict[str, dict] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    skipped: str | None = None
    estimates: dict[str, tuple[Experiment, dict[str, dict[str, StateEstimate]]]] = field(
        default_factory=dict
    )

    def to_dict(self) -> dict:
        """JSON-ready: ``family``, ``runs``, ``failed``, ``skipped`` (``estimates`` left out)."""
        return {
            "family": self.family,
            "runs": self.runs,
            "failed": self.failed,
            "skipped": self.skipped,
        }


def _estimate(
    left_out: Experiment,
    idata,
    robot: RobotProfile,
    folder: Path,
    filters: Sequence[str],
    posterior: Path,
) -> tuple[dict, dict[str, dict[str, StateEstimate]]]:
    """Export the prior, run the filters on ``left_out``, write its files: (record, estimates)."""
    name = left_out.name
    prior = export_prior(idata, order=None, source=str(posterior))
    files = {
        "posterior": str(posterior),
        "prior": str(write_prior(prior, folder / f"{name}.prior.json")),
    }
    estimates, refused = estimate_each(left_out, prior, filters=filters, robot=robot)
    columns = {name: estimate_columns(left_out, estimates)}
    files["estimates"] = str(write_estimates(folder / f"{name}.csv", columns))
    record = {
        "trained_on": prior["experiments"],
        "order": prior["generalised_coordinates"]["order"],
        "converged": prior["converged"],
        "scores": score_estimates(left_out, estimates),
        "filters_failed": refused,
        "files": files,
    }
    return record, estimates


def _write_summary(result: LeaveOneOut, order: list[str], out: Path) -> None:
    """``out/state_estimation.json``, the runs in the analysis' order."""
    result.runs = {run: result.runs[run] for run in order if run in result.runs}
    result.estimates = {run: result.estimates[run] for run in order if run in result.estimates}
    write_json(out / SUMMARY, result.to_dict())


def leave_one_out(
    experiments: Sequence[Experiment],
    robot: RobotProfile,
    family: str,
    out: str | Path,
    *,
    settings: SamplerSettings | None = None,
    seed: int | None = None,
    prior_overrides: Mapping | None = None,
    likelihood_options: Mapping | None = None,
    executor: Executor | None = None,
    filters: Sequence[str] = FILTERS,
    say: Callable[[str], None] = lambda text: None,
) -> LeaveOneOut:
    """Each run's filters, driven by the prior of ``family`` fitted to the other runs.

    See the module text for the cost and the files written under ``out``.

    Parameters
    ----------
    experiments : sequence of Experiment
        The runs, with distinct names; fewer than two: nothing is run.
    robot : RobotProfile
    family : str
        The noise family of every posterior (a name of
        :data:`bayes_jackal.kernels.FAMILIES`).
    out : str or Path
        The analysis folder.
    settings, seed, prior_overrides, likelihood_options, executor
        As in :func:`bayes_jackal.comparison.compare_groups`: the analysis'
        own, so that each posterior is the analysis' on fewer runs.
    filters : sequence of str
        Names from :data:`bayes_jackal.state_estimation.FILTERS`.
    say : callable
        Receives a line per run done or failed (and which posteriors are reused).

    Returns
    -------
    LeaveOneOut

    Examples
    --------
    Two short runs (8 s), white noise on the yaw channel, chains capped at
    100 steps to keep the example quick (far from converged, as each run's
    ``converged`` says):

    >>> import tempfile
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.leave_one_out import leave_one_out
    >>> from bayes_jackal.simulate import Series
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=seed, name=name)
    ...     for seed, name in [(1, "a"), (2, "b")]
    ... ]
    >>> settings = bj.SamplerSettings(max_steps=100, design_points=64)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     result = leave_one_out(
    ...         runs, robot, "white", folder, settings=settings, seed=1,
    ...         likelihood_options={"channels": ["yaw"]},
    ...     )
    >>> {run: record["trained_on"] for run, record in result.runs.items()}
    {'a': ['b'], 'b': ['a']}
    >>> scores = result.runs["a"]["scores"]
    >>> band = scores["kalman-coloured"]["nis"]["yaw"]["band"]  # with the parameters' spread
    >>> [round(x, 3) for x in band], result.runs["a"]["converged"]
    ([0.804, 1.24], False)
    """
    result = LeaveOneOut(family)
    if len(experiments) < 2:
        result.skipped = f"needs two or more runs; {len(experiments)} analysed"
        return result
    folder = Path(out) / FOLDER
    order = [e.name for e in experiments]
    say(
        f"state estimation with the {family} prior, each of the {len(order)} runs left out "
        f"in turn ({len(order)} more posteriors):"
    )
    by_name = dict(zip(order, experiments, strict=True))
    posteriors = {name: folder / "posteriors" / f"{name}.nc" for name in order}

    def failed(name: str, exc: Exception) -> None:
        result.failed[name] = describe(exc, f"leaving out {name}")
        say(f"  leaving out {name} failed: {result.failed[name]}")

    def save(name: str, _family: str, _evidence, idata) -> None:
        save_posterior(idata, posteriors[name])

    def done(name: str, comparison) -> None:
        record, estimates = _estimate(by_name[name], comparison.posteriors[family], robot,
                                      folder, filters, posteriors[name])  # fmt: skip
        result.runs[name] = record | {"warnings": comparison.convergence_messages()}
        refused = "".join(
            f"; {filter_name} could not run: {reason}"
            for filter_name, reason in record["filters_failed"].items()
        )
        say(f"  leaving out {name}: wrote {record['files']['estimates']}{refused}")
        result.estimates[name] = (by_name[name], estimates)

    with keep_warnings() as kept:  # the chains' convergence goes into each run's record
        try:
            for name, comparison in compare_groups(
                {name: [e for e in experiments if e.name != name] for name in order},
                robot,
                families=(family,),
                settings=settings,
                seed=seed,
                prior_overrides=None if prior_overrides is None else dict(prior_overrides),
                likelihood_options=likelihood_options,
                executor=executor,
                reuse={name: {family: path} for name, path in posteriors.items()},
                on_family=save,
                on_failure=failed,
                say=say,
            ):
                try:
                    done(name, comparison)
                except Exception as exc:  # one run's prior or filters: the others go on
                    failed(name, exc)
                _write_summary(result, order, Path(out))
            _write_summary(result, order, Path(out))  # also when every run failed
        finally:
            kept.issue()
    return result
