"""The posterior and grid figures of bayes_jackal.report: their axes, and what they draw.

Every public ``plot_*`` function takes an optional ``ax`` (or ``axes``),
returns ``(fig, axes)``, draws onto the axes it is given, and builds its
figure without pyplot (which arviz imports anyway): pyplot never holds one
of its figures, so no ``plt.show()`` could open a window, and plots.py
calls none. Each figure is rendered by the Agg backend.
The posteriors are built without sampling (:mod:`synthetic_posteriors`)
around chosen parameters, once per module; the lines drawn are compared
with the autocorrelation, Welch spectrum, one-step residuals and model
response computed here, the last two by the independent model of
tests/conftest.py.
"""

from __future__ import annotations

import inspect
import re

import matplotlib
import matplotlib.pyplot as plt  # only to see that it never holds a figure
import numpy as np
import pytest
import scipy.signal
import scipy.stats
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from synthetic_posteriors import ROBOT, posterior_at

from bayes_jackal import report as plots
from bayes_jackal._runtime.errors import InputError
from bayes_jackal.io.simulate import Series, simulate_experiment
from bayes_jackal.report.plots import MAX_POINTS
from bayes_jackal.thesis.gridsearch import damping_grid, grid_search

matplotlib.use("Agg")

#: The posterior's centre: damping [N s/m], then (sigma_h [s], sigma_c, sigma_n)
#: of yaw [rad/s] and of vx [m/s]; all different, so that each can be told apart.
TRUTH = [110.0, 30.0, 0.047, 0.01, 0.005, 0.06, 0.004, 0.003]
CHANNELS = ("yaw", "vx")
#: Kept draws and walkers of a posterior of synthetic_posteriors.posterior_at.
DRAWS, WALKERS = 40, 8
LAGS = 30
#: Every public figure; test_every_public_plot_is_tested keeps it complete.
PLOTS = (
    "plot_autocorrelation",
    "plot_criticism",
    "plot_damping",
    "plot_grid",
    "plot_model_fit",
    "plot_residuals",
    "plot_sigma_h",
    "plot_spectrum",
    "plot_traces",
)
#: Rows of the state, as in the model of eq. 4-32.
STATE = {"vx": 0, "vy": 1, "yaw": 2}


@pytest.fixture(autouse=True)
def no_pyplot_figures():
    """Each test leaves pyplot without figures (it should never have had one)."""
    yield
    open_figures = plt.get_fignums()
    plt.close("all")
    assert open_figures == []


@pytest.fixture(scope="module")
def run():
    """A 10 s steady circle (721 samples), v = 0.3 m/s, w = 22.5 deg/s."""
    return simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, np.deg2rad(22.5), 10.0), rng=4)


@pytest.fixture(scope="module")
def idata(run):
    """A yaw + vx posterior around TRUTH (log-normal spread 5 %)."""
    return posterior_at([run], TRUTH, channels=CHANNELS, spread=0.05)


@pytest.fixture(scope="module")
def predictive(idata):
    """The predictive statistics of the yaw residuals, shared by the ACF and PSD figures."""
    return plots.predictive_bands(idata, 0, "yaw", lags=LAGS, rng=0)


@pytest.fixture(scope="module")
def grid(run):
    """The one-step yaw MSE over a 16 x 11 damping grid."""
    return grid_search(
        [run], ROBOT, damping_grid(50.0, 200.0, 10.0), damping_grid(10.0, 60.0, 5.0)
    )


@pytest.fixture(scope="module")
def drawings(idata, predictive, grid):
    """Name -> (``draw(axes)``: the figure onto ``axes`` or its own, the layout of its axes)."""
    return {
        "plot_autocorrelation": (
            lambda ax: plots.plot_autocorrelation(idata, lags=LAGS, ax=ax, predictive=predictive),
            (1,),
        ),
        "plot_criticism": (lambda axes: plots.plot_criticism(idata, axes=axes), (2, 2)),
        "plot_damping": (lambda ax: plots.plot_damping(idata, ax=ax), (1,)),
        "plot_grid": (lambda ax: plots.plot_grid(grid, ax=ax), (1,)),
        "plot_model_fit": (lambda axes: plots.plot_model_fit(idata, axes=axes), (3,)),
        "plot_residuals": (lambda axes: plots.plot_residuals(idata, axes=axes), (len(CHANNELS),)),
        "plot_sigma_h": (lambda ax: plots.plot_sigma_h(idata, ax=ax), (1,)),
        "plot_spectrum": (
            lambda ax: plots.plot_spectrum(idata, ax=ax, predictive=predictive),
            (1,),
        ),
        "plot_traces": (lambda axes: plots.plot_traces(idata, axes=axes), (len(TRUTH),)),
    }


