"""Model criticism: checks of a fitted posterior and of its data.

A converged posterior can still be wrong. Each check takes an arviz
InferenceData as written by :mod:`bayes_jackal.posterior.posterior` and returns a
:class:`Check`: JSON-ready numbers and warnings, dicts with ``kind``,
``message`` and the fields that locate them. Kinds: ``prior-boundary``
(:func:`prior_boundary`), ``residual-input`` (:func:`residual_input`, MATLAB
``resid``'s independence test), ``input-noise`` (:func:`input_noise`),
``predictive-acf`` (:func:`predictive_acf`),
``not-steady`` (:func:`steady_windows`), ``derived-velocity``
(:func:`derived_velocities`) and ``damping-scale-not-identified``
(:func:`damping_scale`). :func:`criticise` runs them all;
:func:`bayes_jackal.posterior.summarize` reports it under ``warnings`` and
``criticism``. The array-level statistics behind the checks, and
:class:`Check`, are in :mod:`bayes_jackal.posterior.criticism_statistics`; the
checks of the inputs' path (:func:`residual_input`, :func:`input_noise`,
:func:`steady_windows`, :func:`derived_velocities`) are
:mod:`bayes_jackal.posterior.criticism_inputs`'s. All are importable from here.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._runtime import (
    DAMPING_SCALE_NOT_IDENTIFIED,
    HDI_PROB,
    PREDICTIVE_ACF,
    PRIOR_BOUNDARY,
    as_rng,
    az,
)
from ..io import Experiment
from ..likelihood import Prior, channel_residuals
from ..model import DAMPING
from .criticism_inputs import (
    derived_velocities,
    input_noise,
    residual_input,
    steady_windows,
)
from .criticism_statistics import (
    Check,
    acf_statistics,
    boundary_density,
    predictive_flags,
    predictive_p_values,
    prior_shift,
)
from .file_format import observed_residuals, store_criticism
from .posterior import Posterior
from .predictive import predictive_series
from .records import PosteriorMetadata

__all__ = [
    "BOUNDARY_DENSITY",
    "BOUNDARY_STRIP",
    "PORTMANTEAU_LAGS",
    "PREDICTIVE_ALARM",
    "PREDICTIVE_DRAWS",
    "PREDICTIVE_LAGS",
    "PREDICTIVE_WINDOW",
    "PRIOR_SHIFT",
    "boundary_check",
    "criticise",
    "damping_scale",
    "predictive_acf",
    "prior_boundary",
]

#: Width of the strip next to a prior bound, as a fraction of the 94 % HDI's
#: width (both in the prior's coordinate: log for log-uniform priors).
BOUNDARY_STRIP = 0.1
#: A posterior is piled against a bound when its draws' density in that strip
#: is at least this fraction of their mean density over the HDI. For a normal
#: posterior that is a bound within 1.5 sd of the mode (it cuts off >= 6 %).
BOUNDARY_DENSITY = 0.5
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
#: Posterior sds of log d by which the damping's other usual prior (uniform
#: for a log-uniform one) may move the posterior mean before the damping's
#: scale counts as set by its prior (:func:`damping_scale`). A normal
#: posterior of log d moves by about twice its sd (both dampings, the ridge's
#: correlation near one): 0.5 flags an HDI spanning a factor of 2.6 or more;
#: the thesis' robot (d_lat [95, 144]) moves by ~0.2.
PRIOR_SHIFT = 0.5


# --- prior boundary -----------------------------------------------------------------


def prior_boundary(idata: az.InferenceData) -> Check:
    """Warnings for parameters whose posterior is piled against a prior bound.

    Rule: :func:`boundary_density` at a bound is at least
    :data:`BOUNDARY_DENSITY`. Numbers: the two density ratios per parameter.

    Examples
    --------
    A posterior of a chain kept short on purpose (100 steps, not converged;
    the converged chain, 3,300 steps, warns alike), so that the example runs
    in a second; white noise fitted on the yaw rate alone of a run simulated
    with coloured noise:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import prior_boundary
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=100, seed=1)
    >>> check = prior_boundary(posterior)
    >>> [(w["parameter"], w["side"]) for w in check.warnings]  # yaw alone: d_long runs free
    [('d_long', 'low'), ('sigma_n', 'low')]
    >>> from bayes_jackal.posterior import BOUNDARY_DENSITY
    >>> {name: bool(ratios["low"] >= BOUNDARY_DENSITY) for name, ratios in check.numbers.items()}
    {'d_lat': False, 'd_long': True, 'sigma_c': False, 'sigma_n': True}
    """
    posterior = Posterior.of(idata)
    metadata = posterior.metadata
    layout = metadata.layout
    draws, _ = posterior.draws()
    keys = [layout.prior_key(base) for base in layout.bases]
    return boundary_check(draws.reshape(-1, len(keys)), metadata.prior, keys)


def boundary_check(draws: np.ndarray, prior: Prior, keys: Sequence[str] | None = None) -> Check:
    """:func:`prior_boundary`'s rule on plain draws: a warning per parameter piled at a bound.

    Parameters
    ----------
    draws : ndarray, shape (draws, k)
        Posterior draws in natural units, columns in ``prior.names`` order.
    prior : Prior
        Their prior's ranges.
    keys : sequence of str, optional
        The ``--prior`` key of each column in the advice; by default its name.

    Returns
    -------
    Check
        ``warnings`` (kind ``prior-boundary``) and the density ratios per parameter.

    Examples
    --------
    Draws piled against a lower bound of 1 warn; draws in the middle do not:

    >>> import numpy as np
    >>> from bayes_jackal.posterior import boundary_check
    >>> from bayes_jackal.likelihood import Prior
    >>> prior = Prior(("a", "b"), np.array([1.0, 1.0]), np.array([100.0, 100.0]),
    ...               np.array([True, True]))
    >>> rng = np.random.default_rng(1)
    >>> draws = np.column_stack([1.0 + rng.exponential(0.2, 4000), rng.lognormal(2.3, 0.1, 4000)])
    >>> [(w["parameter"], w["side"]) for w in boundary_check(draws, prior).warnings]
    [('a', 'low')]
    """
    keys = list(prior.names if keys is None else keys)
    check = Check()
    for j, name in enumerate(prior.names):
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
                check.warnings.append(
                    _boundary_warning(name, keys[j], bounds[side], side, hdi_range)
                )
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
        "kind": PRIOR_BOUNDARY,
        "parameter": name,
        "bound": bound,
        "side": side,
        "hdi": list(interval),
        "message": f"{name}: the posterior is piled against {where} ({hdi_text}); {advice}",
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
    the model at theta (:func:`bayes_jackal.posterior.predictive_series`);
    their :func:`acf_statistics` give one p-value per statistic
    (:func:`predictive_p_values`). The statistics of one experiment and
    channel are flagged by :func:`predictive_flags` at the family-wise level
    :data:`PREDICTIVE_ALARM` (Bonferroni over both tails of the statistics;
    with 200 draws: only a statistic beyond all replicated ones). Posterior
    predictive p-values are conservative (Meng 1994: they concentrate near
    0.5 when the model holds, because the data fitted theta), so the false
    alarm rate is lower still. The draws are processed in chunks of at most
    :data:`~bayes_jackal.posterior.CHUNK_SAMPLES` samples (one draw per
    chunk at least), and each replicated series comes from its own generator
    spawned from ``rng`` (:func:`bayes_jackal.posterior.predictive_series`),
    so the p-values do not depend on the chunks. Runs with more than
    :data:`PREDICTIVE_WINDOW` residuals are checked on their central
    window of that length.

    Numbers per experiment and channel: ``statistics`` (names),
    ``p_values``, ``draws``, ``alarm``, ``tail_level`` (per tail) and
    ``window`` (the residuals checked, first and last index + 1).

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second; white noise fitted on
    the yaw rate alone of a run simulated with coloured noise:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import predictive_acf
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> check = predictive_acf(posterior)
    >>> row = check.numbers["v1"]["yaw"]
    >>> row["statistics"], row["draws"]
    (['acf[1]', 'acf[2]', 'acf[5]', 'acf[10]', 'Q[1..30]'], 200)
    >>> [(w["statistic"], w["p_value"]) for w in check.warnings]  # white misses the colour
    [('acf[1]', 0.0), ('acf[2]', 0.0), ('acf[5]', 0.0), ('acf[10]', 1.0), ('Q[1..30]', 0.0)]
    """
    posterior = Posterior.of(idata)
    metadata = posterior.metadata
    theta = posterior.thinned_draws(count)
    rng = as_rng(rng)  # one generator: every channel spawns its own series from it
    check = Check()
    for index, experiment in enumerate(posterior.experiments):
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
        "kind": PREDICTIVE_ACF,
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
    """A warning when the damping's scale is not identified: one channel, or a prior-made one.

    The yaw rate's steady state depends on d_lat / d_long only: it
    identifies the ratio, not the scale. vx identifies d_long and vy d_lat.
    Any two channels identify both in principle; the advice names the
    channels every experiment measured
    (:attr:`~bayes_jackal.posterior.PosteriorMetadata.measured_channels`).

    In practice two channels can still leave the scale to the prior: when
    the poles are fast against the noise's bandwidth (a stiff robot under
    smooth noise), the states follow the noise quasi-statically and the
    runs fix the ratio only (docs/design.md §4). So the draws are
    reweighted to the damping's other usual prior (uniform on the same
    range for a log-uniform one, and back;
    :func:`~bayes_jackal.posterior.prior_shift`), and the check
    warns when the mean of log d_lat or log d_long moves by
    :data:`PRIOR_SHIFT` posterior sds or more. Numbers: ``channels``,
    ``identified``, ``measured`` and ``prior_shift`` (per damping parameter,
    in sds).

    Examples
    --------
    A yaw-only posterior of a run that also measured vx and vy (a 20-step
    chain, short on purpose: the single-channel rule reads the file's layout):

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import damping_scale
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> check = damping_scale(posterior)
    >>> {key: check.numbers[key] for key in ("channels", "identified", "measured")}
    {'channels': ['yaw'], 'identified': False, 'measured': ['yaw', 'vx', 'vy']}
    >>> print(check.warnings[0]["message"])
    yaw alone identifies ...; add vx or vy (--channels yaw,vx,vy)
    """
    fitted = Posterior.of(idata)
    metadata = fitted.metadata
    channels = list(metadata.channels)
    # Yaw first: the channel a single-channel posterior usually has.
    measured = [c for c in ("yaw", "vx", "vy") if c in metadata.measured_channels]
    draws, _ = fitted.draws()
    damping = draws.reshape(-1, draws.shape[-1])[:, : len(DAMPING)]
    shift = _damping_prior_shift(damping, metadata.prior)
    scaled = max(abs(value) for value in shift.values()) < PRIOR_SHIFT
    identified = len(channels) >= 2 and scaled
    check = Check(
        {
            "channels": channels,
            "identified": identified,
            "measured": measured,
            "prior_shift": shift,
        }
    )
    if len(channels) >= 2:
        if not scaled:
            check.warnings.append(_prior_made_warning(damping, metadata.prior, shift, channels))
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
            "kind": DAMPING_SCALE_NOT_IDENTIFIED,
            "channels": channels,
            "message": f"{channel} alone identifies {_IDENTIFIES[channel]}; {advice}",
        }
    )
    return check


