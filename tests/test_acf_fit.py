"""The classical widths match independent implementations of the fits they stand for.

Issue 15, must show: "the least-squares widths match an independent
implementation of the thesis' ACF fit". The independent implementations
here use plain numpy and scipy.optimize.curve_fit, not the package:

- the sample autocorrelation as MATLAB's ``autocorr`` computes it, a sum per lag;
- the least-squares width by curve_fit of exp(-(k dt)^2 / (4 s^2)) on lags
  0..L, as issue 15 counts them ("lags 0-1"): lag 0 fits exactly, so the
  minimiser is the package's fit on lags 1..L;
- the thesis' eq. 7-6 on its grid with eq. 7-5's filter truncated at
  +-3 sigma_h (conftest's ``thesis_gaussian_filter``), its autocorrelation
  by np.correlate.

Series: unit white noise through eq. 7-5's filter at widths of 0.6, 2 and
6 samples (120 Hz), plus a white floor of sd 0.3, 4000 samples, fixed seeds.
The tolerance 1e-6 relative is far above both optimisers' convergence
(tolerances 1e-13 and 1e-14) and far below any difference of model or lag
convention (a lag count off by one moves the widths above by 1-40 %).

The thesis' fit is on a 1 ms grid, and the package's filter weights its
edge taps (:mod:`bayes_jackal.model.kernels`) where eq. 7-5 truncates hard, so
the two grid fits may differ by one grid step (1e-3 s), and no more.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize
from conftest import thesis_gaussian_filter

from bayes_jackal._runtime.errors import InputError
from bayes_jackal.thesis.acf_fit import (
    LEAST_SQUARES_LAGS,
    THESIS_LAGS,
    acf_least_squares,
    thesis_fit,
)

DT = 1 / 120
#: Relative agreement of the package's least-squares widths with curve_fit's.
RELATIVE = 1e-6


def _coloured(width: float, dt: float, n: int, seed: int, floor: float = 0.3) -> np.ndarray:
    """Unit white noise through eq. 7-5's filter of ``width`` [s], plus a white floor."""
    rng = np.random.default_rng(seed)
    h = thesis_gaussian_filter(width, dt)
    coloured = np.convolve(rng.standard_normal(n + len(h) - 1), h / np.linalg.norm(h), "valid")
    return coloured + floor * rng.standard_normal(n)


def _autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    """MATLAB's autocorr: r_k = sum x_c[t] x_c[t+k] / sum x_c[t]^2, k = 0..lags."""
    centred = x - x.mean()
    return np.array([centred[: len(x) - k] @ centred[k:] for k in range(lags + 1)]) / (
        centred @ centred
    )


def _curve_fit_width(r: np.ndarray, dt: float, lags: int) -> float:
    """curve_fit of exp(-t^2 / (4 s^2)) at t = 0, dt, .., lags dt, started at lag 1's exact fit."""
    k = np.arange(lags + 1)
    start = dt / (2 * np.sqrt(-np.log(r[1])))
    (width,), _ = scipy.optimize.curve_fit(
        lambda k, s: np.exp(-((k * dt) ** 2) / (4 * s**2)),
        k,
        r[: lags + 1],
        p0=[start],
        xtol=1e-13,
        ftol=1e-13,
    )
    return abs(float(width))


@pytest.mark.parametrize(("samples", "seed"), [(0.6, 1), (2.0, 2), (6.0, 3)])
def test_least_squares_widths_match_curve_fit(samples, seed):
    x = _coloured(samples * DT, DT, 4000, seed)
    widths = acf_least_squares(x, DT)
    r = _autocorrelation(x, max(LEAST_SQUARES_LAGS))
    expected = {lags: _curve_fit_width(r, DT, lags) for lags in LEAST_SQUARES_LAGS}
    assert list(widths) == list(LEAST_SQUARES_LAGS)
    for lags, width in widths.items():
        assert width == pytest.approx(expected[lags], rel=RELATIVE), lags


def test_one_lag_is_the_exact_fit_of_lags_0_and_1():
    # The "lags 0-1": exp(-dt^2 / (4 s^2)) = r_1.
    x = _coloured(0.8 * DT, DT, 720, seed=4)
    r1 = _autocorrelation(x, 1)[1]
    [width] = acf_least_squares(x, DT, lags=[1]).values()
    assert width == pytest.approx(DT / (2 * np.sqrt(-np.log(r1))), rel=1e-12)


def test_no_positive_correlation_gives_width_zero():
    # Differenced white noise: r_1 = -0.5 in expectation, no Gaussian fits better than none.
    x = np.diff(np.random.default_rng(5).standard_normal(2001))
    assert _autocorrelation(x, 1)[1] < 0
    assert acf_least_squares(x, DT, lags=[1]) == {1: 0.0}


def _thesis_grid_fit(x: np.ndarray, dt: float) -> float:
    """Eq. 7-6 over lags 1..30 on the grid 0.001..1 s, eq. 7-5's filter hard-truncated."""
    r = _autocorrelation(x, 30)[1:]
    grid = np.arange(1, 1001) / 1000
    mse = []
    for sigma_h in grid:
        h = thesis_gaussian_filter(sigma_h, dt)
        rho = np.correlate(h, h, "full")[len(h) - 1 :] / (h @ h)
        rho = np.pad(rho, (0, 31))[1:31]
        mse.append(np.mean((r - rho) ** 2))
    return float(grid[np.argmin(mse)])


@pytest.mark.parametrize(("sigma_h", "dt", "seed"), [(0.047, 1 / 72, 6), (0.02, 1 / 120, 7)])
def test_thesis_fit_matches_the_grid_fit_of_eq_7_6(sigma_h, dt, seed):
    x = _coloured(sigma_h, dt, 3000, seed, floor=0.0)
    assert THESIS_LAGS == 30
    steps = round(thesis_fit(x, dt) * 1000) - round(_thesis_grid_fit(x, dt) * 1000)
    assert abs(steps) <= 1  # grid steps of 1 ms


@pytest.mark.parametrize("lags", [[0], [1, 1], [1.5], "ab", [], [True]])
def test_bad_lag_counts_are_refused(lags):
    with pytest.raises(InputError, match="lags"):
        acf_least_squares(np.random.default_rng(1).standard_normal(100), DT, lags=lags)


def test_bad_series_are_refused():
    with pytest.raises(InputError, match="too few"):
        acf_least_squares(np.arange(5.0), DT)
    with pytest.raises(InputError, match="constant"):
        acf_least_squares(np.ones(50), DT)
    with pytest.raises(InputError, match="sample time"):
        acf_least_squares(np.arange(50.0), -DT)
