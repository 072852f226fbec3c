"""Self-contained HTML reports of posteriors, with every figure also saved for papers.

One report covers one or more posterior files. Per file: a red banner when
the chain did not converge; the data's provenance (simulated data are
labelled with their truth); the summary table with its diagnostics; and the
figures of :mod:`bayes_jackal.plots`: model against data, residuals,
residual autocorrelation and spectrum with the fitted filter's
posterior-predictive band (per experiment and channel), walker traces, the
(d_long, d_lat) ridge and sigma_h beside thesis table 7-1. Posteriors that
carry an evidence (``bayes-jackal compare --out``) add an evidence table per
data set. Figures are embedded as PNG and written beside the report as PNG
and SVG.
"""

from __future__ import annotations

import base64
import datetime
import html
import io
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from . import __version__, plots
from ._files import atomic_path
from .errors import InputError, each_input, refuse
from .physics import CHANNELS, discrete_matrices
from .posterior import (
    az,
    load_posterior,
    posterior_metadata,
    summarize,
)

__all__ = [
    "FIGURE_FORMATS",
    "LAGS",
    "read_posteriors",
    "render_report",
    "save_report",
    "write_report",
]

FIGURE_FORMATS = ("png", "svg")
#: Lags of the report's autocorrelation figures.
LAGS = 30
#: Resolution of the embedded and saved PNGs [dots per inch].
DPI = 130

