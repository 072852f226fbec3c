"""Where a run's command steps begin: the segments of an experiment.

A calibration drive holds one command, then steps to the next: each step is
a segment of the run (:attr:`bayes_jackal.io.Experiment.segments`, the first
sample of each). The readers find them in one of two ways:

- from a label the log gives each row (a table's ``segment`` column):
  :func:`label_segments`, a segment wherever the label changes;
- from the command (a table's ``cmd_v, cmd_w`` or ``cmd_omega_r,
  cmd_omega_l``, a bag's ``cmd_vel``, as wheel speeds):
  :func:`command_segments`. The rule: the command is *held* where, over at
  least :data:`MIN_HOLD` seconds, each wheel's commanded speed stays within
  :data:`STEP_TOLERANCE` (its largest minus its smallest value). A held
  stretch at another level than the one before it (a wheel's median speeds
  more than :data:`STEP_TOLERANCE` apart) starts a segment, at the first
  sample after the previous held stretch: the change, a jump or a ramp of
  any length, belongs to the step it leads to, so a ramp is one segment,
  not one per tick. A change that is never held afterwards (a command that
  keeps moving, or one at the end of the run) starts none.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .._runtime import DataError

__all__ = ["MIN_HOLD", "STEP_TOLERANCE", "command_segments", "label_segments"]

#: Largest spread of a held command, and smallest change between two held
#: levels [rad/s of wheel speed]: 0.1 rad/s is 1 cm/s at the Jackal's wheel
#: (r_w = 9.8 cm), a tenth of the smallest step of a calibration drive
#: (0.1 m/s), and above the jitter of a joystick held still.
STEP_TOLERANCE = 0.1
#: Shortest hold of a command step [s]: three times the slowest time constant
#: of the Jackal's model (m / (4 d_long) = 0.14 s at d_long = 30 N s/m), so a
#: step's transient has decayed to 5 % within it; shorter pauses in a changing
#: command are no steps.
MIN_HOLD = 0.5


def label_segments(labels: np.ndarray) -> np.ndarray | None:
    """The first sample of each segment of per-sample labels: wherever the label changes.

    Parameters
    ----------
    labels : array_like, shape (N,)
        A label per sample, integer or text (a table's ``segment`` column on
        the experiment's clock).

    Returns
    -------
    ndarray of int or None
        The segment starts (the first is 0); None for one label throughout.

    Examples
    --------
    >>> from bayes_jackal.io import label_segments
    >>> label_segments(["rest", "rest", "step 1", "step 1", "step 2", "rest"]).tolist()
    [0, 2, 4, 5]
    >>> print(label_segments([3, 3, 3]))
    None
    """
    labels = np.asarray(labels)
    starts = np.concatenate([[0], np.flatnonzero(labels[1:] != labels[:-1]) + 1])
    return starts if len(starts) > 1 else None


def command_segments(
    t: np.ndarray, command: np.ndarray, *, source: str = "<memory>"
) -> np.ndarray | None:
    """The first sample of each command step (the rule of the module text).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times [s].
    command : ndarray, shape (N,) or (N, m)
        The command held at each sample, as wheel speeds [rad/s] (one
        column per wheel).
    source : str
        The file named in errors.

    Returns
    -------
    ndarray of int or None
        The segment starts (the first is 0); None for one segment.

    Raises
    ------
    DataError
        When ``t`` and ``command`` differ in length.

    Examples
    --------
    At 10 Hz: 2 s at rest, a jump to 3 rad/s held 2 s, a 1 s ramp to 5 rad/s
    held 2 s. The jump starts a segment at 2.0 s; the ramp starts one where
    it leaves the hold (2.0 rad/s per second leaves 0.1 rad/s after a step),
    not one per tick:

    >>> import numpy as np
    >>> from bayes_jackal.io import command_segments
    >>> t = np.arange(70) / 10
    >>> wheel = np.interp(t, [0, 1.99, 2, 4, 5, 7], [0, 0, 3, 3, 5, 5])
    >>> starts = command_segments(t, wheel)
    >>> starts.tolist(), t[starts].tolist()
    ([0, 20, 41], [0.0, 2.0, 4.1])
    """
    values = np.asarray(command, float)
    values = values[:, None] if values.ndim == 1 else values
    if len(values) != len(t):
        raise DataError(
            f"{len(values)} command values for {len(t)} samples", source=source, field="command"
        )
    steps = int(np.ceil(MIN_HOLD / float(np.median(np.diff(t))) - 1e-9))
    if len(values) <= steps:
        return None
    windows = sliding_window_view(values, steps + 1, axis=0)  # (N - steps, m, steps + 1)
    held = (windows.max(axis=2) - windows.min(axis=2) <= STEP_TOLERANCE).all(axis=1)
    # A held stretch: the samples that a run of consecutive held windows covers.
    edges = np.diff(np.concatenate([[0], held.astype(np.int8), [0]]))
    runs = zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) + steps, strict=True)
    starts, level, end = [0], None, 0
    for start, stop in runs:
        here = np.median(values[start:stop], axis=0)
        if level is not None and (np.abs(here - level) > STEP_TOLERANCE).any():
            starts.append(int(end))
        level, end = here, stop
    return np.array(starts) if len(starts) > 1 else None
