"""The report on bare noise series: its replicates, its figures, its page and the command.

The characterisations are built from chosen posterior draws (no sampling),
so that what is drawn can be compared with closed forms: the family's
autocorrelation (:mod:`bayes_jackal.model.kernels`) and the replicates' variance
sigma_c^2 + sigma_n^2. One small end-to-end run of ``bayes-jackal noise
--out`` checks that the command writes the report.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt  # only to see that it never holds a figure
import numpy as np
import pytest
from matplotlib.figure import Figure
from test_report import CHROMIUM, render

from bayes_jackal._runtime.errors import InputError
from bayes_jackal.cli import main
from bayes_jackal.model.kernels import FAMILIES, get_family
from bayes_jackal.noise.characterisation import FamilyFit, NoiseCharacterisation
from bayes_jackal.noise.series import NoiseSeries
from bayes_jackal.posterior import predictive
from bayes_jackal.posterior.criticism import PREDICTIVE_DRAWS
from bayes_jackal.posterior.records import Evidence
from bayes_jackal.posterior.series_statistics import (
    sample_autocorrelation,
    spectrum,
)
from bayes_jackal.report.noise_page import NOISE_HEADER, noise_rows, write_noise_report
from bayes_jackal.report.noise_plots import (
    noise_predictive_bands,
    plot_noise_autocorrelation,
    plot_noise_spectrum,
    plot_noise_widths,
    replicate_statistics,
)

matplotlib.use("Agg")

DT = 0.01
#: The coloured part's and the floor's sds of the built posteriors.
SIGMA_C, SIGMA_N = 1.0, 0.5
#: Widths [s] of the built posteriors: 3 samples, the issue's range's middle.
WIDTH = 0.03
LAGS = 30


@pytest.fixture(autouse=True)
def no_pyplot_figures():
    """Each test leaves pyplot without figures (it should never have had one)."""
    yield
    open_figures = plt.get_fignums()
    plt.close("all")
    assert open_figures == []


def family_fit(family: str, draws: np.ndarray, log_evidence: float, warnings=()) -> FamilyFit:
    """A fit of chosen draws (natural units) and evidence, converged."""
    width = get_family(family).width_name
    names = ("sigma",) if width is None else (width, "sigma_c", "sigma_n")
    return FamilyFit(
        family=family,
        names=names,
        draws=draws,
        dt=DT,
        diagnostics={"converged": True},
        evidence=Evidence(log_evidence, 0.05, "bridge sampling"),
        warnings=list(warnings),
    )


def coloured_draws(width: float, count: int = 400, spread: float = 0.05, seed: int = 0):
    """Draws around (width, SIGMA_C, SIGMA_N), log-normal spread ``spread``."""
    rng = np.random.default_rng(seed)
    centre = np.array([width, SIGMA_C, SIGMA_N])
    return centre * np.exp(spread * rng.standard_normal((count, 3)))


def characterisation(family: str, n: int = 2000, name: str = "gyro", seed: int = 1, **fits):
    """A series of ``n`` samples of ``family``'s noise at the draws' centre, and its fits.

    ``fits`` maps family names to draws; by default ``family`` around WIDTH
    (best) and white noise at the total sd.
    """
    rng = np.random.default_rng(seed)
    values = get_family(family).noise(WIDTH, DT, n, scale=SIGMA_C, rng=rng)
    values = values + SIGMA_N * rng.standard_normal(n)
    fits = fits or {family: coloured_draws(WIDTH), "white": np.full((400, 1), np.std(values))}
    return NoiseCharacterisation(
        series=NoiseSeries(values=values, dt=DT, name=name),
        fits={
            name_: family_fit(name_, draws, -100.0 * (name_ == "white"))
            for name_, draws in fits.items()
        },
        acf_least_squares={1: 0.021, 2: 0.024, 3: 0.0},
        thesis_fit=0.025,
    )


@pytest.mark.parametrize("family", ["gaussian", "exponential", "triangular"])
def test_the_predictive_acf_band_covers_the_closed_form(family):
    # The band is the central 94 % of 200 replicates' sample autocorrelations.
    # The closed form at the draws' mean, (sigma_c^2 rho(l) + sigma_n^2 [l = 0])
    # / (sigma_c^2 + sigma_n^2), is the band's centre up to the estimator's
    # bias, O((1 + 2 sum rho) / n) ~ 0.01 here, against a half-width of
    # ~0.15 at n = 2000: a fixed curve that far inside is covered at every
    # lag (tolerance: no lag out of 31), and the band's median lies within
    # 4 standard errors of a median of 200 (1.25 sd / sqrt(200)) plus that
    # bias of it.
    result = characterisation(family)
    bands = noise_predictive_bands(result, families=[family], lags=LAGS, rng=3)[family]["acf"]
    draws = result.fits[family].draws
    width, sigma_c, sigma_n = draws.mean(axis=0)
    rho = get_family(family).autocorrelation(width, DT, LAGS + 1)
    closed = sigma_c**2 * rho
    closed[0] += sigma_n**2
    closed /= closed[0]
    low, median, high = np.percentile(bands, [3.0, 50.0, 97.0], axis=0)
    assert bands.shape == (200, LAGS + 1)
    assert np.all((low - 1e-12 <= closed) & (closed <= high + 1e-12))
    n = len(result.series.values)
    bias = (1.0 + 2.0 * np.sum(np.abs(rho))) / n
    tolerance = 4.0 * 1.25 * bands.std(axis=0) / np.sqrt(len(bands)) + bias
    assert np.all(np.abs(median - closed) <= tolerance + 1e-12)


@pytest.mark.parametrize("family", list(FAMILIES))
def test_replicates_have_the_variance_of_the_coloured_part_plus_the_floor(family):
    # Each replicate is zero-mean: its mean square estimates sigma_c^2 +
    # sigma_n^2 (white: sigma^2). The replicates are independent, so the
    # standard error of the mean of 200 is their sd / sqrt(200); 4 of them.
    white = family == "white"
    draws = np.full((200, 1), 1.3) if white else np.tile([WIDTH, SIGMA_C, SIGMA_N], (200, 1))
    result = characterisation("gaussian", n=1000, **{family: draws})
    square = {"square": lambda x: np.mean(x**2, axis=1)}
    replicated = replicate_statistics(result, family, square, rng=5)["square"]
    expected = 1.3**2 if white else SIGMA_C**2 + SIGMA_N**2
    error = replicated.std() / np.sqrt(len(replicated))
    assert abs(replicated.mean() - expected) < 4.0 * error


def test_the_replicates_do_not_depend_on_the_chunks_and_use_at_most_200_draws(monkeypatch):
    result = characterisation("gaussian", n=500, gaussian=coloured_draws(WIDTH, count=1000))
    statistics = {"sd": lambda x: x.std(axis=1)}
    whole = replicate_statistics(result, "gaussian", statistics, rng=2)["sd"]
    monkeypatch.setattr(predictive, "CHUNK_SAMPLES", 1)  # one replicate per chunk
    chunked = replicate_statistics(result, "gaussian", statistics, rng=2)["sd"]
    assert whole.shape == (200,)
    # Each replicate comes from its own generator; only a batch's arithmetic
    # differs from a lone row's, in the last bits.
    np.testing.assert_allclose(chunked, whole, rtol=1e-12, atol=0)


def test_the_bands_are_the_same_for_the_same_seed():
    result = characterisation("gaussian", n=500)
    first, again, other = (noise_predictive_bands(result, lags=10, rng=seed) for seed in (4, 4, 5))
    for family in ("gaussian", "white"):
        for statistic in ("acf", "psd"):
            np.testing.assert_array_equal(first[family][statistic], again[family][statistic])
            assert not np.array_equal(first[family][statistic], other[family][statistic])


def test_the_acf_and_psd_figures_draw_the_series_and_both_bands():
    result = characterisation("gaussian", n=1000)
    bands = noise_predictive_bands(result, lags=LAGS, rng=0)
    assert list(bands) == ["gaussian", "white"]  # the best, then white for contrast
    fig = Figure()
    axes = fig.subplots(1, 2)
    assert plot_noise_autocorrelation(result, lags=LAGS, ax=axes[0], predictive=bands) == (
        fig,
        axes[0],
    )
    assert plot_noise_spectrum(result, ax=axes[1], predictive=bands) == (fig, axes[1])
    observed = axes[0].get_lines()[-2]  # the series, before the zero line
    np.testing.assert_allclose(
        observed.get_ydata(), sample_autocorrelation(result.series.values, LAGS)
    )
    _, psd = spectrum(result.series.values, DT)
    np.testing.assert_allclose(axes[1].get_lines()[-1].get_ydata(), psd[1:])
    for ax in axes:
        legend = [text.get_text() for text in ax.get_legend().get_texts()]
        assert legend == ["gaussian (best), 94 %", "white, 94 %", "gyro"]
    with pytest.raises(InputError, match=r"lags 0\.\.30"):
        plot_noise_autocorrelation(result, lags=10, predictive=bands)


def test_the_width_plot_puts_every_methods_number_on_the_axis():
    result = characterisation(
        "gaussian",
        gaussian=coloured_draws(WIDTH),
        exponential=coloured_draws(0.05, seed=1),
        white=np.ones((400, 1)),
    )
    fig, ax = plot_noise_widths(result)
    fig.draw_without_rendering()  # places the top axis
    labels = [label.get_text() for label in ax.get_yticklabels()]
    assert labels == [
        "gaussian posterior (best)",
        "exponential posterior",
        "ACF least squares, 1 lag",
        "ACF least squares, 2 lags",
        "ACF least squares, 3 lags (none fits)",
        "thesis' fit (30 lags)",
    ]
    # The points: each marker line's (x, row), and each posterior's interval.
    points = {}
    for line in ax.get_lines():
        if line.get_marker() in ("o", "s", "D"):
            points |= {
                labels[int(y)]: x for x, y in zip(line.get_xdata(), line.get_ydata(), strict=True)
            }
    expected = {
        f"{name} posterior{' (best)' if name == 'gaussian' else ''}": result.fits[name].width()[
            "seconds"
        ]
        for name in ("gaussian", "exponential")
    }
    assert points.keys() == {
        *expected,
        "ACF least squares, 1 lag",
        "ACF least squares, 2 lags",
        "thesis' fit (30 lags)",
    }
    for label, width in expected.items():
        assert points[label] == pytest.approx(width["mean"], rel=1e-12)
    assert points["ACF least squares, 1 lag"] == 0.021
    assert points["ACF least squares, 2 lags"] == 0.024
    assert points["thesis' fit (30 lags)"] == 0.025
    intervals = {
        labels[round(segment[0, 1])]: (segment[0, 0], segment[1, 0])
        for collection in ax.collections
        for segment in collection.get_segments()
        if segment[1, 0] > segment[0, 0]
    }
    assert intervals.keys() == expected.keys()
    for label, width in expected.items():
        assert intervals[label] == pytest.approx((width["hdi_3%"], width["hdi_97%"]), rel=1e-12)
    assert ax.get_xscale() == "log" and ax.get_xlabel() == "width [s]"
    [bins] = ax.child_axes  # the top axis: the same widths in samples
    assert bins.get_xlabel() == "width [samples]"
    np.testing.assert_allclose(bins.get_xlim(), np.array(ax.get_xlim()) / DT)


def test_the_width_plot_draws_a_mean_outside_its_hdi():
    # A two-armed width posterior, as on white noise: 960 draws near 0.003 s
    # and 40 spread over 1-5 s. The 94 % HDI holds the near arm only, the mean
    # (0.96 x 0.003 + 0.04 x 3 ~ 0.12 s) lies far above it: the interval and
    # the mean are drawn apart, each where it is.
    rng = np.random.default_rng(3)
    widths = np.concatenate([0.003 * np.exp(0.05 * rng.standard_normal(960)),
                             rng.uniform(1.0, 5.0, 40)])  # fmt: skip
    draws = np.column_stack([widths, np.full(1000, SIGMA_C), np.full(1000, SIGMA_N)])
    result = characterisation("gaussian", gaussian=draws, white=np.ones((400, 1)))
    width = result.fits["gaussian"].width()["seconds"]
    assert width["mean"] > 10 * width["hdi_97%"]  # the case the figure must draw
    _, ax = plot_noise_widths(result)
    [mean] = [line for line in ax.get_lines() if line.get_marker() == "o"]
    assert mean.get_xdata()[0] == pytest.approx(width["mean"], rel=1e-12)
    segments = [segment for collection in ax.collections for segment in collection.get_segments()]
    [segment] = [segment for segment in segments if segment[1, 0] > segment[0, 0]]
    assert (segment[0, 0], segment[1, 0]) == pytest.approx(
        (width["hdi_3%"], width["hdi_97%"]), rel=1e-12
    )


def test_the_spectrum_figure_refuses_bands_of_another_series():
    # Welch's PSD of 600 samples has 129 frequencies (256-sample segments), that
    # of 200 samples 101 (one segment): bands drawn for the shorter series.
    result = characterisation("gaussian", n=600)
    short = characterisation("gaussian", n=200)
    bands = noise_predictive_bands(short, lags=10, count=20, rng=0)
    with pytest.raises(InputError, match="spectrum has 101 frequencies, the figure 129"):
        plot_noise_spectrum(result, predictive=bands)


def test_series_whose_figure_files_would_be_one_are_refused(tmp_path):
    # "a b" and "a-b" both give the files a-b-acf.png, a-b-psd.png, ...
    results = [characterisation("gaussian", n=200, name=name) for name in ("a b", "a-b")]
    with pytest.raises(InputError, match=r"series 'a b' and 'a-b' would write the same figure"):
        write_noise_report(results, tmp_path / "noise.html")
    assert list(tmp_path.iterdir()) == []  # refused before anything was drawn or written


def test_the_page_has_a_section_per_series_and_its_figures(tmp_path):
    warned = characterisation("gaussian", name="gyro")
    warned.fits["gaussian"].warnings.append({"kind": "prior-boundary", "message": "piled up"})
    results = [warned, characterisation("exponential", name="accel", seed=2)]
    page = write_noise_report(results, tmp_path / "noise.html", formats=("png",), seed=4)
    text = page.read_text()
    assert text.count("<section>") == 2 and text.count("<figure>") == 6
    for result in results:
        summary = result.to_dict()
        assert f">{result.series.name}</h2>" in text
        assert summary["verdict_text"] in text
        for row in noise_rows(summary):  # the table as the command prints it
            assert "".join(f"<td>{cell}</td>" for cell in row) in text
    assert "".join(f"<th>{cell}</th>" for cell in NOISE_HEADER) in text
    assert '<ul class="warnings"><li>gaussian: piled up</li></ul>' in text
    assert f"each of up to {PREDICTIVE_DRAWS} posterior draws" in text  # the bands' own count
    files = sorted(path.name for path in (tmp_path / "noise_figures").iterdir())
    kinds = ("acf", "psd", "widths")
    assert files == sorted(f"{name}-{kind}.png" for name in ("gyro", "accel") for kind in kinds)
    with pytest.raises(InputError, match="two series named 'gyro'"):
        write_noise_report([warned, warned], tmp_path / "twice.html")
    with pytest.raises(InputError, match="results of characterise_noise"):
        write_noise_report([], tmp_path / "none.html")


@pytest.mark.skipif(CHROMIUM is None, reason="Debian package chromium is not installed")
def test_the_page_renders_in_chromium_with_every_figure_loaded(tmp_path):
    page = write_noise_report(
        [characterisation("gaussian", n=600)], tmp_path / "noise.html", formats=()
    )
    counts, console = render(page, tmp_path)
    assert counts == {"images": 3, "images-broken": 0, "errors": 0}, counts
    assert console == []


def test_the_noise_command_writes_the_report(tmp_path, capsys):
    rng = np.random.default_rng(7)
    values = get_family("gaussian").noise(WIDTH, DT, 600, rng=rng) + 0.3 * rng.standard_normal(600)
    data = tmp_path / "gyro.csv"
    np.savetxt(
        data,
        np.column_stack([np.arange(600) * DT, values]),
        delimiter=",",
        header="time,gyro_z",
        comments="",
    )
    out = tmp_path / "results"
    flags = [
        "--families",
        "white,gaussian",
        "--seed",
        "1",
        "--max-steps",
        "300",
        "--no-progress",
        "--processes",
        "1",
    ]
    assert main(["noise", str(data), *flags, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert re.search(
        r"^family +ln Z +\+- +ln B vs white +width \[s\] +94 % HDI +\[bins\]$", printed, re.M
    )
    assert f"wrote {out / 'noise_report.html'}" in printed
    text = (out / "noise_report.html").read_text()
    assert text.count("<section>") == 1 and '<h2 id="gyro">gyro</h2>' in text
    # PNG files by default (vector figures with --formats png,svg).
    assert {path.name for path in (out / "noise_report_figures").iterdir()} == {
        f"gyro-{kind}.png" for kind in ("acf", "psd", "widths")
    }
    assert Path(out / "gyro.noise.json").exists()


def test_a_report_that_cannot_be_written_loses_no_result(tmp_path, capsys):
    # A file stands where the report's figures folder goes: the report fails
    # for real. The run's results are out first (the JSON on stdout, the
    # series' file), then one line names the report, exit 1, no traceback.
    rng = np.random.default_rng(8)
    data = tmp_path / "gyro.csv"
    np.savetxt(data, np.column_stack([np.arange(300) * DT, rng.standard_normal(300)]),
               delimiter=",", header="time,gyro_z", comments="")  # fmt: skip
    out = tmp_path / "results"
    out.mkdir()
    (out / "noise_report_figures").write_text("in the way")
    flags = ["--families", "white", "--max-steps", "200", "--no-progress", "--processes", "1"]
    assert main(["noise", str(data), *flags, "--out", str(out), "--json"]) == 1
    printed = capsys.readouterr()
    result = json.loads(printed.out)
    assert list(result["series"]) == ["gyro"] and result["failed"] == {}
    assert (out / "gyro.noise.json").exists() and not (out / "noise_report.html").exists()
    [line] = [line for line in printed.err.splitlines() if "noise_report" in line]
    assert line.startswith("bayes-jackal: failed: FileExistsError") and "noise_report.html" in line
    assert "Traceback" not in printed.err