def _damping_prior_shift(damping: np.ndarray, prior: Prior) -> dict[str, float]:
    """:func:`prior_shift` of log d_lat and log d_long to the damping's other usual prior.

    Uniform and log-uniform densities on one range differ by the factor d
    (in z = log d), so the weights are d_lat d_long for a log-uniform prior
    and its inverse for a uniform one.
    """
    log_damping = np.log(damping)
    log_weights = log_damping @ np.where(prior.log_uniform[: len(DAMPING)], 1.0, -1.0)
    return {name: prior_shift(log_damping[:, j], log_weights) for j, name in enumerate(DAMPING)}


def _prior_made_warning(
    damping: np.ndarray, prior: Prior, shift: dict[str, float], channels: list[str]
) -> dict:
    """The warning of a posterior whose damping scale another prior would move."""
    kind, other = (
        ("log-uniform", "uniform") if prior.log_uniform[0] else ("uniform", "log-uniform")
    )
    ratio = az.hdi(damping[:, 0] / damping[:, 1], hdi_prob=HDI_PROB)
    name = max(shift, key=lambda key: abs(shift[key]))
    return {
        "kind": DAMPING_SCALE_NOT_IDENTIFIED,
        "channels": channels,
        "prior_shift": shift,
        "message": (
            f"the runs fix the ratio d_lat/d_long (94 % HDI [{ratio[0]:.3g}, {ratio[1]:.3g}]) "
            f"but hardly the damping's scale: a {other} prior on the same range instead of "
            f"the {kind} one moves the posterior mean of log {name} by {shift[name]:.2g} "
            "posterior sd, so the HDIs of d_lat and d_long show the prior's choice as much "
            "as the data (docs/design.md §4). Report the ratio, or give the scale a prior "
            "from elsewhere (--prior d_lat LOW HIGH, --prior d_long LOW HIGH)"
        ),
    }


