"""Model criticism: checks of a fitted posterior and of its data.

A converged posterior can still be wrong. Each check takes an arviz
InferenceData as written by :mod:`bayes_jackal.posterior` and returns a
:class:`Check`: JSON-ready numbers and warnings, dicts with ``kind``,
``message`` and the fields that locate them. Kinds: ``prior-boundary``
(:func:`prior_boundary`), ``residual-input`` (:func:`residual_input`, MATLAB
``resid``'s independence test), ``predictive-acf`` (:func:`predictive_acf`),
``not-steady`` (:func:`steady_windows`) and ``damping-scale-not-identified``
(:func:`damping_scale`). :func:`criticise` runs them all;
:func:`bayes_jackal.posterior.summarize` reports it under ``warnings`` and
``criticism``. The array-level statistics behind the checks are in
:mod:`bayes_jackal.criticism_statistics`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.stats

from .criticism_statistics import (
    acf_statistics,
    boundary_density,
    cross_correlation,
    cross_correlation_sd,
    predictive_flags,
    predictive_p_values,
    simultaneous_threshold,
    steadiness,
)
from .experiment import STEADY_INPUT_TOLERANCE, STEADY_YAW_TOLERANCE, Experiment
from .kernels import as_rng
from .posterior import (
    HDI_PROB,
    PosteriorMetadata,
    az,
    model_autocovariance,
    observed_residuals,
    parameter_draws,
    posterior_experiments,
    posterior_metadata,
    store_criticism,
    thinned_draws,
)
from .predictive import predictive_series
from .residuals import channel_residuals

__all__ = [
    "BOUNDARY_DENSITY",
    "BOUNDARY_STRIP",
    "INPUTS",
    "PORTMANTEAU_LAGS",
    "PREDICTIVE_ALARM",
    "PREDICTIVE_DRAWS",
    "PREDICTIVE_LAGS",
    "PREDICTIVE_WINDOW",
    "RESIDUAL_INPUT_LAGS",
    "RESIDUAL_INPUT_LEVEL",
    "Check",
    "criticise",
    "damping_scale",
    "predictive_acf",
    "prior_boundary",
    "residual_input",
    "steady_windows",
]

#: Width of the strip next to a prior bound, as a fraction of the 94 % HDI's
#: width (both in the prior's coordinate: log for log-uniform priors).
BOUNDARY_STRIP = 0.1
#: A posterior is piled against a bound when its draws' density in that strip
#: is at least this fraction of their mean density over the HDI. For a normal
#: posterior that is a bound within 1.5 sd of the mode (it cuts off >= 6 %).
BOUNDARY_DENSITY = 0.5
#: Lags -L..L of the residual-input cross-correlation (MATLAB ``resid``: 25).
RESIDUAL_INPUT_LAGS = 25
#: Level of the per-lag band, and family-wise level of the warning.
RESIDUAL_INPUT_LEVEL = 0.99
#: Inputs the residuals are correlated with: wheel-speed sum (forward drive,
#: rad/s) and difference (turning), the two directions of B.
INPUTS = ("sum", "difference")
#: Lags of the posterior-predictive autocorrelation statistics, and the
#: largest lag of the Ljung-Box portmanteau statistic (the report's figure).
PREDICTIVE_LAGS = (1, 2, 5, 10)
PORTMANTEAU_LAGS = 30
#: Posterior draws (one replicated series each) behind every p-value, as
#: many as the report's predictive bands: p resolves steps of 0.005.
PREDICTIVE_DRAWS = 200
#: Longest stretch of residuals the predictive check replicates: longer runs
#: are checked on their central 16,384 residuals (3.8 min at 72 Hz), where
#: an autocorrelation has a standard error of 1/128 = 0.008, so the check's
#: cost does not grow with the run (200 replicated hours per channel would
#: take minutes).
PREDICTIVE_WINDOW = 16_384
#: Family-wise false-alarm level of the p-values of one experiment and
#: channel (:func:`criticism_statistics.predictive_flags`: Bonferroni over
#: both tails of the 5 statistics, 0.5 % per tail). With 200 draws a tail
#: is flagged only when the observed statistic lies beyond all 200
#: replicated ones, which an exact p-value does with probability 1/201.
PREDICTIVE_ALARM = 0.05


@dataclass
class Check:
    """The result of one check: JSON-ready numbers and warnings.

    Attributes
    ----------
    numbers : dict
    warnings : list of dict
        Each with ``kind`` and ``message`` and the fields that locate it.
    """

    numbers: dict = field(default_factory=dict)
    warnings: list[dict] = field(default_factory=list)


# --- prior boundary -----------------------------------------------------------------


def prior_boundary(idata: az.InferenceData) -> Check:
    """Warnings for parameters whose posterior is piled against a prior bound.

    Rule: :func:`boundary_density` at a bound is at least
    :data:`BOUNDARY_DENSITY`. Numbers: the two density ratios per parameter.
    """
    metadata = posterior_metadata(idata)
    prior, layout = metadata.prior, metadata.layout
    draws, _ = parameter_draws(idata)
    check = Check()
    for j, name in enumerate(layout.names):
        bounds = {"low": float(prior.low[j]), "high": float(prior.high[j])}
        ratios = boundary_density(
            draws[..., j],
            bounds["low"],
            bounds["high"],
            log=bool(prior.log_uniform[j]),
            prob=HDI_PROB,
            strip=BOUNDARY_STRIP,
        )
        check.numbers[name] = {"low": ratios[0], "high": ratios[1]}
        # arviz's HDI, as in the summary's hdi_3% / hdi_97%.
        hdi_range = tuple(float(v) for v in az.hdi(draws[..., j].ravel(), hdi_prob=HDI_PROB))
        for side, ratio in zip(("low", "high"), ratios, strict=True):
            if ratio >= BOUNDARY_DENSITY:
                key = layout.prior_key(layout.bases[j])
                check.warnings.append(_boundary_warning(name, key, bounds[side], side, hdi_range))
    return check


def _boundary_warning(name: str, key: str, bound: float, side: str, interval: tuple) -> dict:
    """The warning of parameter ``name``, whose prior range is ``key``'s."""
    flag = f"--prior {key} LOW HIGH"
    where = f"the prior's {'lower' if side == 'low' else 'upper'} bound {bound:g}"
    hdi_text = f"94 % HDI [{interval[0]:.4g}, {interval[1]:.4g}]"
    if side == "low":
        advice = (
            "the data give only an upper limit, and the interval's lower end is the "
            f"prior's: report it as a bound, or lower the bound ({flag})"
        )
    else:
        advice = (
            f"the prior, not the data, limits it: widen the range ({flag}), or the model "
            "misses something this parameter absorbs"
        )
    return {
        "kind": "prior-boundary",
        "parameter": name,
        "bound": bound,
        "side": side,
        "hdi": list(interval),
        "message": f"{name}: the posterior is piled against {where} ({hdi_text}); {advice}",
    }