def _axes(returned) -> list:
    return list(np.ravel(returned))


def _line(ax, label: str):
    [line] = [line for line in ax.lines if line.get_label() == label]
    return line


#: The report's modules of posterior and grid figures (the noise series' and the
#: filters' figures are tested with their own).
POSTERIOR_PLOTS = ("plots", "grid_plots", "predictive_plots")


def test_every_public_plot_is_tested():
    assert set(PLOTS) == {
        name
        for name in dir(plots)  # every plot the report offers, public or not
        if name.startswith("plot_")
        and getattr(plots, name).__module__.rsplit(".", 1)[-1] in POSTERIOR_PLOTS
    }


def test_no_plot_goes_through_pyplot():
    source = inspect.getsource(plots)
    assert not re.search(
        r"import matplotlib\.pyplot|from matplotlib import pyplot|\.show\(", source
    )


@pytest.mark.parametrize("name", PLOTS)
def test_a_plot_takes_an_optional_ax(name):
    parameters = inspect.signature(getattr(plots, name)).parameters
    [ax] = [parameters[key] for key in ("ax", "axes") if key in parameters]
    assert ax.default is None


@pytest.mark.parametrize("name", PLOTS)
def test_a_plot_alone_makes_its_own_figure_outside_pyplot(drawings, name):
    draw, layout = drawings[name]
    fig, axes = draw(None)
    assert isinstance(fig, Figure)
    assert np.shape(axes) == (layout if layout != (1,) else ())
    assert all(ax.figure is fig for ax in _axes(axes))
    assert fig.canvas.manager is None  # unknown to pyplot: nothing can show it
    FigureCanvasAgg(fig).draw()  # renders under Agg


@pytest.mark.parametrize("name", PLOTS)
def test_a_plot_draws_onto_the_axes_it_is_given(drawings, name):
    draw, layout = drawings[name]
    fig = Figure()
    given = fig.subplots(*layout, squeeze=False)
    given = given[0, 0] if layout == (1,) else given.reshape(layout)
    returned_fig, returned = draw(given)
    assert returned_fig is fig
    assert _axes(returned) == _axes(given)
    for ax in _axes(given):
        assert ax.lines or ax.collections or ax.patches
    FigureCanvasAgg(fig).draw()


def test_the_autocorrelation_line_is_the_residuals_sample_acf(idata, predictive):
    _, ax = plots.plot_autocorrelation(idata, channel="yaw", lags=LAGS, predictive=predictive)
    x = idata.observed_data["residual_yaw_0"].values
    centred = x - x.mean()
    acf = [centred[: len(x) - k] @ centred[k:] / (centred @ centred) for k in range(LAGS + 1)]
    line = _line(ax, "residuals")
    np.testing.assert_array_equal(line.get_xdata(), np.arange(LAGS + 1))
    np.testing.assert_allclose(line.get_ydata(), acf, rtol=1e-9, atol=1e-12)
    # The white-noise 95 % bounds, +-1.96 / sqrt(n), and the predictive median.
    [bounds] = [p for p in ax.patches if p.get_label() == "white-noise 95 % bounds"]
    bound = scipy.stats.norm.ppf(0.975) / np.sqrt(len(x))
    assert bounds.get_y() == pytest.approx(-bound)
    assert bounds.get_height() == pytest.approx(2 * bound)
    median = ax.lines[0]  # drawn first, before the residuals and the zero line
    np.testing.assert_allclose(median.get_ydata(), np.median(predictive["acf"], axis=0))


def test_the_autocorrelation_refuses_predictive_bands_of_other_lags(idata, predictive):
    with pytest.raises(InputError, match=r"lags 0\.\.30, the figure 10"):
        plots.plot_autocorrelation(idata, lags=10, predictive=predictive)


def test_the_spectrum_line_is_the_residuals_welch_psd(idata, predictive, run):
    _, ax = plots.plot_spectrum(idata, channel="yaw", predictive=predictive)
    x = idata.observed_data["residual_yaw_0"].values
    # Hann window of 256 samples, half overlapping, each segment's mean removed.
    frequency, psd = scipy.signal.welch(x, fs=1.0 / run.dt, nperseg=256, detrend="constant")
    line = _line(ax, "residuals")
    np.testing.assert_allclose(line.get_xdata(), frequency[1:])
    np.testing.assert_allclose(line.get_ydata(), psd[1:], rtol=1e-9)
    assert predictive["psd"].shape == (200, len(frequency))
    assert ax.get_xscale() == ax.get_yscale() == "log"


