"""Figures. Every function takes an optional ``ax`` and returns ``(fig, ax)``.

Figures are built on :class:`matplotlib.figure.Figure` without pyplot, so
nothing here opens a window or depends on a display.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from .gridsearch import GridResult

__all__ = ["plot_grid"]


def _figure(ax: Axes | None, **figure_options) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax
    fig = Figure(layout="constrained", **figure_options)
    return fig, fig.add_subplot()


def plot_grid(
    result: GridResult, surface: np.ndarray | None = None, ax: Axes | None = None
) -> tuple[Figure, Axes]:
    """MSE surface over (d_long, d_lat) with its minimum and ridge line.

    The ridge is the line d_lat = (d_lat / d_long at the minimum) x d_long,
    along which the yaw rate's steady state is constant (thesis fig. 5-4).

    Parameters
    ----------
    result : GridResult
    surface : ndarray, shape (L, M), optional
        One of ``result``'s surfaces; the total (eq. 5-3) by default.
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    fig, ax
    """
    fig, ax = _figure(ax, figsize=(6.0, 4.8))
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
    ax.set_xlabel("d_long [N s/m]")
    ax.set_ylabel("d_lat [N s/m]")
    ax.legend(loc="lower right", fontsize="small", facecolor="0.75")
    return fig, ax
