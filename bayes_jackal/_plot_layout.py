"""What the figures share: new axes without pyplot, colours, units, the band's percentiles.

Private to :mod:`bayes_jackal.plots`, :mod:`bayes_jackal.grid_plots` and
:mod:`bayes_jackal.predictive_plots`.
"""

from __future__ import annotations

from matplotlib.axes import Axes
from matplotlib.figure import Figure

#: Credible band drawn around posterior-predictive medians (the HDI mass).
BAND = (3.0, 97.0)
#: Unit of each channel.
UNITS = {"vx": "m/s", "vy": "m/s", "yaw": "rad/s"}
DATA_COLOUR, MODEL_COLOUR = "0.25", "tab:red"


def new_axes(ax: Axes | None, **figure_options) -> tuple[Figure, Axes]:
    """``ax`` and its figure, or a new figure (``figure_options``) with one axes."""
    if ax is not None:
        return ax.figure, ax
    fig = Figure(layout="constrained", **figure_options)
    return fig, fig.add_subplot()
