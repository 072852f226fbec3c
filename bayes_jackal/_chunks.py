"""Chunks of parameter sets or posterior draws whose work arrays stay within a budget."""

from __future__ import annotations

__all__ = ["chunks"]


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