def test_the_traces_draw_one_line_per_walker_per_parameter_in_order(idata):
    _, axes = plots.plot_traces(idata)
    assert len(axes) == len(TRUTH)
    for ax, centre in zip(axes, TRUTH, strict=True):
        [walkers] = ax.collections  # one line per walker, against the draw
        lines = np.array(walkers.get_segments())
        assert lines.shape == (WALKERS, DRAWS, 2)
        np.testing.assert_array_equal(lines[..., 0], np.tile(np.arange(DRAWS), (WALKERS, 1)))
        assert np.median(lines[..., 1]) == pytest.approx(centre, rel=0.02)
        assert ax.get_ylim()[0] <= lines[..., 1].min() and lines[..., 1].max() <= ax.get_ylim()[1]
    d_lat = np.array(axes[0].collections[0].get_segments())[..., 1]
    np.testing.assert_array_equal(d_lat, idata.posterior["d_lat"].values)


def test_the_damping_plot_draws_the_draws_the_ridge_and_the_truth(idata, run):
    _, ax = plots.plot_damping(idata)
    d_lat = idata.posterior["d_lat"].values.ravel()
    d_long = idata.posterior["d_long"].values.ravel()
    draws = _line(ax, "posterior draws")
    np.testing.assert_array_equal(draws.get_xdata(), d_long)
    np.testing.assert_array_equal(draws.get_ydata(), d_lat)
    ratio = np.median(d_lat / d_long)
    [ridge] = [line for line in ax.lines if line.get_label().startswith("ridge")]
    np.testing.assert_allclose(ridge.get_ydata(), ratio * np.asarray(ridge.get_xdata()))
    thesis = _line(ax, "thesis 11/3")
    np.testing.assert_allclose(thesis.get_ydata(), 11.0 / 3.0 * np.asarray(thesis.get_xdata()))
    truth = _line(ax, "truth (simulated)")
    assert [*truth.get_xdata(), *truth.get_ydata()] == [run.truth["d_long"], run.truth["d_lat"]]


def test_the_sigma_h_histograms_are_densities_of_each_noise_group(idata):
    _, ax = plots.plot_sigma_h(idata)
    variable = idata.posterior["sigma_h"]
    groups = np.moveaxis(variable.values, variable.dims.index("noise_group"), 0)
    groups = groups.reshape(len(CHANNELS), -1)
    assert len(ax.patches) == 60 * len(CHANNELS)
    for number, values in enumerate(groups):
        bars = ax.patches[60 * number : 60 * (number + 1)]
        heights = np.array([bar.get_height() for bar in bars])
        widths = np.array([bar.get_width() for bar in bars])
        assert heights @ widths == pytest.approx(1.0)
        assert bars[0].get_x() == pytest.approx(values.min())
        assert bars[-1].get_x() + bars[-1].get_width() == pytest.approx(values.max())


def _eq_7_3(run, model, d_lat: float, d_long: float, channel: str) -> np.ndarray:
    """w[k] = y[k+1] - Ad y[k] - Bd u[k] over the run (every sample), by the conftest model."""
    keep = np.ones(len(run.t), bool)
    y = run.channel(channel)[keep]
    u = np.column_stack([run.omega_r, run.omega_l])[keep]
    Ad, Bd = model(ROBOT, d_lat, d_long, run.dt)
    row = STATE[channel]
    return y[1:] - Ad[row, row] * y[:-1] - u[:-1] @ Bd[row]


def test_the_residuals_are_eq_7_3_at_the_posterior_median(idata, run, thesis_discrete_model):
    _, axes = plots.plot_residuals(idata)
    d_lat = float(np.median(idata.posterior["d_lat"].values))
    d_long = float(np.median(idata.posterior["d_long"].values))
    for ax, channel in zip(axes, CHANNELS, strict=True):
        [line] = [line for line in ax.lines if len(line.get_xdata()) > 2]  # not the zero line
        expected = _eq_7_3(run, thesis_discrete_model, d_lat, d_long, channel)
        np.testing.assert_allclose(line.get_ydata(), expected, rtol=1e-9, atol=1e-12)
        assert np.abs(line.get_xdata() - run.t[1:]).max() < run.dt