_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto; color: #222; }
h1 { font-size: 1.6em; } h2 { margin-top: 2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th:first-child, td:first-child { text-align: left; }
.not-converged { color: #b00020; border: 2px solid #b00020; padding: 0.6em 1em;
  font-weight: bold; font-size: 1.1em; }
.simulated { background: #eef4fb; padding: 0.5em 1em; }
.warnings li { color: #8a4b00; }
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
    """
    found, failed = each_input(paths, _posterior_files, on_failure=on_failure)
    files = [file for group in found.values() for file in group]
    loaded, unreadable = each_input(files, load_posterior, on_failure=on_failure)
    return [(Path(path), idata) for path, idata in loaded.items()], failed | unreadable


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "figure"


class _Figures:
    """Renders figures to embedded PNG and saves them as PNG/SVG files."""

    def __init__(self, folder: Path, formats: tuple[str, ...]):
        unknown = [f for f in formats if f not in FIGURE_FORMATS]
        if unknown:
            raise InputError(
                f"unknown figure formats {unknown}; use {list(FIGURE_FORMATS)}", field="formats"
            )
        self.folder, self.formats = folder, formats

    def html(self, name: str, caption: str, draw: Callable[[], tuple[Figure, object]]) -> str:
        fig, _ = draw()
        rendered = {}
        for suffix in ("png", *self.formats):
            if suffix not in rendered:
                buffer = io.BytesIO()
                fig.savefig(buffer, format=suffix, dpi=DPI)
                rendered[suffix] = buffer.getvalue()
        for suffix in self.formats:
            path = self.folder / f"{_slug(name)}.{suffix}"
            with atomic_path(path) as temporary:
                temporary.write_bytes(rendered[suffix])
        data = base64.b64encode(rendered["png"]).decode("ascii")
        return (
            f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )


def _number(value) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "-"
    return f"{value:.4g}" if isinstance(value, float) else html.escape(str(value))


def _table(header: list[str], rows: list[list]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{_number(v)}</td>" for v in row) + "</tr>" for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _truth_value(truth: dict | None, label: str, channels: list[str]):
    """The simulated truth of a summary row (e.g. ``sigma_c[yaw]``), when known."""
    if not truth:
        return None
    base, _, group = label.partition("[")
    group = group.rstrip("]") or (channels[0] if len(channels) == 1 else "")
    if base in ("width", "sigma_h"):
        return truth.get("width")
    if base == "ratio":
        return truth["d_lat"] / truth["d_long"]
    value = truth.get(base)
    return value.get(group) if isinstance(value, dict) else value


def _model_truth(idata: az.InferenceData, truth: dict | None) -> dict | None:
    """The truth in the model's terms.

    With one total sd (white noise, diagonal sensor term) sigma_c stands for
    the residual's lag-0 sd at the truth, sqrt(sigma_c^2 + sigma_n^2 (1 + Ad^2)):
    process noise plus the sensor noise's footprint n[k+1] - Ad n[k].
    """
    if not truth or "sigma_n" in idata.posterior.data_vars:
        return truth
    metadata = posterior_metadata(idata)
    dt = metadata.experiments[0].dt
    Ad, _ = discrete_matrices(metadata.robot, truth["d_lat"], truth["d_long"], dt)
    total = {
        c: float(np.hypot(truth["sigma_c"][c], truth["sigma_n"][c] * np.hypot(1.0, Ad[i, i])))
        for i, c in enumerate(CHANNELS)
    }
    return truth | {"sigma_c": total}


def _summary_section(idata: az.InferenceData, truth: dict | None) -> str:
    summary = summarize(idata)
    channels = summary["channels"]
    rows = [
        [
            label,
            row["mean"],
            row["sd"],
            row["hdi_3%"],
            row["hdi_97%"],
            row.get("ess_autocorr"),
            row["ess_bulk"],
            row["r_hat"],
            _truth_value(truth, label, channels),
        ]
        for label, row in summary.items()
        if isinstance(row, dict) and "mean" in row
    ]
    table = _table(
        [
            "parameter",
            "mean",
            "sd",
            "hdi 3%",
            "hdi 97%",
            "ESS (tau)",
            "ESS bulk",
            "R-hat",
            "truth",
        ],
        rows,
    )
    convergence = posterior_metadata(idata).convergence
    taus = summary["autocorr_time"]
    diagnostics = (
        f"<p>{summary['n_steps']} steps of {convergence.walkers} walkers; longest "
        f"autocorrelation time {max(taus.values()):.0f} steps "
        f"({summary['n_steps'] / max(taus.values()):.0f} tau; converged when > "
        f"{convergence.settings['autocorr_multiple']:g} and stable); acceptance "
        f"{convergence.acceptance_fraction:.2f}; corr(d_lat, d_long) = "
        f"{summary['corr_d_lat_d_long']:.3f}; thesis ratio 11/3 = 3.667. R-hat over walkers "
        "is a secondary check: emcee's walkers are not independent chains.</p>"
    )
    return table + diagnostics


def _evidence_section(posteriors: list[tuple[Path, az.InferenceData]]) -> str:
    """Evidence tables, one per data set, from posteriors that carry one."""
    data_sets: dict[tuple, list] = {}
    for path, idata in posteriors:
        metadata = posterior_metadata(idata)
        if metadata.evidence is not None:
            names = tuple(e.name for e in metadata.experiments)
            data_sets.setdefault(names, []).append((path, metadata))
    parts = []
    for names, members in data_sets.items():
        evidence = {m.family: m.evidence.to_dict() for _, m in members}
        best = max(evidence.values(), key=lambda e: e["log_evidence"])["log_evidence"]
        white = evidence.get("white", {}).get("log_evidence")
        rows = [
            [
                family,
                f"{e['log_evidence']:.2f}",
                f"{e['log_evidence_err']:.3f}",
                f"{e['log_evidence'] - best:.2f}",
                "-" if white is None else f"{e['log_evidence'] - white:.2f}",
            ]
            for family, e in sorted(evidence.items(), key=lambda item: -item[1]["log_evidence"])
        ]
        parts.append(
            f"<h3>{html.escape(', '.join(names))}</h3>"
            + _table(["family", "log Z", "error", "ln B vs best", "ln B vs white"], rows)
        )
    if not parts:
        return ""
    return (
        "<h2>Evidence</h2><p>Log evidence by bridge sampling; ln B on Kass &amp; Raftery's "
        "scale: &lt; 1 not worth a mention, 1-3 positive, 3-5 strong, &gt; 5 very strong.</p>"
        + "".join(parts)
    )


def _criticism_section(idata: az.InferenceData, figures: _Figures, prefix: str) -> str:
    """Model criticism: the warnings, the numbers behind them, and their figure."""
    summary = summarize(idata)
    found, criticism = summary["warnings"], summary["criticism"]
    items = "".join(
        f"<li><b>{html.escape(w['kind'])}</b>: {html.escape(w['message'])}</li>" for w in found
    )
    listing = (
        f'<ul class="warnings">{items}</ul>'
        if found
        else "<p>No warnings: every check passed.</p>"
    )
    steady = _table(
        ["experiment", "window [s]", "wheel speeds off median", "yaw-rate drift"],
        [
            [name, row["duration"], _percent(row["input_deviation"]), _percent(row["yaw_drift"])]
            for name, row in criticism["steadiness"].items()
        ],
    )
    return (
        "<h3>Model criticism</h3>"
        + listing
        + "<p>Steadiness of the analysed windows (tolerances as for the detected window: "
        "wheel speeds 5 %, yaw-rate drift 10 %; - where the wheels stand still):</p>"
        + steady
        + "<p>Residual-input cross-correlation over the whole run at the posterior median "
        "(MATLAB <code>resid</code>; band from the model's residual autocorrelation), and "
        "posterior-predictive p-values of the residual autocorrelation (flagged at a "
        "family-wise 5 % per experiment and channel: Bonferroni over both tails of its "
        "statistics; - where a short run has no such statistic):</p>"
        + _criticism_table(criticism)
        + figures.html(
            f"{prefix}-criticism",
            "model criticism: residual-input cross-correlation and ACF p-values",
            lambda: plots.plot_criticism(idata),
        )
    )


def _percent(value: float | None) -> str | None:
    return None if value is None else f"{100 * value:.1f} %"


def _criticism_table(criticism: dict) -> str:
    """Residual-input test and predictive p-values, one row per experiment and channel.

    The p-value columns are the union of every row's statistics (a short run
    has fewer lags): a row without one shows "-".
    """
    tests = criticism["predictive_acf"]
    p_values = {
        (name, channel): dict(zip(row["statistics"], row["p_values"], strict=True))
        for name, rows in tests.items()
        for channel, row in rows.items()
    }
    statistics = list(dict.fromkeys(s for values in p_values.values() for s in values))
    return _table(
        ["experiment", "channel", "max |z| residual-input", "99 % level", *statistics],
        [
            [
                name,
                channel,
                row["max_abs_z"],
                row["threshold"],
                *(p_values[name, channel].get(s) for s in statistics),
            ]
            for name, rows in criticism["residual_input"].items()
            for channel, row in rows.items()
        ],
    )


def _posterior_section(path: Path, idata: az.InferenceData, figures: _Figures, lags: int) -> str:
    metadata = posterior_metadata(idata)
    experiments = metadata.experiments
    channels = metadata.channels
    family = metadata.family
    title = f"{path.name}: {family} noise on {', '.join(channels)}"
    truth = metadata.truth
    parts = [f"<section><h2>{html.escape(title)}</h2>"]
    if not metadata.convergence.converged:
        parts.append(
            '<div class="not-converged">NOT CONVERGED: the chain stopped at '
            f"{metadata.convergence.n_steps} steps, fewer than the convergence criterion "
            "needs. Treat every number below as preliminary; resume the run with more "
            "steps.</div>"
        )
    names = ", ".join(e.name for e in experiments)
    parts.append(
        f"<p>Experiments ({len(experiments)}{', pooled' if len(experiments) > 1 else ''})"
        f": {html.escape(names)}. Sensor noise {metadata.layout.sensor}, engine "
        f"{metadata.engine}."
        + (
            ""
            if "sigma_n" in idata.posterior.data_vars
            else " White noise with the diagonal sensor term has one variance: sigma_c is "
            "the total sd (process and sensor noise together)."
        )
        + "</p>"
    )
    if truth:
        parts.append(
            '<p class="simulated">SIMULATED data with known truth: d_lat = '
            f"{truth['d_lat']:g}, d_long = {truth['d_long']:g} N s/m, {truth['family']} noise "
            f"of width {truth['width']:g} s.</p>"
        )
    parts.append(_summary_section(idata, _model_truth(idata, truth)))
    prefix = path.stem
    parts.append(_criticism_section(idata, figures, prefix))
    parts.append(
        figures.html(
            f"{prefix}-damping",
            "posterior of (d_long, d_lat) and the ridge",
            lambda: plots.plot_damping(idata),
        )
    )
    if "sigma_h" in metadata.layout.noise_bases:  # the thesis' width: the Gaussian's
        parts.append(
            figures.html(
                f"{prefix}-sigma_h",
                "sigma_h beside thesis table 7-1",
                lambda: plots.plot_sigma_h(idata),
            )
        )
    parts.append(
        figures.html(f"{prefix}-traces", "walker traces", lambda: plots.plot_traces(idata))
    )
    for i, experiment in enumerate(experiments):
        name = experiment.name
        parts.append(f"<h3>{html.escape(name)}</h3>")
        parts.append(
            figures.html(
                f"{prefix}-{name}-model",
                f"{name}: model against data",
                lambda i=i: plots.plot_model_fit(idata, i),
            )
        )
        parts.append(
            figures.html(
                f"{prefix}-{name}-residuals",
                f"{name}: residuals",
                lambda i=i: plots.plot_residuals(idata, i),
            )
        )
        for channel in channels:
            # One set of posterior-predictive statistics serves both figures.
            draws = plots.predictive_bands(idata, i, channel, lags=lags, rng=0)
            parts.append(
                figures.html(
                    f"{prefix}-{name}-{channel}-acf",
                    f"{name}: {channel} autocorrelation",
                    lambda i=i, c=channel, p=draws: plots.plot_autocorrelation(
                        idata, i, c, lags, predictive=p
                    ),
                )
            )
            parts.append(
                figures.html(
                    f"{prefix}-{name}-{channel}-psd",
                    f"{name}: {channel} spectrum",
                    lambda i=i, c=channel, p=draws: plots.plot_spectrum(idata, i, c, predictive=p),
                )
            )
    parts.append("</section>")
    return "".join(parts)


def render_report(
    posteriors: list[tuple[Path, az.InferenceData]], figures: _Figures, lags: int = LAGS
) -> str:
    """The HTML text of a report on loaded posteriors."""
    created = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    body = [
        "<h1>bayes_jackal report</h1>",
        f"<p>bayes_jackal {__version__}, {created}; posteriors: "
        f"{html.escape(', '.join(str(p) for p, _ in posteriors))}. Figures as PNG and SVG in "
        f"<code>{html.escape(figures.folder.name)}/</code>.</p>",
    ]
    stale = [p.name for p, i in posteriors if not posterior_metadata(i).convergence.converged]
    if stale:
        body.append(
            f'<div class="not-converged">NOT CONVERGED: {html.escape(", ".join(stale))}. '
            "See the sections below.</div>"
        )
    body.append(_evidence_section(posteriors))
    body += [_posterior_section(path, idata, figures, lags) for path, idata in posteriors]
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        "<title>bayes_jackal report</title>"
        f"<style>{_STYLE}</style><script>{_SELF_CHECK}</script></head>"
        f"<body>{''.join(body)}</body></html>"
    )


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
            name = label or posterior_metadata(item).family
            free, count = name, 1
            while Path(free).stem in taken:
                count += 1
                free = f"{name}-{count}"
            found = [(Path(free), item)]
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
    formats: tuple[str, ...] = FIGURE_FORMATS,
    lags: int = LAGS,
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
        Figure files to write, from ``("png", "svg")``.
    lags : int
        Lags of the autocorrelation figures.

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
    A posterior in memory (200 steps for a quick example, far from
    converged, as the report says in red; real use takes the default cap):

    >>> import tempfile
    >>> from pathlib import Path
    >>> import bayes_jackal as bj
    >>> run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1)
    >>> posterior = bj.sample([run], family="white", channels=["yaw"], max_steps=200, seed=1)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = bj.write_report(posterior, Path(folder) / "report.html", formats=("png",))
    ...     text = path.read_text()
    ...     print(path.name, "white: white noise on yaw" in text, "NOT CONVERGED" in text)
    report.html True True
    """
    labelled, failed, count = _labelled(posteriors)
    refuse(failed, count)
    return save_report(labelled, out, formats, lags)


def save_report(
    posteriors: list[tuple[Path, az.InferenceData]],
    out: str | Path,
    formats: tuple[str, ...] = FIGURE_FORMATS,
    lags: int = LAGS,
) -> Path:
    """Write the HTML report of posteriors already read (:func:`read_posteriors`).

    Parameters and return value as :func:`write_report`.
    """
    if not posteriors:
        raise InputError("no posterior files given", field="POSTERIOR")
    out = Path(out)
    figures = _Figures(out.parent / f"{out.stem}_figures", formats)
    figures.folder.mkdir(parents=True, exist_ok=True)
    text = render_report(posteriors, figures, lags)
    with atomic_path(out) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return out
