"""Channels held on a faster clock: a slow sensor's last value repeated on every row.

A ROS logger that writes one row per tick of its own clock (the DRIVE
calibration dataset's layout: 20 Hz rows) writes each slow topic's last
message again on every row until the next one arrives: lidar-ICP poses at
4-5 Hz, wheel encoders at ~4 Hz. Such a column group repeats its values
*exactly* in runs of consecutive rows, and the run lengths say the sensor's
rate. :func:`held_channel` detects it, and says where the sensor's own
samples are (:class:`HeldChannel`).

The rule (constants below): a column group's rows fall into runs of equal
values. The runs that count are those while the robot moves: not the first
and the last (the log's ends cut them), nor, for a rate (a wheel speed, the
yaw rate, a velocity), a run of zeros (at rest a rate repeats for a real
reason). The group is held when at least :data:`HELD_MIN_RUNS` runs count,
their median length is at least :data:`HELD_MIN_LENGTH` rows (the sensor at
most half the rows' rate), their lengths are regular (an interquartile
range of at most :data:`HELD_SPREAD` times the median: a sensor's clock, not
the random repeats of a quantised encoder), and the rate they say (the
rows' rate over the mean length) is a sensor's (at least the slowest of
:data:`~bayes_jackal.io.PLAUSIBLE_RATES`, 1 Hz: a setpoint held for
seconds is no sensor).

Each run after the first starts with a new message, which arrived between
the previous row and its own: it is placed at their midpoint, uncertain by
half a row step. When the midpoints lie on a grid of the sensor's own
(:func:`bayes_jackal.io.uniform_clock`'s rule 3: within a quarter of the
sensor's step of its ticks, a lost message a gap) and that clock keeps each
within a row step of its midpoint (half a step for the arrival within its
rows, half for the sensor's own jitter), the clock's times are used
instead: a least-squares clock through K midpoints averages their errors
(measured: sd 2 ms against the midpoints' 14 ms for a 4.44 Hz sensor on
20 Hz rows), and their scatter about the midpoints is reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._runtime import DataError
from .stamps import GRID, PLAUSIBLE_RATES, UNIFORM, uniform_clock

__all__ = [
    "HELD_MIN_LENGTH",
    "HELD_MIN_RUNS",
    "HELD_SPREAD",
    "MIDPOINT",
    "SENSOR_CLOCK",
    "HeldChannel",
    "held_channel",
]

#: Fewest runs, while the robot moves, that tell a held channel (fewer: the
#: log is too short, or at rest, to tell).
HELD_MIN_RUNS = 10
#: Least median run length [rows]: the sensor runs at most at half the rows' rate.
HELD_MIN_LENGTH = 2
#: Largest interquartile range of the run lengths, relative to their median:
#: a 4.4 Hz sensor on 20 Hz rows has runs of 4 and 5 rows (range 1 of
#: median 4), a quantised encoder's repeats are geometric (range >= median).
HELD_SPREAD = 0.5
#: Placements of a held channel's samples (``HeldChannel.placement``).
MIDPOINT, SENSOR_CLOCK = "midpoint", "sensor clock"


@dataclass(frozen=True)
class HeldChannel:
    """A column group held on faster rows, and the samples its sensor took.

    Attributes
    ----------
    changes : ndarray of int, shape (K,)
        The rows (indices into the group's rows, in time order) where a new
        value starts: the sensor's messages after the first row.
    times : ndarray, shape (K,)
        When each arrived [s]: the midpoint between the row before and its
        row, or the sensor's fitted clock (``placement``).
    placement : {"midpoint", "sensor clock"}
    rate : float
        The sensor's rate [Hz]: its clock's, or the rows' rate over the mean
        run length.
    row_rate : float
        The rows' rate [Hz] (their median step).
    runs : ndarray of int
        Lengths of the runs that count (while the robot moves) [rows].
    uncertainty : float
        Half the largest row step around a change [s]: how far a midpoint
        may be from the arrival.
    scatter : float, optional
        The sd of the sensor clock's times about the midpoints [s]; None
        for midpoints.

    Examples
    --------
    A 4 Hz sensor written on 20 Hz rows: each value on 5 rows.

    >>> import numpy as np
    >>> from bayes_jackal.io import held_channel
    >>> t = np.arange(200) / 20
    >>> values = 0.3 * np.floor(4 * t) + 1.0  # a new value every 0.25 s
    >>> held = held_channel(t, values)
    >>> round(held.rate, 6), held.placement, held.times[:2].round(6).tolist()
    (4.0, 'sensor clock', [0.225, 0.475])
    >>> print(held.describe("omega_r"))
    omega_r: held on the 20 Hz rows in runs of 5 rows (5-5): a 4 Hz sensor, read as its 39
    samples at its own clock (scatter 0.0 ms about the midpoints)
    """

    changes: np.ndarray
    times: np.ndarray
    placement: str
    rate: float
    row_rate: float
    runs: np.ndarray
    uncertainty: float
    scatter: float | None = None

    @property
    def provenance(self) -> dict:
        """What was detected and how its samples were placed (JSON-ready)."""
        described = {
            "rate": self.rate,
            "row_rate": self.row_rate,
            "run_length": {
                "median": float(np.median(self.runs)),
                "min": int(self.runs.min()),
                "max": int(self.runs.max()),
            },
            "samples": len(self.changes),
            "placement": self.placement,
            "stamp_uncertainty": self.uncertainty,
        }
        if self.scatter is not None:
            described["scatter"] = self.scatter
        return described

    def describe(self, label: str) -> str:
        """One sentence on the held group ``label`` (for repairs and warnings)."""
        where = (
            f"at its own clock (scatter {1e3 * self.scatter:.1f} ms about the midpoints)"
            if self.scatter is not None
            else f"each midway between the row before and its own (+-{self.uncertainty:.3g} s)"
        )
        return (
            f"{label}: held on the {self.row_rate:.4g} Hz rows in runs of "
            f"{np.median(self.runs):g} rows ({self.runs.min()}-{self.runs.max()}): a "
            f"{self.rate:.3g} Hz sensor, read as its {len(self.changes)} samples {where}"
        )

    def series(self, t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sensor's samples to interpolate between: times [s] and values.

        One per message (:attr:`times`), the first row's value at the first
        row, and the last row's at the last; a value held for longer than two
        median runs (at rest, a stop) also at the last row it was held: it
        was measured throughout.

        Parameters
        ----------
        t : ndarray, shape (n,)
            The group's row times [s] (as given to :func:`held_channel`).
        values : ndarray, shape (n,) or (n, m)
            The group's rows.
        """
        starts = np.concatenate([[0], self.changes])
        stops = np.concatenate([self.changes, [len(t)]])
        arrivals = np.concatenate([t[:1], self.times])
        long = np.flatnonzero(stops - starts > 2 * np.median(self.runs))
        long = np.union1d(long, [len(starts) - 1])
        times = np.concatenate([arrivals, t[stops[long] - 1]])
        samples = np.concatenate([values[starts], values[starts[long]]])
        order = np.argsort(times, kind="stable")
        keep = np.concatenate([[True], np.diff(times[order]) > 0])
        return times[order][keep], samples[order][keep]


def held_channel(
    t: np.ndarray, values: np.ndarray, *, rest_is_zero: bool = True
) -> HeldChannel | None:
    """Whether a column group is a slower sensor held on its rows (the rule of the module text).

    Parameters
    ----------
    t : ndarray, shape (n,)
        The group's row times [s], increasing.
    values : ndarray, shape (n,) or (n, m)
        Its values, a row per time.
    rest_is_zero : bool
        Whether runs of zeros are the robot at rest (rates), left out of
        the count; False for poses.

    Returns
    -------
    HeldChannel or None
        None when the group is not held.

    Examples
    --------
    Noisy values at the rows' rate repeat nowhere; zeros at rest do not count:

    >>> import numpy as np
    >>> from bayes_jackal.io import held_channel
    >>> t = np.arange(400) / 20
    >>> print(held_channel(t, np.random.default_rng(1).normal(size=400)))
    None
    >>> print(held_channel(t, np.where(t < 10, 0.0, 1.0)))
    None
    """
    values = np.asarray(values, float)
    rows = values[:, None] if values.ndim == 1 else values
    if len(rows) < 3:
        return None
    new = np.concatenate([[True], (rows[1:] != rows[:-1]).any(axis=1)])
    starts = np.flatnonzero(new)
    lengths = np.diff(np.concatenate([starts, [len(rows)]]))
    counts = np.ones(len(starts), bool)
    counts[[0, -1]] = False  # cut by the log's ends
    if rest_is_zero:
        counts &= (rows[starts] != 0).any(axis=1)
    runs = lengths[counts]
    if len(runs) < HELD_MIN_RUNS:
        return None
    median = float(np.median(runs))
    low, high = np.percentile(runs, [25, 75])
    step = float(np.median(np.diff(t)))
    rate = 1.0 / (float(np.mean(runs)) * step)
    if median < HELD_MIN_LENGTH or high - low > HELD_SPREAD * median or rate < PLAUSIBLE_RATES[0]:
        return None
    changes = starts[1:]
    midpoints = 0.5 * (t[changes - 1] + t[changes])
    half = 0.5 * (t[changes] - t[changes - 1])
    times, scatter, clock_rate = _sensor_clock(midpoints, half)
    return HeldChannel(
        changes=changes,
        times=midpoints if times is None else times,
        placement=MIDPOINT if times is None else SENSOR_CLOCK,
        rate=rate if clock_rate is None else clock_rate,
        row_rate=1.0 / step,
        runs=runs,
        uncertainty=float(half.max()),
        scatter=scatter,
    )


def _sensor_clock(
    midpoints: np.ndarray, half: np.ndarray
) -> tuple[np.ndarray | None, float | None, float | None]:
    """The sensor's own clock at its messages, if a grid keeps each within ``2 half`` [s].

    (times [s], their sd about the midpoints [s], the clock's rate [Hz]), or Nones.
    """
    try:
        clock = uniform_clock(midpoints, max_gap=float(midpoints[-1] - midpoints[0]))
    except DataError:
        return None, None, None
    if clock.provenance["clock"] not in (GRID, UNIFORM) or len(clock.rows) != len(midpoints):
        return None, None, None
    times = clock.t[clock.ticks]
    deviation = times - midpoints[clock.rows]
    if (np.abs(deviation) > 2 * half[clock.rows]).any():
        return None, None, None
    placed = np.empty_like(midpoints)
    placed[clock.rows] = times
    return placed, float(np.std(deviation)), float(clock.provenance["rate"])
