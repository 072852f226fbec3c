"""Self-contained HTML reports of posteriors, with every figure also saved for papers.

One report covers one or more posteriors, read from files or given in
memory (:func:`write_report`). This module reads them and assembles the
page (:func:`render_report`): a title, a summary of the answer and of what
to distrust, a banner naming the chains that did not converge, the
evidence tables, then one section per posterior. The
sections' content is :mod:`bayes_jackal.report.sections`'s; the figures are
embedded as PNG and written beside the report as PNG (and SVG on
request) by :mod:`bayes_jackal.report.figures`.
"""

from __future__ import annotations

import datetime
import html
import logging
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from .. import __version__
from .._runtime import (
    REPORT_FORMATS,
    InputError,
    Phase,
    atomic_path,
    az,
    each_input,
    refuse,
    refuse_link,
    removed_if_empty,
)
from ..posterior import Posterior, load_posterior
from .figures import ReportFigures, formats_text
from .sections import evidence_section, losing_banner, posterior_section, summary_section

__all__ = [
    "LAGS",
    "draw_posterior_sections",
    "posterior_sections",
    "read_posteriors",
    "render_report",
    "report_page",
    "save_report",
    "write_page",
    "write_report",
]

#: The stage's messages (INFO): :mod:`bayes_jackal._runtime.messages`.
_log = logging.getLogger(__package__)

#: Lags of the report's autocorrelation figures.
LAGS = 30
#: A further section of a report: given the figures, its HTML (:func:`render_report`).
Section = Callable[[ReportFigures], str]