def test_the_model_fit_is_the_model_driven_by_the_measured_wheel_speeds(
    run, thesis_discrete_model
):
    # A posterior of (nearly) one point: the model's median is the model at TRUTH.
    narrow = posterior_at([run], TRUTH, channels=CHANNELS, spread=1e-7)
    _, axes = plots.plot_model_fit(narrow)
    Ad, Bd = thesis_discrete_model(ROBOT, TRUTH[0], TRUTH[1], run.dt)
    u = np.column_stack([run.omega_r, run.omega_l])
    states = np.empty((len(run.t), 3))
    states[0] = run.vx[0], run.vy[0], run.yaw_rate[0]
    for k in range(len(run.t) - 1):
        states[k + 1] = Ad @ states[k] + Bd @ u[k]
    for ax, (channel, row) in zip(axes, STATE.items(), strict=True):
        np.testing.assert_array_equal(_line(ax, "measured").get_ydata(), run.channel(channel))
        model = _line(ax, "model (94 % band)").get_ydata()
        np.testing.assert_allclose(model, states[:, row], rtol=1e-5, atol=1e-8)


def test_the_grid_marks_its_minimum_and_ridge(grid):
    _, ax = plots.plot_grid(grid)
    i, j = np.unravel_index(np.argmin(grid.mse), grid.mse.shape)
    d_lat, d_long = grid.d_lat[i], grid.d_long[j]
    [star] = [line for line in ax.lines if line.get_label().startswith("minimum")]
    assert [*star.get_xdata(), *star.get_ydata()] == [d_long, d_lat]
    [ridge] = [line for line in ax.lines if line.get_label().startswith("d_lat =")]
    np.testing.assert_allclose(ridge.get_ydata(), d_lat / d_long * grid.d_long)
    [mesh] = ax.collections
    np.testing.assert_array_equal(np.ravel(mesh.get_array()), grid.mse.ravel())


@pytest.mark.parametrize(("suffix", "magic"), [(".png", b"\x89PNG"), (".svg", b"<?xml")])
def test_save_grid_plot_writes_the_format_of_its_suffix(grid, tmp_path, suffix, magic):
    path = plots.save_grid_plot(grid, tmp_path / f"grid{suffix}")
    assert path == tmp_path / f"grid{suffix}"
    assert path.read_bytes().startswith(magic)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left


def test_the_criticism_bands_are_the_99_percent_normal_band(idata):
    _, axes = plots.plot_criticism(idata)
    band = scipy.stats.norm.ppf(0.995)  # 2.576: the per-lag band of the z statistics
    for left, right in axes:
        [span] = left.patches
        assert span.get_y() == pytest.approx(-band)
        assert span.get_height() == pytest.approx(2 * band)
        p_values = np.concatenate([line.get_ydata() for line in right.lines])
        assert p_values.size and ((p_values >= 0) & (p_values <= 1)).all()


@pytest.fixture(scope="module")
def long_idata():
    """A yaw posterior of a 70 s run: more residuals and samples than MAX_POINTS."""
    run = simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, np.deg2rad(22.5), 70.0), rng=5)
    idata = posterior_at([run], TRUTH[:5], channels=("yaw",), spread=0.05)
    assert idata.observed_data["residual_yaw_0"].size > MAX_POINTS
    return idata


def _distinct_x(collection) -> int:
    return len(np.unique(np.concatenate([path.vertices[:, 0] for path in collection.get_paths()])))


def test_a_long_run_is_drawn_as_an_envelope_of_at_most_max_points(long_idata):
    _, [ax] = plots.plot_residuals(long_idata)
    residuals = long_idata.observed_data["residual_yaw_0"].values
    assert all(len(line.get_xdata()) == 2 for line in ax.lines)  # only the zero line
    [envelope] = ax.collections
    assert _distinct_x(envelope) <= MAX_POINTS // 2
    vertices = np.concatenate([path.vertices for path in envelope.get_paths()])
    assert vertices[:, 1].min() == residuals.min()
    assert vertices[:, 1].max() == residuals.max()

    _, axes = plots.plot_model_fit(long_idata)
    for ax in axes:
        assert all(len(line.get_xdata()) <= MAX_POINTS for line in ax.lines)
        assert ax.collections
        assert all(_distinct_x(c) <= MAX_POINTS // 2 for c in ax.collections)
