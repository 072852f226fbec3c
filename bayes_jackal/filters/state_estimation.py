"""State estimation with an exported prior: every filter on an experiment, scored.

A reviewer's question, "does the identified noise model help estimation?",
is answered by running the filters the prior drives on runs it has not
seen and scoring them the same way:

- ``kalman``: the Kalman filter that assumes white process noise of the
  same per-step variance (:func:`bayes_jackal.filters.kalman_filter`), the
  baseline;
- ``kalman-coloured``: the Kalman filter with the family's shaping filter in
  its state, the exact conditional mean under the identified model;
- ``generalised``: the DEM D-step in generalised coordinates
  (:func:`bayes_jackal.filters.generalised_filter`).

Each filter predicts every measurement from the samples before it; the
prediction error nu_k and its variance S_k give

- the innovation RMSE, sqrt(mean nu_k^2) [channel units];
- the normalised innovation squared, NIS = mean(nu_k^2 / S_k), which is
  1 on average when the filter's account of its uncertainty is right. For
  a Kalman filter under its own model the innovations are independent, so
  n NIS is chi-square(n) and lies in the band [chi2(0.025, n),
  chi2(0.975, n)] / n with probability 0.95 (Bar-Shalom, Li & Kirubarajan
  2001, sec. 5.4) when the parameters are known; identified ones move it
  too, so the Kalman filters' band is widened by the spread of NIS over
  the prior's draws (:func:`nis_band`). The generalised filter's
  predictions come from overlapping windows and its variance from the
  Laplace approximation, so
  its innovations are correlated and the band is a yardstick there, not a
  test; with a look-ahead its estimate at t_(k-1) has seen y_k, so it
  predicts nothing and has no innovation scores (None);
- the state RMSE against the truth, per channel where the experiment
  carries a simulated one (``truth_arrays["<channel>_state"]``; else None),
  and for the Kalman filters that of their Rauch-Tung-Striebel smoother
  (``smoothed_state_rmse``), which uses the whole run. Where vx, vy were
  recorded as motion-capture poses, the reader's Savitzky-Golay velocities
  (a smoother centred on each sample, :data:`DERIVED`) are scored beside
  them as the baseline a pose model has to beat: the smoothers are the
  fair comparison, since a causal filter cannot see the samples after t_k
  that the centred derivative uses.

The scores start at the first sample every filter predicts from its own
steady form: sample p + 1 when the generalised filter of order p runs (its
first p estimates use an embedding window moved inside the run; p + 2 where
it embeds a pose channel's travel, one order more), else sample 1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.stats

from .._runtime import FILTERS, LOOKAHEAD, SENSOR_PRECISIONS, InputError, atomic_path
from ..dem import ActiveInferencePrior
from ..io import CHANNEL_FIELDS, Experiment
from ..model import RobotProfile
from .generalised import generalised_filter
from .kalman_filters import KALMAN_FILTERS, StateEstimate, kalman_filter
from .state_space import check_prior

__all__ = [
    "DERIVED",
    "FILTER_INEXACT",
    "NIS_DRAWS",
    "NIS_PROBABILITY",
    "estimate_columns",
    "estimate_each",
    "estimate_states",
    "inexact_note",
    "nis_band",
    "score_estimates",
    "score_rows",
    "write_estimates",
]

#: Probability of the NIS band (two-sided).
NIS_PROBABILITY = 0.95
#: The prior's draws (evenly spaced among them) each Kalman filter is run
#: with again for its NIS band's parameter term (:func:`estimate_states`):
#: the term's sd is then known to ~13 % (1 / sqrt(2 (D - 1))).
NIS_DRAWS = 32
#: The scores' name of the velocities a reader derived from motion-capture
#: poses (module docstring).
DERIVED = "derived"


def _check_filters(filters: Sequence[str]) -> tuple[str, ...]:
    if isinstance(filters, str):
        raise InputError(
            f"filters must be a sequence of names, got the string {filters!r}", field="filters"
        )
    filters = tuple(dict.fromkeys(filters))
    unknown = [name for name in filters if name not in FILTERS]
    if unknown:
        raise InputError(f"unknown filter {unknown[0]!r}; use some of {FILTERS}", field="filters")
    if not filters:
        raise InputError(f"no filter given; use some of {FILTERS}", field="filters")
    return filters


def estimate_states(
    experiment: Experiment,
    prior: ActiveInferencePrior | Mapping,
    *,
    filters: Sequence[str] = FILTERS,
    channels: Sequence[str] | None = None,
    parameters: str = "plug-in",
    order: int | None = None,
    sensor_precision: str = SENSOR_PRECISIONS[0],
    lookahead: int = LOOKAHEAD,
    robot: RobotProfile | None = None,
) -> dict[str, dict[str, StateEstimate]]:
    """Run each filter of ``filters`` on an experiment with an exported prior.

    Parameters
    ----------
    experiment : Experiment
        A run at the prior's sample time, measuring the channels.
    prior : ActiveInferencePrior or mapping
        An exported prior (:func:`bayes_jackal.dem.export_prior`,
        :func:`bayes_jackal.dem.read_prior`), or its JSON as a mapping
        (:meth:`bayes_jackal.dem.ActiveInferencePrior.from_json` checks it).
    filters : sequence of str
        Names from :data:`FILTERS`.
    channels : sequence of str, optional
        By default every channel of the prior.
    parameters : {"plug-in", "averaged"}
        Noise parameters at the posterior means, or the filters' covariances
        and precisions averaged over the prior's draws.
    order, sensor_precision, lookahead
        The generalised filter's embedding order (default: the prior's),
        Pi_z and look-ahead (:func:`bayes_jackal.filters.generalised_filter`).
    robot : RobotProfile, optional
        When given, its constants must be the prior's.

    Returns
    -------
    dict of str to dict of str to StateEstimate
        ``[filter][channel]``.

    Raises
    ------
    InputError
        For an unknown filter, or a prior that does not fit the experiment
        (:func:`bayes_jackal.filters.check_prior`).

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=seed) for seed in (1, 2)]
    >>> posterior = bj.sample(runs[:1], family="gaussian", channels=["yaw"], max_steps=20, seed=1)
    >>> estimates = bj.estimate_states(runs[1], bj.export_prior(posterior, order=2))
    >>> {name: list(per_channel) for name, per_channel in estimates.items()}
    {'kalman': ['yaw'], 'kalman-coloured': ['yaw'], 'generalised': ['yaw']}
    """
    filters = _check_filters(filters)
    prior = ActiveInferencePrior.from_json(prior)
    estimates = {}
    for name in filters:
        if name in KALMAN_FILTERS:
            options = {"noise": KALMAN_FILTERS[name], "channels": channels, "robot": robot}
            estimate = kalman_filter(experiment, prior, parameters=parameters, **options)
            spread = _nis_spread([kalman_filter(experiment, at_draw, smooth=False, **options)
                                  for at_draw in _draw_priors(prior)])  # fmt: skip
            estimates[name] = {
                c: replace(e, nis_spread=spread.get(c)) for c, e in estimate.items()
            }
        else:
            estimates[name] = generalised_filter(experiment, prior, channels=channels,
                                                 order=order, parameters=parameters,
                                                 sensor_precision=sensor_precision,
                                                 lookahead=lookahead, robot=robot)  # fmt: skip
    return estimates


def _draw_priors(prior: ActiveInferencePrior) -> list[ActiveInferencePrior]:
    """The prior with its noise parameters' means set to :data:`NIS_DRAWS` of its draws.

    Empty for a prior without draws of every noise parameter. The damping
    stays at its mean, as in the filters' averaged mode.
    """
    parameters = prior.noise["parameters"]
    draws = prior.draws
    if not isinstance(draws, Mapping) or not all(name in draws for name in parameters):
        return []
    count = min(len(draws[name]) for name in parameters)
    picks = np.unique(np.linspace(0, count - 1, min(NIS_DRAWS, count)).astype(int))
    return [
        replace(prior, noise={**prior.noise, "parameters": {
            name: {**stats, "mean": draws[name][i]} for name, stats in parameters.items()}})
        for i in picks
    ]  # fmt: skip


def _nis_spread(runs: Sequence[Mapping[str, StateEstimate]]) -> dict[str, float]:
    """Per channel, the sd of log NIS over a filter's runs at the prior's draws.

    A channel with fewer than two finite NIS (draws that are no parameters)
    has none: its band is then the chi-square one.
    """
    spread = {}
    for channel in runs[0] if runs else ():
        nis = np.array([np.nanmean(run[channel].innovation**2 / run[channel].innovation_variance)
                        for run in runs])  # fmt: skip
        nis = nis[np.isfinite(nis) & (nis > 0)]
        if len(nis) >= 2:
            spread[channel] = float(np.std(np.log(nis), ddof=1))
    return spread


#: Fields of the options a caller gives the filters: a filter that cannot
#: honour one is an error, not a filter the prior cannot drive.
_CALLER_FIELDS = ("order", "lookahead")


def estimate_each(
    experiment: Experiment,
    prior: ActiveInferencePrior | Mapping,
    *,
    filters: Sequence[str] = FILTERS,
    **options,
) -> tuple[dict[str, dict[str, StateEstimate]], dict[str, str]]:
    """:func:`estimate_states` filter by filter: one the prior cannot drive is skipped, named.

    The generalised filter needs a sensor-noise sd, which white noise
    fitted with the diagonal sensor term does not have; the Kalman filters
    run on such a prior. ``prior`` and ``options`` are :func:`estimate_states`'.

    Returns
    -------
    estimates : dict
        As :func:`estimate_states`, for the filters that ran.
    refused : dict of str to str
        Filter -> why the prior cannot drive it.

    Raises
    ------
    InputError
        When no filter can run (every reason named), for a prior that does
        not fit the experiment, or for an option of the caller's that a
        filter cannot honour (an embedding order the prior's noise cannot
        give, a look-ahead beyond the order): those are the caller's to
        change, not the prior's.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import estimate_each
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=seed) for seed in (1, 2)]
    >>> posterior = bj.sample(runs[:1], family="white", channels=["yaw"], sensor="diagonal",
    ...                       max_steps=20, seed=1)
    >>> estimates, refused = estimate_each(runs[1], bj.export_prior(posterior, order=0))
    >>> list(estimates), list(refused)
    (['kalman', 'kalman-coloured'], ['generalised'])
    """
    filters = _check_filters(filters)
    prior = ActiveInferencePrior.from_json(prior)
    # A prior that does not fit the experiment fits no filter: that error stops all.
    check_prior(prior, experiment, options.get("channels"), robot=options.get("robot"))
    estimates, refused = {}, {}
    for name in filters:
        try:
            estimates |= estimate_states(experiment, prior, filters=(name,), **options)
        except InputError as exc:
            if exc.field in _CALLER_FIELDS:
                raise
            refused[name] = str(exc)
    if not estimates:
        reasons = "; ".join(f"{name}: {reason}" for name, reason in refused.items())
        raise InputError(f"no filter can run with this prior: {reasons}", field="filters")
    return estimates, refused


def _first_scored(estimates: Mapping[str, Mapping[str, StateEstimate]]) -> int:
    """The first sample of every generalised filter's steady form, else 1 (module docstring)."""
    starts = [
        e.steady_from
        for per_channel in estimates.values()
        for e in per_channel.values()
        if e.derivatives is not None
    ]
    return max([1, *starts])


