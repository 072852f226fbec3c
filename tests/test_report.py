"""HTML reports: content, figure files, bad input, and rendering in a real browser."""

from __future__ import annotations

import html
import itertools
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import messages

from bayes_jackal.cli import main
from bayes_jackal.posterior.posterior import load_posterior, save_posterior
from bayes_jackal.report import plots
from bayes_jackal.report.sections import _criticism_table

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: Flags for headless Chromium as root in a sandbox without network.
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--enable-logging=stderr",
    "--v=0",
    "--virtual-time-budget=20000",
]


@pytest.fixture(scope="module")
def posteriors(yaw_vx_posterior, tmp_path_factory) -> dict[str, Path]:
    """A short (unconverged: 120 steps) yaw+vx posterior, and the same marked converged.

    This module's copy of ``yaw_vx_posterior`` (tests/conftest.py), saved, then marked.
    """
    folder = tmp_path_factory.mktemp("posteriors")
    short = save_posterior(yaw_vx_posterior, folder / "short.nc")
    yaw_vx_posterior.posterior.attrs["converged"] = 1
    return {"short": short, "converged": save_posterior(yaw_vx_posterior, folder / "converged.nc")}


def test_the_envelope_holds_each_bins_min_and_max(monkeypatch):
    monkeypatch.setattr(plots, "MAX_POINTS", 8)  # 4 bins
    t = np.arange(10.0)
    y = np.random.default_rng(2).normal(size=10)
    centres, low, high = plots._envelope(t, y, -y)
    edges = [0, 2, 5, 7, 10]  # np.linspace(0, 10, 5) truncated
    assert centres.tolist() == [0.0, 3.0, 5.0, 8.0]  # each bin's middle sample (lower one)
    assert low.tolist() == [y[a:b].min() for a, b in itertools.pairwise(edges)]
    assert high.tolist() == [(-y[a:b]).max() for a, b in itertools.pairwise(edges)]


def test_a_long_run_is_drawn_with_at_most_max_points_per_curve(posteriors, monkeypatch):
    monkeypatch.setattr(plots, "MAX_POINTS", 200)
    idata = load_posterior(posteriors["converged"])
    residuals = idata.observed_data["residual_yaw_0"].values
    assert len(residuals) > 5 * plots.MAX_POINTS
    for draw in (plots.plot_model_fit, plots.plot_residuals):
        _, axes = draw(idata, 0)
        lines = [line.get_xdata() for ax in axes for line in ax.lines]
        paths = [path.vertices for ax in axes for c in ax.collections for path in c.get_paths()]
        assert paths
        # fill_between closes its polygon with a few vertices more than 2 x points.
        assert max(map(len, lines), default=0) <= plots.MAX_POINTS
        assert max(map(len, paths)) <= 2 * plots.MAX_POINTS + 4
    # The residuals' envelope spans them exactly.
    (envelope,) = axes[0].collections
    vertices = envelope.get_paths()[0].vertices[:, 1]
    assert (vertices.min(), vertices.max()) == (residuals.min(), residuals.max())


def _report(paths, out: Path, *extra) -> tuple[int, str]:
    code = main(["report", *map(str, paths), "--out", str(out), *extra])
    return code, out.read_text() if out.exists() else ""


def test_report_embeds_every_figure_and_saves_png_and_svg(posteriors, tmp_path, capsys):
    code, text = _report(
        [posteriors["converged"]], tmp_path / "report.html", "--formats", "png,svg"
    )
    assert code == 0
    images = re.findall(r'<img alt="[^"]*" src="data:image/png;base64,', text)
    # damping, sigma_h, traces, criticism; model and residuals; acf and psd of 2 channels.
    assert len(images) == 4 + 2 + 2 * 2
    figures = tmp_path / "report_figures"
    pngs, svgs = sorted(figures.glob("*.png")), sorted(figures.glob("*.svg"))
    assert len(pngs) == len(svgs) == len(images)
    assert all(p.read_bytes().startswith(b"\x89PNG") for p in pngs)
    assert all(b"<svg" in p.read_bytes()[:2000] for p in svgs)
    assert "NOT CONVERGED" not in text
    assert "SIMULATED data with known truth" in text
    # The summary states the damping with its interval and whether the truth was held.
    summary = text[text.index('<section class="summary">') : text.index("<section>")]
    assert re.search(r"d_lat = [\d.]+ N s/m \[[\d.]+, [\d.]+\]", summary)
    assert "Truth: 110 and 30 N s/m" in summary
    assert "Is the noise coloured?</b> white noise and a coloured family must both" in summary
    for label in ("d_lat", "sigma_h[yaw]", "sigma_c[vx]", "ratio", "R-hat", "ESS (tau)"):
        assert label in text
    for label in (">Model criticism</h3>", "max |z| residual-input", "acf[1]", "Q[1..30]"):
        assert label in text


