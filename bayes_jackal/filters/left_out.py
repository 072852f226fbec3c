"""State estimation with the analysis' prior on runs it has not seen: leave one out.

Does the identified noise model help estimation? A prior scored on the
runs it was fitted to would flatter it. With N >= 2 runs,
:func:`leave_one_out` takes, for each run i, the posterior of one noise
family (the analysis' best) given the N - 1 other runs, exports its Active
Inference prior (:func:`bayes_jackal.dem.export_prior`, at the highest
order the family allows up to :data:`~bayes_jackal.dem.export.AUTO_ORDER`, as
the analysis' ``prior.json``), and runs every filter of
:mod:`bayes_jackal.filters.state_estimation` on run i, scoring each
(:func:`~bayes_jackal.filters.score_estimates`).

The posterior without run i, without a new chain
------------------------------------------------

Given the analysis' pooled posterior of the family on all N runs
(``pooled``), the posterior without run i is that posterior's draws
reweighted by Pareto-smoothed importance sampling (PSIS,
:mod:`bayes_jackal.posterior.reweighting`): each pooled draw theta_s is weighted by
1 / p(y_i | theta_s), the inverse of run i's own likelihood with the
analysis' likelihood options, and the largest weights are smoothed by a
generalised Pareto fit whose shape k-hat says whether they can be trusted:

- k-hat <= :data:`~bayes_jackal.posterior.PARETO_K_THRESHOLD` (0.7,
  arviz's): the posterior without run i is the pooled draws resampled,
  with replacement and as many as there are, with the smoothed weights (by
  a generator seeded from ``seed`` and the run's position). It is a
  posterior file of the usual layout, that of the N - 1 other runs, whose
  ``reweighting`` attribute
  (:func:`~bayes_jackal.posterior.store_reweighting`) names the posterior
  reweighted, k-hat, the weights' effective sample size and the draws; the
  convergence of its chain is the pooled chain's.
- k-hat > 0.7: run i moves the posterior further than the pooled draws
  reach (typical of few runs: of two, each is half the data), and a few
  draws would carry the weights. That run's posterior is then sampled
  again on the other runs, first without a chain: importance sampling from
  its Laplace fit at their MAP, the search started from the pooled draws
  best without the run (:func:`bayes_jackal.inference.importance_posterior`;
  ``method`` ``importance``), used where the same PSIS test holds for
  those weights (k-hat <= 0.7) and they are worth the sampler's
  ``min_ess`` draws; else refit by a chain
  (:func:`bayes_jackal.inference.compare_groups`). Its message (the
  ``bayes_jackal.filters`` logger), its record (``method``, ``pareto_k``,
  ``refit_reason``) and the report say which and why.

Without ``pooled`` every run is refit. With noise per run the left-out
run's own noise parameters, which the other runs do not inform, are
integrated over their prior, not reweighted (:mod:`bayes_jackal.posterior.reweighting`
says how); as an Active Inference prior needs one noise setting per
channel, the prior exports, and the filters run, only where one other run
is left (of two).

Cost. A reweighting evaluates one run's likelihood once at each pooled
draw (a few thousand: 0.7-1.4 s for 5,000 draws of a 38 s run's three
channels); importance sampling a warm MAP search and as many evaluations
of the other runs' likelihood (the demo's v1_01: 2-3 s, where its refit
chain took 7-9 s); a refit is one more posterior on N - 1 runs, with the
analysis' sampler settings, seed, priors and likelihood options, run at
once with the other refits on the analysis' executor (its bridge-sampling
evidence adds a few per cent). The exported prior and the filters take
about a second per run. ``analyse --no-state-estimation`` skips it all.

Files, under the analysis folder ``out``:

- ``state_estimation/posteriors/<run>.nc``: the posterior without
  ``<run>``, reweighted or refit, saved as it is made and reused by a
  rerun with the same task (a reweighting: the pooled posterior's task,
  the run and ``seed``; a refit: its chain's, as ``compare`` reuses);
- ``state_estimation/<run>.prior.json``: its prior (``experiments`` names
  the runs it was fitted to);
- ``state_estimation/<run>.csv``: the filters' estimates on ``<run>``
  (:func:`~bayes_jackal.filters.write_estimates`);
- ``state_estimation.json``: :meth:`LeaveOneOut.to_dict`, rewritten as each
  run is done, so an interruption keeps the runs finished.

A filter that cannot run on a prior (the generalised filter needs a
sensor-noise sd) is named with its reason and the others are scored; a run
whose posterior or prior fails, or where no filter runs, is named in
``failed`` with its reason, and the other runs go on.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._runtime import DataError, az, describe, write_json
from ..dem import export_prior, write_prior
from ..inference import (
    Executor,
    FitOptions,
    compare_groups,
    importance_posterior,
    keep_warnings,
)
from ..io import Experiment
from ..likelihood import Prior
from ..model import RobotProfile
from ..posterior import (
    PARETO_K_THRESHOLD,
    PooledPosterior,
    Posterior,
    RunWeights,
    load_posterior,
    save_posterior,
    store_reweighting,
)
from .kalman_filters import StateEstimate
from .state_estimation import (
    FILTERS,
    estimate_columns,
    estimate_each,
    score_estimates,
    write_estimates,
)

__all__ = ["FOLDER", "METHODS", "SUMMARY", "LeaveOneOut", "leave_one_out", "method_text"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)

#: The folder of the left-out runs' files, in the analysis folder.
FOLDER = "state_estimation"
#: The scores of every left-out run, in the analysis folder.
SUMMARY = "state_estimation.json"
#: How the posterior without each run was made: reweighted, or sampled again.
METHODS = ("psis", "importance", "refit")
#: What an importance-sampled posterior's task adds to its reweighting's.
_IMPORTANCE_TASK = {"method": "importance", "proposal": "laplace-t"}
#: A run record's fields of how its posterior was made, besides ``refit_reason``.
_RECORD_FIELDS = ("method", "pareto_k", "weights_ess", "draws", "relative_efficiency")


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
        ``converged``, ``warnings`` (its chain's convergence messages: the
        pooled chain's for a reweighting), ``scores``
        (:func:`~bayes_jackal.filters.score_estimates`) of the
        filters that ran, ``filters_failed`` (the reason for each filter
        that could not run on this prior), ``files``, and how its posterior
        was made: ``method`` (``"psis"``, ``"importance"`` or ``"refit"``),
        ``pareto_k`` (the PSIS shape k-hat of the pooled draws' weights, or
        for ``importance`` of the Laplace fit's; None when not estimated),
        ``weights_ess`` (the smoothed weights' effective sample size
        1 / sum(w^2), counting the draws as independent), ``draws`` (the
        draws weighted), ``relative_efficiency`` (their ESS per draw before
        weighting: the pooled chain's, 1 for independent draws) and
        ``refit_reason`` (why the pooled reweighting was not used; None for one).
    failed : dict of str to str
        The reason for each run whose posterior, prior or filters failed.
    skipped : str or None
        Why nothing was run (fewer than two runs, or turned off).
    pooled : str or None
        Where the pooled posterior that was reweighted came from (None: every
        run refit).
    estimates : dict of str to (Experiment, estimates)
        Per run done, in the analysis' order, the run and its filters'
        estimates (``[filter][channel]``), for the report's figures.

    Examples
    --------
    >>> from bayes_jackal.filters import LeaveOneOut
    >>> LeaveOneOut("white", skipped="needs two or more runs").to_dict()  # doctest: +ELLIPSIS
    {'family': 'white', 'pooled': None, 'pareto_k_threshold': 0.7, 'runs': {}, 'failed': {}, ...}
    """

    family: str
    runs: dict[str, dict] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    skipped: str | None = None
    pooled: str | None = None
    estimates: dict[str, tuple[Experiment, dict[str, dict[str, StateEstimate]]]] = field(
        default_factory=dict
    )

    def to_dict(self) -> dict:
        """The result, JSON-ready, without ``estimates``.

        Keys ``family``, ``pooled``, ``pareto_k_threshold``, ``runs``,
        ``failed`` and ``skipped``.
        """
        return {
            "family": self.family,
            "pooled": self.pooled,
            "pareto_k_threshold": PARETO_K_THRESHOLD,
            "runs": self.runs,
            "failed": self.failed,
            "skipped": self.skipped,
        }


