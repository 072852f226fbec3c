"""The report's figures: each drawn once, embedded as PNG and saved as files for papers.

:class:`ReportFigures` turns a figure of :mod:`bayes_jackal.report.plots` into the
HTML ``<figure>`` of :func:`bayes_jackal.report.render_report` (the PNG
inline, base64-encoded) and writes it beside the report as PNG and/or SVG.
"""

from __future__ import annotations

import base64
import html
import io
import logging
import re
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from .._runtime import FIGURE_FORMATS, LOG_INTERVAL, InputError, atomic_path

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["DPI", "ReportFigures", "figure_formats", "formats_text", "slug"]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)

#: Resolution of the embedded and saved PNGs [dots per inch].
DPI = 130


def figure_formats(formats: Sequence[str], *, field: str = "formats") -> tuple[str, ...]:
    """``formats`` as a tuple, each a name of :data:`FIGURE_FORMATS`.

    Raises
    ------
    InputError
        Naming ``field`` and the unknown formats.

    Examples
    --------
    >>> from bayes_jackal.report import figure_formats
    >>> figure_formats(["png", "svg"])
    ('png', 'svg')
    """
    unknown = [f for f in formats if f not in FIGURE_FORMATS]
    if unknown:
        raise InputError(
            f"unknown figure formats {unknown}; use {list(FIGURE_FORMATS)}", field=field
        )
    return tuple(formats)


def formats_text(formats: Sequence[str]) -> str:
    """The formats as a reader names them (``"PNG and SVG"``; empty for none).

    Examples
    --------
    >>> from bayes_jackal.report import formats_text
    >>> formats_text(("png", "svg")), formats_text(())
    ('PNG and SVG', '')
    """
    return " and ".join(suffix.upper() for suffix in formats)


def slug(text: str) -> str:
    """``text`` as a file name: runs of other characters than [A-Za-z0-9_.-] become "-".

    The name of a figure's files (:meth:`ReportFigures.html`); leading and
    trailing "-" are dropped, and nothing left gives ``figure``. Distinct
    names can give one slug (:mod:`bayes_jackal.report.noise_page` refuses such
    series before drawing).

    Parameters
    ----------
    text : str

    Returns
    -------
    str

    Examples
    --------
    >>> from bayes_jackal.report import slug
    >>> slug("v1: a line"), slug("a b") == slug("a-b"), slug("//")
    ('v1-a-line', True, 'figure')
    """
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "figure"


class ReportFigures:
    """Renders figures to embedded PNG and saves them as PNG/SVG files.

    Parameters
    ----------
    folder : Path
        Where the figure files go (it must exist when a figure is rendered).
    formats : tuple of str
        Files to write per figure, from :data:`FIGURE_FORMATS`; the embedded
        PNG is rendered in any case.

    Raises
    ------
    InputError
        For a format not in :data:`FIGURE_FORMATS`.

    Examples
    --------
    One figure, embedded in the HTML and saved as ``<name>.png``:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from matplotlib.figure import Figure
    >>> from bayes_jackal.report import ReportFigures
    >>> def draw():
    ...     fig = Figure()
    ...     ax = fig.add_subplot()
    ...     ax.plot([0.0, 1.0], [0.0, 1.0])
    ...     return fig, ax
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     figures = ReportFigures(Path(folder), ("png",))
    ...     text = figures.html("v1: a line", "a straight line", draw)
    ...     files = sorted(path.name for path in Path(folder).iterdir())
    >>> files
    ['v1-a-line.png']
    >>> text.startswith('<figure><img alt="a straight line" src="data:image/png;base64,')
    True
    """

    def __init__(
        self,
        folder: Path,
        formats: tuple[str, ...],
    ):
        self.folder, self.formats = folder, figure_formats(formats)
        self.drawn, self._said = 0, time.monotonic()

    def html(self, name: str, caption: str, draw: Callable[[], tuple[Figure, object]]) -> str:
        """Draw a figure, save its files and return its HTML ``<figure>``.

        Parameters
        ----------
        name : str
            The files' name, made safe for a file system (``<name>.png``).
        caption : str
            The figure's caption and the image's alternative text.
        draw : callable
            Returns ``(fig, axes)``, e.g. a function of :mod:`bayes_jackal.report.plots`.

        Returns
        -------
        str
            ``<figure>`` with the PNG inline and the caption.
        """
        fig, _ = draw()
        rendered = {}
        for suffix in ("png", *self.formats):
            if suffix not in rendered:
                buffer = io.BytesIO()
                fig.savefig(buffer, format=suffix, dpi=DPI)
                rendered[suffix] = buffer.getvalue()
                # The first rendering placed the axes; the other formats keep
                # that layout instead of solving it again (a third of a
                # report's figure time went to constrained layout).
                fig.set_layout_engine("none")
        for suffix in self.formats:
            path = self.folder / f"{slug(name)}.{suffix}"
            with atomic_path(path) as temporary:
                temporary.write_bytes(rendered[suffix])
        self.drawn += 1
        if time.monotonic() - self._said >= LOG_INTERVAL:
            _log.info(f"  report: {self.drawn} figures drawn, the last {name}")
            self._said = time.monotonic()
        data = base64.b64encode(rendered["png"]).decode("ascii")
        return (
            f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )
