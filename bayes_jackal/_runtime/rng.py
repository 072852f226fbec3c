"""Random number generators: every function that draws takes an ``rng``."""

from __future__ import annotations

import numpy as np

__all__ = ["as_rng"]


def as_rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    """A ``numpy.random.Generator`` from a generator, a seed or None.

    Examples
    --------
    A seed gives numpy's generator for that seed; a generator passes through:

    >>> import numpy as np
    >>> from bayes_jackal._runtime.rng import as_rng
    >>> bool(as_rng(1).standard_normal() == np.random.default_rng(1).standard_normal())
    True
    >>> rng = np.random.default_rng(2)
    >>> as_rng(rng) is rng
    True
    """
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
