"""Model criticism of the inputs' path: residual-input, input noise, steadiness, derived data.

Four checks of a posterior, run with the others by
:func:`bayes_jackal.posterior.criticise` (and importable from
:mod:`bayes_jackal.posterior.criticism`). ``residual-input`` (:func:`residual_input`,
MATLAB ``resid``'s independence test): do the one-step residuals correlate
with the wheel speeds, which a wrong input path would make them do?
``input-noise`` (:func:`input_noise`): do the wheel speeds, which the model
takes as exact, carry enough white noise to bias the damping low?
``not-steady`` (:func:`steady_windows`): are the analysed windows steady
cornering, as the thesis' analysis (ch. 5) assumes? ``derived-velocity``
(:func:`derived_velocities`): are vx, vy modelled as measured where they
were derived from poses the data no longer hold?
"""

from __future__ import annotations

import numpy as np
import scipy.stats

from .._runtime import DERIVED_VELOCITY, INPUT_NOISE, NOT_STEADY, RESIDUAL_INPUT, az
from ..io import CHANNEL_FIELDS, STEADY_INPUT_TOLERANCE, STEADY_YAW_TOLERANCE, UNITS, Experiment
from ..likelihood import channel_residuals
from ..model import RATE_SENSOR, channel_coefficients
from .criticism_statistics import (
    Check,
    cross_correlation,
    cross_correlation_sd,
    simultaneous_threshold,
    steadiness,
)
from .posterior import Posterior
from .series_statistics import sample_autocorrelation

__all__ = [
    "INPUTS",
    "RESIDUAL_ACF_LAGS",
    "RESIDUAL_INPUT_LAGS",
    "RESIDUAL_INPUT_LEVEL",
    "derived_velocities",
    "input_noise",
    "residual_input",
    "steady_windows",
    "velocities_derived",
]

#: Lags -L..L of the residual-input cross-correlation (MATLAB ``resid``: 25).
RESIDUAL_INPUT_LAGS = 25
#: Level of the per-lag band, and family-wise level of the warning.
RESIDUAL_INPUT_LEVEL = 0.99
#: Lags of the residuals' own autocorrelation in the band (twice the test's lags):
#: a white fit on Gaussian noise of 0.3 s (21 samples) gives max |z| 1.2 with it,
#: 4.1 with the family's (flat) autocorrelation; a 30 % input-gain error 5.5.
RESIDUAL_ACF_LAGS = 2 * RESIDUAL_INPUT_LAGS
#: Inputs the residuals are correlated with: wheel-speed sum (forward drive,
#: rad/s) and difference (turning), the two directions of B.
INPUTS = ("sum", "difference")
#: The wheel speeds' white noise carried to a channel through its steady-state gain,
#: as a multiple of the channel's sensor noise, above which ``input-noise`` warns.
#: Measured by hand on one simulation of the thesis circles at 50 Hz (a v1 and a v2
#: circle, 10 Hz poses, gyro noise 5 mrad/s; tests/test_input_noise.py checks the
#: fall at 0.01 rad/s on two seeds): the MAP d_lat falls by 2, 7, 17 and
#: 32 % at yaw ratios 0.054, 0.135, 0.27 and 0.54 (wheel noise 0.002, 0.005, 0.01
#: and 0.02 rad/s); at 0.1 by about 5 %, half the posterior sd of log d_lat there.
INPUT_NOISE_RATIO = 0.1


# --- residual-input cross-correlation -------------------------------------------------


def _input_series(experiment: Experiment) -> dict[str, np.ndarray]:
    """Wheel-speed sum and difference at the samples' times [rad/s].

    The residual k of every channel begins at sample k: the first of them
    line up with the residuals.
    """
    u = experiment.inputs
    return dict(zip(INPUTS, (u[:, 0] + u[:, 1], u[:, 0] - u[:, 1]), strict=True))


def _posterior_median(idata: az.InferenceData) -> np.ndarray:
    draws, _ = Posterior.of(idata).draws()
    return np.median(draws.reshape(-1, draws.shape[-1]), axis=0)


def _tapered_autocorrelation(residual: np.ndarray, lags: int) -> np.ndarray:
    """The residuals' sample autocorrelation at 0..lags, times Bartlett's taper 1 - j/(lags+1).

    The taper keeps the band's variance positive and damps the sample
    autocorrelation's noise at long lags.
    """
    return sample_autocorrelation(residual, lags) * (1.0 - np.arange(lags + 1) / (lags + 1))


