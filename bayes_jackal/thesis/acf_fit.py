"""The classical widths of a noise series: least squares on its first autocorrelation lags.

What the field does to tune a DEM filter, shown beside the posterior so that
the method's effect is visible (issue 15): fit a Gaussian autocorrelation
to the sample autocorrelation r of the series over its first lags.

- :func:`acf_least_squares`: for each lag count L (1..10 by default), the
  width s [s] minimising

      MSE(s) = (1 / L) sum_{k=1..L} (r_k - exp(-(k dt)^2 / (4 s^2)))^2,

  the continuous autocorrelation of the package's Gaussian family
  (:class:`bayes_jackal.model.Gaussian`: kernel exp(-t^2 / (2 s^2)),
  autocorrelation exp(-t^2 / (4 s^2)), DEM's smoothness convention),
  minimised over s > 0 without a grid.
- :func:`thesis_fit`: the thesis' own fit (ch. 7-3-1, eq. 7-6), which is
  :func:`bayes_jackal.thesis.fit_sigma_h`: the same MSE over
  lags 1..30 against the autocorrelation of white noise through the
  sampled filter of eq. 7-5 (truncated at +-3 s), on the thesis' grid
  0.001..1 s in steps of 0.001 s.

Both use one sample autocorrelation,
:func:`bayes_jackal.posterior.sample_autocorrelation` (MATLAB's
``autocorr``: mean removed, every lag divided by the same sum, r_0 = 1).

The lag convention: eq. 7-6 sums i = 1..l, leaving lag 0 out. Both
autocorrelations are 1 at lag 0, so including it only scales the MSE by
L / (L + 1) and leaves its minimiser alone: a fit "on lags 0-L", as issue
15 counts them (its 0.0066, 0.0072 and 0.0069 s on lags 0-1, 0-2 and 0-5),
is the fit of lag count L here.

The two fits differ in the model autocorrelation, and so differ below about
half a sample: the thesis' sampled filter is a single tap (white noise)
below s = dt / 3, so its fit cannot resolve such widths, while the
continuous Gaussian resolves widths down to a small fraction of a sample.
Neither fit allows for a white floor (sensor noise): the floor lowers every
r_k with k >= 1 and pulls the width down (docs/design.md §4). Where the
autocorrelation at lags 1..L is not positive enough for any Gaussian to fit
better than none, the least-squares width is 0.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import scipy.optimize

from .._runtime import RESIDUAL_LAGS as LAGS
from .._runtime import InputError, positive_number
from ..posterior import sample_autocorrelation
from .residual_analysis import SIGMA_H_GRID, fit_sigma_h

__all__ = ["LEAST_SQUARES_LAGS", "THESIS_LAGS", "acf_least_squares", "thesis_fit"]

#: Lag counts of :func:`acf_least_squares` (issue 15: 1 to 10 lags).
LEAST_SQUARES_LAGS = range(1, 11)
#: Lags of the thesis' fit (eq. 7-6, l = 30).
THESIS_LAGS = LAGS
#: Widths [samples] searched for the least-squares minimum before it is
#: polished: 1e-2 (autocorrelation exp(-2500) at lag 1, i.e. white) to 1e6
#: (r_1 = 1 - 2.5e-13), 40 points per decade.
_START = np.geomspace(1e-2, 1e6, 321)
#: Filter taps held at once by :func:`thesis_fit` (~16 MB of them).
_CHUNK_TAPS = 2_000_000


def _check_counts(lags: Iterable[int]) -> list[int]:
    given = list(lags) if isinstance(lags, Iterable) and not isinstance(lags, str) else [lags]
    bad = [
        k for k in given if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1
    ]
    if not given or bad or len(set(given)) != len(given):
        raise InputError(f"lag counts must be distinct integers >= 1, got {lags!r}", field="lags")
    return sorted(int(k) for k in given)


def _gaussian(log_width: np.ndarray, squares: np.ndarray) -> np.ndarray:
    """exp(-k^2 / (4 w^2)) at widths w = exp(log_width) [samples], shape (..., L)."""
    return np.exp(-squares / (4.0 * np.exp(2.0 * np.asarray(log_width))[..., None]))


def _least_squares_width(r: np.ndarray) -> float:
    """The width [samples] fitting exp(-k^2 / (4 w^2)) to r_1..r_L; 0 at the lower end."""
    squares = np.arange(1, len(r) + 1) ** 2.0
    start = np.log(_START)
    mse = np.mean((r - _gaussian(start, squares)) ** 2, axis=-1)
    best = int(np.argmin(mse))
    if best == 0:
        return 0.0
    fit = scipy.optimize.least_squares(
        lambda x: _gaussian(x[0], squares) - r,
        [start[best]],
        jac=lambda x: (_gaussian(x[0], squares) * squares * np.exp(-2.0 * x[0]) / 2.0)[:, None],
        method="lm",
        xtol=1e-14,
        ftol=1e-14,
        gtol=1e-14,
    )
    return float(np.exp(fit.x[0]))


def acf_least_squares(
    values: np.ndarray, dt: float, *, lags: Iterable[int] = LEAST_SQUARES_LAGS
) -> dict[int, float]:
    """Least-squares Gaussian widths for several lag counts (see the module text).

    Parameters
    ----------
    values : ndarray, shape (n,)
        The series [any unit], finite and not constant; n > max(lags).
    dt : float
        Sample time [s].
    lags : iterable of int
        Lag counts L >= 1: each fit uses lags 1..L (equivalently 0..L).

    Returns
    -------
    dict of int to float
        L -> width s [s] of the Gaussian autocorrelation exp(-t^2 / (4 s^2)),
        in increasing L; 0.0 where no positive width fits better than none.

    Raises
    ------
    InputError
        For lag counts that are not distinct integers >= 1, a series too
        short for them, non-finite or constant, or dt not positive.

    Examples
    --------
    With one lag the fit is exact: r_1 = exp(-dt^2 / (4 s^2)). Noise through
    the Gaussian filter of width 0.02 s at 120 Hz, 20 000 samples:

    >>> import numpy as np
    >>> from bayes_jackal.thesis import acf_least_squares
    >>> from bayes_jackal.model import get_family
    >>> from bayes_jackal.posterior import sample_autocorrelation
    >>> x = get_family("gaussian").noise(0.02, 1 / 120, 20000, rng=1)
    >>> widths = acf_least_squares(x, 1 / 120, lags=[1, 5, 10])
    >>> {lags: round(width, 4) for lags, width in widths.items()}
    {1: 0.0199, 5: 0.0199, 10: 0.0199}
    >>> r1 = sample_autocorrelation(x, 1)[1]
    >>> bool(np.isclose(widths[1], (1 / 120) / (2 * np.sqrt(-np.log(r1)))))
    True
    """
    dt = positive_number(dt, name="dt", unit="s", required=True, what="the sample time")
    counts = _check_counts(lags)
    r = sample_autocorrelation(values, counts[-1])
    return {count: dt * _least_squares_width(r[1 : count + 1]) for count in counts}


def thesis_fit(values: np.ndarray, dt: float) -> float:
    """The thesis' sigma_h of a series: eq. 7-6 over 30 lags on its 1 ms grid [s].

    :func:`bayes_jackal.thesis.fit_sigma_h` with the thesis'
    lags (:data:`THESIS_LAGS`) and grid (0.001..1 s by 0.001 s). The grid
    bounds the answer: widths below 1 ms or above 1 s come out as 0.001 or 1 s.

    Parameters
    ----------
    values : ndarray, shape (n,)
        The series [any unit], finite and not constant; n >= 31.
    dt : float
        Sample time [s].

    Returns
    -------
    float
        sigma_h [s], a multiple of 0.001 s.

    Examples
    --------
    The thesis' width 0.047 s at the Jackal's 72 Hz is found on the grid:

    >>> from bayes_jackal.thesis import thesis_fit
    >>> from bayes_jackal.model import get_family
    >>> thesis_fit(get_family("gaussian").noise(0.047, 1 / 72, 20000, rng=1), 1 / 72)
    0.047
    """
    dt = positive_number(dt, name="dt", unit="s", required=True, what="the sample time")
    # The grid's widest filter (1 s) has 6 s / dt taps: fit the grid in pieces
    # of ~_CHUNK_TAPS taps in all (in one piece, 1 kHz would take ~0.4 GB).
    chunks = np.array_split(
        SIGMA_H_GRID, max(1, round(len(SIGMA_H_GRID) * 6.0 / dt / _CHUNK_TAPS))
    )
    mse = np.concatenate([fit_sigma_h(values, dt, THESIS_LAGS, chunk)[1] for chunk in chunks])
    return float(SIGMA_H_GRID[np.argmin(mse)])