def nis_band(samples: int, spread: float | None = None) -> np.ndarray:
    """The :data:`NIS_PROBABILITY` band of a mean NIS over ``samples`` predictions.

    Under the filter's model with known parameters, n NIS is chi-square(n)
    (Bar-Shalom et al. 2001, sec. 5.4). A filter driven by identified
    parameters misses the data's innovation variance by their estimation
    error too: with ``spread``, the sd of log NIS over the prior's draws
    (:attr:`~bayes_jackal.filters.StateEstimate.nis_spread`), each side's
    half-width in log NIS becomes sqrt(h^2 + (z spread)^2), z the band's
    normal quantile (both terms near normal in log NIS; the chi-square band
    for spread 0 or None).

    Examples
    --------
    >>> from bayes_jackal.filters import nis_band
    >>> nis_band(2700).round(3).tolist(), nis_band(2700, 0.02).round(3).tolist()
    ([0.947, 1.054], [0.935, 1.068])
    """
    tail = (1.0 - NIS_PROBABILITY) / 2.0
    band = scipy.stats.chi2.ppf([tail, 1.0 - tail], samples) / samples
    if not spread:
        return band
    z = scipy.stats.norm.isf(tail)
    return np.exp(np.sign(np.log(band)) * np.hypot(np.log(band), z * spread))


