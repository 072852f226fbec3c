"""What the command line prints: the JSON/text reporter and the result tables."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from .._runtime import KIND_MEANINGS, json_text, write_line
from ..filters import inexact_note, method_text, score_rows
from ..thesis import GridResult

if TYPE_CHECKING:  # the workflow's stages are not loaded for the other commands
    from ..workflow import Analysis
from .exits import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK, print_failure


class Reporter:
    """Human text to stdout, or to stderr when stdout carries JSON."""

    def __init__(self, json_mode: bool):
        self.json_mode = json_mode

    def say(self, text: str = "") -> None:
        write_line(text, sys.stderr if self.json_mode else sys.stdout)

    def result(self, payload: dict) -> None:
        """With ``--json``, print ``payload`` as strict JSON (NaN and +-inf as null)."""
        if self.json_mode:
            sys.stdout.write(json_text(payload) + "\n")


def grid_table(result: GridResult, out: Reporter) -> None:
    summary = result.summary()
    out.say(
        f"{result.method} MSE of the {result.channel} channel over "
        f"d_lat {result.d_lat[0]:g}..{result.d_lat[-1]:g} ({len(result.d_lat)} values) x "
        f"d_long {result.d_long[0]:g}..{result.d_long[-1]:g} ({len(result.d_long)} values)"
    )
    out.say(f"{'':12s} {'runs':>5s} {'d_lat':>8s} {'d_long':>8s} {'ratio':>7s} {'MSE':>11s}")
    rows = [(label, len(s["experiments"]), s) for label, s in summary["series"].items()]
    rows.append(("total (5-3)", sum(n for _, n, _ in rows), summary))
    for label, runs, s in rows:
        out.say(
            f"{label:12s} {runs:5d} {s['d_lat']:8g} {s['d_long']:8g} "
            f"{s['d_lat'] / s['d_long']:7.3f} {s['mse']:11.4g}"
        )
    if result.caveat:
        out.say(f"note: {result.caveat}")


def grid_warnings(warnings: list[dict], flag: str) -> None:
    """Each ``grid-edge`` warning on stderr, with the flag that widens the grid.

    ``flag`` is formatted with the damping's ``name`` (``d_lat``) and its
    ``option`` (``d-lat``), e.g. ``"--{option} START STOP STEP"``.
    """
    for warning in warnings:
        name = warning["parameter"]
        widen = flag.format(name=name, option=name.replace("_", "-"))
        print(f"bayes-jackal: WARNING: {warning['message']} ({widen})", file=sys.stderr)


def residual_table(result: dict, out: Reporter) -> None:
    out.say(
        f"one-step residuals (eq. 7-3) of the steady-state window at d_lat={result['d_lat']:g}, "
        f"d_long={result['d_long']:g} N s/m; Ljung-Box and sigma_h fit over {result['lags']} lags"
    )
    out.say(
        f"{'experiment':12s} {'channel':7s} {'n':>6s} {'sd':>10s} {'LB p':>9s} "
        f"{'r1':>7s} {'sigma_h [s]':>11s}"
    )
    derived = False
    for name, channels in result["experiments"].items():
        for channel, row in channels.items():
            r1 = row["autocorrelation"][0]
            mark = "*" if row.get("derived") else ""
            derived |= bool(mark)
            out.say(
                f"{name:12s} {channel + mark:7s} {row['n']:6d} {row['sd']:10.4g} "
                f"{row['ljung_box_p']:9.3g} {r1:7.3f} {row['sigma_h']:11.3f}"
            )
    if derived:
        out.say(
            "* derived from motion-capture poses by the reader's smoother, as the thesis' data "
            "were: its sigma_h is the smoother's too; the posterior (sample) models the poses"
        )
    out.say()
    out.say("sigma_h of the yaw channel (thesis table 7-1: v1 0.051, v2 0.041, all 0.047 s)")
    out.say(f"{'series':12s} {'runs':>5s} {'sigma_h [s]':>11s}")
    members = result["series"]
    for label, value in result["sigma_h"].items():
        runs = len(result["experiments"]) if label == "all" else len(members[label])
        out.say(f"{label:12s} {runs:5d} {value:11.4f}")


def filter_table(name: str, scores: dict, out: Reporter) -> None:
    """One experiment's filter scores: innovation RMSE, NIS in its band, state RMSEs."""
    first = next(iter(scores.values()))["first_sample"]
    out.say(
        f"{name}: prediction errors scored from sample {first} on (the first start the filters)"
    )
    out.say(
        f"{'filter':16s} {'channel':7s} {'innov. RMSE':>11s} {'NIS':>6s} "
        f"{'95% band':>13s} {'':14s} {'state RMSE':>10s} {'smoothed':>10s}"
    )
    for filter_name, channel, rmse, nis, band, verdict, state, smoothed in score_rows(scores):
        out.say(
            f"{filter_name:16s} {channel:7s} {_number(rmse, '11.4g')} {_number(nis, '6.3f')} "
            f"{'-' if band is None else '[{:5.3f},{:5.3f}]'.format(*band):>13s} {verdict:14s} "
            f"{_number(state, '10.4g')} {_number(smoothed, '10.4g')}"
        )
    if note := inexact_note(scores):
        out.say(f"  {note}")