# --- all checks -----------------------------------------------------------------------


def criticise(idata: az.InferenceData, *, rng: np.random.Generator | int | None = 0) -> dict:
    """Every check of a posterior: ``{"warnings": [...], "criticism": {...}}``.

    ``criticism`` holds the numbers under ``prior_boundary``,
    ``residual_input``, ``input_noise``, ``predictive_acf``,
    ``steadiness``, ``derived_velocities`` and ``damping_scale``. The result is computed
    once per posterior and kept in its ``criticism`` attribute (a saved file
    carries it); ``rng`` seeds the replicated series (fixed by default, so
    the numbers are reproducible).

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second; white noise fitted on
    the yaw rate alone of a run simulated with coloured noise:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import criticise
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> result = criticise(posterior)
    >>> sorted(result["criticism"])
    ['damping_scale', 'derived_velocities', 'input_noise', 'predictive_acf',
     'prior_boundary', 'residual_input', 'steadiness']
    >>> sorted({warning["kind"] for warning in result["warnings"]})
    ['damping-scale-not-identified', 'predictive-acf', 'prior-boundary']
    """
    stored = Posterior.of(idata).metadata.criticism
    if stored is not None:
        return stored
    checks = {
        "damping_scale": damping_scale(idata),
        "prior_boundary": prior_boundary(idata),
        "steadiness": steady_windows(idata),
        "residual_input": residual_input(idata),
        "input_noise": input_noise(idata),
        "predictive_acf": predictive_acf(idata, rng=rng),
        "derived_velocities": derived_velocities(idata),
    }
    result = {
        "warnings": [w for check in checks.values() for w in check.warnings],
        "criticism": {name: check.numbers for name, check in checks.items()},
    }
    store_criticism(idata, result)
    return result