# --- residual-input cross-correlation -------------------------------------------------


def _input_series(experiment: Experiment) -> dict[str, np.ndarray]:
    """Wheel-speed sum and difference at the residuals' times k = 0..N-2 [rad/s]."""
    u = experiment.inputs[:-1]
    return dict(zip(INPUTS, (u[:, 0] + u[:, 1], u[:, 0] - u[:, 1]), strict=True))


def _posterior_median(idata: az.InferenceData) -> np.ndarray:
    draws, _ = parameter_draws(idata)
    return np.median(draws.reshape(-1, draws.shape[-1]), axis=0)


def residual_input(idata: az.InferenceData, *, lags: int = RESIDUAL_INPUT_LAGS) -> Check:
    """Cross-correlation of the one-step residuals with the inputs, per experiment and channel.

    The residuals and the model are taken at the posterior median, over the
    whole run: in a steady window the wheel speeds are constant, and a
    wrong input gain is absorbed by the damping there; only where the input
    varies can the residuals betray it. The residual autocorrelation in the
    band (:func:`cross_correlation_sd`) is the fitted model's, so the band
    is exact under the model. Each input's z(k) = r(k) / sd is flagged when
    max |z| over both inputs and lags -L..L exceeds
    :func:`simultaneous_threshold` (family-wise level 99 %); the per-lag
    99 % band is +-2.58 sd, as MATLAB's ``resid`` draws it.

    Numbers per experiment and channel: ``lags``, ``z`` per input (list
    over lags), ``sd`` per input, ``band`` (per-lag z), ``threshold``,
    ``max_abs_z``. An input that is constant over the run is left out.
    """
    metadata = posterior_metadata(idata)
    theta = _posterior_median(idata)[None]
    band = float(scipy.stats.norm.isf((1.0 - RESIDUAL_INPUT_LEVEL) / 2.0))
    check = Check()
    for index, experiment in enumerate(posterior_experiments(idata)):
        inputs = {name: u for name, u in _input_series(experiment).items() if np.ptp(u) > 0}
        rows = {}
        for channel in metadata.channels:
            residual = channel_residuals(
                experiment, metadata.robot, theta[0, 0], theta[0, 1], channel, steady=False
            )
            n = len(residual)
            acov = model_autocovariance(metadata, index, channel, theta, n)[0]
            length = min(lags, n - 1)
            sd = {
                name: float(cross_correlation_sd(acov / acov[0], u)) for name, u in inputs.items()
            }
            z = {
                name: cross_correlation(residual, u, length) / sd[name]
                for name, u in inputs.items()
            }
            threshold = simultaneous_threshold(
                max(1, len(z)) * (2 * length + 1), level=RESIDUAL_INPUT_LEVEL
            )
            worst = max(z, key=lambda name: np.abs(z[name]).max(), default=None)
            peak = 0.0 if worst is None else float(np.abs(z[worst]).max())
            rows[channel] = {
                "lags": length,
                "z": {name: values.tolist() for name, values in z.items()},
                "sd": sd,
                "band": band,
                "threshold": threshold,
                "max_abs_z": peak,
            }
            if peak > threshold:
                check.warnings.append(
                    _input_warning(experiment.name, channel, worst, z[worst], threshold)
                )
        check.numbers[experiment.name] = rows
    return check


