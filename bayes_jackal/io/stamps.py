"""Time stamps: from what real logs record to the uniform clock the model needs.

Every analysis assumes uniform sampling (the model is discretised with one
step dt, thesis eq. 6-5/6-6). Real logs are rarely that clean: simulators
and drivers stamp messages late or early by a tick or two, messages arrive
out of order or twice, and some go missing. :func:`uniform_clock` decides,
by the rules of docs/design.md §2.1, which uniform clock the recorded stamps belong to, and
reports what it did; :func:`sort_stamps` is the sorting and de-duplication
that the bag reader (:mod:`bayes_jackal.io.bags`) and the array readers share.

The rules of :func:`uniform_clock` (1. rate and origin, 2. sorting, 3. a
grid with gaps filled or cut, 4. one sample per tick of a jittered clock,
5. otherwise an error) are docs/design.md §2.1; the code cites them by number.
Stamps within :data:`UNIFORM_TOLERANCE` steps of the clock, with nothing
sorted, dropped or filled, are uniform: no repair is listed. Everything
else is described in ``UniformClock.repairs`` and ``UniformClock.provenance``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._runtime import MAX_GAP_STEPS, DataError, positive_number

__all__ = [
    "GRID",
    "GRID_TOLERANCE",
    "MAX_JITTER_FRACTION",
    "MAX_JITTER_STEPS",
    "MAX_TICKS",
    "MIN_SAMPLES",
    "ONE_PER_TICK",
    "PLAUSIBLE_RATES",
    "UNIFORM",
    "UNIFORM_TOLERANCE",
    "UniformClock",
    "hold_values",
    "longest_run",
    "sort_stamps",
    "uniform_clock",
]

#: Fewest samples an experiment may have (one-step residuals need two).
MIN_SAMPLES = 3
#: Deviation from the clock [steps] below which stamps count as uniform.
UNIFORM_TOLERANCE = 0.01
#: Largest deviation of a stamp from its tick on a clock with gaps [steps].
GRID_TOLERANCE = 0.25
#: Largest deviation of a jittered stamp from its tick [steps] ...
MAX_JITTER_STEPS = 5.0
#: ... and as a fraction of the run's duration.
MAX_JITTER_FRACTION = 0.01
#: Largest drift [steps] between a declared and the fitted clock over the run.
MAX_DRIFT_STEPS = 0.5
#: Float floor of the stamps' scatter [steps] when rounding rate and origin.
FLOAT_FLOOR = 1e-9
#: Most steps a stamp may lie from the run's median stamp: a double holds
#: whole numbers exactly up to 2^53, so beyond it no clock tells a tick from
#: its neighbours (and the clock's sums overflow near 1e308 s).
MAX_TICKS = 2.0**53
#: Sample rates [Hz] a robot's or a sensor's log can have: a 10 Hz Husky log
#: to a 10 kHz simulator. A declared rate outside is a unit slip (0.072 Hz
#: for a 72 Hz log stamped in milliseconds), which it would otherwise confirm;
#: a value repeated more slowly is a held setpoint, not a sensor's
#: (:mod:`bayes_jackal.io.held`).
PLAUSIBLE_RATES = (1.0, 10_000.0)
#: Names of the clocks in the provenance (``time_base["clock"]``).
ONE_PER_TICK, GRID, UNIFORM = "one sample per tick", "grid", "uniform"


@dataclass(frozen=True)
class UniformClock:
    """A uniform clock for a series of samples, and how the samples map onto it.

    Attributes
    ----------
    t : ndarray, shape (M,)
        Uniform sample times t0 + k dt [s].
    rows : ndarray of int, shape (K,)
        The input samples kept, in time order (indices into the input).
    ticks : ndarray of int, shape (K,)
        The tick (index into ``t``) of each kept sample.
    provenance : dict
        ``rate`` [Hz], ``rate_source``, ``fitted_rate`` [Hz], ``t0`` [s],
        ``clock`` (``"uniform"``, ``"grid"`` (rule 3, gaps or not) or ``"one
        sample per tick"``), ``jitter`` of the samples kept (``sd``, ``max``
        [s], ``sd_steps``, ``max_steps``, and ``repeated``, ``backward``:
        the input stamps over the kept span equal to an earlier one, and
        the backward steps among them in file order), ``samples_in`` (input
        samples), ``samples`` (on the clock), ``interpolated`` (ticks
        filled) and ``dropped`` (input samples not kept: repeated stamps
        and pieces cut off at long gaps).
    repairs : list of str
        Every change to the stamps, in words.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.io import uniform_clock
    >>> clock = uniform_clock(np.delete(np.arange(6) / 100, 2))  # 100 Hz, one sample lost
    >>> clock.ticks.tolist(), clock.resample([0.0, 1.0, 3.0, 4.0, 5.0]).tolist()
    ([0, 1, 3, 4, 5], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    """

    t: np.ndarray
    rows: np.ndarray
    ticks: np.ndarray
    provenance: dict = field(default_factory=dict)
    repairs: list[str] = field(default_factory=list)

    def resample(self, values: np.ndarray) -> np.ndarray:
        """Input values (one per input sample) on the clock.

        Kept samples keep their values exactly; missing ticks are linearly
        interpolated between their neighbours.
        """
        kept = np.asarray(values, float)[self.rows]
        if len(kept) == len(self.t):
            return kept
        return np.interp(np.arange(len(self.t)), self.ticks, kept)

    @property
    def measured(self) -> np.ndarray:
        """Which ticks hold a sample of their own, shape (M,): False where one was filled.

        A filled tick (rule 3) is an interpolation, not a measurement: a
        reader marks it unmeasured for the fields the sensor measured
        (:attr:`bayes_jackal.io.Experiment.measured`).

        Examples
        --------
        >>> import numpy as np
        >>> from bayes_jackal.io import uniform_clock
        >>> uniform_clock(np.delete(np.arange(6) / 100, 2)).measured.tolist()
        [True, True, False, True, True, True]
        """
        mask = np.zeros(len(self.t), bool)
        mask[self.ticks] = True
        return mask


@dataclass(frozen=True)
class _Fit:
    """A clock fitted to stamps (rule 1): step, origin and the stamps' deviation from it."""

    step: float
    fitted_step: float
    rate_source: str
    origin: float
    whole_origin: int | None
    drift: float
    deviation: np.ndarray

    def times(self, ticks: np.ndarray) -> np.ndarray:
        """The clock's times at ``ticks`` [s]."""
        return _times(self.step, self.origin, self.whole_origin, ticks)

    def worst(self) -> int:
        """Index of the stamp farthest from the clock."""
        return int(np.argmax(np.abs(self.deviation)))


def _times(step: float, origin: float, whole_origin: int | None, ticks: np.ndarray) -> np.ndarray:
    if whole_origin is not None:
        return (whole_origin + ticks) * step
    return origin + ticks * step


def _fit_clock(t: np.ndarray, ticks: np.ndarray, step: float | None) -> _Fit | None:
    """Least-squares clock through stamps ``t`` at ``ticks``; None if it does not advance."""
    centred = ticks - ticks.mean()
    fitted = float(centred @ (t - t.mean()) / (centred @ centred))
    if not fitted > 0:
        return None
    scatter = float(np.std(t - t.mean() - fitted * centred))
    span = float(ticks[-1] - ticks[0])
    source = "declared"
    if step is None:
        whole = round(1.0 / fitted)
        if whole >= 1 and span * abs(fitted - 1.0 / whole) <= max(scatter, FLOAT_FLOOR * fitted):
            step, source = 1.0 / whole, "fitted, whole Hz"
        else:
            step, source = fitted, "fitted"
    origin = float(np.mean(t - ticks * step))
    whole_origin = round(origin / step)
    if abs(origin - whole_origin * step) > max(scatter, FLOAT_FLOOR * step):
        whole_origin = None
    return _Fit(
        step=step,
        fitted_step=fitted,
        rate_source=source,
        origin=origin,
        whole_origin=whole_origin,
        drift=span * (fitted - step) / step,
        deviation=t - _times(step, origin, whole_origin, ticks),
    )


def sort_stamps(
    stamps: np.ndarray,
    *,
    max_backstep: float,
    where: Callable[[int], str],
    source: str,
    field: str,
    label: str,
    unit: float = 1.0,
) -> tuple[np.ndarray, list[str]]:
    """Order that sorts stamps and drops repeated ones (rule 2; bags and arrays).

    Parameters
    ----------
    stamps : ndarray, shape (N,)
        Stamps in recording order, in any unit (``unit`` seconds each).
    max_backstep : float
        Largest backward step [stamp units] taken as out-of-order delivery;
        a longer one is a clock jump and an error.
    where : callable
        Describes input sample i for messages, e.g. ``"line 9"``.
    source, field : str
        File and field named in errors.
    label : str
        Prefix of the repair texts (the topic or column).
    unit : float
        Seconds per stamp unit (1e-9 for nanoseconds).

    Returns
    -------
    order : ndarray of int
        Indices of the samples kept, in time order (the first of each
        repeated stamp is kept).
    repairs : list of str

    Examples
    --------
    Millisecond stamps, one delivered late and one repeated:

    >>> import numpy as np
    >>> from bayes_jackal.io import sort_stamps
    >>> stamps = np.array([0, 10, 30, 20, 40, 40, 50])
    >>> order, repairs = sort_stamps(stamps, max_backstep=15, where=str, source="run.bag",
    ...                              field="stamp", label="/imu", unit=1e-3)
    >>> stamps[order].tolist(), repairs[0]
    ([0, 10, 20, 30, 40, 50], '/imu: 1 out-of-order stamps; sorted')
    """
    steps = np.diff(stamps)
    jumps = np.flatnonzero(steps < -max_backstep)
    if jumps.size:
        i = int(jumps[0]) + 1
        raise DataError(
            f"timestamps go backwards by {_seconds(-steps[i - 1] * unit)} s at {where(i)} (more "
            f"than max_gap {max_backstep * unit:g} s: a clock jump)",
            source=source,
            field=field,
        )
    repairs = []
    order = np.arange(len(stamps))
    backward = int((steps < 0).sum())
    if backward:
        order = np.argsort(stamps, kind="stable")
        reverse = " (in reverse time order throughout)" if not (steps > 0).any() else ""
        repairs.append(f"{label}: {backward} out-of-order stamps{reverse}; sorted")
    repeated = np.flatnonzero(np.diff(stamps[order]) == 0) + 1
    if repeated.size:
        repairs.append(
            f"{label}: {repeated.size} duplicate stamps (first at "
            f"{where(int(order[repeated[0]]))}); kept the first message of each"
        )
        order = np.delete(order, repeated)
    return order, repairs


def _seconds(value: float) -> str:
    """A duration [s] in messages: to the millisecond, in 4 significant digits when huge."""
    return f"{value:.3f}" if abs(value) < 1e6 else f"{value:.4g}"


def _check_span(
    t: np.ndarray, step: float, source: str, row_name: Callable[[int], str], field: str
) -> None:
    """Refuse the first stamp more than :data:`MAX_TICKS` steps from the median stamp.

    Such a stamp (a corrupt one, 1e308 s) is a clock jump no clock can
    hold: fitting one through it would overflow.
    """
    centre, limit = float(np.median(t)), MAX_TICKS * step
    with np.errstate(over="ignore"):
        distance = np.abs(t - centre)
    far = np.flatnonzero(~(distance <= limit))
    if far.size:
        i = int(far[0])
        raise DataError(
            f"a clock jump at {row_name(i)}: {field} = {t[i]:.4g} s, {distance[i]:.4g} s from "
            f"the median stamp {centre:.6g} s, beyond the {limit:.4g} s (2^53 steps of "
            f"{step:.4g} s) a clock resolves",
            source=source,
            field=field,
        )


def longest_run(mask: np.ndarray) -> tuple[int, int]:
    """Start and stop index of the longest run of True in ``mask`` ((0, 0) if none).

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.io import longest_run
    >>> longest_run(np.array([True, False, True, True, True, False]))
    (2, 5)
    """
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    if not starts.size:
        return 0, 0
    longest = int(np.argmax(stops - starts))
    return int(starts[longest]), int(stops[longest])


def hold_values(
    stamps: np.ndarray, values: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Values held from each stamp to the next (a zero-order hold), at times ``t``.

    A command is followed until the next one: its value at a time is the
    last one stamped at or before it.

    Parameters
    ----------
    stamps : ndarray, shape (n,)
        Increasing stamps of the values [s].
    values : ndarray, shape (n, ...)
        A value per stamp.
    t : ndarray, shape (M,)
        Where the values are wanted [s].

    Returns
    -------
    held : ndarray, shape (M, ...)
        The last value at or before each time (before the first stamp: the first value).
    after : ndarray of bool, shape (M,)
        Whether a value had been stamped by then.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.io import hold_values
    >>> held, after = hold_values(np.array([0.5, 1.0]), np.array([2.0, 3.0]), np.arange(4) / 2)
    >>> held.tolist(), after.tolist()
    ([2.0, 2.0, 3.0, 3.0], [False, True, True, True])
    """
    last = np.searchsorted(stamps, t, side="right") - 1
    return np.asarray(values)[np.maximum(last, 0)], last >= 0


def uniform_clock(
    t: np.ndarray,
    *,
    rate: float | None = None,
    max_gap: float | None = None,
    source: str = "<memory>",
    row_name: Callable[[int], str] = lambda i: f"sample {i}",
    field: str = "t",
) -> UniformClock:
    """The uniform clock of recorded stamps, by the rules of docs/design.md §2.1.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Finite stamps [s] in file order.
    rate : float, optional
        Declared sampling rate [Hz]; detected when omitted.
    max_gap : float, optional
        Longest gap [s] filled by interpolation; longer gaps split the series,
        and a longer backward step is a clock jump. Default
        :data:`MAX_GAP_STEPS` nominal steps.
    source : str
        File named in errors.
    row_name : callable
        Names input sample i in messages, e.g. ``lambda i: f"line {i + 2}"``.
    field : str
        Name of the time column (errors and repairs).

    Returns
    -------
    UniformClock

    Raises
    ------
    DataError
        Where no uniform clock fits (naming the line and the stamp), on a
        clock jump, or when fewer than :data:`MIN_SAMPLES` samples remain.
    InputError
        When ``rate`` or ``max_gap`` is not a positive number.

    Examples
    --------
    A 1 kHz simulator's stamps, each up to two ticks early or late (rule 4),
    and 100 Hz stamps with a repeated one and a lost one (rule 3):

    >>> import numpy as np
    >>> from bayes_jackal.io import uniform_clock
    >>> late = np.random.default_rng(1).integers(-2, 3, 1000)
    >>> clock = uniform_clock((np.arange(1000) + late) / 1000)
    >>> clock.provenance["clock"], clock.provenance["rate"], len(clock.t)
    ('one sample per tick', 1000.0, 1000)
    >>> clock = uniform_clock(np.array([0.0, 0.01, 0.02, 0.02, 0.03, 0.05, 0.06]))
    >>> clock.provenance["clock"], clock.provenance["dropped"], clock.provenance["interpolated"]
    ('grid', 1, 1)
    """
    t = np.asarray(t, float)
    declared = positive_number(rate, name="rate", unit="Hz")
    declared = None if declared is None else 1.0 / declared
    max_gap = positive_number(max_gap, name="max_gap", unit="s")
    distinct = np.unique(t)
    if len(distinct) < MIN_SAMPLES:
        raise DataError(
            f"only {len(distinct)} distinct stamps; at least {MIN_SAMPLES} are needed",
            source=source,
            field=field,
        )
    nominal = declared or float(np.median(np.diff(distinct)))
    _check_span(t, nominal, source, row_name, field)
    steps = np.diff(t)
    increasing = bool((steps > 0).all())
    one, one_fits = _one_per_tick(t, declared)

    def jittered() -> UniformClock:
        return _clock(t, np.arange(len(t)), np.arange(len(t)), one, [], field, ONE_PER_TICK)

    max_gap = max_gap if max_gap is not None else MAX_GAP_STEPS * nominal
    try:
        order, repairs = sort_stamps(
            t, max_backstep=max_gap, where=row_name, source=source, field=field, label=field
        )
    except DataError:
        if one_fits:
            return jittered()
        raise
    grid = _on_grid(t[order], declared)
    if isinstance(grid, _Grid) and (increasing or not one_fits or grid.gapless):
        return _grid_clock(t, order, grid, max_gap, repairs, source, row_name, field)
    if one_fits:
        return jittered()
    index, where = grid
    advice = (
        "check the declared rate, or resample the series onto a uniform clock first"
        if declared
        else "if the rate is known, declare it (--rate HZ; rate= in Python), or resample the "
        "series onto a uniform clock first"
    )
    raise DataError(
        f"time is not uniformly sampled at {row_name(int(order[index]))}: {where}; "
        f"{_one_per_tick_text(one, declared, len(t))}; {advice}",
        source=source,
        field=field,
    )


def _jitter_limit(samples: int) -> float:
    """Largest deviation [steps] of one sample per tick (rule 4)."""
    return min(MAX_JITTER_STEPS, MAX_JITTER_FRACTION * (samples - 1))


def _one_per_tick(t: np.ndarray, step: float | None) -> tuple[_Fit | None, bool]:
    """Rule 4: the clock with sample k at tick k, and whether it fits."""
    fit = _fit_clock(t, np.arange(len(t), dtype=float), step)
    fits = (
        fit is not None
        and abs(fit.drift) <= MAX_DRIFT_STEPS
        and float(np.abs(fit.deviation).max()) <= _jitter_limit(len(t)) * fit.step
    )
    return fit, fits


def _one_per_tick_text(fit: _Fit | None, declared: float | None, samples: int) -> str:
    """Why one sample per tick does not fit either (for the error)."""
    if fit is None:
        return "the stamps do not advance"
    text = (
        f"as one sample per tick they stray up to {np.abs(fit.deviation).max() / fit.step:.3g} "
        f"steps from a {1 / fit.step:.6g} Hz clock (limit {_jitter_limit(samples):.3g})"
    )
    if declared:
        text += (
            f" and their own rate, {1 / fit.fitted_step:.6g} Hz, drifts {fit.drift:+.3g} steps "
            f"from the declared {1 / declared:.6g} Hz over the run (limit {MAX_DRIFT_STEPS:g})"
        )
    return f"no uniform clock fits these stamps: {text}"


@dataclass(frozen=True)
class _Grid:
    """Sorted distinct stamps on a clock: the fit and each stamp's tick."""

    fit: _Fit
    ticks: np.ndarray

    @property
    def gapless(self) -> bool:
        return bool(self.ticks[-1] == len(self.ticks) - 1)


def _on_grid(stamps: np.ndarray, declared: float | None) -> _Grid | tuple[int, str]:
    """Rule 3 on sorted distinct stamps: the clock and ticks, or (index, why not)."""
    steps = np.diff(stamps)
    nominal = declared or float(np.median(steps))
    count = np.rint(steps / nominal)
    close = np.flatnonzero(count < 1)
    if close.size:
        i = int(close[0]) + 1
        return i, (
            f"t = {stamps[i]:.10g} s follows {stamps[i - 1]:.10g} s by {steps[i - 1]:.3g} s, "
            f"less than half the {nominal:.6g} s step"
        )
    ticks = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    fit = _fit_clock(stamps, ticks.astype(float), declared)
    if np.abs(fit.deviation).max() > GRID_TOLERANCE * fit.step:
        i = fit.worst()
        return i, (
            f"t = {stamps[i]:.10g} s is {fit.deviation[i] / fit.step:+.2f} steps off the nearest "
            f"tick of a {1 / fit.step:.6g} Hz clock (limit {GRID_TOLERANCE:g})"
        )
    return _Grid(fit, ticks)


def _grid_clock(
    t: np.ndarray,
    order: np.ndarray,
    grid: _Grid,
    max_gap: float,
    repairs: list[str],
    source: str,
    row_name: Callable[[int], str],
    field: str,
) -> UniformClock:
    """Rule 3: keep the longest piece between gaps > max_gap; fill shorter gaps."""
    stamps, ticks, fit = t[order], grid.ticks, grid.fit
    steps = np.diff(stamps)
    long = np.flatnonzero(steps > max_gap)
    starts = np.concatenate([[0], long + 1])
    stops = np.concatenate([long + 1, [len(stamps)]])
    piece = int(np.argmax(ticks[stops - 1] - ticks[starts]))
    start, stop = int(starts[piece]), int(stops[piece])
    repairs = list(repairs)
    for i in long:
        repairs.append(
            f"{field}: gap of {steps[i]:.6g} s ({ticks[i + 1] - ticks[i]} steps) after "
            f"{row_name(int(order[i]))} (t = {stamps[i]:.10g} s), longer than max_gap "
            f"{max_gap:.6g} s"
        )
    if stop - start < MIN_SAMPLES:
        raise DataError(
            f"no stretch of {MIN_SAMPLES} samples without a gap longer than max_gap "
            f"{max_gap:.6g} s ({len(long)} such gaps)",
            source=source,
            field=field,
        )
    if long.size:
        repairs.append(
            f"{field}: series cut at gaps to {row_name(int(order[start]))} .. "
            f"{row_name(int(order[stop - 1]))} (t = {stamps[start]:.10g} .. "
            f"{stamps[stop - 1]:.10g} s), the longest piece; was {stamps[0]:.10g} .. "
            f"{stamps[-1]:.10g} s"
        )
    kept = ticks[start:stop]
    missing = np.diff(kept) - 1
    if missing.any():
        first = start + int(np.flatnonzero(missing)[0])
        gaps = np.count_nonzero(missing)
        repairs.append(
            f"{field}: {gaps} gap{'s' if gaps > 1 else ''} of at most {missing.max() + 1} "
            f"steps filled with {missing.sum()} linearly interpolated samples (the first after "
            f"{row_name(int(order[first]))}, t = {stamps[first]:.10g} s)"
        )
    return _clock(
        t,
        order[start:stop],
        kept - kept[0],
        fit,
        repairs,
        field,
        GRID,
        kept[0],
        slice(start, stop),
    )


def _clock(
    t: np.ndarray,
    rows: np.ndarray,
    ticks: np.ndarray,
    fit: _Fit,
    repairs: list[str],
    field: str,
    kind: str,
    origin: int = 0,
    piece: slice = slice(None),
) -> UniformClock:
    """The clock's times over ``ticks``, with the jitter and every repair described.

    The jitter covers the samples kept: ``fit.deviation[piece]`` and the
    input stamps within the kept span (``rows`` of ``t``), in file order.
    """
    kept = t[rows]
    within = t[(t >= kept.min()) & (t <= kept.max())]
    steps = np.diff(within)
    deviation = fit.deviation[piece]
    rate = 1.0 / fit.step
    jitter = {
        "sd": float(np.std(deviation)),
        "max": float(np.abs(deviation).max()),
        "sd_steps": float(np.std(deviation) / fit.step),
        "max_steps": float(np.abs(deviation).max() / fit.step),
        "repeated": len(within) - len(np.unique(within)),
        "backward": int(np.count_nonzero(steps < 0)),
    }
    if jitter["max_steps"] > UNIFORM_TOLERANCE:
        counts = (
            f"; {jitter['repeated']} repeated and {jitter['backward']} backward stamps, steps "
            f"{steps.min():.6g} .. {steps.max():.6g} s; one sample per tick, values kept"
            if kind == ONE_PER_TICK
            else ""
        )
        repairs = [
            *repairs,
            f"{field}: stamps jittered around a uniform {rate:.6g} Hz clock (sd "
            f"{jitter['sd']:.3g} s, largest deviation {jitter['max']:.3g} s = "
            f"{jitter['max_steps']:.3g} steps{counts}); replaced by t0 + k / {rate:.6g} Hz",
        ]
    elif not repairs and len(rows) == len(t) and ticks[-1] == len(t) - 1:
        kind = UNIFORM
    times = fit.times(origin + np.arange(int(ticks[-1]) + 1, dtype=float))
    provenance = {
        "clock": kind,
        "rate": rate,
        "rate_source": fit.rate_source,
        "fitted_rate": 1.0 / fit.fitted_step,
        "t0": float(times[0]),
        "jitter": jitter,
        "samples_in": len(t),
        "samples": len(times),
        "interpolated": len(times) - len(rows),
        "dropped": len(t) - len(rows),
    }
    return UniformClock(times, rows, ticks, provenance, repairs)