def _nis(estimate: StateEstimate, first: int) -> dict | None:
    """Mean NIS from sample ``first``, its band (:func:`nis_band`), whether it lies in it.

    Also the innovations' lag-1 autocorrelation, about 0 (within
    2 / sqrt(n)) for a filter exact under its model. None without predictions.
    """
    innovation = estimate.innovation[first:]
    if not np.isfinite(innovation).any():
        return None
    band = nis_band(len(innovation), estimate.nis_spread)
    mean = float(np.mean(innovation**2 / estimate.innovation_variance[first:]))
    finite = innovation[np.isfinite(innovation)]
    lag1 = float(np.corrcoef(finite[:-1], finite[1:])[0, 1]) if len(finite) > 2 else None
    return {"mean": mean, "band": band.tolist(), "consistent": bool(band[0] <= mean <= band[1]),
            "parameter_spread": estimate.nis_spread, "innovation_lag1": lag1}  # fmt: skip


#: The filter whose NIS tests the prior itself (the exact conditional mean
#: under the identified model), and the one it tells apart from it.
EXACT_FILTER, APPROXIMATE_FILTER = "kalman-coloured", "generalised"
#: The verdict of the approximate filter outside its band where the exact one
#: is inside on the same channel: the prior holds, the filter's variance is off.
FILTER_INEXACT = "filter inexact"


