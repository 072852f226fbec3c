"""The forest plot of a campaign: every unit's and group's damping, with the population's band.

Draws the ``population --json`` object (:meth:`bayes_jackal.inference.Population.to_dict`,
or ``population.json`` read back), so a saved result is plotted as the
fresh one. Built on :class:`matplotlib.figure.Figure` without pyplot.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .._runtime import InputError
from ._layout import DATA_COLOUR, MODEL_COLOUR, save_figure

__all__ = ["plot_population", "save_population_plot"]

_DAMPING = ("d_lat", "d_long")
_POPULATION_COLOUR = "tab:blue"


def _rows(summary: Mapping) -> list[tuple[str, dict, str]]:
    """(label, interval, kind) from top to bottom: per group its units, its independent
    fit and its hierarchical estimate."""
    rows = []
    for label, group in summary["groups"].items():
        units = [(n, u) for n, u in summary["units"].items() if u["group"] == label]
        if len(units) > 1 or units[0][0] != label:
            rows += [(f"  {name}", unit, "unit") for name, unit in units]
        rows.append((f"{label} (alone)", group["independent"], "independent"))
        rows.append((f"{label} ({summary['model']})", group, "group"))
    return rows


def plot_population(summary: Mapping, *, axes=None) -> tuple[Figure, np.ndarray]:
    """Forest plot of d_lat and d_long [N s/m]: units, groups and the population.

    Each row is a 94 % HDI with its mean: every unit sampled alone (grey),
    each group fitted alone (open marker) and by the population model
    (filled, red). The population mean's 94 % HDI is the dark band, a new
    group's 94 % interval the light one.

    Parameters
    ----------
    summary : mapping
        :meth:`bayes_jackal.inference.Population.to_dict`, or ``population.json``.
    axes : sequence of two matplotlib Axes, optional

    Returns
    -------
    fig, axes

    Raises
    ------
    InputError
        When ``summary`` lacks ``groups``, ``units`` or ``population``.

    Examples
    --------
    Two floors of two runs each, chains short for the example:

    >>> import bayes_jackal as bj
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, d_long, rng=seed, name=f"run{seed}")
    ...     for seed, d_long in enumerate([30.0, 30.0, 40.0, 40.0])
    ... ]
    >>> floors = {"run0": "tiles", "run1": "tiles", "run2": "carpet", "run3": "carpet"}
    >>> result = bj.population(
    ...     runs, groups=floors, family="white", channels=["yaw"], seed=1,
    ...     max_steps=400, progress=False,
    ... )
    >>> from bayes_jackal.report import plot_population
    >>> fig, axes = plot_population(result.to_dict())
    >>> [ax.get_xlabel() for ax in axes]
    ['d_lat [N s/m]', 'd_long [N s/m]']
    """
    missing = [key for key in ("groups", "units", "population") if key not in summary]
    if missing:
        raise InputError(f"not a population summary: no {missing}", field=missing[0])
    rows = _rows(summary)
    if axes is None:
        fig = Figure(layout="constrained", figsize=(9.0, 1.2 + 0.3 * len(rows)))
        axes = np.array(fig.subplots(1, 2, sharey=True))
    axes = np.asarray(axes)
    fig = axes[0].figure
    y = np.arange(len(rows))[::-1]
    for ax, name in zip(axes, _DAMPING, strict=True):
        population = summary["population"][name]
        mean, spread = population["mean"]["N s/m"], population["new_group"]
        ax.axvspan(
            spread["hdi_3%"],
            spread["hdi_97%"],
            color=_POPULATION_COLOUR,
            alpha=0.12,
            label="a new group (94 %)",
        )
        ax.axvspan(
            mean["hdi_3%"],
            mean["hdi_97%"],
            color=_POPULATION_COLOUR,
            alpha=0.3,
            label="population mean (94 % HDI)",
        )
        for row, (_, interval, kind) in zip(y, rows, strict=True):
            value = interval[name]
            colour = MODEL_COLOUR if kind == "group" else DATA_COLOUR
            ax.plot(
                [value["hdi_3%"], value["hdi_97%"]],
                [row, row],
                color=colour,
                lw=2.0 if kind == "group" else 1.2,
                alpha=0.6 if kind == "unit" else 1.0,
            )
            ax.plot(
                value["mean"],
                row,
                "o",
                color=colour,
                markerfacecolor="white" if kind == "independent" else colour,
            )
        ax.set_xlabel(f"{name} [N s/m]")
        ax.grid(axis="x", alpha=0.3)
    axes[0].set_yticks(y, [label for label, _, _ in rows])
    axes[0].legend(loc="best", fontsize="small")
    fig.suptitle(f"Damping by group: {summary.get('verdict', '')}", fontsize="small")
    return fig, axes


def save_population_plot(summary: Mapping, path: str | Path, dpi: int = 120) -> Path:
    """Save :func:`plot_population` (png, svg, pdf by the suffix), atomically.

    Examples
    --------
    The forest plot of two floors of two runs each, as SVG:

    >>> import bayes_jackal as bj
    >>> robot = bj.load_profile()
    >>> runs = [
    ...     bj.simulate_experiment(robot, 110.0, d_long, rng=seed, name=f"run{seed}")
    ...     for seed, d_long in enumerate([30.0, 30.0, 40.0, 40.0])
    ... ]
    >>> floors = {"run0": "tiles", "run1": "tiles", "run2": "carpet", "run3": "carpet"}
    >>> result = bj.population(
    ...     runs, groups=floors, family="white", channels=["yaw"], seed=1,
    ...     max_steps=400, progress=False,
    ... )
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.report import save_population_plot
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = save_population_plot(result.to_dict(), Path(folder) / "population.svg")
    ...     print(path.name, path.read_text().startswith("<?xml"))
    population.svg True
    """
    fig, _ = plot_population(summary)
    return save_figure(fig, path, dpi)
