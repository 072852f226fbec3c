"""Figures of the thesis' grid searches: an MSE surface over (d_long, d_lat).

Built on :class:`matplotlib.figure.Figure` without pyplot, as every figure
of :mod:`bayes_jackal.report.plots` (which exports these too).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from ..thesis import GridResult
from ._layout import new_axes, save_figure

__all__ = ["plot_grid", "save_grid_plot"]


def plot_grid(
    result: GridResult, surface: np.ndarray | None = None, ax: Axes | None = None
) -> tuple[Figure, Axes]:
    """MSE surface over (d_long, d_lat) with its minimum and ridge line.

    The ridge is the line d_lat = (d_lat / d_long at the minimum) x d_long,
    along which the yaw rate's steady state is constant (thesis fig. 5-4).
    An axis of log-spaced values (the default grids,
    :func:`bayes_jackal.thesis.prior_grid`) is drawn on a log scale, the
    thesis' linear grids on a linear one; the ridge is a straight line on
    either.

    Parameters
    ----------
    result : GridResult
    surface : ndarray, shape (L, M), optional
        One of ``result``'s surfaces; the total (eq. 5-3) by default.
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    fig, ax

    Examples
    --------
    The one-step yaw-rate MSE of a simulated run on a coarse grid:

    >>> import bayes_jackal as bj
    >>> from bayes_jackal.thesis import damping_grid, grid_search
    >>> from bayes_jackal.report import plot_grid
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> result = grid_search(
    ...     [run], robot, damping_grid(50.0, 200.0, 10.0), damping_grid(10.0, 60.0, 5.0)
    ... )
    >>> fig, ax = plot_grid(result)
    >>> len(fig.axes), ax.get_xlabel(), ax.get_ylabel()  # the surface and its colour bar
    (2, 'd_long [N s/m]', 'd_lat [N s/m]')
    >>> [text.get_text() for text in ax.get_legend().get_texts()]
    ['d_lat = 3.33 d_long', 'minimum (50, 15): 9.63e-05']
    >>> ax.get_xscale(), ax.get_yscale()  # linear grids
    ('linear', 'linear')

    The default grid over the Jackal's prior, log-spaced:

    >>> from bayes_jackal.thesis import prior_grid
    >>> grid = prior_grid(robot, "d_lat", "simulation")[::10]
    >>> fig, ax = plot_grid(grid_search([run], robot, grid, grid))
    >>> ax.get_xscale(), ax.get_yscale()
    ('log', 'log')
    """
    fig, ax = new_axes(ax, figsize=(6.0, 4.8))
    surface = result.mse if surface is None else surface
    floor = max(float(surface.min()), np.finfo(float).tiny)
    mesh = ax.pcolormesh(
        result.d_long, result.d_lat, np.maximum(surface, floor), shading="nearest", norm=LogNorm()
    )
    fig.colorbar(mesh, ax=ax, label=f"{result.method} MSE ({result.channel})")
    d_lat, d_long, mse = result.argmin(surface)
    ratio = d_lat / d_long
    ax.plot(result.d_long, ratio * result.d_long, "w--", lw=1, label=f"d_lat = {ratio:.3g} d_long")
    ax.plot(d_long, d_lat, "r*", ms=12, label=f"minimum ({d_lat:g}, {d_long:g}): {mse:.3g}")
    ax.set_xlim(result.d_long[0], result.d_long[-1])
    ax.set_ylim(result.d_lat[0], result.d_lat[-1])
    if _log_spaced(result.d_long):
        ax.set_xscale("log")
    if _log_spaced(result.d_lat):
        ax.set_yscale("log")
    ax.set_xlabel("d_long [N s/m]")
    ax.set_ylabel("d_lat [N s/m]")
    ax.legend(loc="lower right", fontsize="small", facecolor="0.75")
    return fig, ax


def _log_spaced(values: np.ndarray) -> bool:
    """Whether an axis of more than two values has equal ratios (and not equal steps)."""
    if len(values) < 3:
        return False
    ratios = np.diff(np.log(values))
    return bool(np.allclose(ratios, ratios[0], rtol=1e-6) and ratios[0] > 0)


def save_grid_plot(result: GridResult, path: str | Path, dpi: int = 120) -> Path:
    """Save :func:`plot_grid` of the total surface (png, svg, pdf by the suffix).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.thesis import damping_grid, grid_search
    >>> from bayes_jackal.report import save_grid_plot
    >>> robot = bj.load_profile()
    >>> run = bj.simulate_experiment(robot, 110.0, 30.0, rng=1)
    >>> result = grid_search(
    ...     [run], robot, damping_grid(50.0, 200.0, 10.0), damping_grid(10.0, 60.0, 5.0)
    ... )
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = save_grid_plot(result, Path(folder) / "grid.svg")
    ...     print(path.name, path.read_text().startswith("<?xml"))
    grid.svg True
    """
    fig, _ = plot_grid(result)
    return save_figure(fig, path, dpi)
