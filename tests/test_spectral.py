"""The ``fast`` engine (bayes_jackal.likelihood.spectral) against the Durbin-Levinson reference.

The engine evaluates each parameter set on a short spectral grid when its
spectral factor has converged there, else on the full grid, else by the
stopped recursion; every path must give the exact Toeplitz log-density. The
issue's bar is 1e-6 nats; the reference is the full O(N^2) recursion
(``engine="exact"``), itself checked against a dense Gaussian density in
test_likelihood.py.
"""

import numpy as np
import pytest

from bayes_jackal import load_profile
from bayes_jackal._runtime.chunking import chunks
from bayes_jackal.io.experiment import Experiment
from bayes_jackal.likelihood import spectral
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.model.kernels import FAMILIES

ROBOT = load_profile()
DT = 1.0 / 72.0
#: The issue's agreement bar between the engines [nats].
AGREEMENT = 1e-6


def _noise_run(n: int, seed: int) -> Experiment:
    """A stationary run of n + 1 samples: Gaussian-coloured yaw rate about a large mean.

    The means (0.3 rad/s, wheel speeds near 4 rad/s) dwarf the residuals'
    scale (~0.01 rad/s): the case where lagged sums lose digits unless the
    means are split off.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n + 1) * DT
    yaw = 0.3 + FAMILIES["gaussian"].noise(0.047, DT, n + 1, 0.01, rng)
    omega = 4.0 + 0.01 * rng.standard_normal(n + 1)
    return Experiment(t, yaw + 0.005 * rng.standard_normal(n + 1), omega, omega - 1.0)


def _theta(likelihood: ResidualLikelihood, rng: np.random.Generator, count: int) -> np.ndarray:
    """Parameter sets spread over the prior: widths 0.005-0.5 s, sds 1e-3-0.05."""
    columns = [110.0 * np.exp(0.3 * rng.standard_normal(count))]
    columns.append(30.0 * np.exp(0.3 * rng.standard_normal(count)))
    ranges = {"sigma_h": (0.005, 0.5), "width": (0.005, 0.5), "sigma_c": (1e-3, 0.05)}
    ranges["sigma_n"] = (1e-3, 0.05)
    for _ in likelihood.noise_groups:
        for name in likelihood.noise_parameter_names:
            low, high = ranges[name]
            columns.append(np.exp(rng.uniform(np.log(low), np.log(high), count)))
    return np.column_stack(columns)


@pytest.fixture(scope="module")
def runs():
    # Two series of 5,000 residuals share a block (E = 2); the short grids
    # 512 and 4096 and the full grid are all below and above n.
    return [_noise_run(5_000, seed) for seed in (1, 2)]


@pytest.mark.parametrize("sensor", ["ma1", "diagonal"])
@pytest.mark.parametrize("family", list(FAMILIES))
def test_fast_engine_equals_the_exact_recursion(runs, family, sensor):
    options = {"family": family, "sensor": sensor, "steady": False}
    fast = ResidualLikelihood(runs, ROBOT, **options)
    exact = ResidualLikelihood(runs, ROBOT, engine="exact", **options)
    theta = _theta(fast, np.random.default_rng(3), 12)
    np.testing.assert_allclose(fast(theta), exact(theta), rtol=0, atol=AGREEMENT)


def _grids_used(monkeypatch, likelihood, theta) -> list[int]:
    """Sizes of the grids that certified each set, in call order."""
    used = []
    original = spectral.spectral_loglike

    def recording(acov, block, coefficients, size):
        values, converged = original(acov, block, coefficients, size)
        used.extend([size] * int(converged.sum()))
        return values, converged

    monkeypatch.setattr("bayes_jackal.likelihood.residual_likelihood.spectral_loglike", recording)
    likelihood(theta)
    return used


def test_every_path_of_the_engine_is_exact(runs, monkeypatch):
    # Exponential kernels: at 72 Hz a 0.005 s one is certified on the
    # 512-point grid; a 0.3 s one (autocovariance 1e-13 of its variance only
    # after ~650 lags, checked over the grid's last half) on 4096; a 1 s one
    # (~2,200 lags) on no grid shorter than the full 10,000 points; a 3 s one
    # (cepstrum still ~1e-8 at lag 2,500) on none: the stopped recursion.
    likelihood = ResidualLikelihood(runs[:1], ROBOT, family="exponential", steady=False)
    theta = np.array([[110.0, 30.0, width, 0.01, 0.005] for width in (0.005, 0.3, 1.0, 3.0)])
    assert _grids_used(monkeypatch, likelihood, theta) == [512, 4096, likelihood.blocks[0].size]
    exact = ResidualLikelihood(runs[:1], ROBOT, family="exponential", steady=False, engine="exact")
    np.testing.assert_allclose(likelihood(theta), exact(theta), rtol=0, atol=AGREEMENT)
    # Without the fallback (the MAP search's scan) the last set is -inf.
    scan = ResidualLikelihood(runs[:1], ROBOT, family="exponential", steady=False, fallback=False)
    values = scan(theta)
    assert np.isneginf(values[3]) and np.all(np.isfinite(values[:3]))


def test_a_short_series_is_certified_on_the_full_grid(monkeypatch):
    # 600 residuals: only the 512- and 1024-point grids are shorter than 2n;
    # a 0.2 s exponential kernel's autocovariance is not negligible by their
    # last half, so the full grid (every lag represented) certifies it.
    run = _noise_run(600, 5)
    likelihood = ResidualLikelihood([run], ROBOT, family="exponential", steady=False)
    theta = np.array([[110.0, 30.0, 0.2, 0.01, 0.005]])
    assert _grids_used(monkeypatch, likelihood, theta) == [likelihood.blocks[0].size]
    exact = ResidualLikelihood([run], ROBOT, family="exponential", steady=False, engine="exact")
    np.testing.assert_allclose(likelihood(theta), exact(theta), rtol=0, atol=AGREEMENT)


def test_lagged_sums_equal_a_per_lag_loop(runs):
    # R(l) = sum_e sum_i x_e[i] x_e[i+l], written directly for each lag.
    likelihood = ResidualLikelihood(runs, ROBOT, steady=False)
    block = likelihood.blocks[0]
    coefficients = np.array([[1.0, -0.98, -0.004, 0.003], [1.0, -0.5, 0.1, -0.2]])
    lags = 40
    series = block.residuals(coefficients)  # (B, E, n)
    direct = np.array(
        [[np.sum(x[:, : block.n - lag] * x[:, lag:]) for lag in range(lags)] for x in series]
    )
    np.testing.assert_allclose(block.lagged_sums(coefficients, lags), direct, rtol=1e-11)


def test_chunks_do_not_change_the_values(runs, monkeypatch):
    # A budget of 8,000 elements: a set on the 512-point grid with E = 2
    # series counts 512 x (1 + 2E) = 2,560, so 40 sets go in 14 chunks of
    # three; on longer grids and in the recursion in chunks of one. The
    # values agree to rounding.
    likelihood = ResidualLikelihood(runs, ROBOT, family="exponential", steady=False)
    theta = _theta(likelihood, np.random.default_rng(7), 40)
    whole = likelihood(theta)
    monkeypatch.setattr(spectral, "CHUNK_ELEMENTS", 8_000)
    assert len(chunks(40, 512 * 5, budget=spectral.CHUNK_ELEMENTS)) == 14
    np.testing.assert_allclose(likelihood(theta), whole, rtol=1e-12, atol=1e-9)
