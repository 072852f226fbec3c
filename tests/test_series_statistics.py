"""Generic series statistics: autocorrelation, its bounds, spectra, Ljung-Box."""

import numpy as np
import pytest
import scipy.signal
import scipy.stats

from bayes_jackal import InputError
from bayes_jackal.model.kernels import get_family
from bayes_jackal.posterior.series_statistics import (
    MATLAB_LEVEL,
    autocorrelation_bounds,
    ljung_box,
    magnitude_spectrum,
    sample_autocorrelation,
    spectrum,
)

DT = 1.0 / 72.0


# --- autocorrelation, bounds, spectra -------------------------------------------------------


def test_sample_autocorrelation_matches_a_direct_sum():
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.standard_normal((3, 500)), axis=-1) + 5.0  # coloured, non-zero mean
    lags = 40
    r = sample_autocorrelation(x, lags)
    assert r.shape == (3, lags + 1)
    for row, series in zip(r, x, strict=True):
        centred = series - series.mean()
        direct = np.array([centred[: len(series) - k] @ centred[k:] for k in range(lags + 1)]) / (
            centred @ centred
        )
        # Both are exact; FFT rounding is ~1e-16 relative to the lag-0 sum.
        np.testing.assert_allclose(row, direct, rtol=0, atol=1e-12)
    assert r[0, 0] == 1.0
    # The largest lag a series allows (n = lags + 1) still has no circular wrap.
    short = rng.standard_normal(8)
    centred = short - short.mean()
    assert sample_autocorrelation(short, 7)[7] == pytest.approx(
        centred[0] * centred[7] / (centred @ centred), abs=1e-12
    )


def test_autocorrelation_bounds():
    # 1.959963985 = Phi^-1(0.975), closed form to the digits quoted.
    assert autocorrelation_bounds(2500) == pytest.approx(1.959963985 / 50.0, rel=1e-9)
    # MATLAB's autocorr draws 2 standard errors: +-2 / sqrt(n).
    assert autocorrelation_bounds(400, MATLAB_LEVEL) == pytest.approx(0.1, rel=1e-12)
    for n, level, field in ((0, 0.95, "n"), (10, 1.0, "level"), (10, 0.0, "level")):
        with pytest.raises(InputError, match=field):
            autocorrelation_bounds(n, level)


def test_magnitude_spectrum_reads_a_sine_amplitude():
    for n in (720, 721):  # even (with a Nyquist bin) and odd
        t = np.arange(n) * DT
        frequency_bin = 50
        f0 = frequency_bin / (n * DT)
        x = 0.3 + 2.0 * np.sin(2 * np.pi * f0 * t)
        frequency, magnitude = magnitude_spectrum(x, DT)
        assert len(frequency) == n // 2 + 1
        assert frequency[frequency_bin] == pytest.approx(f0, rel=1e-12)
        # An integer number of periods: the sine is exactly one bin (rounding 1e-12).
        assert magnitude[frequency_bin] == pytest.approx(2.0, rel=1e-12)
        assert magnitude[0] == pytest.approx(0.3, rel=1e-12)
        others = np.delete(magnitude, [0, frequency_bin])
        np.testing.assert_allclose(others, 0.0, atol=1e-12)


def test_welch_spectrum_integrates_to_the_variance():
    rng = np.random.default_rng(4)
    n, sd = 2**16, 0.01
    x = sd * rng.standard_normal(n)
    frequency, psd = spectrum(x, DT)
    assert frequency[-1] == pytest.approx(36.0)  # Nyquist of 72 Hz
    assert np.diff(frequency)[0] == pytest.approx(72.0 / 256)
    # Each Hann segment's weighted mean square has relative variance
    # 2 sum(w^4) / sum(w^2)^2 = 2 * 1.94 / 256 = 0.015; over >= 256 independent
    # segments the relative sd is <= 0.008, so 4 % is 5 sd. White noise of
    # variance s^2 has the flat one-sided density 2 s^2 dt.
    df = frequency[1]
    assert np.sum(psd) * df == pytest.approx(sd**2, rel=0.04)
    # Per bin the average of ~500 half-overlapping Hann periodograms has a
    # relative sd of ~0.06 (>= 256 independent segments); the median over 129
    # bins errs by ~0.01 relative, and the skew of the nearly chi^2 bins moves
    # the median below the mean by < 0.2 %: 10 % is a wide margin.
    assert np.median(psd) == pytest.approx(2 * sd**2 * DT, rel=0.1)
    two = spectrum(np.stack([x, 2 * x]), DT)[1]
    np.testing.assert_allclose(two[1], 4 * two[0], rtol=1e-12)


# --- Ljung-Box --------------------------------------------------------------------------------


def test_ljung_box_on_white_noise_is_not_rejected_and_p_is_uniform():
    rng = np.random.default_rng(3)
    _, p = ljung_box(rng.standard_normal(2000), 30)
    assert p > 0.05  # a fixed-seed white series (Q = 33.1 on 30 dof: p = 0.32)
    # Under whiteness the p-values are ~U(0, 1). 400 series of 1000 samples,
    # 10 lags: the chi^2 approximation errs far below the KS resolution at 400
    # draws (~0.07), so a KS p-value below 1e-3 would mean a broken statistic.
    _, p_values = ljung_box(rng.standard_normal((400, 1000)), 10)
    assert p_values.shape == (400,)
    assert scipy.stats.kstest(p_values, "uniform").pvalue > 1e-3


def test_ljung_box_rejects_coloured_noise():
    coloured = get_family("gaussian").noise(0.047, DT, 1500, rng=5)
    # rho_1 = exp(-dt^2 / (4 sigma_h^2)) = 0.98: r_1 alone gives Q ~ 1500 * 0.96 ~ 1440
    # on 30 dof, where chi^2_30 exceeds 1000 with probability ~ 1e-190.
    q, p = ljung_box(coloured, 30)
    assert q > 1000
    assert p < 1e-6


def test_ljung_box_statistic_matches_a_direct_loop_on_an_ar1():
    rng = np.random.default_rng(8)
    n, lags, phi = 800, 20, 0.3
    x = scipy.signal.lfilter([1.0], [1.0, -phi], rng.standard_normal(n))
    centred = x - x.mean()
    total = 0.0
    for k in range(1, lags + 1):
        r_k = centred[: n - k] @ centred[k:] / (centred @ centred)
        total += r_k**2 / (n - k)
    q_direct = n * (n + 2) * total
    q, p = ljung_box(x, lags)
    # Same sum; only the FFT's rounding (~1e-16 per r_k) differs.
    assert q == pytest.approx(q_direct, rel=1e-12)
    assert p == pytest.approx(scipy.stats.chi2.sf(q_direct, lags), rel=1e-9)