def _number(value: float | None, spec: str) -> str:
    """``value`` formatted, or a dash as wide where there is none."""
    width = int(spec.split(".")[0])
    return "-".rjust(width) if value is None else format(value, spec)


def posterior_table(summary: dict, out: Reporter) -> None:
    out.say(
        f"{'':16s} {'mean':>10s} {'sd':>10s} {'hdi_3%':>10s} {'hdi_97%':>10s} "
        f"{'ess':>8s} {'r_hat':>6s}"
    )
    for name, row in summary.items():
        if isinstance(row, dict) and "mean" in row:
            out.say(
                f"{name:16s} {row['mean']:10.4g} {row['sd']:10.3g} {row['hdi_3%']:10.4g} "
                f"{row['hdi_97%']:10.4g} {row.get('ess_autocorr', float('nan')):8.0f} "
                f"{row['r_hat']:6.3f}"
            )
    ratio = summary["ratio"]
    out.say(
        f"corr(d_lat, d_long) = {summary['corr_d_lat_d_long']:.3f}; d_lat/d_long 94 % HDI "
        f"[{ratio['hdi_3%']:.3f}, {ratio['hdi_97%']:.3f}] (thesis: {ratio['thesis']:.4f})"
    )
    taus = summary["autocorr_time"]
    status = "converged" if summary["converged"] else "NOT CONVERGED"
    longest = max(taus.values())
    out.say(
        f"{status}: {summary['n_steps']} steps, {summary['n_steps'] / longest:.0f} times the "
        f"longest autocorrelation time ({longest:.0f} steps); ess: effective draws, r_hat: "
        "the walkers' agreement (1 is best)"
    )


def warn_not_converged(what: str) -> None:
    """Warn on stderr that a prior comes from ``what``, a chain that did not converge."""
    print(f"bayes-jackal: WARNING: {what} is NOT CONVERGED; the prior inherits that",
          file=sys.stderr)  # fmt: skip


def print_criticism(findings: list[dict], *, where: str = "--json and the report") -> None:
    """Criticism warnings on stderr: one line per kind, then what the kinds mean.

    A kind found once is shown whole; found more often, its first message
    with the count and where the others are (``compare``: per family), or
    each whole where only their text tells them apart. The
    last line says in a phrase what each kind means
    (:data:`bayes_jackal._runtime.KIND_MEANINGS`) and ``where`` every
    warning is given in full.
    """
    groups: dict[tuple[str, str], list[dict]] = {}
    for finding in findings:
        groups.setdefault((finding.get("family", ""), finding["kind"]), []).append(finding)
    for (family, kind), group in groups.items():
        named = f"{family}: " if family else ""
        places = [_place(finding) for finding in group[1:]]
        if not places or not all(places):  # once, or not told apart but by its text
            for finding in group:
                print(f"bayes-jackal: WARNING: {named}{finding['message']}", file=sys.stderr)
            continue
        print(
            f"bayes-jackal: WARNING: {named}{kind} x{len(group)}: {group[0]['message']}; the "
            f"same at {', '.join(places)}",
            file=sys.stderr,
        )
    kinds = dict.fromkeys(kind for _, kind in groups)
    if kinds:
        meanings = "; ".join(f"{kind}: {KIND_MEANINGS.get(kind, kind)}" for kind in kinds)
        print(
            f"bayes-jackal: note: {len(findings)} warning(s): {meanings}. In full: {where}",
            file=sys.stderr,
        )