def _blame(scores: dict[str, dict]) -> None:
    """Where the generalised filter's NIS misses its band: the filter's fault or the model's.

    Sets its ``nis[channel]["cause"]``: ``"filter"`` where the exact filter
    under the same prior (``kalman-coloured``) is consistent on that channel
    (the prior holds; the DEM D-step's Laplace variance and finite embedding
    order are what is off), ``"model"`` where that one misses its band too;
    absent where it is consistent or the exact filter did not run.
    """
    exact = scores.get(EXACT_FILTER, {}).get("nis", {})
    for channel, nis in scores.get(APPROXIMATE_FILTER, {}).get("nis", {}).items():
        if nis is None or nis["consistent"] or exact.get(channel) is None:
            continue
        nis["cause"] = "filter" if exact[channel]["consistent"] else "model"


def inexact_note(scores: Mapping[str, Mapping]) -> str | None:
    """What a :data:`FILTER_INEXACT` verdict of one run's scores means, with its numbers.

    None where no channel has that verdict.

    Examples
    --------
    >>> from bayes_jackal.filters.state_estimation import inexact_note
    >>> off = {"mean": 1.15, "band": [0.95, 1.05], "consistent": False, "cause": "filter",
    ...        "innovation_lag1": -0.1}
    >>> note = inexact_note({"generalised": {"nis": {"vx": off}}})
    >>> print(note.split(": ")[0])
    filter inexact (generalised on vx)
    >>> print(note.split("(NIS ")[1])
    1.15; its innovations' lag-1 correlation -0.10, about 0 for an exact filter)
    """
    nis = scores.get(APPROXIMATE_FILTER, {}).get("nis", {})
    off = {c: v for c, v in nis.items() if v is not None and v.get("cause") == "filter"}
    if not off:
        return None
    means = ", ".join(f"{v['mean']:.2f}" for v in off.values())
    lags = ", ".join(f"{v['innovation_lag1']:+.2f}" for v in off.values()
                     if v.get("innovation_lag1") is not None)  # fmt: skip
    return (
        f"{FILTER_INEXACT} ({APPROXIMATE_FILTER} on {', '.join(off)}): the exact filter under "
        f"the same prior ({EXACT_FILTER}) is consistent there, so the prior holds; the DEM "
        "D-step's own approximations (its Laplace variance, the finite embedding order) make "
        f"its stated variance miss its prediction errors (NIS {means}"
        + (f"; its innovations' lag-1 correlation {lags}, about 0 for an exact filter)"
           if lags else ")")
    )  # fmt: skip


