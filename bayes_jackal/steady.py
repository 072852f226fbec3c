"""Steady-state cornering windows: where the wheel speeds are held and the yaw rate has settled.

:func:`detect_steady` finds the window that :func:`bayes_jackal.bags.read_bag`
uses unless one is given; :func:`steady_smoothing` is its smoothing, shared
with the steadiness check of model criticism
(:func:`bayes_jackal.criticism_statistics.steadiness`), whose tolerances are
the ``STEADY_*`` constants here.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from .stamps import longest_run

__all__ = [
    "STEADY_INPUT_TOLERANCE",
    "STEADY_MIN_DURATION",
    "STEADY_SMOOTHING",
    "STEADY_YAW_FLOOR",
    "STEADY_YAW_TOLERANCE",
    "detect_steady",
    "steady_smoothing",
]

#: Steady-state rule (:func:`detect_steady`): moving-average length [s],
#: relative tolerances on the wheel speeds and the yaw rate, the yaw-rate
#: tolerance floor [rad/s] and the shortest steady window [s].
STEADY_SMOOTHING = 0.25
STEADY_INPUT_TOLERANCE = 0.05
STEADY_YAW_TOLERANCE = 0.1
STEADY_YAW_FLOOR = 0.01
STEADY_MIN_DURATION = 1.0


def steady_smoothing(
    t: np.ndarray, yaw_rate: np.ndarray, inputs: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Wheel speeds and yaw rate smoothed as by the steady rule (:data:`STEADY_SMOOTHING`).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times [s].
    yaw_rate : ndarray, shape (N,)
        Yaw rate [rad/s].
    inputs : ndarray, shape (N, 2)
        Wheel speeds [rad/s].

    Returns
    -------
    inputs, yaw_rate : ndarray, shapes (N, 2) and (N,)
        Smoothed, same units (edges padded with the end values).
    """
    size = max(1, round(STEADY_SMOOTHING / (t[1] - t[0])))
    u = uniform_filter1d(np.asarray(inputs, float), size, axis=0, mode="nearest")
    r = uniform_filter1d(np.asarray(yaw_rate, float), size, mode="nearest")
    return u, r


def detect_steady(
    t: np.ndarray, yaw_rate: np.ndarray, inputs: np.ndarray
) -> tuple[float, float] | None:
    """Steady-state cornering window: wheel speeds constant and yaw rate settled.

    Rule (all signals first smoothed by a :data:`STEADY_SMOOTHING` moving
    average): the held input level is the median of the wheel speeds where
    the robot moves (largest wheel speed at least half its maximum); the
    input is constant where both wheel speeds are within
    :data:`STEADY_INPUT_TOLERANCE` times the largest held level of it, and
    the window is the longest such stretch. Its start is moved to where the
    yaw rate has settled: the first sample of the stretch at which the yaw
    rate is within :data:`STEADY_YAW_TOLERANCE` (relative, at least
    :data:`STEADY_YAW_FLOOR`) of its median over the stretch. Process noise
    makes the yaw rate wander by ~10 % in steady state, so "first within",
    not "stays within", is the test. The end is the input's: the yaw rate
    lags the input. Windows shorter than :data:`STEADY_MIN_DURATION` count
    as none.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times [s].
    yaw_rate : ndarray, shape (N,)
        Yaw rate [rad/s].
    inputs : ndarray, shape (N, 2)
        Wheel speeds (omega_r, omega_l) [rad/s].

    Returns
    -------
    (float, float) or None
        Start and end [s], or None when the run has no steady stretch.
    """
    u, r = steady_smoothing(t, yaw_rate, inputs)
    speed = np.abs(u).max(axis=1)
    if not speed.max() > 0:
        return None
    level = np.median(u[speed >= 0.5 * speed.max()], axis=0)
    constant = (np.abs(u - level) <= STEADY_INPUT_TOLERANCE * np.abs(level).max()).all(axis=1)
    start, stop = longest_run(constant)
    if stop - start < 2:
        return None
    settled = np.median(r[start:stop])
    tolerance = max(STEADY_YAW_TOLERANCE * abs(settled), STEADY_YAW_FLOOR)
    start += int(np.argmax(np.abs(r[start:stop] - settled) <= tolerance))
    if t[stop - 1] - t[start] < STEADY_MIN_DURATION:
        return None
    return float(t[start]), float(t[stop - 1])
