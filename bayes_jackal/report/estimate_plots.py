"""The filters' state estimates and their bands against the measurements, over a short window.

:func:`plot_state_estimates` draws what :func:`bayes_jackal.filters.estimate_states`
returns, one axes per filter (the analysis report's "State estimation with
this prior", :mod:`bayes_jackal.filters.left_out`). Built on
:class:`matplotlib.figure.Figure` without pyplot, as every figure of
:mod:`bayes_jackal.report.plots`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from .._runtime import InputError
from ..filters import StateEstimate
from ..io import Experiment
from ._layout import DATA_COLOUR, DATA_LABELS, MODEL_COLOUR, UNITS

__all__ = ["SHOWN_SECONDS", "plot_state_estimates", "shown_window"]

#: Length of the window drawn [s]: a few seconds, so that single samples show.
SHOWN_SECONDS = 3.0


def shown_window(experiment: Experiment, *, seconds: float = SHOWN_SECONDS) -> tuple[float, float]:
    """The ``seconds`` [s] around the middle of the steady window (or of the run), inside it.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import shown_window
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> run.steady_window, shown_window(run)
    ((3.0, 36.0), (18.0, 21.0))
    """
    first, last = experiment.steady_window or (experiment.t[0], experiment.t[-1])
    start = max(experiment.t[0], (first + last - seconds) / 2.0)
    return float(start), float(min(experiment.t[-1], start + seconds))


def plot_state_estimates(
    experiment: Experiment,
    estimates: Mapping[str, Mapping[str, StateEstimate]],
    *,
    channel: str | None = None,
    seconds: float = SHOWN_SECONDS,
    axes=None,
) -> tuple[Figure, np.ndarray]:
    """Each filter's estimate with its +-2 sd band, against the measurements and any truth.

    One axes per filter, over :func:`shown_window`: the measurements as
    dots, each filter's estimate of x_k (the Kalman filters' E[x_k | y_0..y_k])
    as a line and the band mean +- 2 sqrt(variance); the simulated true state dashed, where the
    experiment carries one (``truth_arrays["<channel>_state"]``).

    Parameters
    ----------
    experiment : Experiment
        The run the filters ran on.
    estimates : mapping
        ``[filter][channel]``, as :func:`~bayes_jackal.filters.estimate_states` returns.
    channel : str, optional
        The channel drawn: by default yaw when estimated, else the first.
    seconds : float
        Length of the window [s].
    axes : sequence of matplotlib.axes.Axes, optional
        One per filter.

    Returns
    -------
    fig, axes

    Raises
    ------
    InputError
        For a channel the estimates lack.

    Examples
    --------
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import plot_state_estimates
    >>> robot = bj.load_profile()
    >>> runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=seed) for seed in (1, 2)]
    >>> posterior = bj.sample(runs[:1], family="gaussian", channels=["yaw"], max_steps=20, seed=1)
    >>> prior = bj.export_prior(posterior, order=2)
    >>> estimates = bj.estimate_states(runs[1], prior, filters=["kalman", "generalised"])
    >>> fig, axes = plot_state_estimates(runs[1], estimates)
    >>> [ax.get_title(loc="left") for ax in axes], axes[-1].get_ylabel()
    (['kalman', 'generalised'], 'yaw [rad/s]')
    """
    estimated = list(next(iter(estimates.values())))
    channel = channel or ("yaw" if "yaw" in estimated else estimated[0])
    if channel not in estimated:
        raise InputError(
            f"no estimates of channel {channel!r}; estimated: {estimated}", field="channel"
        )
    if axes is None:
        fig = Figure(layout="constrained", figsize=(7.0, 1.0 + 1.8 * len(estimates)))
        axes = fig.subplots(len(estimates), 1, sharex=True, squeeze=False)[:, 0]
    axes = np.atleast_1d(axes)
    start, stop = shown_window(experiment, seconds=seconds)
    shown = (experiment.t >= start) & (experiment.t <= stop)
    t = experiment.t[shown]
    truth = experiment.truth_arrays.get(f"{channel}_state")
    for ax, (name, per_channel) in zip(axes, estimates.items(), strict=True):
        estimate = per_channel[channel]
        mean, sd = estimate.mean[shown], np.sqrt(estimate.variance[shown])
        ax.fill_between(t, mean - 2 * sd, mean + 2 * sd, color=MODEL_COLOUR, alpha=0.25, lw=0,
                        label="+-2 sd")  # fmt: skip
        ax.plot(t, experiment.channel(channel)[shown], ".", color=DATA_COLOUR, ms=3,
                label=DATA_LABELS[experiment.measurement(channel)])  # fmt: skip
        if truth is not None:
            ax.plot(t, truth[shown], "--", color="black", lw=0.9, label="true state")
        ax.plot(t, mean, color=MODEL_COLOUR, lw=1.2, label="estimate")
        ax.set_title(name, loc="left", fontsize="medium")
        ax.set_ylabel(f"{channel} [{UNITS[channel]}]")
    axes[0].legend(loc="upper right", fontsize="small", ncols=4)
    axes[-1].set_xlabel("t [s]")
    return axes[0].figure, axes
