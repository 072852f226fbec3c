"""The HTML sections of a report: one per posterior, and the evidence tables.

:func:`posterior_section` writes one posterior's part of the page: a red
banner when the chain did not converge, the data's provenance (simulated
data are labelled with their truth), the summary table with its
diagnostics, the model criticism, and the figures of
:mod:`bayes_jackal.report.plots` (model against data, residuals, residual
autocorrelation and spectrum with the fitted filter's posterior-predictive
band per experiment and channel, walker traces, the (d_long, d_lat) ridge
and sigma_h beside thesis table 7-1). :func:`evidence_section` tables the
evidence of posteriors that carry one (``bayes-jackal compare --out``), one
table per data set. :func:`bayes_jackal.report.render_report` assembles
them into the page; these are its parts, not an API of their own.
:func:`population_section` is the section on a campaign's groups of runs
(:func:`bayes_jackal.population`), which ``analyse --groups`` adds.
:func:`state_estimation_section` is the analysis' section on the filters
its prior drives, on runs left out of the prior
(:mod:`bayes_jackal.filters.left_out`), with how each posterior without a run
was made (PSIS reweighting with its Pareto k-hat, or a refit), which
``analyse`` adds.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._runtime import CHANNELS, HDI_PROB, KIND_MEANINGS, az
from ..filters import FILTER_INEXACT, LeaveOneOut, inexact_note, score_rows
from ..inference import Comparison
from ..model import discrete_matrices
from ..posterior import PARETO_K_THRESHOLD, Posterior, summarize
from . import estimate_plots, plots, population_plots, predictive_plots
from .figures import ReportFigures

# The page's parts are for :mod:`bayes_jackal.report.page` only; its table serves every report.
__all__ = [
    "html_table",
    "population_highlight",
    "population_section",
    "state_estimation_highlight",
    "state_estimation_section",
]


def _number(value) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "-"
    return f"{value:.4g}" if isinstance(value, float) else html.escape(str(value))


def html_table(header: list[str], rows: list[list]) -> str:
    """An HTML table of a report: a header row, then one row per ``rows`` entry.

    Parameters
    ----------
    header : list of str
        The column names (plain text, escaped).
    rows : list of list
        Each row's cells: a float is written with 4 significant digits, a
        missing or non-finite one as ``-``, anything else as its text, escaped.

    Returns
    -------
    str
        ``<table>`` with ``<thead>`` and ``<tbody>``.

    Examples
    --------
    >>> from bayes_jackal.report import html_table
    >>> table = html_table(["family", "ln Z"], [["white", -851.23456], ["a<b", None]])
    >>> print(table.replace("<tr>", "\\n<tr>"))
    <table><thead>
    <tr><th>family</th><th>ln Z</th></tr></thead><tbody>
    <tr><td>white</td><td>-851.2</td></tr>
    <tr><td>a&lt;b</td><td>-</td></tr></tbody></table>
    """
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
    metadata = Posterior.of(idata).metadata
    dt = metadata.experiments[0].dt
    Ad, _ = discrete_matrices(metadata.robot, truth["d_lat"], truth["d_long"], dt)
    total = {
        c: float(np.hypot(truth["sigma_c"][c], truth["sigma_n"][c] * np.hypot(1.0, Ad[i, i])))
        for i, c in enumerate(CHANNELS)
        if c in truth["sigma_n"]  # a bag's pose channels have sigma_p (bag_writer.bag_truth)
    }
    return truth | {"sigma_c": truth["sigma_c"] | total}


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
    table = html_table(
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
    convergence = Posterior.of(idata).metadata.convergence
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


def summary_section(
    posteriors: list[tuple[Path, az.InferenceData]], highlights: Sequence[str] = ()
) -> str:
    """The report's opening: the answer, and what to distrust, in thirty seconds.

    Of the reported posterior (:func:`reported_posterior`): the damping with
    its interval and the ratio beside it, the noise family and width, the
    verdict on colour from the evidence of the families fitted to the same
    data, the chain's state, then ``highlights`` (HTML lines of further
    sections, e.g. :func:`state_estimation_highlight`), and each kind of
    warning once, with what it means. Simulated data say so, with whether
    the truth was held.
    """
    path, idata = reported_posterior(posteriors)
    metadata = Posterior.of(idata).metadata
    summary = summarize(idata)
    runs = ", ".join(e.name for e in metadata.experiments)
    lines = [
        _damping_summary(summary, metadata.truth),
        _noise_summary(summary, metadata),
        _colour_summary(posteriors, idata),
        f"<b>Chain</b>: {_chain_summary(summary)}; {len(metadata.experiments)} run(s) "
        f"({html.escape(runs)}), channels {', '.join(summary['channels'])}; "
        f"<code>{html.escape(path.name)}</code>.",
        *highlights,
    ]
    items = "".join(f"<li>{line}</li>" for line in lines)
    return (
        '<section class="summary"><h2>Summary</h2>'
        + ('<p class="simulated">SIMULATED data with known truth.</p>' if metadata.truth else "")
        + f"<p>Posterior means, {100 * HDI_PROB:.0f} % HDIs in brackets.</p><ul>{items}</ul>"
        + f"<p><b>What to distrust</b></p>{_distrust(summary['warnings'])}"
        + "</section>"
    )


def reported_posterior(
    posteriors: list[tuple[Path, az.InferenceData]],
) -> tuple[Path, az.InferenceData]:
    """The posterior a report's summary reports: of highest evidence on the first's data.

    Among the posteriors fitted to the same runs as the first that carry a
    log evidence; the first where none does.
    """
    rivals = _with_evidence(posteriors).get(_runs(posteriors[0][1]))
    if not rivals:
        return posteriors[0]
    return max(rivals, key=lambda item: Posterior.of(item[1]).metadata.evidence.log_evidence)


def _runs(idata: az.InferenceData) -> tuple[str, ...]:
    return tuple(e.name for e in Posterior.of(idata).metadata.experiments)


def _with_evidence(
    posteriors: list[tuple[Path, az.InferenceData]],
) -> dict[tuple[str, ...], list[tuple[Path, az.InferenceData]]]:
    """The posteriors that carry a log evidence, grouped by the runs they were fitted to."""
    groups: dict[tuple[str, ...], list[tuple[Path, az.InferenceData]]] = {}
    for path, idata in posteriors:
        if Posterior.of(idata).metadata.evidence is not None:
            groups.setdefault(_runs(idata), []).append((path, idata))
    return groups


def losing_banner(posteriors: list[tuple[Path, az.InferenceData]], idata: az.InferenceData) -> str:
    """A banner for a posterior that lost by evidence to another family on the same runs.

    Empty for the best family (the reported posterior) and for a posterior
    without a rival.
    """
    rivals = _with_evidence(posteriors).get(_runs(idata), [])
    evidence = {m.family: m.evidence for m in (Posterior.of(i).metadata for _, i in rivals)}
    family = Posterior.of(idata).metadata.family
    if family not in evidence or len(evidence) < 2:
        return ""
    best = max(evidence, key=lambda name: evidence[name].log_evidence)
    if best == family:
        return ""
    value = evidence[family].log_evidence - evidence[best].log_evidence
    return (
        f'<div class="not-converged losing">NOT THE REPORTED POSTERIOR: the {html.escape(family)} '
        f"family lost to {html.escape(best)} on these runs (ln B = {value:.1f}). Shown for "
        "comparison only: its damping and noise are not the estimate.</div>"
    )


def _hdi(row: dict, unit: str = "") -> str:
    """``mean unit [low, high]`` (the HDI), three significant digits."""
    return f"{row['mean']:.3g}{unit} [{row['hdi_3%']:.3g}, {row['hdi_97%']:.3g}]"


def _damping_summary(summary: dict, truth: dict | None) -> str:
    ratio = summary["ratio"]
    text = (
        f"<b>Damping</b>: d_lat = {_hdi(summary['d_lat'], ' N s/m')}, d_long = "
        f"{_hdi(summary['d_long'], ' N s/m')}; their ratio d_lat/d_long = {_hdi(ratio)}"
    )
    spread = {name: summary[name]["sd"] / summary[name]["mean"] for name in ("d_lat", "ratio")}
    if spread["ratio"] < 0.5 * spread["d_lat"]:
        text += (
            f", known far better than either (correlation "
            f"{summary['corr_d_lat_d_long']:.3f}: the two move together along a ridge)"
        )
    if truth:
        missed = [
            name
            for name in ("d_lat", "d_long")
            if not summary[name]["hdi_3%"] <= truth[name] <= summary[name]["hdi_97%"]
        ]
        held = "both inside their intervals" if not missed else f"{' and '.join(missed)} missed"
        text += f". Truth: {truth['d_lat']:g} and {truth['d_long']:g} N s/m, {held}"
    return text + "."


def _noise_summary(summary: dict, metadata) -> str:
    layout = metadata.layout
    family = html.escape(metadata.family)
    if layout.width_name is None:
        return f"<b>Noise</b>: {family} (no correlation time)."
    widths = ", ".join(
        f"{html.escape(name)} = {_hdi(summary[name], ' s')}"
        for name in layout.names_of(layout.width_name)
    )
    return f"<b>Noise</b>: {family} family, width {widths}."


def _colour_summary(
    posteriors: list[tuple[Path, az.InferenceData]], idata: az.InferenceData
) -> str:
    """The verdict on colour from the families fitted to the reported posterior's runs."""
    fitted = {
        Posterior.of(i).metadata.family: i
        for _, i in _with_evidence(posteriors).get(_runs(idata), [])
    }
    evidence = {family: Posterior.of(i).metadata.evidence for family, i in fitted.items()}
    verdict = Comparison(list(_runs(idata)), evidence, fitted).verdict()[1]
    return f"<b>Is the noise coloured?</b> {html.escape(verdict)}."