def _input_warning(
    experiment: str, channel: str, name: str, z: np.ndarray, threshold: float
) -> dict:
    index = int(np.argmax(np.abs(z)))
    lag = index - len(z) // 2
    return {
        "kind": "residual-input",
        "experiment": experiment,
        "channel": channel,
        "input": name,
        "lag": lag,
        "z": float(z[index]),
        "message": (
            f"{experiment}, {channel}: the one-step residuals correlate with the wheel-speed "
            f"{name} at lag {lag} (z = {z[index]:.1f}; 99 % over all lags: |z| < "
            f"{threshold:.1f}): the model's input path is wrong (wheel radius, input "
            "conversion, track width or a missing dynamic)"
        ),
    }


# --- posterior-predictive autocorrelation ------------------------------------------


def _statistic_names(lags: tuple[int, ...], portmanteau: int) -> list[str]:
    return [f"acf[{k}]" for k in lags] + [f"Q[1..{portmanteau}]"]


def predictive_acf(
    idata: az.InferenceData,
    *,
    count: int = PREDICTIVE_DRAWS,
    rng: np.random.Generator | int | None = 0,
) -> Check:
    """Posterior-predictive p-values of the residual autocorrelation.

    For each of ``count`` posterior draws theta: the observed residuals at
    theta's damping and one replicated residual series drawn exactly from
    the model at theta (:func:`bayes_jackal.predictive.predictive_series`);
    their :func:`acf_statistics` give one p-value per statistic
    (:func:`predictive_p_values`). The statistics of one experiment and
    channel are flagged by :func:`predictive_flags` at the family-wise level
    :data:`PREDICTIVE_ALARM` (Bonferroni over both tails of the statistics;
    with 200 draws: only a statistic beyond all replicated ones). Posterior
    predictive p-values are conservative (Meng 1994: they concentrate near
    0.5 when the model holds, because the data fitted theta), so the false
    alarm rate is lower still. The draws are processed in chunks of at most
    :data:`~bayes_jackal.predictive.CHUNK_SAMPLES` samples (one draw per
    chunk at least), and each replicated series comes from its own generator
    spawned from ``rng`` (:func:`bayes_jackal.predictive.predictive_series`),
    so the p-values do not depend on the chunks. Runs with more than
    :data:`PREDICTIVE_WINDOW` residuals are checked on their central
    window of that length.

    Numbers per experiment and channel: ``statistics`` (names),
    ``p_values``, ``draws``, ``alarm``, ``tail_level`` (per tail) and
    ``window`` (the residuals checked, first and last index + 1).
    """
    metadata = posterior_metadata(idata)
    theta = thinned_draws(idata, count)
    rng = as_rng(rng)  # one generator: every channel spawns its own series from it
    check = Check()
    for index, experiment in enumerate(posterior_experiments(idata)):
        rows = {}
        for channel in metadata.channels:
            total = observed_residuals(idata, index, channel).size
            n = min(total, PREDICTIVE_WINDOW)
            window = slice((total - n) // 2, (total - n) // 2 + n)
            lags = tuple(k for k in PREDICTIVE_LAGS if k < n // 2)
            portmanteau = min(PORTMANTEAU_LAGS, n // 2)
            names = _statistic_names(lags, portmanteau)
            p_values = _p_values(
                metadata, experiment, (index, channel, window), theta, lags, portmanteau, rng
            )
            rows[channel] = {
                "statistics": names,
                "p_values": p_values.tolist(),
                "draws": len(theta),
                "alarm": PREDICTIVE_ALARM,
                "tail_level": PREDICTIVE_ALARM / (2 * len(names)),
                "window": [window.start, window.stop],
            }
            flags = predictive_flags(p_values, len(theta), alarm=PREDICTIVE_ALARM)
            check.warnings += [
                _predictive_warning(experiment.name, channel, name, p, len(theta), metadata.family)
                for name, p, flag in zip(names, p_values, flags, strict=True)
                if flag
            ]
        check.numbers[experiment.name] = rows
    return check


def _p_values(
    metadata: PosteriorMetadata,
    experiment: Experiment,
    series: tuple[int, str, slice],
    theta: np.ndarray,
    lags: tuple[int, ...],
    portmanteau: int,
    rng: np.random.Generator | int | None,
) -> np.ndarray:
    """:func:`predictive_p_values` over the draws ``theta``, from chunks of their series.

    ``series`` is (``experiment``'s index, channel, window of the residuals
    checked). Per chunk of draws, the observed residuals in the window at
    each draw's damping and the replicated series of the window's length
    are reduced to their :func:`acf_statistics`; only those (draws x
    statistics) are kept.
    """
    index, channel, window = series
    n = window.stop - window.start
    observed, replicated = [], []
    for part, draws in predictive_series(metadata, index, channel, theta, n, rng):
        residuals = channel_residuals(
            experiment,
            metadata.robot,
            theta[part, 0],
            theta[part, 1],
            channel,
            metadata.steady,
            window,
        )
        observed.append(acf_statistics(residuals, lags=lags, portmanteau=portmanteau))
        replicated.append(acf_statistics(draws, lags=lags, portmanteau=portmanteau))
    return predictive_p_values(np.concatenate(observed), np.concatenate(replicated))


def _predictive_warning(
    experiment: str,
    channel: str,
    name: str,
    p: float,
    draws: int,
    family: str,
) -> dict:
    side = "higher" if p < 0.5 else "lower"
    beaten = round((1.0 - p if p < 0.5 else p) * draws)
    return {
        "kind": "predictive-acf",
        "experiment": experiment,
        "channel": channel,
        "statistic": name,
        "p_value": float(p),
        "message": (
            f"{experiment}, {channel}: the residuals' {name} is {side} than in {beaten} of "
            f"{draws} posterior-predictive series (p = {p:.3f}; flagged at a family-wise "
            f"{100 * PREDICTIVE_ALARM:g} % over this channel's statistics): the fitted "
            f"{family} noise does not reproduce the residuals' colour"
        ),
    }


# --- steadiness ----------------------------------------------------------------------


def steady_windows(idata: az.InferenceData) -> Check:
    """Warnings for analysed windows that are not steady cornering (thesis ch. 5).

    The window is each experiment's steady window when the posterior used
    them, else the whole run. Numbers per experiment: ``input_deviation``
    (None when the wheels stand still), ``yaw_drift`` (:func:`steadiness`),
    ``duration`` [s], and the tolerances.
    """
    steady = posterior_metadata(idata).steady
    check = Check()
    for experiment in posterior_experiments(idata):
        window = experiment.steady() if steady else experiment
        deviation, drift = steadiness(window.t, window.yaw_rate, window.inputs)
        duration = float(window.t[-1] - window.t[0])
        check.numbers[experiment.name] = {
            "input_deviation": deviation,
            "yaw_drift": drift,
            "duration": duration,
            "input_tolerance": STEADY_INPUT_TOLERANCE,
            "yaw_tolerance": STEADY_YAW_TOLERANCE,
        }
        failures = _steadiness_failures(deviation, drift)
        if not failures:
            continue
        span = "steady window" if steady and experiment.steady_window else "run"
        check.warnings.append(
            {
                "kind": "not-steady",
                "experiment": experiment.name,
                "input_deviation": deviation,
                "yaw_drift": drift,
                "message": (
                    f"{experiment.name}: the analysed {span} ({duration:.1f} s) is not steady: "
                    f"{' and '.join(failures)}; the thesis' analysis assumes steady circles "
                    "(ch. 5): transients test the model where it is least sure"
                ),
            }
        )
    return check


def _steadiness_failures(deviation: float | None, drift: float) -> list[str]:
    """The steadiness criteria a window fails, in words."""
    failures = []
    if deviation is None:
        failures.append("the wheels stand still")
    elif deviation > STEADY_INPUT_TOLERANCE:
        failures.append(
            f"the wheel speeds depart from their median by {100 * deviation:.0f} % "
            f"(tolerance {100 * STEADY_INPUT_TOLERANCE:.0f} %)"
        )
    if drift > STEADY_YAW_TOLERANCE:
        failures.append(
            f"the yaw rate drifts by {100 * drift:.0f} % "
            f"(tolerance {100 * STEADY_YAW_TOLERANCE:.0f} %)"
        )
    return failures


# --- identification -----------------------------------------------------------------

#: What each channel alone identifies of the damping, and what it does not.
_IDENTIFIES = {
    "yaw": (
        "the ratio d_lat/d_long but not the damping's scale: along that ridge the noise "
        "parameters (width, sigma_c) absorb the damping error, so they are biased too"
    ),
    "vx": "d_long but not d_lat (vx does not depend on it)",
    "vy": "d_lat but not d_long",
}


def damping_scale(idata: az.InferenceData) -> Check:
    """A warning when the posterior used a single channel: the damping is then not identified.

    The yaw rate's steady state depends on d_lat / d_long only: it
    identifies the ratio, not the scale. vx identifies d_long and vy d_lat.
    Any two channels identify both. The advice names the channels every
    experiment measured (the posterior's stored data). Numbers:
    ``channels``, ``identified``, ``measured``.
    """
    metadata = posterior_metadata(idata)
    channels = list(metadata.channels)
    count = len(metadata.experiments)
    data = idata.constant_data
    stored = {"yaw": "yaw_rate", "vx": "vx", "vy": "vy"}
    measured = [
        c for c in ("yaw", "vx", "vy") if all(f"{stored[c]}_{i}" in data for i in range(count))
    ]
    identified = len(channels) >= 2
    check = Check({"channels": channels, "identified": identified, "measured": measured})
    if identified:
        return check
    (channel,) = channels
    others = [c for c in measured if c != channel]
    if others:
        advice = f"add {' or '.join(others)} (--channels {','.join([channel, *others])})"
    else:
        advice = (
            f"these logs measure {channel} only, so the damping cannot be identified from "
            "them: record vx or vy (motion capture) and add it"
        )
    check.warnings.append(
        {
            "kind": "damping-scale-not-identified",
            "channels": channels,
            "message": f"{channel} alone identifies {_IDENTIFIES[channel]}; {advice}",
        }
    )
    return check


# --- all checks -----------------------------------------------------------------------


def criticise(idata: az.InferenceData, *, rng: np.random.Generator | int | None = 0) -> dict:
    """Every check of a posterior: ``{"warnings": [...], "criticism": {...}}``.

    ``criticism`` holds the numbers under ``prior_boundary``,
    ``residual_input``, ``predictive_acf``, ``steadiness`` and
    ``damping_scale``. The result is computed once per posterior and kept in
    its ``criticism`` attribute (a saved file carries it); ``rng`` seeds the
    replicated series (fixed by default, so the numbers are reproducible).
    """
    stored = posterior_metadata(idata).criticism
    if stored is not None:
        return stored
    checks = {
        "damping_scale": damping_scale(idata),
        "prior_boundary": prior_boundary(idata),
        "steadiness": steady_windows(idata),
        "residual_input": residual_input(idata),
        "predictive_acf": predictive_acf(idata, rng=rng),
    }
    result = {
        "warnings": [w for check in checks.values() for w in check.warnings],
        "criticism": {name: check.numbers for name, check in checks.items()},
    }
    store_criticism(idata, result)
    return result