_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto; color: #222; }
h1 { font-size: 1.6em; } h2 { margin-top: 2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th:first-child, td:first-child { text-align: left; }
.not-converged { color: #b00020; border: 2px solid #b00020; padding: 0.6em 1em;
  font-weight: bold; font-size: 1.1em; }
.simulated { background: #eef4fb; padding: 0.5em 1em; }
.summary { background: #f6f8f6; border-left: 4px solid #2e7d32; padding: 0.2em 1.2em 0.6em; }
.summary h2 { margin-top: 0.6em; } .not-converged-text { color: #b00020; font-weight: bold; }
.warnings li { color: #8a4b00; }
nav.contents { font-size: 0.9em; margin-top: 1.2em; } nav.contents ul { margin: 0.2em 0; }
.losing-entry { color: #b00020; }
figure { display: inline-block; margin: 0.5em; vertical-align: top; }
figure img { max-width: 100%; } figcaption { font-size: 0.85em; color: #555; }
"""

# Records, for a test in a real browser, that every image decoded and no
# script error happened; harmless for a reader.
_SELF_CHECK = """
window.reportErrors = [];
window.addEventListener('error', function (e) {
  window.reportErrors.push(String(e.message || (e.target && e.target.src) || e));
}, true);
window.addEventListener('load', function () {
  var images = Array.prototype.slice.call(document.images);
  var broken = images.filter(function (i) { return !(i.complete && i.naturalWidth > 0); });
  document.body.setAttribute('data-images', images.length);
  document.body.setAttribute('data-images-broken', broken.length);
  document.body.setAttribute('data-errors', window.reportErrors.length);
});
"""


def _posterior_files(path: str | Path) -> list[Path]:
    """The posterior file ``path``, or a folder's ``*.nc`` files, sorted.

    Raises
    ------
    InputError
        For a missing path or a folder without ``.nc`` files.
    """
    path = Path(path)
    if path.is_dir():
        found = sorted(path.glob("*.nc"))
        if not found:
            raise InputError("folder holds no posterior files (*.nc)", source=str(path))
        return found
    if not path.exists():
        raise InputError("no such file or folder", source=str(path))
    return [path]


def read_posteriors(
    paths: list[str | Path], *, on_failure: Callable[[str, Exception], None] | None = None
) -> tuple[list[tuple[Path, az.InferenceData]], dict[str, str]]:
    """Read every posterior of files and folders on its own, past bad ones.

    Parameters
    ----------
    paths : list of str or Path
        Posterior files, or folders of them (their ``*.nc`` files, sorted).
    on_failure : callable, optional
        ``on_failure(path, exception)``, called as each bad path or file is met.

    Returns
    -------
    posteriors : list of (Path, InferenceData)
    failed : dict of str to str
        Why each missing path, empty folder or unreadable file cannot be used
        (the reason names it), by path.

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged, as the report says in red), so that the example is quick:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import read_posteriors
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = bj.save_posterior(posterior, Path(folder) / "white.nc")
    ...     read, failed = read_posteriors([folder, Path(folder) / "gaussian.nc"])
    ...     print([path.name for path, _ in read], [Path(path).name for path in failed])
    ...     print(list(failed.values()))
    ['white.nc'] ['gaussian.nc']
    ['...gaussian.nc: no such file or folder']
    """
    found, failed = each_input(paths, _posterior_files, on_failure=on_failure)
    files = [file for group in found.values() for file in group]
    loaded, unreadable = each_input(files, load_posterior, on_failure=on_failure)
    return [(Path(path), idata) for path, idata in loaded.items()], failed | unreadable


def render_report(
    posteriors: list[tuple[Path, az.InferenceData]],
    figures: ReportFigures,
    lags: int = LAGS,
    *,
    sections: Sequence[Section] = (),
    highlights: Sequence[str] = (),
    drawn: Sequence[str] | None = None,
) -> str:
    """The HTML text of a report on loaded posteriors.

    Parameters
    ----------
    posteriors : list of (Path, arviz.InferenceData)
        Each posterior with the path that names it in the report
        (:func:`read_posteriors`).
    figures : ReportFigures
        Draws, embeds and saves the figures.
    lags : int
        Lags of the autocorrelation figures.
    sections : sequence of callable
        Further sections after the evidence tables, each called with
        ``figures`` and returning its HTML (``analyse`` adds
        :func:`~bayes_jackal.report.sections.state_estimation_section`).
    highlights : sequence of str
        Further lines of the summary at the top, as HTML (``analyse`` adds
        :func:`~bayes_jackal.report.sections.state_estimation_highlight`).
    drawn : sequence of str, optional
        Each posterior's section, in order, drawn beforehand
        (:func:`draw_posterior_sections`: ``analyse`` draws them while its
        filters run); None: drawn here (:func:`posterior_sections`).

    Returns
    -------
    str
        One self-contained HTML page.

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged, as the report says in red), so that the example is quick:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import render_report
    >>> from bayes_jackal.report import ReportFigures
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     figures = ReportFigures(Path(folder), ())  # embedded only: no figure files
    ...     text = render_report([(Path("white.nc"), posterior)], figures)
    >>> text.startswith("<!DOCTYPE html>"), text.count("<figure>")
    (True, 7)
    >>> "NOT CONVERGED: white.nc" in text
    True
    """
    body = [summary_section(posteriors, highlights)]
    stale = [p.name for p, i in posteriors if not Posterior.of(i).metadata.convergence.converged]
    if stale:
        body.append(
            f'<div class="not-converged">NOT CONVERGED: {html.escape(", ".join(stale))}. '
            "See the sections below.</div>"
        )
    body.append(evidence_section(posteriors))
    body += [section(figures) for section in sections]
    if drawn is None:
        drawn = posterior_sections(posteriors, figures, lags)
    elif len(drawn) != len(posteriors):
        raise InputError(
            f"{len(drawn)} sections drawn for {len(posteriors)} posteriors", field="drawn"
        )
    body += drawn
    what = f"posteriors: {', '.join(str(p) for p, _ in posteriors)}"
    return report_page("bayes_jackal report", what, figures, body)


def posterior_sections(
    posteriors: list[tuple[Path, az.InferenceData]], figures: ReportFigures, lags: int = LAGS
) -> list[str]:
    """Each posterior's section of a report, its figures drawn by ``figures``.

    A posterior that lost by evidence to another of ``posteriors`` says so
    under its title (:func:`~bayes_jackal.report.sections.losing_banner`).
    """
    parts = []
    for number, (path, idata) in enumerate(posteriors, 1):
        _log.info(
            f"  report: {path.name} ({number} of {len(posteriors)}): criticism and figures..."
        )
        banner = losing_banner(posteriors, idata)
        with Phase(
            f"  report: {path.name}", enabled=_log.isEnabledFor(logging.INFO), terminal_only=True
        ):
            parts.append(posterior_section(path, idata, figures, lags, banner))
    return parts


def draw_posterior_sections(
    paths: Sequence[str | Path],
    out: str | Path,
    formats: tuple[str, ...] = REPORT_FORMATS,
    lags: int = LAGS,
) -> list[str]:
    """The posterior files' sections of the report ``out``, drawn before the page.

    What :func:`save_report` takes as ``drawn``; the figures are written
    where the page's go (``<out stem>_figures/``, made). ``analyse`` draws
    them in a process of their own while its filters run.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import draw_posterior_sections, save_report
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = bj.save_posterior(posterior, Path(folder) / "white.nc")
    ...     out = Path(folder) / "report.html"
    ...     drawn = draw_posterior_sections([path], out, ("png",))
    ...     page = save_report([(path, posterior)], out, ("png",), drawn=drawn).read_text()
    ...     in_place = save_report([(path, posterior)], out, ("png",)).read_text()
    >>> len(drawn), page == in_place  # the page of the sections drawn in its place
    (1, True)
    """
    posteriors, failed = read_posteriors(list(paths))
    refuse(failed, len(paths))
    figures = _figures_beside(Path(out), formats)
    figures.folder.mkdir(parents=True, exist_ok=True)
    return posterior_sections(posteriors, figures, lags)


#: A section's heading: the report's own ``<h2>``/``<h3>``, which carry no attributes.
_HEADING = re.compile(r"<h([23])>(.*?)</h\1>", re.S)
#: What follows the heading of a family that lost by evidence (:func:`losing_banner`).
_LOSING = '<div class="not-converged losing">'


def _with_contents(body: str) -> str:
    """``body`` with an anchor on every section heading and their table of contents.

    The contents go after the summary (the page's first section, when it is
    one) or first; an entry of a family that lost by evidence says so.

    Examples
    --------
    >>> from bayes_jackal.report.page import _with_contents
    >>> page = _with_contents("<section><h2>A &amp; B</h2><h3>c</h3></section><h2>A &amp; B</h2>")
    >>> '<h2 id="a-b">' in page, '<h2 id="a-b-2">' in page, 'href="#c"' in page
    (True, True, True)
    """
    entries: list[tuple[int, str, str, bool]] = []
    seen: dict[str, int] = {}

    def anchor(match: re.Match) -> str:
        level, text = int(match[1]), match[2]
        slug = re.sub(r"[^a-z0-9]+", "-", html.unescape(re.sub("<[^>]+>", "", text)).lower())
        slug = slug.strip("-") or "section"
        seen[slug] = seen.get(slug, 0) + 1
        unique = slug if seen[slug] == 1 else f"{slug}-{seen[slug]}"
        losing = body.startswith(_LOSING, match.end())
        entries.append((level, unique, text, losing))
        return f'<h{level} id="{unique}">{text}</h{level}>'

    anchored = _HEADING.sub(anchor, body)
    items, open_sub = [], False
    for level, slug, text, losing in entries:
        if level == 3 and not open_sub:
            items.append("<ul>")
        if level == 2 and open_sub:
            items.append("</ul>")
        open_sub = level == 3
        mark = ' <span class="losing-entry">(not the reported posterior)</span>' if losing else ""
        items.append(f'<li><a href="#{slug}">{text}</a>{mark}</li>')
    items.append("</ul>" if open_sub else "")
    contents = f'<nav class="contents"><b>Contents</b><ul>{"".join(items)}</ul></nav>'
    split = anchored.index("</section>") + len("</section>") if anchored.startswith(
        '<section class="summary">') else 0  # fmt: skip
    return anchored[:split] + contents + anchored[split:]


def report_page(title: str, what: str, figures: ReportFigures, body: Sequence[str]) -> str:
    """A self-contained page: the report's style and self-check, a heading, provenance, ``body``.

    Every report of the package is one (:func:`render_report`,
    :func:`bayes_jackal.report.render_noise_report`): the same style,
    and the same script that records for a browser test whether every image
    decoded.

    Parameters
    ----------
    title : str
        The page's title and heading (plain text, escaped).
    what : str
        What the page reports on (plain text, escaped); the provenance line
        adds the package's version, the time [UTC] and the figures' folder.
    figures : ReportFigures
        The page's figures (only their folder's name is used here).
    body : sequence of str
        The page's HTML after the provenance line, joined as it is.

    Returns
    -------
    str
        The HTML page.

    Examples
    --------
    >>> from pathlib import Path
    >>> from bayes_jackal.report import report_page
    >>> from bayes_jackal.report import ReportFigures
    >>> figures = ReportFigures(Path("drift_figures"), ("png", "svg"))
    >>> page = report_page("drift <test>", "series: gyro", figures, ["<p>body</p>"])
    >>> page.startswith("<!DOCTYPE html>"), "<title>drift &lt;test&gt;</title>" in page
    (True, True)
    >>> "series: gyro. Figures as PNG and SVG in <code>drift_figures/</code>" in page
    True
    """
    created = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    files = formats_text(figures.formats)
    where = f" Figures as {files} in <code>{html.escape(figures.folder.name)}/</code>."
    head = (
        f"<h1>{html.escape(title)}</h1><p>bayes_jackal {__version__}, {created}; "
        f"{html.escape(what)}.{where if files else ''}</p>"
    )
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title>"
        f"<style>{_STYLE}</style><script>{_SELF_CHECK}</script></head>"
        f"<body>{head}{_with_contents(''.join(body))}</body></html>"
    )


def write_page(
    out: str | Path,
    render: Callable[[ReportFigures], str],
    *,
    formats: tuple[str, ...] = REPORT_FORMATS,
) -> Path:
    """Write the page ``render(figures)`` to ``out``, its figures to ``<out stem>_figures/``.

    The folder is made first (with its parents); the page is written
    atomically once rendered, so a failed rendering leaves no page behind.

    Parameters
    ----------
    out : str or Path
        The HTML file.
    render : callable
        ``render(figures)``: the page's text (e.g. of :func:`report_page`),
        given the :class:`~bayes_jackal.report.ReportFigures` that
        write its figures into the folder.
    formats : tuple of str
        Figure files to write, from ``("png", "svg")`` (default PNG alone; every
        figure is embedded as PNG in any case).

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    InputError
        For an unknown format, or when the figure folder's name holds a
        symbolic link (:func:`~bayes_jackal._runtime.output_safety.refuse_link`).
    OSError
        When the folder or the page cannot be written (e.g. a file stands
        where the folder should be).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from bayes_jackal.report import report_page, write_page
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = write_page(Path(folder) / "drift.html",
    ...                       lambda figures: report_page("drift", "nothing", figures, []))
    ...     print(path.name, sorted(file.name for file in Path(folder).iterdir()))
    drift.html ['drift.html', 'drift_figures']
    """
    out = Path(out)
    figures = _figures_beside(out, formats)
    with removed_if_empty([figures.folder], on_success=False):  # a failed page leaves none
        figures.folder.mkdir(parents=True, exist_ok=True)
        text = render(figures)
    with atomic_path(out) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return out


def _figures_beside(out: Path, formats: tuple[str, ...]) -> ReportFigures:
    """The figures of the page ``out``, in ``<out stem>_figures/`` (no link there)."""
    figures = ReportFigures(out.parent / f"{out.stem}_figures", formats)
    refuse_link(figures.folder, folder=True)
    return figures


#: The posteriors :func:`write_report` takes (see there).
Posteriors = str | Path | az.InferenceData | Sequence[str | Path | az.InferenceData] | Mapping


def _labelled(
    posteriors: Posteriors,
) -> tuple[list[tuple[Path, az.InferenceData]], dict[str, str], int]:
    """(label, posterior) pairs in order, unreadable inputs (path -> reason), input count."""
    if isinstance(posteriors, Mapping) and not isinstance(posteriors, az.InferenceData):
        items = [(str(label), item) for label, item in posteriors.items()]  # (a Mapping too)
    else:
        many = isinstance(posteriors, Sequence) and not isinstance(posteriors, str)
        items = [(None, item) for item in (posteriors if many else [posteriors])]
    labelled, failed, taken = [], {}, set()
    for label, item in items:
        if isinstance(item, az.InferenceData):
            posterior = Posterior.of(item)  # read once here, for every section and figure
            name = label or posterior.family
            free, count = name, 1
            while Path(free).stem in taken:
                count += 1
                free = f"{name}-{count}"
            found = [(Path(free), posterior)]
        elif isinstance(item, str | Path) and label is None:
            found, unreadable = read_posteriors([item])
            failed |= unreadable
        else:
            raise InputError(
                "expected posterior files or folders, posteriors in memory "
                f"(arviz.InferenceData) or a mapping of labels to them, got {item!r:.80}",
                field="posteriors",
            )
        taken |= {path.stem for path, _ in found}
        labelled += found
    return labelled, failed, len(items)


def write_report(
    posteriors: Posteriors,
    out: str | Path,
    *,
    formats: tuple[str, ...] = REPORT_FORMATS,
    lags: int = LAGS,
    sections: Sequence[Section] = (),
    highlights: Sequence[str] = (),
) -> Path:
    """Write the HTML report of posteriors, in files or in memory, and its figures beside it.

    Parameters
    ----------
    posteriors : path, arviz.InferenceData, sequence of them, or mapping
        Posterior files (``bayes-jackal sample`` or ``compare --out``),
        folders of them (their ``*.nc`` files, sorted), posteriors in memory
        (:func:`bayes_jackal.sample`), or a mapping of labels to posteriors
        in memory, e.g. a comparison's ``posteriors`` (family -> posterior).
        The report names each posterior where a file's name would be (its
        section title, the list of posteriors, figure file names): a file by
        its path, a posterior in memory by its mapping key, else by its
        noise family (``gaussian``; ``gaussian-2`` for a second one).
    out : str or Path
        The HTML file; figures go to ``<out stem>_figures/``.
    formats : tuple of str
        Figure files to write, from ``("png", "svg")`` (default PNG alone; every
        figure is embedded as PNG in any case).
    lags : int
        Lags of the autocorrelation figures.
    sections : sequence of callable
        Further sections after the evidence tables (:func:`render_report`).
    highlights : sequence of str
        Further lines of the summary at the top, as HTML (:func:`render_report`).

    Returns
    -------
    Path
        The report.

    Raises
    ------
    InputError
        Naming every missing file, empty folder and file that is not a
        posterior (:func:`read_posteriors`), or an input of another type.

    Examples
    --------
    A posterior in memory (20 steps for a quick example, far from
    converged, as the report says in red; real use takes the default cap):

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = bj.write_report(posterior, Path(folder) / "report.html", formats=("png",))
    ...     text = path.read_text()
    ...     print(path.name, "white: white noise on yaw" in text, "NOT CONVERGED" in text)
    report.html True True
    """
    labelled, failed, count = _labelled(posteriors)
    refuse(failed, count)
    return save_report(labelled, out, formats, lags, sections=sections, highlights=highlights)


def save_report(
    posteriors: list[tuple[Path, az.InferenceData]],
    out: str | Path,
    formats: tuple[str, ...] = REPORT_FORMATS,
    lags: int = LAGS,
    *,
    sections: Sequence[Section] = (),
    highlights: Sequence[str] = (),
    drawn: Sequence[str] | None = None,
) -> Path:
    """Write the HTML report of posteriors already read (:func:`read_posteriors`).

    Parameters and return value as :func:`write_report`; ``drawn``, the
    posteriors' sections drawn beforehand, as :func:`render_report`'s.

    Examples
    --------
    A posterior of a chain kept short on purpose (20 steps, far from
    converged, as the report says in red), so that the example is quick:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> from bayes_jackal.report import save_report
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=20, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     out = Path(folder) / "fit.html"
    ...     path = save_report([(Path("white.nc"), posterior)], out, ("png",))
    ...     figures = sorted(file.name for file in (Path(folder) / "fit_figures").iterdir())
    >>> path.name, len(figures), figures[0]
    ('fit.html', 7, 'white-criticism.png')
    """
    if not posteriors:
        raise InputError("no posterior files given", field="POSTERIOR")
    return write_page(
        out,
        lambda figures: render_report(
            posteriors, figures, lags, sections=sections, highlights=highlights, drawn=drawn
        ),
        formats=formats,
    )