def _reweighting(path: Path) -> tuple[az.InferenceData, dict] | None:
    """The posterior saved in ``path`` and its ``reweighting`` record, if it is a reweighting."""
    if not path.exists():
        return None
    try:
        idata = load_posterior(path)
        record = Posterior.of(idata).metadata.reweighting
    except DataError:
        return None
    return None if record is None else (idata, record)


def method_text(record: Mapping) -> str:
    """How a left-out run's posterior was made, in words (say, the CLI, the report).

    Parameters
    ----------
    record : mapping
        A run's record of :attr:`LeaveOneOut.runs` (``method``,
        ``pareto_k``, ``weights_ess``, ``draws``, ``refit_reason``).

    Returns
    -------
    str

    Examples
    --------
    >>> from bayes_jackal.filters import method_text
    >>> psis = {"method": "psis", "pareto_k": 0.412, "weights_ess": 812.4, "draws": 3200}
    >>> print(method_text(psis))
    PSIS reweighting of the pooled posterior (Pareto k-hat 0.412 <= 0.7, weights ESS 812
    of 3200 draws)
    >>> reason = "Pareto k-hat 1.287 > 0.7"
    >>> drawn = psis | {"method": "importance", "pareto_k": 0.353, "refit_reason": reason}
    >>> print(method_text(drawn))
    importance sampling from its Laplace fit on the other runs (Pareto k-hat 0.353 <= 0.7,
    weights ESS 812 of 3200 draws), without a chain; the pooled posterior's reweighting:
    Pareto k-hat 1.287 > 0.7
    >>> print(method_text({"method": "refit", "refit_reason": "no pooled posterior was given"}))
    refit: no pooled posterior was given
    """
    if record["method"] == "refit":
        return f"refit: {record['refit_reason']}"
    weights = (
        f"(Pareto k-hat {record['pareto_k']:.3f} <= {PARETO_K_THRESHOLD}, weights ESS "
        f"{record['weights_ess']:.0f} of {record['draws']} draws)"
    )
    if record["method"] == "psis":
        return f"PSIS reweighting of the pooled posterior {weights}"
    return (
        f"importance sampling from its Laplace fit on the other runs {weights}, without a "
        f"chain; the pooled posterior's reweighting: {record['refit_reason']}"
    )


