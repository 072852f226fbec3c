"""A table's sensors as streams, and the experiment they make on the clock of its samples.

A table (CSV, MATLAB) holds the samples of several sensors. Each group of
columns (:data:`GROUPS`) is one sensor's stream: the *sample* stream (the
yaw rate: its rows' stamps give the experiment's clock, by the rules of
:mod:`bayes_jackal.io.stamps`), the pose (x, y, heading and, where the file
gives one, its own time ``pose_t``), the wheel speeds, a command (``cmd_v,
cmd_w`` or ``cmd_omega_r, cmd_omega_l``), measured vx, vy and a segment
label. In a dense table every row holds every group. In a table of sparse
rows (the union of several sensors' samples, as a pandas outer join writes
it) an empty cell is "no value at this row": each group has the rows where
its cells are filled (all of its cells in a row, or none:
:mod:`bayes_jackal.io.tables` reads them). The rules, docs/design.md §2.3:

- **Placement.** A stream *on the sample rows* (each of its rows has a yaw
  rate, and it has no time of its own) is placed on those rows' ticks: a
  dense table reads as it always has. Any other stream keeps its own
  stamps, sorted and de-duplicated as a bag's topics are
  (:func:`bayes_jackal.io.sort_stamps`).
- **Yaw rate.** Each sample on its tick; a tick filled by the clock (rule
  3) is marked unmeasured (:attr:`bayes_jackal.io.Experiment.measured`).
- **vx, vy** (a velocity sensor's, without poses) must be on the sample
  rows: a tick without them is marked unmeasured (their values there are
  interpolated, for plots). At stamps of their own they are refused: the
  model measures a rate channel on the experiment's clock.
- **Pose.** A :class:`~bayes_jackal.io.PoseTrack` at its ticks (on the
  sample rows) or its own stamps, heading unwrapped, gaps as recorded;
  vx, vy are derived from it for plots where the table has none.
- **Wheel speeds** (the model's input) are interpolated linearly onto the
  clock, across its filled ticks too; from stamps of their own, the run is
  cut to the span they cover, and at a gap longer than ``max_gap`` (and
  than :data:`~bayes_jackal._runtime.defaults.MAX_GAP_STEPS` of their own
  step) to the longest piece.
- **Command.** Held onto the clock (zero-order hold: the last value at or
  before a tick); ``cmd_v, cmd_w`` become wheel speeds by the robot's
  diff-drive formula (:func:`bayes_jackal.model.wheel_speeds`). It is the
  model's input where the table has no wheel speeds, or holds them (below),
  and the run then starts at its first value.
- **Segments** (:attr:`~bayes_jackal.io.Experiment.segments`): where the
  held segment label changes (:func:`~bayes_jackal.io.label_segments`),
  else where the command steps (:func:`~bayes_jackal.io.command_segments`).
- **Held groups** (:func:`bayes_jackal.io.held_channel`: a slower sensor's
  values repeated on faster rows). A held pose is its sensor's poses, one
  per change, at their arrival times; held wheel speeds give way to the
  command where there is one, and are otherwise interpolated between the
  sensor's samples (transients shorter than its step are lost); a held yaw
  rate, vx or vy is measured only at the ticks where it changes. Each is
  said in a warning and in the repairs.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._runtime import (
    MAX_GAP_STEPS,
    OPTIONAL,
    POSE_ROLES,
    POSE_TIME,
    SEGMENT,
    VELOCITIES,
    VELOCITY_COMMAND,
    WHEEL_COMMAND,
    DataError,
    InputError,
)
from ..model import RobotProfile, as_profile, wheel_speeds
from .experiment import Experiment, check_values
from .held import HeldChannel, held_channel
from .pose_track import PoseTrack, body_velocities
from .segments import MIN_HOLD, STEP_TOLERANCE, command_segments, label_segments
from .stamps import (
    MIN_SAMPLES,
    UniformClock,
    hold_values,
    longest_run,
    sort_stamps,
    uniform_clock,
)

__all__ = ["GROUPS", "TableStream", "table_experiment"]

#: A table's column groups, each one sensor's stream (all of a group's cells
#: in a row, or none).
GROUPS = {
    "sample": ("yaw_rate",),
    "velocity": OPTIONAL,
    "pose": (*POSE_ROLES, POSE_TIME),
    "wheels": ("omega_r", "omega_l"),
    "velocity command": VELOCITY_COMMAND,
    "wheel command": WHEEL_COMMAND,
    "segment": (SEGMENT,),
}
#: Groups that are commands.
COMMANDS = ("velocity command", "wheel command")
#: Groups a value of which holds until the next (a command, a label): one row is enough.
HELD_UNTIL_NEXT = (*COMMANDS, "segment")
#: The model's input: the wheel speeds [rad/s].
WHEELS = GROUPS["wheels"]
#: Slack [ticks] of the zero-order hold: a value stamped at a tick (within
#: float rounding of its time) holds from that tick.
HOLD_SLACK = 1e-6


@dataclass(frozen=True)
class TableStream:
    """One sensor's samples in a table: its rows, stamps and values by role.

    Attributes
    ----------
    rows : ndarray of int
        Where each sample is in the file: the index of its row (of the
        table's rows, or of the vectors of ``pose_t``).
    t : ndarray
        Its stamps [s].
    values : dict of str to ndarray
        By role; numbers, or text for a segment label.
    row_name : callable
        Names row ``rows[i]`` in messages (``"line 9"``, ``"index 8"``).
    own_time : bool
        Whether the stamps are a time of its own (``pose_t``), not the table's ``t``.
    """

    rows: np.ndarray
    t: np.ndarray
    values: dict[str, np.ndarray]
    row_name: Callable[[int], str]
    own_time: bool = False

    def where(self, i: int) -> str:
        """Names sample ``i`` in messages."""
        return self.row_name(int(self.rows[i]))


@dataclass(frozen=True)
class _Placed:
    """A stream against the clock, in time order: positions [ticks], times [s], values."""

    position: np.ndarray
    times: np.ndarray
    values: dict[str, np.ndarray]
    on_rows: bool
    where: Callable[[int], str]

    def stacked(self, roles: tuple[str, ...]) -> np.ndarray:
        """The values of ``roles``, a column each."""
        return np.column_stack([self.values[role] for role in roles])


@dataclass
class _Reading:
    """The clock, and what the reader says on the way: repairs, warnings, provenance."""

    clock: UniformClock
    sample: TableStream
    gap: float
    source: str
    repairs: list[str]
    provenance: dict = field(default_factory=dict)

    @property
    def step(self) -> float:
        """The clock's step [s]."""
        return 1.0 / self.clock.provenance["rate"]

    @property
    def ticks(self) -> np.ndarray:
        """The clock's ticks, 0 .. M - 1."""
        return np.arange(len(self.clock.t))

    def say(self, text: str) -> None:
        """A repair the user is told of: listed, and warned of."""
        self.repairs.append(text)
        warnings.warn(f"{self.source}: {text}", UserWarning, stacklevel=2)

    def place(self, stream: TableStream, group: str) -> _Placed:
        """The stream on the sample rows' ticks, or at its own stamps (sorted, de-duplicated)."""
        if not stream.own_time and np.isin(stream.rows, self.sample.rows).all():
            tick = np.full(int(max(stream.rows.max(), self.sample.rows.max())) + 1, -1)
            tick[self.sample.rows[self.clock.rows]] = self.clock.ticks
            at = tick[stream.rows]
            index = np.flatnonzero(at >= 0)
            index = index[np.argsort(at[index], kind="stable")]
            position, times, on_rows = at[index].astype(float), self.clock.t[at[index]], True
        else:
            index, repairs = sort_stamps(
                stream.t, max_backstep=self.gap_of(stream.t), where=stream.where,
                source=self.source, field=GROUPS[group][0], label=", ".join(stream.values),
            )  # fmt: skip
            self.repairs.extend(repairs)
            times = stream.t[index]
            position, on_rows = (times - self.clock.t[0]) / self.step, False
        return _Placed(
            position=position,
            times=times,
            values={role: values[index] for role, values in stream.values.items()},
            on_rows=on_rows,
            where=lambda i: stream.where(int(index[i])),
        )

    def gap_of(self, t: np.ndarray) -> float:
        """The longest gap [s] of stamps of their own: max_gap, and at least 5 of their steps."""
        steps = np.diff(np.unique(t))
        return max(self.gap, MAX_GAP_STEPS * float(np.median(steps)) if steps.size else 0.0)

    def held(
        self, placed: _Placed, roles: tuple[str, ...], *, rest_is_zero: bool = True
    ) -> HeldChannel | None:
        """The group held on faster rows (:func:`held_channel`), recorded; None if not."""
        held = held_channel(placed.times, placed.stacked(roles), rest_is_zero=rest_is_zero)
        if held is not None:
            self.provenance.setdefault("held", {})[", ".join(roles)] = held.provenance
        return held

    def interpolate(self, position: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Values at ``position`` [ticks] linearly interpolated onto every tick."""
        if np.array_equal(position, self.ticks):
            return values
        return np.interp(self.ticks, position, values)

    def hold(self, placed: _Placed, role: str) -> tuple[np.ndarray, np.ndarray]:
        """A stream's values held onto every tick, and where it has had a value yet."""
        return hold_values(placed.position, placed.values[role], self.ticks + HOLD_SLACK)


def table_experiment(
    streams: dict[str, TableStream],
    *,
    names: dict[str, str],
    source: str,
    format: str,
    name: str,
    series: str | None,
    rate: float | None,
    max_gap: float | None,
    velocities: str,
    robot: RobotProfile | None,
) -> Experiment:
    """The experiment of a table's streams (by group of :data:`GROUPS`; the module's rules).

    ``streams`` holds ``"sample"`` and the other groups the file has;
    ``names`` (role to column) goes into the provenance; ``rate``,
    ``max_gap`` and ``velocities`` are those of
    :func:`bayes_jackal.io.read_csv`, ``robot`` converts a ``cmd_v, cmd_w``
    command into wheel speeds (the default profile when None).
    """
    if velocities not in VELOCITIES:
        raise InputError(
            f"unknown velocities {velocities!r}; use one of {VELOCITIES}", field="velocities"
        )
    for group, stream in streams.items():
        numbers = {role: v for role, v in stream.values.items() if role != SEGMENT}
        check_values(
            {"t": stream.t, **numbers}, source, stream.where,
            min_samples=1 if group in HELD_UNTIL_NEXT else MIN_SAMPLES,
        )  # fmt: skip
    sample = streams["sample"]
    _check_velocity_rows(streams, source)
    clock = uniform_clock(
        sample.t, rate=rate, max_gap=max_gap, source=source, row_name=sample.where
    )
    step = 1.0 / clock.provenance["rate"]
    reading = _Reading(
        clock, sample, MAX_GAP_STEPS * step if max_gap is None else max_gap, source,
        list(clock.repairs),
    )  # fmt: skip
    placed = {group: reading.place(stream, group) for group, stream in streams.items()}
    if any(not p.on_rows or len(p.times) < len(clock.rows) for p in placed.values()):
        reading.provenance["streams"] = {
            group: {"samples": len(p.times), "stamps": "sample rows" if p.on_rows else "own"}
            for group, p in placed.items()
        }
    columns, measured = _rate_fields(reading, placed)
    pose = _pose(reading, placed["pose"]) if "pose" in placed else None
    inputs, command, covered = _inputs(reading, placed, robot)
    start, stop = longest_run(covered)
    what = reading.provenance.get("input", {}).get("from", "wheel speeds")
    if stop - start < MIN_SAMPLES:
        raise DataError(
            f"the model's input ({what}) covers no {MIN_SAMPLES} samples of the clock "
            f"({clock.t[0]:.6g} .. {clock.t[-1]:.6g} s)",
            source=source,
        )
    if stop - start < len(covered):
        reading.repairs.append(
            f"run cut to {clock.t[start]:.6g} .. {clock.t[stop - 1]:.6g} s, where the model's "
            f"input ({what}) has values; was {clock.t[0]:.6g} .. {clock.t[-1]:.6g} s"
        )
    keep = slice(start, stop)
    t = clock.t[keep]
    columns = {role: values[keep] for role, values in (columns | inputs).items()}
    if pose is not None:
        pose = pose.window(t[0] - step, t[-1] + step)
        velocities = "derived"
        if "vx" not in columns:
            columns["vx"], columns["vy"] = body_velocities(pose, t)
        measured = {role: mask for role, mask in measured.items() if role not in OPTIONAL}
    provenance = {
        "source": source,
        "format": format,
        "columns": names,
        "time_base": clock.provenance,
        "repairs": reading.repairs,
    }
    if "vx" in columns:
        provenance["velocities"] = velocities
    segments = _segments(reading, placed, None if command is None else command[keep], keep)
    return Experiment(
        t=t,
        **columns,
        pose=pose,
        name=name,
        series=series,
        provenance=provenance | reading.provenance,
        source=source,
        measured={role: mask[keep] for role, mask in measured.items()},
        segments=segments,
    )


def _check_velocity_rows(streams: dict[str, TableStream], source: str) -> None:
    """Refuse measured vx, vy at rows without a yaw rate (the rule of the module text)."""
    velocity = streams.get("velocity")
    if velocity is None:
        return
    outside = np.flatnonzero(~np.isin(velocity.rows, streams["sample"].rows))
    if outside.size:
        roles = ", ".join(velocity.values)
        raise DataError(
            f"{roles} are measured at rows of their own ({velocity.where(int(outside[0]))} has "
            "them and no yaw_rate; the model measures a velocity sensor on the experiment's "
            f"clock): give {roles} on the yaw-rate rows (resampled onto the IMU's stamps), or "
            "the motion-capture poses (x, y, heading) at their own stamps instead",
            source=source,
            field=next(iter(velocity.values)),
        )


def _rate_fields(
    reading: _Reading, placed: dict[str, _Placed]
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The yaw rate and measured vx, vy on every tick, and masks of the ticks measured."""
    groups = {"sample": ("yaw_rate",)}
    if "velocity" in placed:
        groups["velocity"] = tuple(placed["velocity"].values)
    columns, measured = {}, {}
    for group, roles in groups.items():
        stream = placed[group]
        ticks = stream.position.astype(int)
        held = reading.held(stream, roles)
        if held is not None:
            reading.say(f"{held.describe(', '.join(roles))}; measured at those ticks only")
            ticks = ticks[held.changes]
        mask = np.zeros(len(reading.ticks), bool)
        mask[ticks] = True
        for role in roles:
            columns[role] = reading.interpolate(stream.position, stream.values[role])
            measured[role] = mask
    return columns, measured


def _pose(reading: _Reading, placed: _Placed) -> PoseTrack:
    """The pose track: at its ticks or own stamps, or its sensor's poses where held."""
    t, values = placed.times, placed.stacked(POSE_ROLES)
    held = reading.held(placed, POSE_ROLES, rest_is_zero=False)
    if held is not None:
        reading.say(f"{held.describe(', '.join(POSE_ROLES))}; the pose track holds those")
        t, values = held.times, values[held.changes]
    x, y, heading = values.T
    return PoseTrack(t, x, y, np.unwrap(heading), source=reading.source)


def _inputs(
    reading: _Reading, placed: dict[str, _Placed], robot: RobotProfile | None
) -> tuple[dict[str, np.ndarray], np.ndarray | None, np.ndarray]:
    """The model's input on every tick, the command (as wheel speeds), and the ticks covered.

    The input is the wheel speeds, or the command where the table has none
    or they are held; the command, shape (M, 2), is None without one. The
    provenance's ``input`` says where the input came from when it is not
    the wheel speeds measured at every tick.
    """
    group = _command_group(placed, reading.source)
    command = None if group is None else _command(reading, placed[group], group, robot)
    wheels = placed.get("wheels")
    held = None if wheels is None else reading.held(wheels, WHEELS)
    if wheels is not None and (held is None or command is None):
        inputs, covered = _wheel_speeds(reading, wheels, held)
        return inputs, None if command is None else command[0], covered
    if command is None:
        raise DataError(
            f"missing column(s) {list(WHEELS)} and no command ({', '.join(VELOCITY_COMMAND)} "
            f"or {', '.join(WHEEL_COMMAND)}): the model needs its input (name yours with "
            "--column ROLE NAME, columns= in Python)",
            source=reading.source,
            field=WHEELS[0],
        )
    why = (
        f"the wheel speeds are held ({held.describe(', '.join(WHEELS))})"
        if held is not None
        else "the table has no wheel speeds"
    )
    converted = (
        f", converted by {reading.provenance['robot']}'s diff-drive formula"
        if group == COMMANDS[0]
        else ""
    )
    reading.say(
        f"{why}: the command ({', '.join(GROUPS[group])}) is the model's input, each value "
        f"held until the next{converted}"
    )
    reading.provenance["input"] = {
        "from": "command",
        "columns": list(GROUPS[group]),
        "held": "zero-order hold: the last command at or before each tick",
    }
    values, covered = command
    return dict(zip(WHEELS, values.T, strict=True)), values, covered


def _command_group(placed: dict[str, _Placed], source: str) -> str | None:
    """The table's command group, if any; two of them are refused."""
    groups = [group for group in COMMANDS if group in placed]
    if len(groups) > 1:
        raise DataError(
            f"two commands, {', '.join(VELOCITY_COMMAND)} and {', '.join(WHEEL_COMMAND)}: "
            "which one the robot followed is ambiguous (map one of them only)",
            source=source,
            field=VELOCITY_COMMAND[0],
        )
    return groups[0] if groups else None


def _command(
    reading: _Reading, placed: _Placed, group: str, robot: RobotProfile | None
) -> tuple[np.ndarray, np.ndarray]:
    """The command held onto every tick as wheel speeds [rad/s], shape (M, 2), and where it is.

    Before its first value a command is taken to be that value (for
    segments; as the input, the run starts at it).
    """
    (first, covered), (second, _) = (reading.hold(placed, role) for role in GROUPS[group])
    if group == "velocity command":
        robot = as_profile(robot)
        first, second = wheel_speeds(robot, first, second)
        reading.provenance["robot"] = robot.name
    return np.column_stack([first, second]), covered


def _wheel_speeds(
    reading: _Reading, wheels: _Placed, held: HeldChannel | None
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The wheel speeds on every tick (de-held where held), and the ticks they cover."""
    position, values = wheels.position, wheels.stacked(WHEELS)
    if held is not None:
        reading.say(
            f"{held.describe(', '.join(WHEELS))}; the model's input interpolates between them: "
            f"transients shorter than the sensor's step ({1 / held.rate:.3g} s) are not "
            f"resolved (a command, {', '.join(VELOCITY_COMMAND)} or {', '.join(WHEEL_COMMAND)}, "
            "would be the input instead)"
        )
        times, values = held.series(wheels.times, values)
        position = (times - reading.clock.t[0]) / reading.step
    inputs = {
        role: reading.interpolate(position, column)
        for role, column in zip(WHEELS, values.T, strict=True)
    }
    ticks = reading.ticks
    covered = (ticks >= position[0] - HOLD_SLACK) & (ticks <= position[-1] + HOLD_SLACK)
    if not wheels.on_rows and held is None:  # stamps of their own: a long gap is a dropout
        steps, limit = np.diff(wheels.times), reading.gap_of(wheels.times)
        for i in np.flatnonzero(steps > limit):
            reading.repairs.append(
                f"{', '.join(WHEELS)}: gap of {steps[i]:.6g} s after {wheels.where(int(i))} "
                f"(t = {wheels.times[i]:.10g} s), longer than {limit:.6g} s"
            )
            covered &= ~((ticks > position[i]) & (ticks < position[i + 1]))
    filled = reading.clock.provenance["interpolated"]
    if held is not None or not wheels.on_rows or filled:
        reading.provenance["input"] = {
            "from": "wheel speeds" + (", de-held" if held is not None else ""),
            "columns": list(WHEELS),
            "interpolated": (
                "linearly onto the clock, between the held sensor's own samples"
                if held is not None
                else f"linearly across the clock's {filled} filled ticks"
                if wheels.on_rows
                else "linearly onto the clock, from their own stamps"
            ),
        }
    return inputs, covered


def _segments(
    reading: _Reading, placed: dict[str, _Placed], command: np.ndarray | None, keep: slice
) -> np.ndarray | None:
    """The segment starts on the kept ticks: from the label, else the command; or None."""
    if "segment" in placed:
        labels, _ = reading.hold(placed["segment"], SEGMENT)
        starts, rule = label_segments(labels[keep]), {"from": "segment column"}
    elif command is not None:
        starts = command_segments(reading.clock.t[keep], command, source=reading.source)
        rule = {"from": "command", "step_tolerance": STEP_TOLERANCE, "min_hold": MIN_HOLD}
    else:
        return None
    reading.provenance["segments"] = rule | {"count": 1 if starts is None else len(starts)}
    return starts
