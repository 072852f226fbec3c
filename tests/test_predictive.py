"""Posterior-predictive series and model states in chunks: equal to the whole computation."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic_posteriors import ROBOT, posterior_at

from bayes_jackal._runtime.chunking import chunks
from bayes_jackal.io.simulate import Series, simulate_experiment
from bayes_jackal.likelihood.residual_likelihood import sample_stationary
from bayes_jackal.model.physics import simulate
from bayes_jackal.posterior import Posterior, predictive
from bayes_jackal.posterior.posterior import (
    model_autocovariance,
)
from bayes_jackal.posterior.predictive import (
    model_percentiles,
    predictive_series,
    predictive_statistics,
)
from bayes_jackal.posterior.series_statistics import sample_autocorrelation

#: Damping, then (sigma_h, sigma_c, sigma_n) of yaw: the simulator's truth.
TRUTH = [110.0, 30.0, 0.047, 0.01, 0.005]
DRAWS = 12


@pytest.fixture(scope="module")
def idata():
    """A posterior around the truth of a 10 s run (721 samples)."""
    run = simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, np.deg2rad(22.5), 10.0), rng=4)
    return posterior_at([run], TRUTH, spread=0.05)


@pytest.mark.parametrize(("count", "samples", "budget"), [(200, 720, 400_000), (7, 10, 25)])
def test_chunks_cover_every_draw_once_within_the_budget(count, samples, budget):
    parts = chunks(count, samples, budget=budget)
    covered = np.concatenate([np.arange(count)[part] for part in parts])
    assert covered.tolist() == list(range(count))
    assert all((part.stop - part.start) * samples <= budget for part in parts)
    assert len(parts) == -(-count // (budget // samples))


def test_a_series_longer_than_the_budget_is_one_draw_per_chunk():
    assert [part.stop - part.start for part in chunks(3, 259_200, budget=10)] == [1, 1, 1]


def _reference_series(idata, seed: int) -> np.ndarray:
    """Series i drawn alone from the i-th generator spawned from the seed."""
    metadata = Posterior.of(idata).metadata
    theta = Posterior.of(idata).thinned_draws(DRAWS)
    n = idata.observed_data["residual_yaw_0"].size
    generators = np.random.default_rng(seed).spawn(DRAWS)
    return np.concatenate(
        [
            sample_stationary(model_autocovariance(metadata, 0, "yaw", row[None], n), g)
            for row, g in zip(theta, generators, strict=True)
        ]
    )


def test_predictive_series_do_not_depend_on_the_chunks(idata, monkeypatch):
    metadata = Posterior.of(idata).metadata
    theta = Posterior.of(idata).thinned_draws(DRAWS)
    n = idata.observed_data["residual_yaw_0"].size
    whole = list(predictive_series(metadata, 0, "yaw", theta, n, rng=3))
    monkeypatch.setattr(predictive, "CHUNK_SAMPLES", 5 * n)  # chunks of 5, 5 and 2 draws
    chunks = list(predictive_series(metadata, 0, "yaw", theta, n, rng=3))
    assert len(whole) == 1 and [part.stop - part.start for part, _ in chunks] == [5, 5, 2]
    chunked = np.concatenate([series for _, series in chunks])
    # Every series comes from its own generator; only the autocovariance of a
    # batch differs from a lone row's, in the last bits (series ~1e-2).
    np.testing.assert_allclose(chunked, whole[0][1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(chunked, _reference_series(idata, 3), rtol=0, atol=1e-15)


def test_predictive_statistics_equal_the_statistics_of_all_series_at_once(idata, monkeypatch):
    monkeypatch.setattr(predictive, "CHUNK_SAMPLES", 1)  # one draw per chunk
    result = predictive_statistics(
        idata,
        0,
        "yaw",
        {"acf": lambda x: sample_autocorrelation(x, 10), "var": lambda x: x.var(axis=-1)},
        count=DRAWS,
        rng=5,
    )
    series = _reference_series(idata, 5)
    np.testing.assert_allclose(
        result["acf"], sample_autocorrelation(series, 10), rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(result["var"], series.var(axis=-1), rtol=1e-12, atol=0)


def _reference_percentiles(idata, percentiles, count: int) -> np.ndarray:
    """The percentiles of the model states of every draw over the whole run at once."""
    likelihood = Posterior.of(idata).likelihood()
    (run,) = likelihood.experiments
    theta = Posterior.of(idata).thinned_draws(count)
    x0 = np.array([run.vx[0], run.vy[0], run.yaw_rate[0]])
    states = simulate(ROBOT, theta[:, 0], theta[:, 1], run.inputs, x0, dt=run.dt)
    return np.percentile(states, percentiles, axis=0)


def test_model_percentiles_in_one_segment_are_those_of_one_simulation(idata):
    # 50 draws x 721 samples fit the budget: one segment, the whole-run computation.
    reference = _reference_percentiles(idata, [3.0, 50.0, 97.0], 50)
    np.testing.assert_allclose(
        model_percentiles(idata, 0, [3.0, 50.0, 97.0]), reference, rtol=0, atol=0
    )


def test_model_percentiles_over_short_segments_match_one_simulation(idata, monkeypatch):
    monkeypatch.setattr(predictive, "CHUNK_SAMPLES", 50 * 8)  # segments of 7 steps
    result = model_percentiles(idata, 0, [3.0, 50.0, 97.0])
    reference = _reference_percentiles(idata, [3.0, 50.0, 97.0], 50)
    assert result.shape == reference.shape == (3, 721, 3)
    # The segments restart the FFT convolution from each segment's first
    # state: rounding of ~1e-16 of the states (~0.4 m/s, 0.4 rad/s) per step.
    np.testing.assert_allclose(result, reference, rtol=0, atol=1e-12)
