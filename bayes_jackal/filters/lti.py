"""A stable linear time-invariant recursion over a whole series, without a loop over time.

Both filters of issue 14 become such a recursion once their gains are
constant: the Kalman filter after its covariance has converged
(:mod:`bayes_jackal.filters.kalman_filters`), the generalised filter from the start
(:mod:`bayes_jackal.filters.generalised`). For

    x_i = T x_(i-1) + C d_i,   z_i = O x_i,   i = 0 .. N-1,   x_(-1) = x_start,

z_i = O T^(i+1) x_start + sum_j (O T^j C) d_(i-j): the impulse response
O T^j C, cut where T^j has fallen below a tolerance (T is stable), convolved
with the drive d by FFT (overlap-add). The memory is that of the response
and of N x outputs x drives, never N x states x states.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from .._runtime import InputError

__all__ = ["lti_outputs", "matrix_powers"]


def matrix_powers(matrix: np.ndarray, limit: int, tolerance: float) -> np.ndarray:
    """matrix^j for j = 0 .. L - 1, up to where the largest entry falls below ``tolerance``.

    By repeated doubling (log2 L batched products): the block
    [M^0 .. M^(n-1)] times M^n gives [M^n .. M^(2n-1)].

    Parameters
    ----------
    matrix : ndarray, shape (n, n)
        A stable matrix (spectral radius < 1), or the powers run to ``limit``.
    limit : int
        Most powers returned, L <= limit.
    tolerance : float
        Largest entry of the first power left out.

    Returns
    -------
    ndarray, shape (L, n, n)

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_jackal.filters import matrix_powers
    >>> powers = matrix_powers(np.array([[0.5]]), 100, 1e-3)
    >>> len(powers), float(powers[-1, 0, 0])  # 0.5^9 > 1e-3 > 0.5^10
    (10, 0.001953125)
    """
    powers = np.eye(len(matrix))[None]
    while len(powers) < limit and np.abs(powers[-1]).max() >= tolerance:
        powers = np.concatenate([powers, powers @ (powers[-1] @ matrix)])
    small = np.abs(powers[:limit]).max(axis=(1, 2)) < tolerance
    return powers[: int(np.argmax(small)) if small.any() else limit]


def lti_outputs(
    transition: np.ndarray,
    input_matrix: np.ndarray,
    drive: np.ndarray,
    start: np.ndarray,
    *,
    outputs: np.ndarray | None = None,
    tolerance: float,
) -> np.ndarray:
    """z_i = O x_i of x_i = T x_(i-1) + C d_i over a whole series (module docstring).

    Parameters
    ----------
    transition : ndarray, shape (n, n)
        T, stable.
    input_matrix : ndarray, shape (n, m)
        C.
    drive : ndarray, shape (N, m)
        d_0 .. d_(N-1).
    start : ndarray, shape (n,)
        x_(-1).
    outputs : ndarray, shape (o, n), optional
        O; the identity (the states) by default.
    tolerance : float
        Powers of T whose largest entry is below it are left out
        (:func:`matrix_powers`).

    Returns
    -------
    ndarray, shape (N, o)

    Examples
    --------
    A first-order low-pass x_i = 0.9 x_(i-1) + 0.1 d_i, against its loop:

    >>> import numpy as np
    >>> from bayes_jackal.filters import lti_outputs
    >>> d = np.random.default_rng(1).normal(size=(50, 1))
    >>> z = lti_outputs(np.array([[0.9]]), np.array([[0.1]]), d, np.array([2.0]),
    ...                 tolerance=1e-16)
    >>> x, loop = 2.0, []
    >>> for value in d[:, 0]:
    ...     x = 0.9 * x + 0.1 * value
    ...     loop.append(x)
    >>> bool(np.allclose(z[:, 0], loop, rtol=0, atol=1e-13))
    True
    """
    drive = np.asarray(drive, float)
    if drive.ndim != 2 or drive.shape[1] != input_matrix.shape[1]:
        raise InputError(
            f"expected a drive of shape (N, {input_matrix.shape[1]}), got {drive.shape}",
            field="drive",
        )
    size = len(drive)
    observe = np.eye(len(transition)) if outputs is None else outputs
    powers = observe @ matrix_powers(transition, size + 1, tolerance)  # O T^j, (J, o, n)
    response = powers @ input_matrix  # O T^j C, (J, o, m)
    convolved = scipy.signal.oaconvolve(response, drive[:, None, :], axes=0)
    values = convolved[:size].sum(axis=-1)
    head = min(len(powers) - 1, size)
    values[:head] += powers[1 : head + 1] @ start
    return values