def residual_input(idata: az.InferenceData, *, lags: int = RESIDUAL_INPUT_LAGS) -> Check:
    """Cross-correlation of the one-step residuals with the inputs, per experiment and channel.

    The residuals and the model are taken at the posterior median, over the
    whole run: in a steady window the wheel speeds are constant, and a
    wrong input gain is absorbed by the damping there; only where the input
    varies can the residuals betray it. The residual autocorrelation in the
    band (:func:`cross_correlation_sd`) is the residuals' own, to
    :data:`RESIDUAL_ACF_LAGS` lags with Bartlett's taper (Ljung, *System
    Identification*, 16.6), not the fitted family's: a family that misses
    the residuals' colour (white noise on coloured, which the
    ``predictive-acf`` check flags) would make the band too narrow and blame
    the input path for it. Each input's z(k) = r(k) / sd is flagged when
    max |z| over both inputs and lags -L..L exceeds
    :func:`simultaneous_threshold` (family-wise level 99 %); the per-lag
    99 % band is +-2.58 sd, as MATLAB's ``resid`` draws it.

    Numbers per experiment and channel: ``lags``, ``z`` per input (list
    over lags), ``sd`` per input, ``band`` (per-lag z), ``threshold``,
    ``max_abs_z``. An input that is constant over the run is left out.

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second; white noise fitted on
    the yaw rate alone of a run simulated with coloured noise:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import residual_input
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> check = residual_input(posterior)
    >>> row = check.numbers["v1"]["yaw"]
    >>> row["lags"], round(row["threshold"], 2), round(row["max_abs_z"], 1), check.warnings
    (25, 3.9, 1.0, [])
    """
    posterior = Posterior.of(idata)
    metadata = posterior.metadata
    theta = _posterior_median(idata)[None]
    band = float(scipy.stats.norm.isf((1.0 - RESIDUAL_INPUT_LEVEL) / 2.0))
    check = Check()
    for experiment in posterior.experiments:
        inputs = {name: u for name, u in _input_series(experiment).items() if np.ptp(u) > 0}
        rows = {}
        for channel in metadata.channels:
            residual = channel_residuals(
                experiment, metadata.robot, theta[0, 0], theta[0, 1], channel, steady=False
            )
            n = len(residual)
            length = min(lags, n - 1)
            rho = _tapered_autocorrelation(residual, min(RESIDUAL_ACF_LAGS, n - 1))
            sd = {name: float(cross_correlation_sd(rho, u[:n])) for name, u in inputs.items()}
            z = {
                name: cross_correlation(residual, u[:n], length) / sd[name]
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
        "kind": RESIDUAL_INPUT,
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


# --- input noise -----------------------------------------------------------------------


def input_white_noise(inputs: np.ndarray) -> np.ndarray:
    """The white-noise sd of each column of ``inputs``, from its second differences.

    A wheel speed that is smooth at the sample rate has second differences
    near 0; white noise of sd s gives e[k+1] - 2 e[k] + e[k-1], of variance
    6 s^2. The median absolute deviation (scaled to a normal sd) ignores the
    few samples at a command step or a kink of an interpolated encoder. A
    sensor held and interpolated onto a faster clock gives about 0: its
    error is no longer white there, and this estimate does not see it.

    Parameters
    ----------
    inputs : array_like, shape (N, m)
        Samples on a uniform clock, N >= 3 (wheel speeds [rad/s]).

    Returns
    -------
    ndarray, shape (m,)
        White-noise sd of each column, in its unit.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.posterior.criticism_inputs import input_white_noise
    >>> rng = np.random.default_rng(1)
    >>> smooth = np.repeat([[3.0, 2.0], [4.0, 1.0]], 2000, axis=0)  # one step
    >>> noisy = smooth + 0.01 * rng.standard_normal(smooth.shape)
    >>> input_white_noise(noisy).round(4).tolist(), input_white_noise(smooth).tolist()
    ([0.0103, 0.0101], [0.0, 0.0])
    """
    second = np.diff(np.asarray(inputs, float), 2, axis=0)
    return scipy.stats.median_abs_deviation(second, axis=0, scale="normal") / np.sqrt(6.0)


def input_noise(idata: az.InferenceData) -> Check:
    """Warnings where white noise on the wheel speeds biases the damping (errors in the input).

    The model takes the wheel speeds as exact; a measured wheel speed
    u + e makes the one-step residual w - Bd e, correlated with the input
    the model conditions on, and the fit lowers the damping to follow e
    less (errors in variables). At low frequencies, where a channel's own
    sensor noise n enters as (1 - alpha) n, the input's white noise enters
    as Bd e = (1 - alpha) G e, G the channel's steady-state gain
    Bd / (1 - alpha): the ratio of |G e| to the sensor noise sigma_n says how
    much of the residual's slow part the input noise is. Above
    :data:`INPUT_NOISE_RATIO` a channel warns ``input-noise``. Left out: a
    channel recorded as poses (its sensor noise a position's), one without
    an input (vy), and one without a sigma_n (white noise with the diagonal
    sensor term, whose one sd is the residual's total). With
    ``--damping speed`` the gain is taken at the reference speed's damping.

    Numbers per experiment: ``wheel_noise`` (:func:`input_white_noise`, [rad/s],
    omega_r and omega_l) and ``channels``, per channel ``gain`` (G at the
    posterior median, per wheel), ``input_noise`` (|G e| in the channel's
    unit), ``sensor_noise`` (the posterior median of its sigma_n) and ``ratio``.

    Examples
    --------
    A simulated run's wheel speeds are exact: nothing to say. The 20-step
    chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import input_noise
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> check = input_noise(posterior)
    >>> check.numbers["v1"]["channels"]["yaw"]["ratio"], check.warnings
    (0.0, [])
    """
    posterior = Posterior.of(idata)
    layout, robot = posterior.layout, posterior.robot
    theta = _posterior_median(idata)
    check = Check()
    for experiment in posterior.experiments:
        noise = input_white_noise(experiment.inputs)
        rows: dict[str, dict[str, object]] = {}
        for channel in posterior.channels:
            group = layout.group(channel, experiment.name)
            if layout.sensor_parameter(group) != RATE_SENSOR:
                continue
            alpha, row = channel_coefficients(robot, theta[0], theta[1], channel, experiment.dt)
            if not np.any(row):
                continue
            gain = row / (1.0 - alpha)
            carried = float(np.hypot(*(gain * noise)))
            sensor = float(theta[layout.column(RATE_SENSOR, group)])
            rows[channel] = {
                "gain": gain.tolist(),
                "input_noise": carried,
                "sensor_noise": sensor,
                "ratio": carried / sensor,
            }
            if carried > INPUT_NOISE_RATIO * sensor:
                check.warnings.append(
                    _input_noise_warning(experiment.name, channel, rows[channel], noise)
                )
        check.numbers[experiment.name] = {"wheel_noise": noise.tolist(), "channels": rows}
    return check


def _input_noise_warning(experiment: str, channel: str, row: dict, noise: np.ndarray) -> dict:
    """The ``input-noise`` warning of one channel: its numbers (``row``) and the wheels' noise."""
    right, left = noise
    unit = UNITS[CHANNEL_FIELDS[channel]]
    return {
        "kind": INPUT_NOISE,
        "experiment": experiment,
        "channel": channel,
        "ratio": row["ratio"],
        "message": (
            f"{experiment}, {channel}: the wheel speeds scatter from sample to sample by "
            f"{right:.2g} (right) and {left:.2g} rad/s (left) of white noise (from their "
            "second differences), which the model takes as exact input; through the "
            f"channel's steady-state gain that is {row['input_noise']:.2g} {unit}, "
            f"{row['ratio']:.2g} times its sensor noise ({row['sensor_noise']:.2g} {unit}; "
            f"above {INPUT_NOISE_RATIO:g} the damping is biased low: errors in the input, "
            "docs/guide/model.md). Give the input as the commanded or filtered wheel speeds"
        ),
    }


# --- steadiness ----------------------------------------------------------------------


def steady_windows(idata: az.InferenceData) -> Check:
    """Steadiness of each segment of the runs; warnings where a steady window was asked for.

    The likelihood takes every sample by default: transients are data the
    model covers. The numbers then describe each run's segments (its
    command steps, :attr:`bayes_jackal.io.Experiment.segments`; the whole
    run where it has none): ``start``, ``duration`` [s], ``input_deviation``
    (None when the wheels stand still), ``yaw_drift`` (:func:`steadiness`)
    and ``steady`` (both within the tolerances ``input_tolerance``,
    ``yaw_tolerance``, which are given too). With ``--steady`` (the thesis'
    crop) the window analysed is each run's steady window, and one that is
    not steady cornering warns (``not-steady``): the thesis' analysis
    assumes steady circles (ch. 5).

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged), so that the example runs in a second; white noise fitted on
    the yaw rate alone of a run simulated with coloured noise, its rest,
    ramps and hold one segment:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import steady_windows
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> check = steady_windows(posterior)
    >>> [segment] = check.numbers["v1"]["segments"]
    >>> segment["duration"], segment["steady"], check.warnings
    (38.0, False, [])
    """
    posterior = Posterior.of(idata)
    steady = posterior.metadata.steady
    check = Check()
    for experiment in posterior.experiments:
        if not steady:
            check.numbers[experiment.name] = {
                "segments": [_segment_steadiness(piece) for piece in _segments(experiment)],
                "input_tolerance": STEADY_INPUT_TOLERANCE,
                "yaw_tolerance": STEADY_YAW_TOLERANCE,
            }
            continue
        window = experiment.steady()
        row = _segment_steadiness(window)
        check.numbers[experiment.name] = {
            **row,
            "input_tolerance": STEADY_INPUT_TOLERANCE,
            "yaw_tolerance": STEADY_YAW_TOLERANCE,
        }
        failures = _steadiness_failures(row["input_deviation"], row["yaw_drift"])
        if not failures:
            continue
        span = "steady window" if experiment.steady_window else "run"
        check.warnings.append(
            {
                "kind": NOT_STEADY,
                "experiment": experiment.name,
                "input_deviation": row["input_deviation"],
                "yaw_drift": row["yaw_drift"],
                "message": (
                    f"{experiment.name}: the analysed {span} ({row['duration']:.1f} s) is not "
                    f"steady: {' and '.join(failures)}; the thesis' analysis (--steady) assumes "
                    "steady circles (ch. 5): leave --steady out to use every sample"
                ),
            }
        )
    return check


def _segments(experiment: Experiment) -> list[Experiment]:
    """The experiment's segments (command steps) as experiments of their own."""
    starts = experiment.segment_starts
    stops = [*starts[1:], len(experiment.t)]
    return [
        experiment.window(experiment.t[start], experiment.t[stop - 1])
        for start, stop in zip(starts, stops, strict=True)
        if stop - start >= 3
    ]


def _segment_steadiness(window: Experiment) -> dict:
    """A window's start, duration [s] and steadiness (:func:`steadiness`)."""
    deviation, drift = steadiness(window.t, window.yaw_rate, window.inputs)
    return {
        "start": float(window.t[0]),
        "duration": float(window.t[-1] - window.t[0]),
        "input_deviation": deviation,
        "yaw_drift": drift,
        "steady": not _steadiness_failures(deviation, drift),
    }


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


# --- derived velocities ------------------------------------------------------------------


def velocities_derived(provenance: dict) -> bool:
    """Whether an experiment's vx, vy were derived from poses (its provenance says so).

    A table read with ``velocities="derived"`` records it, and so does every
    bag's reading, whose provenance names the ``smoother``: one read before
    the poses were kept has only those velocities, one read since has its
    poses too, and its vx, vy are then modelled through them
    (:func:`derived_velocities` flags only velocities modelled as measured).

    Examples
    --------
    >>> from bayes_jackal.posterior import velocities_derived
    >>> velocities_derived({"smoother": {"window_s": 0.1}}), velocities_derived({})
    (True, False)
    """
    return provenance.get("velocities") == "derived" or "smoother" in provenance


def derived_velocities(idata: az.InferenceData) -> Check:
    """Warnings for vx, vy modelled as measured that were derived from poses (docs/design.md §2.2).

    A smoothing derivative of the poses widens the process noise's kernel
    and colours the pose noise: modelled as a measured velocity it put the
    damping at half its truth on motion-capture bags. An experiment whose
    poses are kept has its vx, vy modelled through them and is not flagged.
    Numbers per experiment: ``derived`` (its provenance says so) and
    ``channels`` (those modelled as measured although derived).

    Examples
    --------
    A simulated run measures its velocities: nothing to say. The 20-step
    chain is short on purpose:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.posterior import derived_velocities
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw", "vx"], max_steps=20,
    ...                       seed=1)
    >>> check = derived_velocities(posterior)
    >>> check.numbers["v1"], check.warnings
    ({'derived': False, 'channels': []}, [])
    """
    metadata = Posterior.of(idata).metadata
    modelled = [
        c
        for c in metadata.channels
        if c in ("vx", "vy") and c not in metadata.layout.pose_channels
    ]
    check = Check()
    for record in metadata.experiments:
        derived = velocities_derived(record.provenance)
        channels = modelled if derived else []
        check.numbers[record.name] = {"derived": derived, "channels": channels}
        if channels:
            check.warnings.append(
                {
                    "kind": DERIVED_VELOCITY,
                    "experiment": record.name,
                    "channels": channels,
                    "message": (
                        f"{record.name}: {' and '.join(channels)} were derived from poses by a "
                        "smoothing derivative and are modelled as measured velocities (the "
                        "data hold no poses): the smoothing widens their kernel and colours "
                        "the pose noise, which has put the damping at half its truth "
                        "(docs/design.md 2.2); ingest the bag again (ingest keeps the poses), "
                        "give the poses as columns x, y, heading, or use --channels yaw"
                    ),
                }
            )
    return check