def _importance(
    others: list[Experiment],
    family: str,
    fit: FitOptions,
    draws: PooledPosterior,
    weights: RunWeights,
    warm: np.ndarray,
    rng: np.random.Generator,
) -> tuple[az.InferenceData | None, dict]:
    """The posterior on ``others`` by importance sampling from its Laplace fit, and its record.

    :func:`~bayes_jackal.inference.importance_posterior`, as many draws as
    the pooled posterior has, its MAP search started from ``warm``; where its
    weights cannot be trusted, None and the record of a refit, saying why.
    """
    likelihood = fit.likelihood_options.likelihood(others, fit.robot, family)
    prior = Prior.for_likelihood(likelihood, fit.robot, fit.prior_overrides)
    sample = importance_posterior(
        likelihood, prior, shape=draws.shape, settings=fit.settings, rng=rng, starts=warm
    )
    if sample.idata is None:
        return None, weights.fields("refit") | {
            "refit_reason": f"{weights.reason}; {sample.reason}"
        }
    return sample.idata, {
        "method": "importance",
        "pareto_k": sample.pareto_k,
        "weights_ess": sample.ess,
        "draws": sample.draws,
        "relative_efficiency": 1.0,
        "refit_reason": weights.reason,
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
        "trained_on": prior.experiments,
        "order": prior.order,
        "converged": prior.converged,
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
    family: str,
    out: str | Path,
    options: FitOptions | None = None,
    *,
    pooled: az.InferenceData | None = None,
    pooled_source: str | None = None,
    executor: Executor | None = None,
    filters: Sequence[str] = FILTERS,
    importance: bool = True,
) -> LeaveOneOut:
    """Each run's filters, driven by the prior of ``family`` given the other runs.

    See the module text for how each posterior without a run is made (PSIS
    reweighting of ``pooled``, or a refit where its Pareto k-hat exceeds
    :data:`PARETO_K_THRESHOLD`), the cost and the files written under ``out``.

    Parameters
    ----------
    experiments : sequence of Experiment
        The runs, with distinct names; fewer than two: nothing is run.
    family : str
        The noise family of every posterior (a name of
        :data:`bayes_jackal.model.FAMILIES`).
    out : str or Path
        The analysis folder.
    options : FitOptions, optional
        The analysis' robot, likelihood options, priors, sampler settings
        and seed (:class:`bayes_jackal.inference.FitOptions`), so that each
        refit is the analysis' posterior on fewer runs. The seed also seeds
        each reweighting's resampling (with the run's position); None:
        fresh entropy.
    pooled : arviz.InferenceData, optional
        The posterior of ``family`` on all of ``experiments`` (in their
        order), sampled with these likelihood options and priors: each
        run's posterior without it is this one reweighted. None: every run
        is refit.
    pooled_source : str, optional
        Where ``pooled`` was read from or saved (named in each reweighted
        posterior and in the result; default ``<memory>``).
    executor : Executor, optional
        Where the refits run, as in :func:`bayes_jackal.inference.compare_groups`.
    filters : sequence of str
        Names from :data:`bayes_jackal.FILTERS`.
    importance : bool
        Where the pooled reweighting is unreliable, try importance sampling
        from the Laplace fit on the other runs before a refit (True; False:
        refit by a chain at once).

    Returns
    -------
    LeaveOneOut

    Raises
    ------
    InputError
        When ``pooled`` is not the posterior of ``family`` on exactly these
        runs (names and data) with these likelihood options and priors.

    Examples
    --------
    Two short runs (8 s), white noise on the yaw channel, chains capped at
    100 steps to keep the example quick (far from converged, as each run's
    ``converged`` says). Without a pooled posterior each run is refit; with
    two runs each is half the data, and the pooled posterior's PSIS
    reweighting would be refit too (its Pareto k-hat is above 0.7). The
    NIS band of the coloured Kalman filter includes the parameters' spread.
    The call writes files and runs chains, so the doctests skip it
    (tests/test_leave_one_out.py runs it):

    >>> import tempfile
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import leave_one_out
    >>> from bayes_jackal.inference import FitOptions
    >>> from bayes_jackal.likelihood import LikelihoodOptions
    >>> from bayes_jackal.io import Series
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, 30.0, Series(0.3, 0.39, 8.0), rng=seed, name=name)
    ...     for seed, name in [(1, "a"), (2, "b")]
    ... ]
    >>> options = FitOptions(
    ...     robot=robot, likelihood_options=LikelihoodOptions(channels=["yaw"]),
    ...     settings=bj.SamplerSettings(max_steps=100, design_points=64), seed=1,
    ... )
    >>> with tempfile.TemporaryDirectory() as folder:  # doctest: +SKIP
    ...     result = leave_one_out(runs, "white", folder, options)
    >>> {run: (record["trained_on"], record["method"])  # doctest: +SKIP
    ...  for run, record in result.runs.items()}
    {'a': (['b'], 'refit'), 'b': (['a'], 'refit')}
    >>> scores = result.runs["a"]["scores"]  # doctest: +SKIP
    >>> band = scores["kalman-coloured"]["nis"]["yaw"]["band"]  # doctest: +SKIP
    >>> [round(x, 3) for x in band], result.runs["a"]["converged"]  # doctest: +SKIP
    ([0.796, 1.252], False)
    """
    fit = FitOptions.of(options)
    source = None if pooled is None else pooled_source or "<memory>"
    result = LeaveOneOut(family, pooled=source)
    if len(experiments) < 2:
        result.skipped = f"needs two or more runs; {len(experiments)} analysed"
        return result
    folder = Path(out) / FOLDER
    order = [e.name for e in experiments]
    by_name = dict(zip(order, experiments, strict=True))
    posteriors = {name: folder / "posteriors" / f"{name}.nc" for name in order}
    draws = None
    if pooled is not None:  # checked before anything is written
        draws = PooledPosterior(pooled, experiments, fit.robot, family, fit.likelihood_options,
                                fit.prior_overrides, source)  # fmt: skip
        _log.info(
            f"state estimation with the {family} prior, each of the {len(order)} runs left out "
            f"in turn: the pooled posterior's {draws.count} draws reweighted by PSIS; where "
            f"its Pareto k-hat > {PARETO_K_THRESHOLD}, importance sampling from the Laplace fit "
            "on the other runs, or a refit:"
        )
    else:
        _log.info(
            f"state estimation with the {family} prior, each of the {len(order)} runs left out "
            f"in turn ({len(order)} more posteriors):"
        )

    def failed(name: str, exc: Exception) -> None:
        result.failed[name] = describe(exc, f"leaving out {name}")
        _log.info(f"  leaving out {name} failed: {result.failed[name]}")

    def done(name: str, idata, fields: dict, warnings: list[str]) -> None:
        record, estimates = _estimate(by_name[name], idata, fit.robot, folder, filters,
                                      posteriors[name])  # fmt: skip
        result.runs[name] = record | {"warnings": warnings} | fields
        refused = "".join(
            f"; {filter_name} could not run: {reason}"
            for filter_name, reason in record["filters_failed"].items()
        )
        _log.info(
            f"  leaving out {name}: {method_text(result.runs[name])}; prior from "
            f"{', '.join(record['trained_on'])}; wrote {record['files']['estimates']}{refused}"
        )
        result.estimates[name] = (by_name[name], estimates)

    refits: dict[str, dict] = {}  # run -> its record's fields, with the reason
    starts: dict[str, dict[str, np.ndarray]] = {}  # run -> family -> the refit's warm start

    def reweigh(name: str, sequence: np.random.SeedSequence) -> None:
        path = posteriors[name]
        task = draws.task(name, fit.seed)
        saved = _reweighting(path)
        tasks = {"psis": task}
        if importance and task is not None:  # a refit at once does not reuse one
            tasks["importance"] = task | _IMPORTANCE_TASK
        if task is not None and saved is not None and saved[1].get("task") in tasks.values():
            idata, stored = saved
            kind = "PSIS reweighting" if stored["method"] == "psis" else "importance sample"
            _log.info(f"  leaving out {name}: reusing the {kind} in {path}")
        else:
            weights = draws.weights(by_name[name])
            rng = np.random.default_rng(sequence)
            record = {"of": source, "experiments": order, "left_out": name}
            if weights.weights is None:
                others = [e for e in experiments if e.name != name]
                warm = draws.best_draws_without(weights, others)
                idata, stored = None, weights.fields("refit")
                if importance:
                    idata, stored = _importance(others, family, fit, draws, weights, warm, rng)
                if idata is None:
                    refits[name] = stored
                    starts[name] = {family: warm}
                    _log.info(
                        f"  leaving out {name}: {stored['refit_reason']}; refitting it on the "
                        "other runs, its MAP search started from the pooled draws best without it"
                    )
                    return
                stored |= record | {"task": tasks["importance"]}
                store_reweighting(idata, stored)
            else:
                stored = weights.fields("psis") | {"refit_reason": None} | record
                stored["task"] = task
                idata = draws.posterior_without(name, weights, rng, stored)
            save_posterior(idata, path)
        fields = {key: stored.get(key) for key in (*_RECORD_FIELDS, "refit_reason")}
        messages = draws.metadata.convergence_messages if fields["method"] == "psis" else ()
        done(name, idata, fields, list(messages))

    def refit() -> None:
        reuse = {}
        for name in refits:
            if _reweighting(posteriors[name]) is None:
                reuse[name] = {family: posteriors[name]}
            else:  # made from another pooled posterior, whose k-hat was lower
                _log.info(
                    f"  leaving out {name}: replacing the PSIS reweighting in {posteriors[name]}"
                )

        def save(name: str, _family: str, _evidence, idata) -> None:
            save_posterior(idata, posteriors[name])

        for name, comparison in compare_groups(
            {name: [e for e in experiments if e.name != name] for name in refits},
            fit,
            families=(family,),
            executor=executor,
            reuse=reuse,
            on_family=save,
            on_failure=failed,
            starts=starts,
        ):
            try:
                done(name, comparison.posteriors[family], refits[name],
                     comparison.convergence_messages())  # fmt: skip
            except Exception as exc:  # one run's prior or filters: the others go on
                failed(name, exc)
            _write_summary(result, order, Path(out))

    with keep_warnings() as kept:  # the chains' convergence goes into each run's record
        try:
            if draws is None:
                reason = "no pooled posterior was given to reweight"
                refits.update({name: dict.fromkeys(_RECORD_FIELDS) | {"method": "refit",
                               "refit_reason": reason} for name in order})  # fmt: skip
            else:
                sequences = np.random.SeedSequence(fit.seed).spawn(len(order))
                for name, sequence in zip(order, sequences, strict=True):
                    try:
                        reweigh(name, sequence)
                    except Exception as exc:  # one run's weights, prior or filters
                        failed(name, exc)
                    _write_summary(result, order, Path(out))
            if refits:
                refit()
            _write_summary(result, order, Path(out))  # also when every run failed
        finally:
            kept.issue()
    return result