def _place(finding: dict) -> str:
    """Where a warning points, in a few words (experiment, channel, parameter, statistic).

    Empty for a warning that says it only in its text (a chain's convergence).
    """
    fields = ("experiment", "channel", "parameter", "statistic", "input", "left_out")
    return " ".join(str(finding[key]) for key in fields if key in finding)


def comparison_table(result: dict, out: Reporter) -> None:
    out.say(
        f"{'family':16s} {'log Z':>12s} {'+-':>6s} {'lnB best':>9s} {'lnB white':>10s}  "
        "width mean [94 % HDI] (s)"
    )
    for name, row in result["families"].items():
        widths = "; ".join(
            f"{label} {w['mean']:.4g} [{w['hdi_3%']:.4g}, {w['hdi_97%']:.4g}]"
            for label, w in (row["width"] or {}).items()
            if label != "hdi_prob"
        )
        versus_white = row["log_bayes_factor_vs_white"]
        out.say(
            f"{name:16s} {row['log_evidence']:12.2f} {row['log_evidence_err']:6.3f} "
            f"{row['log_bayes_factor_vs_best']:9.2f} "
            f"{'' if versus_white is None else f'{versus_white:10.2f}':>10s}  {widths or '-'}"
            + ("" if row["converged"] else "  NOT CONVERGED")
        )
        if "log_evidence_nested" in row:
            out.say(
                f"{'':16s} {row['log_evidence_nested']:12.2f} "
                f"{row['log_evidence_nested_err']:6.3f}  (nested sampling)"
            )
    out.say(f"best: {result['best']}. Verdict: {result['verdict_text']}")


def population_text(result: dict, out: Reporter) -> None:
    """``population``'s evidence table, each group's damping, the population and the verdicts."""
    out.say(f"{'structure':22s} {'log Z':>14s} {'+-':>6s} {'lnB best':>9s}")
    for name, row in result["evidence"].items():
        out.say(
            f"{name:22s} {row['log_evidence']:14.2f} {row['log_evidence_err']:6.3f} "
            f"{row['log_bayes_factor_vs_best']:9.2f}"
        )
    out.say(f"best: {result['best']}. Verdict: {result['verdict']}")
    out.say(f"each group's damping, mean [94 % HDI] (N s/m), {result['model']}:")
    for label, group in result["groups"].items():
        out.say(
            f"  {label:20s} "
            + "; ".join(f"{name} {_interval(group[name])}" for name in ("d_lat", "d_long"))
        )
    population = result["population"]
    out.say(
        "population mean: "
        + "; ".join(
            f"{name} {_interval(population[name]['mean']['N s/m'])}, a new group "
            f"{_interval(population[name]['new_group'])}"
            for name in ("d_lat", "d_long")
        )
    )
    if result["speed_dependence"] is not None:
        out.say(f"speed dependence: {result['speed_dependence']['verdict']}")
    for warning in result["warnings"]:
        print(f"bayes-jackal: WARNING: {warning['message']}", file=sys.stderr)


def _interval(row: dict) -> str:
    return f"{row['mean']:.4g} [{row['hdi_3%']:.4g}, {row['hdi_97%']:.4g}]"


