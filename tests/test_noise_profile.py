"""The MAP search's start for a bare noise series (bayes_jackal.inference.series_profile)."""

from __future__ import annotations

import numpy as np
import pytest

from bayes_jackal.inference.starts import series_profile
from bayes_jackal.likelihood.series_likelihood import SeriesLikelihood
from bayes_jackal.likelihood.whittle import (
    expected_periodogram,
    frequency_weights,
)
from bayes_jackal.model.kernels import FAMILIES, get_family
from bayes_jackal.noise.characterisation import series_prior

DT = 0.01


def _series(family: str, width: float, n: int, seed: int) -> np.ndarray:
    """Unit-sd noise of ``family``, ``width`` samples, over a white floor of sd 0.3."""
    rng = np.random.default_rng(seed)
    return get_family(family).noise(width * DT, DT, n, rng=rng) + 0.3 * rng.standard_normal(n)


def _whittle(values: np.ndarray, acov: np.ndarray) -> float:
    """The debiased Whittle log-likelihood of the centred series, frequency 0 left out,
    without its constant: -1/2 sum_j w_j (log E_j + I_j / E_j), written out here."""
    n = len(values)
    periodogram = np.abs(np.fft.rfft(values - values.mean())) ** 2 / n
    expected = expected_periodogram(acov[None], n)[0]
    weights = frequency_weights(n)
    weights[0] = 0.0
    return -0.5 * float(np.sum(weights * (np.log(expected) + periodogram / expected)))


@pytest.mark.parametrize("family", list(FAMILIES))
def test_the_series_profile_is_the_whittle_likelihood_at_its_best_scale(family):
    # 1,000 samples (fewer than the profile's 4,096 frequencies: no
    # averaging), so each candidate's value is the debiased Whittle
    # likelihood itself, written independently above (agreement to
    # rounding, 1e-9 relative); candidates best first, inside the prior.
    # The best's sds are inside the prior's box, and scaling both by 1 +-
    # 1e-3 lowers its value: the closed-form scale is the best one (the
    # others' can sit on the box's bound, e.g. sigma_c at 10 times the
    # series' sd for a width far wider than the truth).
    values = _series(family, 4.0, 1000, 1)
    likelihood = SeriesLikelihood(values=values, dt=DT, family=family)
    prior = series_prior(likelihood)
    theta, profile = series_profile(likelihood, prior.low, prior.high, starts=4)
    assert 1 <= len(theta) <= 4 and np.all(np.diff(profile) <= 0)
    assert prior.inside(np.log(theta)).all()
    sds = np.array([name.startswith("sigma") for name in likelihood.names])
    for row, value in zip(theta, profile, strict=True):
        acov = likelihood.autocovariance(row, len(values))[0]
        assert value == pytest.approx(_whittle(values, acov), rel=1e-9)
    best = theta[0]
    assert np.all((best[sds] > prior.low[sds] * 1.01) & (best[sds] < prior.high[sds] / 1.01))
    for factor in (1 - 1e-3, 1 + 1e-3):
        scaled = likelihood.autocovariance(best * np.where(sds, factor, 1.0), len(values))
        assert _whittle(values, scaled[0]) < profile[0]


@pytest.mark.parametrize("family", [name for name in FAMILIES if name != "white"])
@pytest.mark.parametrize("width", [2.0, 20.0])
def test_the_best_candidate_is_in_the_true_basin(family, width):
    # 5,000 samples (the periodogram averaged onto 4,096 frequencies) of each
    # coloured family at 2 and 20 samples: the profile's best width is within
    # 15 % of the truth (its grid's step is 14 % over the default prior and
    # each of the 5 zooms halves it; the posterior sd of the width is ~2 %
    # here, the moving-average family's local optima at half and 1.5 times
    # the truth are far outside).
    values = _series(family, width, 5000, 2)
    likelihood = SeriesLikelihood(values=values, dt=DT, family=family)
    prior = series_prior(likelihood)
    theta, _ = series_profile(likelihood, prior.low, prior.high, starts=4)
    assert theta[0, 0] / DT == pytest.approx(width, rel=0.15)


def test_white_noise_has_one_candidate_its_sd():
    # The white family's profile is its sd (n - 1 frequencies: the mean's left out).
    values = _series("white", 1.0, 500, 3)
    likelihood = SeriesLikelihood(values=values, dt=DT, family="white")
    prior = series_prior(likelihood)
    theta, profile = series_profile(likelihood, prior.low, prior.high, starts=4)
    assert theta.shape == (1, 1) and profile.shape == (1,)
    assert theta[0, 0] == pytest.approx(values.std() * np.sqrt(500 / 499), rel=1e-12)