def _rmse(error: np.ndarray) -> float | None:
    """Root mean square [units]; None where there is nothing to score (NaN)."""
    return float(np.sqrt(np.mean(np.square(error)))) if np.isfinite(error).any() else None


def score_estimates(
    experiment: Experiment, estimates: Mapping[str, Mapping[str, StateEstimate]]
) -> dict[str, dict]:
    """Innovation RMSE, NIS against its chi-square band, and state RMSE against a truth.

    Parameters
    ----------
    experiment : Experiment
        The run the filters ran on; its ``truth_arrays["<channel>_state"]``,
        where present, are the true states.
    estimates : mapping
        :func:`estimate_states`' result.

    Returns
    -------
    dict
        Per filter: ``innovation_rmse`` and ``nis`` (``mean``, ``band``,
        ``consistent``, ``parameter_spread``, ``innovation_lag1``, and for
        the generalised filter outside its band ``cause``: ``"filter"``
        where ``kalman-coloured`` is consistent on that channel, else
        ``"model"``) per channel (None where the filter predicts nothing),
        ``state_rmse`` and ``smoothed_state_rmse`` per channel (None
        without a truth or a smoother), and ``first_sample``, the first
        sample scored (module docstring); and :data:`DERIVED`, the derived
        velocities of the channels recorded as poses, where the experiment
        has a truth.

    Examples
    --------
    A filter whose innovations are standard normal and whose variance says
    so is consistent:

    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import StateEstimate
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> n = len(run.t)
    >>> nu = np.random.default_rng(2).standard_normal(n)
    >>> made_up = StateEstimate(run.yaw_rate, np.zeros(n), nu, np.ones(n), steady_from=0)
    >>> score = bj.score_estimates(run, {"kalman": {"yaw": made_up}})["kalman"]
    >>> score["nis"]["yaw"]["consistent"], score["state_rmse"]["yaw"] > 0
    (True, True)
    """
    first = _first_scored(estimates)
    truths = {
        c: truth[first:]
        for per_channel in estimates.values()
        for c in per_channel
        if (truth := experiment.truth_arrays.get(f"{c}_state")) is not None
    }

    def error(c: str, values: np.ndarray | None) -> float | None:
        return None if values is None or c not in truths else _rmse(values[first:] - truths[c])

    scores = {}
    for name, per_channel in estimates.items():
        scores[name] = {
            "first_sample": first,
            "innovation_rmse": {c: _rmse(e.innovation[first:]) for c, e in per_channel.items()},
            "nis": {c: _nis(e, first) for c, e in per_channel.items()},
            "state_rmse": {c: error(c, e.mean) for c, e in per_channel.items()},
            "smoothed_state_rmse": {c: error(c, e.smoothed) for c, e in per_channel.items()},
        }
    _blame(scores)
    derived = [c for c in truths if experiment.measurement(c) == "pose"]
    if derived:
        nothing = dict.fromkeys(derived)
        scores[DERIVED] = {
            "first_sample": first,
            "innovation_rmse": nothing,
            "nis": nothing,
            "state_rmse": nothing,
            "smoothed_state_rmse": {c: error(c, experiment.channel(c)) for c in derived},
        }
    return scores


def score_rows(scores: Mapping[str, Mapping]) -> list[tuple]:
    """One experiment's scores as table rows, one per filter and channel.

    Returns
    -------
    list of tuple
        (filter, channel, innovation RMSE, NIS mean, (band low, band high),
        verdict, state RMSE, smoothed state RMSE); None where a score does
        not exist (scores written before the smoother have none), verdict
        ``consistent``, ``INCONSISTENT``, :data:`FILTER_INEXACT` (the
        generalised filter outside its band where the exact filter is
        inside: the prior holds) or ``no prediction``.

    Examples
    --------
    >>> from bayes_jackal.filters import score_rows
    >>> nis = {"mean": 1.3, "band": [0.9, 1.1], "consistent": False}
    >>> scores = {"kalman": {"innovation_rmse": {"yaw": 0.01}, "nis": {"yaw": nis},
    ...                      "state_rmse": {"yaw": None}}}
    >>> score_rows(scores)
    [('kalman', 'yaw', 0.01, 1.3, (0.9, 1.1), 'INCONSISTENT', None, None)]
    """
    rows = []
    for name, score in scores.items():
        for channel, rmse in score["innovation_rmse"].items():
            nis = score["nis"][channel]
            verdict = (
                "no prediction"
                if nis is None
                else "consistent"
                if nis["consistent"]
                else FILTER_INEXACT
                if nis.get("cause") == "filter"
                else "INCONSISTENT"
            )
            rows.append(
                (
                    name,
                    channel,
                    rmse,
                    None if nis is None else nis["mean"],
                    None if nis is None else tuple(nis["band"]),
                    verdict,
                    score["state_rmse"][channel],
                    score.get("smoothed_state_rmse", {}).get(channel),
                )
            )
    return rows