def state_estimation_text(state: dict, out: Reporter) -> None:
    """analyse's filter scores on each run left out of the prior; its failures on stderr."""
    if state["skipped"]:
        out.say(f"State estimation on runs left out of the prior: not run, {state['skipped']}.")
        return
    out.say(f"\nState estimation with the {state['family']} prior fitted to the other runs:")
    refit = [run for run, record in state["runs"].items() if record["method"] == "refit"]
    if state["pooled"] is not None:
        out.say(
            f"posteriors without each run: {state['pooled']} reweighted (Pareto-smoothed "
            "importance sampling); where the reweighting is unreliable (Pareto k-hat "
            f"> {state['pareto_k_threshold']:g}), importance sampling from the Laplace fit on "
            "the other runs, or a refit: "
            + (f"{', '.join(refit)} refit" if refit else "none refit")
        )
    for run, record in state["runs"].items():
        trained = ", ".join(record["trained_on"])
        out.say(f"{run}: posterior without it by {method_text(record)}")
        filter_table(f"{run} (prior from {trained})", record["scores"], out)
        for name, reason in record["filters_failed"].items():
            print(f"bayes-jackal: WARNING: {run}: {name} could not run: {reason}", file=sys.stderr)
    for reason in state["failed"].values():
        print(f"bayes-jackal: WARNING: {reason}", file=sys.stderr)


def analysis_text(analysis: Analysis, out: Reporter) -> int:
    """Print what analyse_logs found; warnings and bad inputs on stderr; the exit code."""
    result = analysis.to_dict()
    out.say(
        f"\n{result['best']}-noise posterior (the best family by evidence), pooled over "
        f"{len(result['experiments'])} experiment(s), channels {', '.join(result['channels'])}:"
    )
    posterior_table(result["posterior"], out)
    out.say(f"Is the noise coloured? {result['comparison']['verdict_text']}")
    state_estimation_text(result["state_estimation"], out)
    if result["population"] is not None:
        population_text(result["population"], out)
    files = result["files"]
    out.say(
        f"Open {files['report']} in a browser. Also written: {files['prior']} (Active "
        f"Inference prior), {files['posterior']}, posteriors/, experiments/, grid_*.png, *.json."
    )
    for summary in result["grids"].values():  # the thesis' criteria, not the posterior's
        grid_warnings(
            summary["warnings"],
            "in grid.json; analyse's grids span the prior ranges, "
            "bayes-jackal grid --{option} START STOP STEP looks beyond them",
        )
    family_warnings(
        result["warnings"],
        result["comparison"],
        where="compare.json, posterior.json and the report",
    )
    for reason in result["failed"].values():
        print(f"bayes-jackal: error: {reason}", file=sys.stderr)
    out.result(result)
    return EXIT_BAD_INPUT if result["failed"] else EXIT_OK


def family_warnings(findings: list[dict], comparison: dict, *, where: str) -> None:
    """The best family's warnings (:func:`print_criticism`); a losing family's in one line each.

    ``comparison`` is a comparison's JSON (``best``, ``families``). The
    families that lost by evidence are not the result: a wrong model's
    posterior often piles at a bound, and its every warning would bury the
    ones that matter. Their warnings stay in ``where`` (the JSON, the report).
    """
    best = comparison["best"]
    print_criticism([w for w in findings if w.get("family", best) == best], where=where)
    others: dict[str, list[str]] = {}
    for warning in findings:
        if warning.get("family", best) != best:
            others.setdefault(warning["family"], []).append(warning["kind"])
    for family, kinds in others.items():
        versus = comparison["families"][family]["log_bayes_factor_vs_best"]
        counts = ", ".join(f"{kind} {kinds.count(kind)}" for kind in dict.fromkeys(kinds))
        print(
            f"bayes-jackal: note: {family} (ln B = {versus:.1f} against {best}, not the "
            f"posterior reported): {len(kinds)} criticism warnings ({counts}), listed in {where}",
            file=sys.stderr,
        )


class Failures:
    """Reports each input that fails as it fails (:func:`print_failure`); the exit code.

    Pass it as ``on_failure`` of :func:`~bayes_jackal._runtime.errors.each_input`.
    ``code`` is 0 while nothing failed, 2 when only bad inputs did, 1 when
    any input failed otherwise.
    """

    def __init__(self, debug: bool = False):
        self.debug = debug
        self.code = EXIT_OK

    def __call__(self, source: str, exc: Exception) -> None:
        code = print_failure(exc, source, debug=self.debug)
        self.code = EXIT_FAILURE if EXIT_FAILURE in (code, self.code) else code
