"""The HTML report of bare noise series: one section per series (``bayes-jackal noise --out``).

Each section holds the series' table (each family's log evidence, its
Bayes factor against white noise and its width in seconds and bins, as
``bayes-jackal noise`` prints it: :func:`noise_rows`), the verdict, the
warnings, the classical widths, and three figures of
:mod:`bayes_jackal.report.noise_plots`: the autocorrelation and the Welch PSD
against the posterior-predictive bands of the best family and of white
noise, and every method's width on one axis. The page has the style and
the browser self-check of :mod:`bayes_jackal.report.page`, and its figures are
embedded and saved beside it as that report's are
(:class:`~bayes_jackal.report.ReportFigures`).
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._runtime import REPORT_FORMATS, InputError
from ..noise import NoiseCharacterisation
from ..posterior import PREDICTIVE_DRAWS
from ..thesis import THESIS_LAGS
from .figures import ReportFigures, slug
from .noise_plots import (
    noise_predictive_bands,
    plot_noise_autocorrelation,
    plot_noise_spectrum,
    plot_noise_widths,
)
from .page import LAGS, report_page, write_page
from .sections import html_table

__all__ = [
    "NOISE_HEADER",
    "NOISE_REPORT",
    "noise_rows",
    "render_noise_report",
    "write_noise_report",
]

#: The columns of a series' table, in the report and as ``bayes-jackal noise`` prints it.
NOISE_HEADER = ("family", "ln Z", "+-", "ln B vs white", "width [s]", "94 % HDI", "[bins]")
#: The report's file name in ``bayes-jackal noise --out DIR``.
NOISE_REPORT = "noise_report.html"
#: The autocorrelation figure shows this many widths (in bins) of the best family, at
#: least :data:`~bayes_jackal.report.LAGS` lags and at most a quarter of the series.
LAG_WIDTHS = 5

_INTRODUCTION = (
    "<p>Each series is modelled as a constant mean, coloured noise of each family and a white "
    "floor (the mean integrated out). The bands are posterior-predictive: each of up to "
    f"{PREDICTIVE_DRAWS} posterior draws gives a replicate series, the family's coloured noise "
    "plus the floor, as long as the series; a band spans the central 94 % of the replicates' "
    "autocorrelations or spectra, estimated exactly as the series' are, the line their "
    "median. Data outside the best family's band are what the model does not explain. The "
    "widths are each family's own kernel's (docs/families.md); the classical least-squares "
    "fits and the thesis' fit are a Gaussian's, and ignore the white floor.</p>"
)


def noise_rows(summary: dict) -> list[list[str]]:
    """A series' table: one row of formatted cells per family, under :data:`NOISE_HEADER`.

    Parameters
    ----------
    summary : dict
        :meth:`NoiseCharacterisation.to_dict
        <bayes_jackal.noise.NoiseCharacterisation.to_dict>`.

    Returns
    -------
    list of list of str
        ``-`` where a family has no width or white noise was not fitted.

    Examples
    --------
    >>> from bayes_jackal.report import NOISE_HEADER, noise_rows
    >>> width = {"seconds": {"mean": 0.0301, "hdi_3%": 0.025, "hdi_97%": 0.036},
    ...          "bins": {"mean": 3.01}}
    >>> summary = {"families": {
    ...     "white": {"log_evidence": -900.0, "log_evidence_err": 0.0043, "width": None,
    ...               "log_bayes_factor_vs_white": 0.0},
    ...     "gaussian": {"log_evidence": -850.5, "log_evidence_err": 0.05, "width": width,
    ...                  "log_bayes_factor_vs_white": 49.5}}}
    >>> for row in [list(NOISE_HEADER), *noise_rows(summary)]:
    ...     print(" | ".join(row))
    family | ln Z | +- | ln B vs white | width [s] | 94 % HDI | [bins]
    white | -900.00 | 0.0043 | 0.00 | - | - | -
    gaussian | -850.50 | 0.05 | 49.50 | 0.0301 | [0.025, 0.036] | 3.01
    """
    rows = []
    for name, entry in summary["families"].items():
        width, bayes = entry["width"], entry["log_bayes_factor_vs_white"]
        cells = ["-", "-", "-"]
        if width is not None:
            seconds = width["seconds"]
            interval = f"[{seconds['hdi_3%']:.4g}, {seconds['hdi_97%']:.4g}]"
            cells = [f"{seconds['mean']:.4g}", interval, f"{width['bins']['mean']:.3g}"]
        # The error to two significant digits: bridge sampling's 0.004 read "0.00".
        rows.append([name, f"{entry['log_evidence']:.2f}", f"{entry['log_evidence_err']:.2g}",
                     "-" if bayes is None else f"{bayes:.2f}", *cells])  # fmt: skip
    return rows


def _lags(result: NoiseCharacterisation) -> int:
    """The autocorrelation figure's lags: :data:`LAG_WIDTHS` widths of the best family."""
    width = result.fits[result.best].width()
    wanted = LAGS if width is None else max(LAGS, int(np.ceil(LAG_WIDTHS * width["bins"]["mean"])))
    return min(wanted, len(result.series.values) // 4)


def _section(
    result: NoiseCharacterisation, figures: ReportFigures, rng: np.random.Generator
) -> str:
    """One series' section: provenance, verdict, warnings, tables, figures."""
    series, summary = result.series, result.to_dict()
    name = html.escape(series.name)
    parts = [
        f"<section><h2>{name}</h2><p>{len(series.values)} samples at {1 / series.dt:.4g} Hz "
        f"(dt = {series.dt:.4g} s), from <code>{html.escape(str(series.source))}</code>.</p>",
        f"<p><b>Verdict: {html.escape(summary['verdict_text'])}</b></p>",
    ]
    warnings = [f"{family}: {warning['message']}" for family, entry in summary["families"].items()
                for warning in entry["warnings"]]  # fmt: skip
    if warnings:
        items = "".join(f"<li>{html.escape(warning)}</li>" for warning in warnings)
        parts.append(f'<ul class="warnings">{items}</ul>')
    parts.append(html_table(list(NOISE_HEADER), noise_rows(summary)))
    classical = result.acf_least_squares
    parts.append(
        "<p>Classical widths [s]: least squares on the autocorrelation's first L lags, and the "
        f"thesis' fit ({THESIS_LAGS} lags).</p>"
        + html_table([f"L = {count}" for count in classical] + ["thesis' fit"],
                 [[f"{value:.4g}" for value in (*classical.values(), result.thesis_fit)]])
    )  # fmt: skip
    lags = _lags(result)
    bands = noise_predictive_bands(result, lags=lags, rng=rng)
    figures_html = [
        ("acf", "autocorrelation against the posterior-predictive bands",
         lambda: plot_noise_autocorrelation(result, lags=lags, predictive=bands)),
        ("psd", "Welch PSD against the posterior-predictive bands",
         lambda: plot_noise_spectrum(result, predictive=bands)),
        ("widths", "the width by each method (94 % HDI for the posteriors)",
         lambda: plot_noise_widths(result)),
    ]  # fmt: skip
    parts += [figures.html(_figure_name(series.name, kind), f"{series.name}: {caption}", draw)
              for kind, caption, draw in figures_html]  # fmt: skip
    parts.append("</section>")
    return "".join(parts)


def _figure_name(series: str, kind: str) -> str:
    """The name of a series' figure of a kind (``acf``, ``psd``, ``widths``), before its slug."""
    return f"{series}-{kind}"


def _check_results(results: Sequence[NoiseCharacterisation]) -> list[NoiseCharacterisation]:
    """Refuse no results, other objects, or two series whose figure files would be one.

    Two series of one name, or of names of one slug ("a b" and "a-b": both
    ``a-b-acf.png``), would overwrite each other's figures.
    """
    results = list(results)
    if not results or not all(isinstance(r, NoiseCharacterisation) for r in results):
        raise InputError(
            "expected one or more results of characterise_noise, got "
            f"{[type(r).__name__ for r in results] or 'none'}",
            field="results",
        )
    seen: dict[str, str] = {}
    for result in results:
        name = result.series.name
        stem = slug(_figure_name(name, "acf"))
        if stem in seen:
            other = seen[stem]
            clash = (f"two series named {name!r}" if other == name else
                     f"series {other!r} and {name!r} would write the same figure files "
                     f"({stem}.png, ...)")  # fmt: skip
            raise InputError(f"{clash}: rename one", field="results")
        seen[stem] = name
    return results


def render_noise_report(
    results: Sequence[NoiseCharacterisation],
    figures: ReportFigures,
    *,
    seed: int | None = 0,
) -> str:
    """The HTML text of the report on noise series: one section per series.

    Parameters
    ----------
    results : sequence of NoiseCharacterisation
        Of series of distinct names (and distinct figure file names).
    figures : ReportFigures
        Draws, embeds and saves the figures.
    seed : int, optional
        Seeds the predictive bands (series i draws from the i-th stream
        spawned from it): same seed, same page.

    Returns
    -------
    str
        One self-contained HTML page.

    Raises
    ------
    InputError
        For no results, objects of another type, or two series of one name
        or of names whose figure files would be one (:func:`~bayes_jackal.report.slug`).

    Examples
    --------
    A white-noise posterior built at the series' sd (not sampled):

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.report import render_noise_report
    >>> from bayes_jackal.report import ReportFigures
    >>> from bayes_jackal.noise import NoiseSeries
    >>> values = np.random.default_rng(1).standard_normal(600)
    >>> series = NoiseSeries(values=values, dt=0.01, name="imu")
    >>> white = FamilyFit(family="white", names=("sigma",), draws=np.ones((50, 1)), dt=0.01,
    ...                   evidence=Evidence(-851.2, 0.01, "bridge sampling"),
    ...                   diagnostics={"converged": True}, warnings=[])
    >>> result = NoiseCharacterisation(series=series, fits={"white": white},
    ...                                acf_least_squares={1: 0.0, 2: 0.0}, thesis_fit=0.001)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     text = render_noise_report([result], ReportFigures(Path(folder), ()))
    >>> text.startswith("<!DOCTYPE html>"), text.count("<section>"), text.count("<figure>")
    (True, 1, 3)
    """
    results = _check_results(results)
    streams = np.random.default_rng(seed).spawn(len(results))
    body = [_INTRODUCTION]
    body += [_section(r, figures, rng) for r, rng in zip(results, streams, strict=True)]
    what = f"series: {', '.join(result.series.name for result in results)}"
    return report_page("bayes_jackal noise report", what, figures, body)


def write_noise_report(
    results: Sequence[NoiseCharacterisation],
    out: str | Path,
    *,
    formats: tuple[str, ...] = REPORT_FORMATS,
    seed: int | None = 0,
) -> Path:
    """Write the HTML report on noise series, and its figures beside it.

    Parameters
    ----------
    results : sequence of NoiseCharacterisation
        :func:`bayes_jackal.characterise_noise`'s, of series of distinct names.
    out : str or Path
        The HTML file; figures go to ``<out stem>_figures/``, named
        ``<series>-acf``, ``<series>-psd`` and ``<series>-widths``.
    formats : tuple of str
        Figure files to write, from ``("png", "svg")`` (default PNG alone; every
        figure is embedded as PNG in any case).
    seed : int, optional
        As :func:`render_noise_report`'s.

    Returns
    -------
    Path
        The report.

    Raises
    ------
    InputError
        As :func:`render_noise_report`, or for an unknown format.

    Examples
    --------
    A white-noise posterior built at the series' sd (not sampled):

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from bayes_jackal.posterior import Evidence
    >>> from bayes_jackal.noise import FamilyFit, NoiseCharacterisation
    >>> from bayes_jackal.report import write_noise_report
    >>> from bayes_jackal.noise import NoiseSeries
    >>> values = np.random.default_rng(1).standard_normal(600)
    >>> series = NoiseSeries(values=values, dt=0.01, name="imu")
    >>> white = FamilyFit(family="white", names=("sigma",), draws=np.ones((50, 1)), dt=0.01,
    ...                   evidence=Evidence(-851.2, 0.01, "bridge sampling"),
    ...                   diagnostics={"converged": True}, warnings=[])
    >>> result = NoiseCharacterisation(series=series, fits={"white": white},
    ...                                acf_least_squares={1: 0.0, 2: 0.0}, thesis_fit=0.001)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = write_noise_report([result], Path(folder) / "noise_report.html",
    ...                               formats=("png",))
    ...     print(sorted(file.name for file in (Path(folder) / "noise_report_figures").iterdir()))
    ['imu-acf.png', 'imu-psd.png', 'imu-widths.png']
    """
    results = _check_results(results)
    return write_page(
        out, lambda figures: render_noise_report(results, figures, seed=seed), formats=formats
    )
