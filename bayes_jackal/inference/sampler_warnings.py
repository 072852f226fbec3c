"""The sampler's warnings: :class:`ConvergenceWarning`, and warnings kept to be issued elsewhere.

A job that runs in a worker process (:mod:`bayes_jackal.inference.executors`) keeps
its warnings (:func:`keep_warnings`) and returns them with its result, so
that they reach the user from the main process instead of the worker's
stderr. :mod:`bayes_jackal.inference.sampling` re-exports these names.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field

__all__ = ["ConvergenceWarning", "KeptWarnings", "keep_warnings"]


class ConvergenceWarning(UserWarning):
    """The chain hit its step cap before the convergence criterion held.

    Examples
    --------
    A UserWarning, so Python's warning filters apply to it:

    >>> from bayes_jackal import ConvergenceWarning
    >>> try:
    ...     raise ConvergenceWarning("NOT CONVERGED")
    ... except UserWarning as warning:
    ...     print(type(warning).__name__, warning)
    ConvergenceWarning NOT CONVERGED
    """


@dataclass
class KeptWarnings:
    """The warnings raised in a block, kept to be issued elsewhere (picklable).

    A job that runs in a worker process (:mod:`bayes_jackal.inference.executors`) keeps
    its warnings here and returns them with its result, so that they reach
    the user from the main process instead of the worker's stderr.

    Attributes
    ----------
    convergence : list of str
        The :class:`ConvergenceWarning` messages, in order.
    other : list of (type, str)
        Every other warning's category and message, each pair once, in order.

    Examples
    --------
    Warnings kept in a worker, issued again in the main process with the job's
    name before them:

    >>> import warnings
    >>> from bayes_jackal.inference import KeptWarnings
    >>> kept = KeptWarnings(other=[(RuntimeWarning, "a prior is narrow")])
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     kept.issue("white: ")
    >>> caught[0].category.__name__, str(caught[0].message)
    ('RuntimeWarning', 'white: a prior is narrow')
    """

    convergence: list[str] = field(default_factory=list)
    other: list[tuple[type[Warning], str]] = field(default_factory=list)

    def issue(self, prefix: str = "", *, stacklevel: int = 2) -> None:
        """Issue the other warnings again, here, each message after ``prefix``."""
        for category, message in self.other:
            warnings.warn(f"{prefix}{message}", category, stacklevel=stacklevel + 1)


@contextlib.contextmanager
def keep_warnings() -> Iterator[KeptWarnings]:
    """Keep the warnings raised in the block, instead of showing them.

    Python's filters still decide which warnings are raised (an "error"
    filter still raises); every :class:`ConvergenceWarning` is kept. The
    :class:`KeptWarnings` yielded is filled when the block ends, also when
    it raises.

    Examples
    --------
    >>> import warnings
    >>> from bayes_jackal.inference import ConvergenceWarning, keep_warnings
    >>> with keep_warnings() as kept:
    ...     warnings.warn(ConvergenceWarning("NOT CONVERGED: 50 steps"))
    >>> kept.convergence, kept.other
    (['NOT CONVERGED: 50 steps'], [])
    """
    kept = KeptWarnings()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        try:
            yield kept
        finally:
            for caught_warning in caught:
                pair = (caught_warning.category, str(caught_warning.message))
                if issubclass(pair[0], ConvergenceWarning):
                    kept.convergence.append(pair[1])
                elif pair not in kept.other:
                    kept.other.append(pair)
