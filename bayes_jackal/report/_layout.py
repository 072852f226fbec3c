"""What the figures share: new axes without pyplot, colours, units, the band's percentiles.

Private to :mod:`bayes_jackal.report.plots`, :mod:`bayes_jackal.report.grid_plots`,
:mod:`bayes_jackal.report.predictive_plots` and :mod:`bayes_jackal.report.noise_plots`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .._runtime import atomic_path

#: Credible band drawn around posterior-predictive medians (the HDI mass).
BAND = (3.0, 97.0)
#: Unit of each channel.
UNITS = {"vx": "m/s", "vy": "m/s", "yaw": "rad/s"}
DATA_COLOUR, MODEL_COLOUR = "0.25", "tab:red"
#: The legend of a channel's data, by how it was recorded
#: (:meth:`bayes_jackal.io.Experiment.measurement`).
DATA_LABELS = {"rate": "measured", "pose": "derived from the poses"}


def new_axes(ax: Axes | None, **figure_options) -> tuple[Figure, Axes]:
    """``ax`` and its figure, or a new figure (``figure_options``) with one axes."""
    if ax is not None:
        return ax.figure, ax
    fig = Figure(layout="constrained", **figure_options)
    return fig, fig.add_subplot()


def draw_band(ax: Axes, x: np.ndarray, draws: np.ndarray, *, color, label: str) -> None:
    """The central :data:`BAND` of ``draws`` (shape (B, len(x))) over x, filled, and its median."""
    low, median, high = np.percentile(draws, [BAND[0], 50.0, BAND[1]], axis=0)
    ax.fill_between(x, low, high, color=color, alpha=0.3, label=label)
    ax.plot(x, median, color=color, lw=1)


def save_figure(fig: Figure, path: str | Path, dpi: int) -> Path:
    """Write ``fig`` to ``path`` atomically, in the format of its suffix (png, svg, pdf)."""
    path = Path(path)
    with atomic_path(path) as temporary:
        fig.savefig(temporary, dpi=dpi, format=path.suffix.lstrip(".").lower() or None)
    return path