def _chain_summary(summary: dict) -> str:
    tau = max(summary["autocorr_time"].values())
    steps = f"{summary['n_steps']} steps ({summary['n_steps'] / tau:.0f} autocorrelation times)"
    if summary["converged"]:
        return f"converged, {steps}"
    return (
        f'<span class="not-converged-text">NOT CONVERGED after {steps}: every number '
        "is preliminary</span>"
    )


def _distrust(warnings: list[dict]) -> str:
    """Each kind of warning once: what it means, its first message, how many."""
    if not warnings:
        return (
            "<p>Nothing flagged: prior bounds, the damping's scale, residual-input "
            "correlation, the residuals' predicted colour and the runs' steadiness all "
            "passed their checks (section <i>Model criticism</i> below).</p>"
        )
    kinds: dict[str, list[dict]] = {}
    for warning in warnings:
        kinds.setdefault(warning["kind"], []).append(warning)
    items = "".join(
        f"<li><b>{html.escape(KIND_MEANINGS.get(kind, kind))}</b> ({html.escape(kind)}"
        f"{f', {len(found)} times' if len(found) > 1 else ''}): "
        f"{html.escape(found[0]['message'])}</li>"
        for kind, found in kinds.items()
    )
    return f'<ul class="warnings">{items}</ul>'