def test_an_unconverged_posterior_says_so_at_the_top_in_red(posteriors, tmp_path):
    code, text = _report([posteriors["short"]], tmp_path / "report.html")  # PNG by default
    assert code == 0
    assert "Figures as PNG in <code>report_figures/</code>." in text
    banner = text.index('<div class="not-converged">NOT CONVERGED')
    assert banner < text.index("<section>")
    # The summary above it says so too, and that its numbers are preliminary.
    summary = text[text.index('<section class="summary">') : banner]
    assert "NOT CONVERGED after 120 steps" in summary and "preliminary" in summary
    assert re.search(r"\.not-converged \{ color: #b00020", text)
    assert not list((tmp_path / "report_figures").glob("*.svg"))


def test_an_evidence_table_appears_for_compared_families(compared, tmp_path):
    # compare --out stores each family's evidence in its posterior's attributes:
    # the session's comparison of a simulated v1 run, white and gaussian on yaw
    # (tests/conftest.py), read here, the report written elsewhere.
    folder = compared.folder
    assert compared.code == 0, compared.err
    code, text = _report([folder], tmp_path / "report.html", "--formats", "png")
    assert code == 0
    evidence = json.loads((folder / "v1_01.compare.json").read_text())
    assert '<h2 id="evidence">Evidence</h2>' in text
    assert f"<td>{evidence['families']['gaussian']['log_evidence']:.2f}</td>" in text
    # White noise cannot produce the residuals' colour: the criticism says so.
    assert "predictive-acf" in {w["kind"] for w in evidence["families"]["white"]["warnings"]}
    for warning in evidence["warnings"]:
        assert html.escape(warning["message"]) in text
    # The report opens with a summary of the family of highest evidence (issue 24, item 11).
    summary = text[text.index('<section class="summary">') :]
    summary = summary[: summary.index("</section>")]
    assert text.index('<section class="summary">') < text.index('<h2 id="evidence">Evidence</h2>')
    best = evidence["best"]
    assert f"<code>{best}.nc</code>" in summary.replace("v1_01.", "")
    assert html.escape(evidence["verdict_text"]) in summary
    row = evidence["families"][best]
    assert "<b>Damping</b>: d_lat = " in summary and "their ratio d_lat/d_long = " in summary
    shown = [w for w in evidence["warnings"] if w["family"] == best]
    for kind in {w["kind"] for w in shown}:
        assert f"({kind}" in summary
    if not shown:
        assert "Nothing flagged" in summary
    assert row["converged"] == ("NOT CONVERGED" not in summary)
    # The losing family's section says it is not the reported posterior (issue 37, item 18).
    loser = next(name for name in evidence["families"] if name != best)
    sections = {name: text[text.index(f'<h2 id="v1-01-{name}-nc') :] for name in (best, loser)}
    banner = f"NOT THE REPORTED POSTERIOR: the {loser} family lost to {best}"
    assert banner in sections[loser][: sections[loser].index("</h2>") + 400]
    assert "NOT THE REPORTED POSTERIOR" not in sections[best].split("<section>")[0]
    # The loser's figures are those a reader compares; each run's are the winner's alone
    # (its criticism, damping, traces; the winner's also its run's model, residuals,
    # and yaw acf and psd), and its report alone draws them.
    files = {path.stem for path in (tmp_path / "report_figures").glob("*.png")}
    assert {name for name in files if name.startswith(f"v1_01.{loser}")} == {
        f"v1_01.{loser}-{figure}" for figure in ("criticism", "damping", "traces")
    }
    runs = {"model", "residuals", "yaw-acf", "yaw-psd"}
    assert {f"v1_01.{best}-v1_01-{figure}" for figure in runs} <= files
    assert f"bayes-jackal report {folder / f'v1_01.{loser}.nc'}</code>" in sections[loser]
    code, alone = _report([folder / f"v1_01.{loser}.nc"], tmp_path / "alone.html")
    assert code == 0 and alone.count("<figure>") == 3 + len(runs)
    # Contents after the summary, an anchor per section, the loser's entry marked (item 18).
    contents = text[text.index('<nav class="contents">') : text.index("</nav>")]
    assert text.index("</section>") < text.index('<nav class="contents">')
    entries = {name: contents[contents.index(f'href="#v1-01-{name}-nc') :].split("</li>")[0]
               for name in (best, loser)}  # fmt: skip
    assert "(not the reported posterior)" in entries[loser]
    assert "not the reported" not in entries[best]
    assert 'href="#evidence"' in contents and 'href="#model-criticism"' in contents


