"""Generalised coordinates: the shift operator, the embedding, white noise embedded."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from bayes_jackal import InputError
from bayes_jackal.filters.generalised_coordinates import (
    embed,
    shift_operator,
    taylor_step,
    white_sensor_precision,
)


@pytest.mark.parametrize("order", [0, 1, 2, 3, 4])
def test_embedding_is_exact_on_polynomials_of_degree_up_to_the_order(order):
    rng = np.random.default_rng(order)
    dt = 0.05
    t = np.arange(12) * dt
    polynomial = np.polynomial.Polynomial(rng.normal(size=order + 1))
    # Closed form: derivative j of the polynomial at every sample.
    expected = np.column_stack([polynomial.deriv(j)(t) for j in range(order + 1)])
    for lookahead in range(order + 1):
        np.testing.assert_allclose(
            # inv(T) of a Vandermonde-like system at dt = 0.05: its condition
            # number grows as dt^-p (~1e5 at p = 4), so 1e-8 leaves rounding room
            embed(polynomial(t), order, dt, lookahead=lookahead),
            expected,
            rtol=1e-8,
            atol=1e-8,
        )
    # One degree more is not exact: the centred first derivative of t^3 is
    # ((t + h)^3 - (t - h)^3) / (2 h) = 3 t^2 + h^2, off by h^2 (closed form).
    if order == 2:
        embedded = embed(t**3, 2, dt)
        # a closed form against a 3 x 3 solve: rounding, far below 1e-10
        np.testing.assert_allclose(embedded[1:-1, 1], 3 * t[1:-1] ** 2 + dt**2, rtol=1e-10)


def test_embedding_of_several_series_and_too_short_series():
    t = np.arange(6) * 0.1
    both = embed(np.column_stack([t, 2 * t]), 1, 0.1)
    assert both.shape == (6, 2, 2)
    np.testing.assert_allclose(both[:, 1], [[1.0, 2.0]] * 6, rtol=1e-12)
    with pytest.raises(InputError, match="needs at least 3 samples"):
        embed(np.ones(2), 2, 0.1)
    with pytest.raises(InputError, match=r"lookahead must lie in 0 \.\. 2"):
        embed(np.ones(5), 2, 0.1, lookahead=3)


@pytest.mark.parametrize(("order", "lookahead"), [(1, 0), (2, 1), (2, 0), (3, 1)])
def test_sensor_precision_is_the_inverse_covariance_of_embedded_white_noise(order, lookahead):
    # Monte Carlo: 200,000 white samples embedded; windows overlap, so about
    # 200,000 / (p + 1) independent ones, and each variance is within
    # ~sqrt(2 (p + 1) / 200,000) < 0.7 % (1 sd): 4 % is > 5 sd.
    dt, sigma = 0.02, 0.3
    noise = sigma * np.random.default_rng(5).standard_normal(200_000)
    embedded = embed(noise, order, dt, lookahead=lookahead)[order:-order]
    expected = np.linalg.inv(white_sensor_precision(order, dt, sigma, lookahead=lookahead))
    scale = np.sqrt(np.diag(expected))
    np.testing.assert_allclose(
        np.cov(embedded.T) / np.outer(scale, scale), expected / np.outer(scale, scale), atol=0.04
    )


def test_shift_operator_moves_each_derivative_up():
    x = np.array([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(shift_operator(3) @ x, [2.0, 3.0, 4.0, 0.0])


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_taylor_step_is_the_motion_over_one_step(order):
    # expm(D dt)'s first row carries x~ one step: exact on polynomials of degree <= p.
    dt = 0.03
    polynomial = np.polynomial.Polynomial(np.arange(1.0, order + 2))
    here = np.array([polynomial.deriv(j)(0.2) for j in range(order + 1)])
    # exact but for rounding of p + 1 terms of order 1: 1e-13 is ~500 ulps
    assert taylor_step(order, dt) @ here == pytest.approx(polynomial(0.2 + dt), rel=1e-13)
    np.testing.assert_allclose(
        taylor_step(order, dt), scipy.linalg.expm(shift_operator(order) * dt)[0], rtol=1e-13
    )