def estimate_columns(
    experiment: Experiment, estimates: Mapping[str, Mapping[str, StateEstimate]]
) -> dict[str, np.ndarray]:
    """The estimates as columns ``t`` and ``FILTER.STATE`` (``kalman.yaw_rate``, ..).

    A Kalman filter's smoother is a filter of its own name plus
    ``-smoothed`` (``kalman-coloured-smoothed.vx``), after the filters.

    Parameters
    ----------
    experiment : Experiment
        The run the filters ran on (its ``t``).
    estimates : mapping
        :func:`estimate_states`' result.

    Returns
    -------
    dict of str to ndarray, shape (N,)
        ``t`` [s], then each filter's estimate of each channel's state
        [m/s, rad/s], named after the experiment's column (:func:`write_estimates`).

    Examples
    --------
    >>> import numpy as np
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.filters import StateEstimate
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> estimate = StateEstimate(*np.zeros((4, len(run.t))), steady_from=0)
    >>> list(bj.filters.estimate_columns(run, {"kalman": {"yaw": estimate, "vx": estimate}}))
    ['t', 'kalman.yaw_rate', 'kalman.vx']
    """
    columns = {"t": experiment.t}
    for name, per_channel in estimates.items():
        for channel, estimate in per_channel.items():
            columns[f"{name}.{CHANNEL_FIELDS[channel]}"] = estimate.mean
    for name, per_channel in estimates.items():
        for channel, estimate in per_channel.items():
            if estimate.smoothed is not None:
                columns[f"{name}-smoothed.{CHANNEL_FIELDS[channel]}"] = estimate.smoothed
    return columns


def write_estimates(path: str | Path, tables: Mapping[str, Mapping[str, np.ndarray]]) -> Path:
    """Write estimate columns (:func:`estimate_columns`) as one CSV, atomically.

    Parameters
    ----------
    path : str or Path
        The CSV.
    tables : mapping of str to columns
        Per experiment name, its columns; with more than one experiment a
        first column ``experiment`` names each row's run, and every table
        must have the same columns.

    Returns
    -------
    Path

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from bayes_jackal.filters import write_estimates
    >>> table = {"t": np.array([0.0, 0.1]), "kalman.vx": np.array([0.5, 0.51])}
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     text = write_estimates(Path(folder) / "estimates.csv", {"run": table}).read_text()
    >>> print(text.strip())
    t,kalman.vx
    0,0.5
    0.1,0.51
    """
    path = Path(path)
    headers = {tuple(columns) for columns in tables.values()}
    if len(headers) != 1:
        raise InputError(
            f"the experiments' estimates have different columns: {sorted(headers)}",
            field="tables",
        )
    header = list(headers.pop())
    several = len(tables) > 1
    with atomic_path(path) as temporary, temporary.open("w") as file:
        file.write(",".join((["experiment"] if several else []) + header) + "\n")
        for name, columns in tables.items():
            prefix = _csv_field(name).replace("%", "%%") + "," if several else ""
            rows = np.column_stack([columns[key] for key in header])
            np.savetxt(file, rows, fmt=prefix + ",".join(["%.10g"] * len(header)))
    return path


def _csv_field(text: str) -> str:
    """``text`` as one CSV field: quoted (RFC 4180) when it holds a comma, quote or newline."""
    if any(mark in text for mark in ',"\n\r'):
        return '"' + text.replace('"', '""') + '"'
    return text