def test_the_criticism_table_aligns_runs_with_different_statistics():
    # A 15-sample run has lags 1, 2, 5 and Q[1..7] only; the long run has all
    # five statistics. Every row has one cell per column, "-" where it lacks one.
    tests = {
        "long": {
            "yaw": {
                "statistics": ["acf[1]", "acf[2]", "acf[5]", "acf[10]", "Q[1..30]"],
                "p_values": [0.1, 0.2, 0.3, 0.4, 0.5],
            }
        },
        "short": {
            "yaw": {
                "statistics": ["acf[1]", "acf[2]", "acf[5]", "Q[1..7]"],
                "p_values": [0.6, 0.7, 0.8, 0.9],
            }
        },
    }
    residual = {name: {"yaw": {"max_abs_z": 1.0, "threshold": 3.9}} for name in tests}
    table = _criticism_table({"predictive_acf": tests, "residual_input": residual})
    header = re.findall(r"<th>(.*?)</th>", table)
    rows = [re.findall(r"<td>(.*?)</td>", row) for row in re.findall(r"<tr>(.*?)</tr>", table)[1:]]
    assert header[4:] == ["acf[1]", "acf[2]", "acf[5]", "acf[10]", "Q[1..30]", "Q[1..7]"]
    assert [dict(zip(header, row, strict=True)) for row in rows] == [
        {
            "experiment": "long",
            "channel": "yaw",
            "max |z| residual-input": "1",
            "99 % level": "3.9",
            "acf[1]": "0.1",
            "acf[2]": "0.2",
            "acf[5]": "0.3",
            "acf[10]": "0.4",
            "Q[1..30]": "0.5",
            "Q[1..7]": "-",
        },
        {
            "experiment": "short",
            "channel": "yaw",
            "max |z| residual-input": "1",
            "99 % level": "3.9",
            "acf[1]": "0.6",
            "acf[2]": "0.7",
            "acf[5]": "0.8",
            "acf[10]": "-",
            "Q[1..30]": "-",
            "Q[1..7]": "0.9",
        },
    ]


@pytest.mark.parametrize(
    ("make", "pattern"),
    [
        (lambda d: d / "absent.nc", r"absent\.nc: no such file"),
        (lambda d: (d / "empty").mkdir() or d / "empty", r"empty: folder holds no posterior"),
        (
            lambda d: (d / "notes.nc").write_text("not netcdf") and d / "notes.nc",
            r"notes\.nc: not a readable posterior",
        ),
    ],
)
def test_report_bad_input_exits_2_naming_the_file(tmp_path, capsys, make, pattern):
    code, _ = _report([make(tmp_path)], tmp_path / "out" / "report.html")
    captured = capsys.readouterr()
    assert code == 2
    assert "Traceback" not in captured.err
    assert re.search(pattern, captured.err), captured.err
    assert not (tmp_path / "out" / "report.html").exists()


def test_an_experiment_file_is_not_a_posterior(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path), "--seed", "2", "--v1", "0", "--v2", "1"]) == 0
    code, _ = _report([tmp_path / "v2_01.nc"], tmp_path / "report.html")
    assert code == 2
    assert "v2_01.nc: not a bayes_jackal posterior" in capsys.readouterr().err


def render(page: Path, tmp_path: Path) -> tuple[dict[str, int], list[str]]:
    """Load a page in headless Chromium: the self-check's counts and console errors."""
    result = subprocess.run(
        [
            CHROMIUM,
            *CHROMIUM_FLAGS,
            f"--user-data-dir={tmp_path / 'profile'}",
            "--dump-dom",
            page.resolve().as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    body = re.search(r"<body([^>]*)>", result.stdout)
    assert body, result.stdout[:500]
    counts = {k: int(v) for k, v in re.findall(r'data-([a-z-]+)="(\d+)"', body.group(1))}
    console = [line for line in result.stderr.splitlines() if ":CONSOLE" in line]
    return counts, console


@pytest.mark.skipif(CHROMIUM is None, reason="Debian package chromium is not installed")
def test_the_report_renders_in_chromium_with_every_figure_loaded(posteriors, tmp_path):
    page = tmp_path / "report.html"
    assert (
        _report([posteriors["short"], posteriors["converged"]], page, "--formats", "png")[0] == 0
    )
    counts, console = render(page, tmp_path)
    assert counts == {"images": 20, "images-broken": 0, "errors": 0}, counts
    assert console == []


@pytest.mark.skipif(CHROMIUM is None, reason="Debian package chromium is not installed")
def test_the_browser_check_catches_a_broken_figure_and_a_script_error(tmp_path):
    # The check above can fail: a page with a missing image and a bad script.
    from bayes_jackal.report.page import _SELF_CHECK

    page = tmp_path / "broken.html"
    page.write_text(
        f"<html><head><script>{_SELF_CHECK}</script></head><body>"
        '<img src="missing.png"><script>no_such_function()</script></body></html>'
    )
    counts, console = render(page, tmp_path)
    assert counts["images-broken"] == 1 and counts["errors"] >= 1
    assert any("no_such_function" in line for line in console)


def test_a_long_report_says_how_many_figures_it_has_drawn(tmp_path, monkeypatch):
    # report of two posteriors under load: 8 minutes with nothing after
    # "(1 of 2)" (issue 37, item 16). Each figure past LOG_INTERVAL says so.
    from matplotlib.figure import Figure

    from bayes_jackal.report import ReportFigures, figures

    monkeypatch.setattr(figures, "LOG_INTERVAL", 0.0)
    drawer = ReportFigures(tmp_path, ("png",))
    with messages() as said:
        for name in ("v1: acf", "v1: psd"):
            drawer.html(name, "a figure", lambda: (Figure(), None))
    assert said == ["  report: 1 figures drawn, the last v1: acf",
                    "  report: 2 figures drawn, the last v1: psd"]  # fmt: skip
