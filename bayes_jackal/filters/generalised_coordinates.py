"""Generalised coordinates of sampled series: the shift, the embedding and white noise in them.

A state described by its generalised coordinates x~ = (x, x', .., x^(p)) of
embedding order p (Friston 2008, "Hierarchical models in the brain") moves
by the shift operator D: D x~ = (x', .., x^(p), 0).

The data's generalised coordinates come from a local Taylor expansion of
p + 1 samples, as ``spm_DEM_embed``: with T[i, j] = ((i - x) dt)^j / j!, the
sample i of a window is y[i] = sum_j T[i, j] y^(j)(t_x), so y~ = inv(T) y. The
window holds ``lookahead`` samples after the estimated one (SPM's centring:
floor(p / 2)); at the ends of a series it is moved inside the series and
the expansion point moves in it, so the embedding stays exact on
polynomials of degree <= p (``spm_DEM_embed`` repeats the end sample).

White sensor noise has no derivatives, so its generalised precision needs a
choice. :func:`white_sensor_precision` takes the exact covariance of the
embedded noise: z~ = inv(T) z_window has covariance sigma_n^2 inv(T) inv(T)',
so Pi_z = T' T / sigma_n^2, with no smoothness parameter and consistent with
the embedding actually used.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.special

from .._runtime import InputError

__all__ = [
    "embed",
    "embedding_operator",
    "shift_operator",
    "taylor_step",
    "white_sensor_precision",
]


def _check_order(order: int) -> int:
    if isinstance(order, bool) or not isinstance(order, int | np.integer) or order < 0:
        raise InputError(f"embedding order must be an integer >= 0, got {order!r}", field="order")
    return int(order)


def _lookahead(order: int, lookahead: int | None) -> int:
    if lookahead is None:
        return order // 2  # spm_DEM_embed's centred window
    if isinstance(lookahead, bool) or not isinstance(lookahead, int | np.integer):
        raise InputError(f"lookahead must be an integer, got {lookahead!r}", field="lookahead")
    if not 0 <= lookahead <= order:
        raise InputError(
            f"lookahead must lie in 0 .. {order} (the order), got {lookahead}", field="lookahead"
        )
    return int(lookahead)


def shift_operator(order: int) -> np.ndarray:
    """The derivative operator D of generalised coordinates, shape (p + 1, p + 1).

    D (x, x', .., x^(p)) = (x', .., x^(p), 0): ones on the first
    superdiagonal. The highest derivative's motion is truncated to zero.

    Examples
    --------
    >>> from bayes_jackal.filters import shift_operator
    >>> shift_operator(2).tolist()
    [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]
    """
    return np.eye(_check_order(order) + 1, k=1)


def _taylor_matrix(order: int, dt: float, position: np.ndarray | int) -> np.ndarray:
    """T[i, j] = ((i - x) dt)^j / j!, shape (..., p + 1, p + 1), x = ``position``."""
    i, j = np.indices((order + 1, order + 1))
    offset = (i - np.asarray(position)[..., None, None]) * dt
    return offset**j / scipy.special.factorial(j)


def embedding_operator(order: int, dt: float, *, lookahead: int | None = None) -> np.ndarray:
    """The operator E = inv(T) from p + 1 samples to generalised coordinates.

    The local Taylor expansion of ``spm_DEM_embed``: sample i of the window
    is y[i] = sum_j T[i, j] y^(j)(t*), T[i, j] = ((i - x) dt)^j / j!, with
    t* the sample x = p - ``lookahead`` of the window; E solves for the
    derivatives at t*. Exact for polynomials of degree <= p.

    Parameters
    ----------
    order : int
        Embedding order p (p + 1 samples, derivatives 0 .. p).
    dt : float
        Sample time [s].
    lookahead : int, optional
        Samples of the window after t*; by default SPM's centring, floor(p / 2).

    Returns
    -------
    ndarray, shape (p + 1, p + 1)
        Row j gives derivative j [channel units / s^j] from the window.

    Examples
    --------
    Order 2, centred: the central differences, (y[2] - y[0]) / (2 dt) and
    (y[0] - 2 y[1] + y[2]) / dt^2:

    >>> import numpy as np
    >>> from bayes_jackal.filters import embedding_operator
    >>> E = embedding_operator(2, 0.5)
    >>> np.round(E, 12).tolist()
    [[0.0, 1.0, 0.0], [-1.0, 0.0, 1.0], [4.0, -8.0, 4.0]]
    """
    order = _check_order(order)
    return np.linalg.inv(_taylor_matrix(order, dt, order - _lookahead(order, lookahead)))


def embed(
    series: np.ndarray, order: int, dt: float, *, lookahead: int | None = None
) -> np.ndarray:
    """Generalised coordinates of a sampled series at every sample.

    Each sample's window is the p + 1 samples around it (``lookahead`` after
    it, see :func:`embedding_operator`); near the ends the window is moved
    inside the series and the expansion point moves within it, so every
    sample's coordinates are exact for polynomials of degree <= p.

    Parameters
    ----------
    series : array_like, shape (N, ...)
        Samples along the first axis, N >= p + 1.
    order : int
        Embedding order p.
    dt : float
        Sample time [s].
    lookahead : int, optional
        As :func:`embedding_operator`.

    Returns
    -------
    ndarray, shape (N, p + 1, ...)
        Derivative j of sample k at ``[k, j]`` [units / s^j].

    Raises
    ------
    InputError
        For a series shorter than p + 1 samples.

    Examples
    --------
    A quadratic is embedded exactly, ends included: y = t^2 has y' = 2 t and
    y'' = 2:

    >>> import numpy as np
    >>> from bayes_jackal.filters import embed
    >>> t = np.arange(5) * 0.1
    >>> y = embed(t**2, 2, 0.1)
    >>> bool(np.allclose(y, np.column_stack([t**2, 2 * t, np.full(5, 2.0)])))
    True
    """
    order = _check_order(order)
    ahead = _lookahead(order, lookahead)
    series = np.asarray(series, float)
    n = len(series)
    if n < order + 1:
        raise InputError(
            f"embedding order {order} needs at least {order + 1} samples, got {n}",
            field="order",
        )
    k = np.arange(n)
    start = np.clip(k - (order - ahead), 0, n - order - 1)
    operators = np.linalg.inv(_taylor_matrix(order, dt, np.arange(order + 1)))
    windows = np.lib.stride_tricks.sliding_window_view(series, order + 1, axis=0)[start]
    # windows: (N, ..., p + 1); the operator of each sample's position in its window
    return np.einsum("kij,k...j->ki...", operators[k - start], windows)


def white_sensor_precision(
    order: int, dt: float, sigma: float, *, lookahead: int | None = None
) -> np.ndarray:
    """Pi_z = T' T / sigma^2: the precision of embedded white sensor noise.

    White noise z of sd ``sigma`` has no derivatives, but its embedding
    z~ = E z_window (:func:`embedding_operator`, E = inv(T)) has the covariance
    sigma^2 E E', whose inverse is T' T / sigma^2. This is the sensor
    precision the filter uses by default: no smoothness parameter to choose,
    and consistent with the embedding of the data.

    Parameters
    ----------
    order : int
        Embedding order p.
    dt : float
        Sample time [s].
    sigma : float
        Sensor-noise sd [channel units], > 0.
    lookahead : int, optional
        As :func:`embedding_operator`.

    Returns
    -------
    ndarray, shape (p + 1, p + 1)
        [1 / (units / s^i) / (units / s^j)].

    Examples
    --------
    At order 0 it is 1 / sigma^2; at order 1 (backward difference) the
    derivative's variance is 2 sigma^2 / dt^2, as the closed form says:

    >>> import numpy as np
    >>> from bayes_jackal.filters import white_sensor_precision
    >>> white_sensor_precision(0, 0.1, 0.5).tolist()
    [[4.0]]
    >>> covariance = np.linalg.inv(white_sensor_precision(1, 0.1, 0.5))
    >>> bool(np.isclose(covariance[1, 1], 2 * 0.5**2 / 0.1**2))
    True
    """
    if not (math.isfinite(sigma) and sigma > 0):
        raise InputError(f"sensor-noise sd must be positive, got {sigma!r}", field="sigma_n")
    order = _check_order(order)
    T = _taylor_matrix(order, dt, order - _lookahead(order, lookahead))
    return T.T @ T / sigma**2


def taylor_step(order: int, dt: float) -> np.ndarray:
    """t with t_j = dt^j / j!: x(t + dt) = t . x~(t) under the motion D.

    The first row of expm(D dt), the generalised motion carried over one
    sample: exact for polynomials of degree <= p.

    Parameters
    ----------
    order : int
        Embedding order p.
    dt : float
        Step [s].

    Returns
    -------
    ndarray, shape (p + 1,)
        [s^j].

    Examples
    --------
    >>> import numpy as np
    >>> import scipy.linalg
    >>> from bayes_jackal.filters import shift_operator, taylor_step
    >>> taylor_step(2, 0.5).tolist()
    [1.0, 0.5, 0.125]
    >>> bool(np.allclose(taylor_step(3, 0.5), scipy.linalg.expm(shift_operator(3) * 0.5)[0]))
    True
    """
    j = np.arange(_check_order(order) + 1)
    return dt**j / scipy.special.factorial(j)