def evidence_section(posteriors: list[tuple[Path, az.InferenceData]]) -> str:
    """Evidence tables, one per data set, from posteriors that carry one."""
    parts = []
    for names, members in _with_evidence(posteriors).items():
        metadata = [Posterior.of(idata).metadata for _, idata in members]
        evidence = {m.family: m.evidence.to_dict() for m in metadata}
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
            + html_table(["family", "log Z", "error", "ln B vs best", "ln B vs white"], rows)
        )
    if not parts:
        return ""
    return (
        "<h2>Evidence</h2><p>Log evidence by bridge sampling; ln B on Kass &amp; Raftery's "
        "scale: &lt; 1 not worth a mention, 1-3 positive, 3-5 strong, &gt; 5 very strong.</p>"
        + "".join(parts)
    )


def _criticism_section(idata: az.InferenceData, figures: ReportFigures, prefix: str) -> str:
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
    steady = html_table(
        ["experiment", "start [s]", "duration [s]", "wheel speeds off median", "yaw-rate drift",
         "steady"],
        [
            [name, row["start"], row["duration"], _percent(row["input_deviation"]),
             _percent(row["yaw_drift"]), "yes" if row["steady"] else "no"]
            for name, numbers in criticism["steadiness"].items()
            for row in numbers.get("segments", [numbers])
        ],
    )  # fmt: skip
    return (
        "<h3>Model criticism</h3>"
        + listing
        + "<p>Steadiness of each segment of the runs (their command steps; the steady "
        "window with --steady). Transients are data: an unsteady segment is not a fault, "
        "the model covers it. Tolerances as for the detected window: wheel speeds 5 %, "
        "yaw-rate drift 10 %; - where the wheels stand still:</p>"
        + steady
        + "<p>Residual-input cross-correlation over the whole run at the posterior median "
        "(MATLAB <code>resid</code>; band from the residuals' own autocorrelation), and "
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
    return html_table(
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


def posterior_section(
    path: Path, idata: az.InferenceData, figures: ReportFigures, lags: int, banner: str = ""
) -> str:
    """One posterior's ``<section>``, titled by ``path``'s name, its figures drawn by ``figures``.

    ``lags`` is the largest lag of the autocorrelation figures; ``banner``
    goes under the title (:func:`losing_banner`). A family that lost (a
    banner) gets the figures a reader compares with the winner's (its
    criticism, damping and traces), not each run's: those are drawn where
    it is reported alone. Per run they were 16 of the demo's 39 figures
    for the losing family, 40 % of the report's time.
    """
    metadata = Posterior.of(idata).metadata
    experiments = metadata.experiments
    channels = metadata.channels
    family = metadata.family
    title = f"{path.name}: {family} noise on {', '.join(channels)}"
    truth = metadata.truth
    parts = [f"<section><h2>{html.escape(title)}</h2>", banner]
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
    if banner:
        parts.append(
            "<p>Each run's figures (model, residuals, autocorrelation, spectrum) are drawn "
            "for the reported posterior; a report on this posterior alone "
            f"(<code>bayes-jackal report {html.escape(str(path))}</code>) draws them for "
            "this family.</p></section>"
        )
        return "".join(parts)
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
            draws = predictive_plots.predictive_bands(idata, i, channel, lags=lags, rng=0)
            parts.append(
                figures.html(
                    f"{prefix}-{name}-{channel}-acf",
                    f"{name}: {channel} autocorrelation",
                    lambda i=i, c=channel, p=draws: predictive_plots.plot_autocorrelation(
                        idata, i, c, lags, predictive=p
                    ),
                )
            )
            parts.append(
                figures.html(
                    f"{prefix}-{name}-{channel}-psd",
                    f"{name}: {channel} spectrum",
                    lambda i=i, c=channel, p=draws: predictive_plots.plot_spectrum(
                        idata, i, c, predictive=p
                    ),
                )
            )
    parts.append("</section>")
    return "".join(parts)


def _filter_rows(run: str, record: dict) -> list[list]:
    """A left-out run's table rows: per filter and channel, its scores."""
    trained = ", ".join(record["trained_on"])
    return [
        [run, trained, name, channel, rmse, nis,
         None if band is None else "{:.3f}-{:.3f}".format(*band), verdict, state, smoothed]
        for name, channel, rmse, nis, band, verdict, state, smoothed
        in score_rows(record["scores"])
    ]  # fmt: skip


def state_estimation_highlight(result: LeaveOneOut) -> str | None:
    """The summary's line on the filters: on the runs left out, how often each is consistent.

    Per filter that predicts, over every run left out and channel: how many
    have a consistent NIS and how many its prediction error is the lowest
    of; None where nothing ran.
    """
    rows = [
        (run, *row) for run, record in result.runs.items() for row in score_rows(record["scores"])
    ]
    predicted = [row for row in rows if row[6] != "no prediction"]
    if not predicted:
        return None
    lowest: dict[tuple[str, str], tuple[float, str]] = {}
    for run, name, channel, rmse, *_ in predicted:
        lowest[run, channel] = min(lowest.get((run, channel), (rmse, name)), (rmse, name))
    parts = []
    for name in dict.fromkeys(row[1] for row in predicted):
        mine = [row for row in predicted if row[1] == name]
        consistent = sum(row[6] == "consistent" for row in mine)
        inexact = sum(row[6] == FILTER_INEXACT for row in mine)
        best = sum(winner == name for _, winner in lowest.values())
        parts.append(
            f"<b>{html.escape(name)}</b> consistent on {consistent} of {len(mine)}"
            + (f" ({FILTER_INEXACT} on {inexact}: the exact filter under the same prior is "
               "consistent there, so the prior holds and the filter's variance is off)"
               if inexact else "")
            + f", lowest prediction error on {best}"
        )  # fmt: skip
    return (
        f"<b>Filters</b> driven by the {html.escape(result.family)} prior on the runs left out "
        f"(run and channel): {'; '.join(parts)} (section <i>State estimation</i> below)."
    )


#: How a posterior without a run was made, in the report's table.
_METHOD_NAMES = {"psis": "PSIS reweighting", "importance": "importance sampling", "refit": "refit"}


def _left_out_posteriors(result: LeaveOneOut) -> str:
    """How each posterior without a run was made: PSIS diagnostics, and which runs were refit."""
    threshold = f"{PARETO_K_THRESHOLD:g}"
    rows = [
        [
            run,
            _METHOD_NAMES[record["method"]],
            record["pareto_k"],
            record["weights_ess"],
            record["draws"],
            record["refit_reason"] or "-",
        ]
        for run, record in result.runs.items()
    ]
    again = {
        label: [run for run, record in result.runs.items() if record["method"] == method]
        for label, method in (("By importance sampling", "importance"), ("Refit", "refit"))
    }
    said = " ".join(f"{label}: {html.escape(', '.join(runs))}." for label, runs in again.items()
                    if runs)  # fmt: skip
    source = html.escape(result.pooled) if result.pooled else "none was given"
    return (
        "<h3>The posterior without each run</h3><p>Each is the analysis' pooled posterior "
        f"of every run (<code>{source}</code>) reweighted by Pareto-smoothed importance "
        "sampling (PSIS): each draw weighted by the inverse of the left-out run's likelihood, "
        "the largest weights smoothed by a generalised Pareto fit, the draws resampled with "
        f"them. The fit's shape k-hat says whether the weights can be trusted: at most "
        f"{threshold}, they can (Vehtari et al. 2024; arviz's threshold); above {threshold}, "
        "the run moves the posterior further than the pooled draws reach, and its posterior "
        "is sampled again from the other runs: by importance sampling from its Laplace fit "
        "at their MAP where the same test passes for those weights, else by a chain (refit). "
        "The weights' ESS, 1 / sum of their "
        "squares, is how many independent draws they are worth. "
        + (said or "No run needed sampling again.")
        + "</p>"
        + html_table(
            ["left out", "posterior", "Pareto k-hat", "weights ESS", "draws", "why not PSIS"],
            rows,
        )
    )


def state_estimation_section(result: LeaveOneOut, figures: ReportFigures) -> str:
    """The section "State estimation with this prior": the left-out runs' scores, a figure.

    ``result`` is :func:`bayes_jackal.filters.leave_one_out`'s.
    """
    family = html.escape(result.family)
    parts = [
        "<section><h2>State estimation with this prior</h2><p>Does the identified noise "
        "model help estimation, on data the prior has not seen? Each run is left out in "
        f"turn: the {family}-noise posterior given the other runs (below: how), its Active "
        "Inference prior is exported (as the analysis' <code>prior.json</code> is), and "
        "the filters driven by that prior estimate the states of the run left out. "
        "<b>kalman</b> assumes white process noise (the baseline); <b>kalman-coloured</b> "
        "carries the family's shaping filter in its state, the best linear filter under the "
        "identified model; "
        "<b>generalised</b> is the DEM D-step in generalised coordinates of the prior's "
        "embedding order. Each filter predicts every measurement from the ones before it. "
        "The innovation RMSE is the size of its prediction errors [channel units]: lower "
        "is better. The normalised innovation squared (NIS) is the mean squared prediction "
        "error divided by the variance the filter gave it: 1 on average when the filter's "
        "account of its uncertainty is right, above 1 when it is overconfident, below 1 "
        "when it is too cautious; it falls in the 95 % band when the model holds. The state "
        "RMSE against the true state is known only for simulated runs; the smoothed one is "
        "that of the Kalman filters' smoother, which also uses the samples after each one. "
        "Where vx and vy were recorded as motion-capture poses, <b>derived</b> scores the "
        "velocities the reader derived from them (a Savitzky-Golay derivative centred on each "
        "sample, itself a smoother): the baseline the smoothers have to beat. The estimates "
        "are in "
        "<code>state_estimation/&lt;run&gt;.csv</code>, the scores in "
        "<code>state_estimation.json</code>.</p>"
    ]
    if result.skipped:
        parts.append(f"<p>Not run: {html.escape(result.skipped)}.</p></section>")
        return "".join(parts)
    parts.append(_left_out_posteriors(result))
    problems = [f"leaving out {run}: {reason}" for run, reason in result.failed.items()]
    for run, record in result.runs.items():
        problems += [f"{run}: {filter_name} could not run: {reason}"
                     for filter_name, reason in record["filters_failed"].items()]  # fmt: skip
        problems += [f"leaving out {run}: {message}" for message in record["warnings"]]
    if problems:
        items = "".join(f"<li>{html.escape(problem)}</li>" for problem in problems)
        parts.append(f'<ul class="warnings">{items}</ul>')
    rows = [row for run, record in result.runs.items() for row in _filter_rows(run, record)]
    header = ["left out", "prior from", "filter", "channel", "innovation RMSE", "NIS",
              "95 % band", "verdict", "state RMSE", "smoothed state RMSE"]  # fmt: skip
    parts.append(html_table(header, rows))
    notes = [f"{run}: {note}" for run, record in result.runs.items()
             if (note := inexact_note(record["scores"]))]  # fmt: skip
    if notes:
        items = "".join(f"<li>{html.escape(note)}</li>" for note in notes)
        parts.append(f'<ul class="notes">{items}</ul>')
    for name, (experiment, estimates) in result.estimates.items():
        start, stop = estimate_plots.shown_window(experiment)
        parts.append(
            figures.html(
                f"state-estimation-{name}",
                f"{name} (left out): each filter's estimate with its +-2 sd band "
                f"against the measurements, {start:.1f}-{stop:.1f} s",
                lambda e=experiment, x=estimates: estimate_plots.plot_state_estimates(e, x),
            )
        )
    parts.append("</section>")
    return "".join(parts)


def population_highlight(summary: dict) -> str:
    """The summary's line on the groups: the best structure's verdict, and the speed's."""
    speed = summary["speed_dependence"]
    return (
        f"<b>Groups of runs</b>: {html.escape(summary['verdict'])}"
        + ("" if speed is None else f"; {html.escape(speed['verdict'])}")
        + " (section <i>Groups of runs</i> below)."
    )


def population_section(summary: dict, figures: ReportFigures) -> str:
    """The section "Groups of runs": each structure's evidence and the forest plot.

    ``summary`` is :meth:`bayes_jackal.inference.Population.to_dict`'s.
    """
    evidence = [
        [name, row["log_evidence"], row["log_evidence_err"], row["log_bayes_factor_vs_best"]]
        for name, row in summary["evidence"].items()
    ]
    warnings = "".join(f"<li>{html.escape(w['message'])}</li>" for w in summary["warnings"])
    return (
        "<section><h2>Groups of runs</h2><p>Each group's damping, and how the groups relate: "
        "one damping for all (<b>pooled</b>), each group's own drawn from one population "
        "(<b>hierarchical</b>), or each its own (<b>independent</b>); with a covariate, each "
        "also with log d linear in it (<b>+ slope</b>). Each unit (a group's runs, or a run) "
        "was sampled alone with the best family, then combined (docs/guide/population.md); "
        f"the result is in <code>population.json</code>. "
        f"<b>Verdict</b>: {html.escape(summary['verdict'])}.</p>"
        + html_table(["structure", "log Z", "+-", "ln B vs best"], evidence)
        + (f'<ul class="warnings">{warnings}</ul>' if warnings else "")
        + figures.html(
            "population",
            "each unit's and group's damping (94 % HDI) with the population's band",
            lambda: population_plots.plot_population(summary),
        )
        + "</section>"
    )
