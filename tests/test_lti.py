"""The LTI recursion of both filters against its plain loop."""

from __future__ import annotations

import numpy as np
import pytest

from bayes_jackal import InputError
from bayes_jackal.filters.lti import lti_outputs, matrix_powers


def _loop(transition, input_matrix, drive, start, outputs):
    """x_i = T x_(i-1) + C d_i, z_i = O x_i, one step at a time: the reference."""
    x, values = start, []
    for d in drive:
        x = transition @ x + input_matrix @ d
        values.append(outputs @ x)
    return np.array(values)


@pytest.mark.parametrize("radius", [0.3, 0.95, 0.999])
def test_outputs_equal_the_loop(radius):
    # radius 0.999: the response outlives the 500 samples and is cut at the run's
    # end, not at the tolerance; 0.3 cuts it after ~30 steps.
    rng = np.random.default_rng(4)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    transition = q @ np.diag([radius, -0.5 * radius, 0.2]) @ q.T
    input_matrix, outputs = rng.normal(size=(3, 2)), rng.normal(size=(2, 3))
    drive, start = rng.normal(size=(500, 2)), rng.normal(size=3)
    expected = _loop(transition, input_matrix, drive, start, outputs)
    values = lti_outputs(transition, input_matrix, drive, start, outputs=outputs, tolerance=1e-16)
    # Terms left out are below 1e-16 of the start and drive (sd 1), and the FFT's
    # rounding is ~1e-15 of the sum's scale; 1e-11 leaves a wide margin.
    np.testing.assert_allclose(values, expected, rtol=0, atol=1e-11 * np.abs(expected).max())


def test_powers_stop_below_the_tolerance_or_at_the_limit():
    powers = matrix_powers(np.diag([0.5, 0.25]), 100, 1e-6)
    assert len(powers) == 20  # 0.5^19 = 1.9e-6 >= 1e-6 > 0.5^20
    np.testing.assert_array_equal(powers[3], np.diag([0.125, 0.25**3]))
    assert len(matrix_powers(np.diag([0.5, 0.25]), 7, 1e-6)) == 7


def test_a_drive_of_the_wrong_shape_is_refused():
    with pytest.raises(InputError, match=r"drive of shape \(N, 2\), got \(5, 3\)"):
        lti_outputs(np.eye(2) / 2, np.eye(2), np.ones((5, 3)), np.zeros(2), tolerance=1e-16)
