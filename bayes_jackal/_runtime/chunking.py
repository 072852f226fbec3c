"""Chunks of parameter sets or posterior draws whose work arrays stay within a budget."""

from __future__ import annotations

import numpy as np

__all__ = ["chunks", "thinned_indices"]


def chunks(rows: int, row_elements: int, *, budget: int) -> list[slice]:
    """Consecutive slices of ``rows`` rows, each chunk's array within ``budget`` elements.

    Each chunk has ``budget // row_elements`` rows, one at least: a row
    larger than the budget is processed alone.

    Parameters
    ----------
    rows : int
        Number of rows (parameter sets, posterior draws).
    row_elements : int
        Elements of the largest work array per row (e.g. the samples of one
        draw's series).
    budget : int
        Elements a chunk's largest array may hold.
    """
    step = max(1, budget // max(1, row_elements))
    return [slice(start, min(start + step, rows)) for start in range(0, rows, step)]


def thinned_indices(count: int, limit: int) -> np.ndarray:
    """Evenly spaced indices of at most ``limit`` out of ``count`` draws.

    Examples
    --------
    Four evenly spaced draws out of ten:

    >>> from bayes_jackal._runtime.chunking import thinned_indices
    >>> thinned_indices(10, 4).tolist()
    [0, 3, 6, 9]
    >>> thinned_indices(3, 4).tolist()  # fewer draws than the limit: all of them
    [0, 1, 2]
    """
    return np.unique(np.linspace(0, count - 1, min(count, limit)).astype(int))
