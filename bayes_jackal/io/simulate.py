"""Thesis-like experiments with known truth.

The robot starts from rest, accelerates to a constant command (v, w), drives
steady circles, and stops (thesis ch. 2-3, table 2-2). The states follow the
discretised model with coloured process noise, white Gaussian noise filtered
by a kernel of one of the noise families (by default the thesis' Gaussian of
width sigma_h, eq. 7-5), and the measured states add white sensor noise. The
truth travels with the data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._runtime import CHANNELS, FAMILY, SIMULATED_NOISE, InputError, as_rng
from ..model import RobotProfile, get_family, simulate, wheel_speeds
from .experiment import Experiment

__all__ = [
    "SERIES",
    "NoiseSettings",
    "Series",
    "command_profile",
    "simulate_experiment",
    "simulate_series",
]


@dataclass(frozen=True)
class Series:
    """A thesis experiment series: a constant command held for a duration.

    Attributes
    ----------
    v : float
        Commanded forward speed [m/s].
    w : float
        Commanded yaw rate [rad/s].
    duration : float
        Length of the whole run [s].

    Examples
    --------
    The thesis' v1 setting (table 2-2), and a shorter run of one's own:

    >>> from bayes_jackal.io import SERIES, Series
    >>> v1 = SERIES["v1"]
    >>> print(v1.v, round(v1.w, 4), v1.duration)
    0.3 0.3927 38.0
    >>> Series(v=0.3, w=0.39, duration=14.0)
    Series(v=0.3, w=0.39, duration=14.0)
    """

    v: float
    w: float
    duration: float


#: Thesis table 2-2 and the run lengths of ch. 7-3 (~38 s and ~26 s).
SERIES = {
    "v1": Series(v=0.3, w=float(np.deg2rad(22.5)), duration=38.0),
    "v2": Series(v=0.4, w=float(np.deg2rad(30.0)), duration=26.0),
}

#: Seconds at rest before the start and after the stop.
REST = 1.0
#: Seconds to ramp the command up or down.
RAMP = 1.0
#: Seconds after the ramp before the state counts as steady.
SETTLE = 1.0


@dataclass(frozen=True)
class NoiseSettings:
    """Noise of a simulated experiment.

    Attributes
    ----------
    width : float
        Width of the process-noise kernel [s]: sigma_h of the thesis'
        Gaussian (eq. 7-5), or the width of another family.
    sigma_c : (float, float, float)
        Standard deviation of the process noise on (vx, vy, yaw) per step
        [m/s, m/s, rad/s].
    sigma_n : (float, float, float)
        Standard deviation of the white sensor noise on (vx, vy, yaw).
    family : str
        Process-noise family (:data:`bayes_jackal.model.FAMILIES`).

    Examples
    --------
    The defaults (the thesis' Gaussian filter of width 0.047 s), and white
    process noise without sensor noise:

    >>> from bayes_jackal.io import NoiseSettings
    >>> NoiseSettings()
    NoiseSettings(width=0.047, sigma_c=(0.005, 0.005, 0.01),
                  sigma_n=(0.003, 0.003, 0.005), family='gaussian')
    >>> NoiseSettings(family="white", sigma_n=(0.0, 0.0, 0.0)).sigma_n
    (0.0, 0.0, 0.0)
    """

    width: float = SIMULATED_NOISE["width"]
    sigma_c: tuple[float, float, float] = SIMULATED_NOISE["sigma_c"]
    sigma_n: tuple[float, float, float] = SIMULATED_NOISE["sigma_n"]
    family: str = FAMILY

    def __post_init__(self) -> None:
        for name in ("sigma_c", "sigma_n"):
            values = np.asarray(getattr(self, name), float)
            if values.shape != (3,) or not (np.isfinite(values).all() and (values >= 0).all()):
                raise InputError(
                    f"expected three non-negative values (vx, vy, yaw), got {values.tolist()}",
                    field=name,
                )
        get_family(self.family)
        if not (np.isfinite(self.width) and self.width > 0):
            raise InputError(f"must be positive, got {self.width!r} s", field="width")


def command_profile(series: Series, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity command of one run: rest, ramp up, hold, ramp down, rest.

    Parameters
    ----------
    series : Series
    dt : float
        Sample time [s].

    Returns
    -------
    t : ndarray, shape (N,)
        Sample times [s], N = round(duration / dt) + 1.
    v, w : ndarray, shape (N,)
        Commanded forward speed [m/s] and yaw rate [rad/s].

    Examples
    --------
    An 8 s run sampled every 0.5 s: 1 s at rest, a 1 s ramp, the hold, a
    1 s ramp down and 1 s at rest:

    >>> from bayes_jackal.io import Series, command_profile
    >>> t, v, w = command_profile(Series(v=0.3, w=0.39, duration=8.0), 0.5)
    >>> print(len(t), v.tolist())
    17 [0.0, 0.0, 0.0, 0.15, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.15, 0.0, 0.0, 0.0]
    """
    if series.duration <= 2 * (REST + RAMP + SETTLE):
        raise InputError(
            f"run of {series.duration} s is too short for rest, ramps and a steady window",
            field="duration",
        )
    t = np.arange(round(series.duration / dt) + 1) * dt
    stop = t[-1] - REST
    level = np.clip(np.minimum((t - REST) / RAMP, (stop - t) / RAMP), 0.0, 1.0)
    return t, series.v * level, series.w * level


def simulate_experiment(
    robot: RobotProfile,
    d_lat: float,
    d_long: float,
    series: str | Series = "v1",
    noise: NoiseSettings | None = None,
    rng: np.random.Generator | int | None = None,
    name: str | None = None,
    conversion: str | None = None,
) -> Experiment:
    """Simulate one thesis-like experiment with known truth.

    Parameters
    ----------
    robot : RobotProfile
        Constants and sampling rate (dt = 1 / ``robot.rate``).
    d_lat, d_long : float
        True damping [N s/m], within the profile's prior ranges
        (``robot.priors``; InputError otherwise).
    series : {"v1", "v2"} or Series
        Command setting (table 2-2), or any :class:`Series` (labelled
        ``"custom"``).
    noise : NoiseSettings, optional
        Process and sensor noise; the defaults of :class:`NoiseSettings`.
    rng : numpy.random.Generator, int or None
        Source of the noise; the same seed gives the same experiment.
    name : str, optional
        Experiment name; ``series`` when omitted.
    conversion : {"ros", "thesis"}, optional
        Command-to-wheel-speed conversion; ``robot.conversion`` when omitted.

    Returns
    -------
    Experiment
        Measured vx, vy, yaw rate and wheel speeds; ``truth`` holds the
        parameters, ``truth_arrays`` the noise-free states and the process
        noise, ``steady_window`` the steady-state cornering window.

    Examples
    --------
    A v2 run (26 s at the Jackal's 72 Hz) at the thesis' damping:

    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_experiment
    >>> run = simulate_experiment(load_profile(), 110.0, 30.0, "v2", rng=1)
    >>> print(run.name, len(run.t), run.channels, run.steady_window)
    v2 1873 ('vx', 'vy', 'yaw') (3.0, 24.0)
    >>> print(run.truth["d_lat"], run.truth["family"], run.truth["sigma_h"])
    110.0 gaussian 0.047
    """
    if isinstance(series, Series):
        command, label = series, "custom"
    elif series in SERIES:
        command, label = SERIES[series], series
    else:
        raise InputError(f"unknown series {series!r}; use one of {list(SERIES)}", field="series")
    for parameter, value in (("d_lat", d_lat), ("d_long", d_long)):
        low, high = robot.priors[parameter]
        if not low <= value <= high:  # NaN too
            raise InputError(
                f"{value:g} N s/m is outside the robot profile's prior range [{low:g}, "
                f"{high:g}]: no posterior could recover it; widen [priors] {parameter} to "
                "simulate it",
                field=parameter,
            )
    noise = NoiseSettings() if noise is None else noise
    rng = as_rng(rng)
    dt = robot.dt
    t, v, w = command_profile(command, dt)
    omega_r, omega_l = wheel_speeds(robot, v, w, conversion)
    family = get_family(noise.family)
    process = family.noise(noise.width, dt, len(t), np.asarray(noise.sigma_c), rng)
    states = simulate(robot, d_lat, d_long, np.column_stack([omega_r, omega_l]), None, process)
    measured = states + np.asarray(noise.sigma_n) * rng.standard_normal(states.shape)
    truth_arrays = {f"{c}_state": states[:, i] for i, c in enumerate(CHANNELS)}
    truth_arrays |= {f"{c}_process_noise": process[:, i] for i, c in enumerate(CHANNELS)}
    return Experiment(
        t=t,
        vx=measured[:, 0],
        vy=measured[:, 1],
        yaw_rate=measured[:, 2],
        omega_r=omega_r,
        omega_l=omega_l,
        name=name or label,
        series=label,
        steady_window=(REST + RAMP + SETTLE, float(t[-1]) - REST - RAMP),
        truth={
            "d_lat": float(d_lat),
            "d_long": float(d_long),
            "family": noise.family,
            "width": noise.width,
            # and under the family's name for it: sigma_h for the Gaussian
            **({family.width_name: noise.width} if family.has_width else {}),
            "sigma_c": dict(zip(CHANNELS, map(float, noise.sigma_c), strict=True)),
            "sigma_n": dict(zip(CHANNELS, map(float, noise.sigma_n), strict=True)),
            "conversion": conversion or robot.conversion,
            "command": {"v": command.v, "w": command.w, "duration": command.duration},
        },
        truth_arrays=truth_arrays,
        provenance={"simulated": True, "robot": robot.name, "profile": robot.source},
    )


def simulate_series(
    robot: RobotProfile,
    d_lat: float,
    d_long: float,
    counts: dict[str, int],
    noise: NoiseSettings | None = None,
    rng: np.random.Generator | int | None = None,
    conversion: str | None = None,
) -> list[Experiment]:
    """Simulate several experiments per series, as the thesis' 10 x v1 + 5 x v2.

    The parameters not listed here are those of :func:`simulate_experiment`.

    Parameters
    ----------
    counts : dict of str to int
        Number of runs per series, e.g. ``{"v1": 10, "v2": 5}``; runs are
        named ``v1_01``, ``v1_02``, ...
    rng : numpy.random.Generator, int or None
        Each run gets an independent child generator of this one.

    Examples
    --------
    >>> from bayes_jackal.model import load_profile
    >>> from bayes_jackal.io import simulate_series
    >>> runs = simulate_series(load_profile(), 110.0, 30.0, {"v1": 2, "v2": 1}, rng=1)
    >>> [(run.name, run.series) for run in runs]
    [('v1_01', 'v1'), ('v1_02', 'v1'), ('v2_01', 'v2')]
    """
    total = sum(counts.values())
    children = iter(as_rng(rng).spawn(total))
    return [
        simulate_experiment(
            robot, d_lat, d_long, series, noise, next(children), f"{series}_{i:02d}", conversion
        )
        for series, count in counts.items()
        for i in range(1, count + 1)
    ]
