"""Names a package offers from its modules, imported on first use (PEP 562).

The top level and the runtime load their modules lazily, so that importing
either, e.g. for ``bayes-jackal --version`` or the CLI's signal handlers,
loads no numpy, scipy or arviz.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Collection, Mapping

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, homes: Mapping[str, str], subpackages: Collection[str] = ()
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` offering ``homes``.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    homes : mapping of str to str
        Each name -> the (relative) module that defines it.
    subpackages : collection of str, optional
        Subpackages reached as attributes (``bj.filters``), imported on first use.

    Returns
    -------
    tuple of callables
        ``__getattr__``, which imports a name's module on its first use and
        keeps the name in the package's namespace, and ``__dir__``.

    Examples
    --------
    >>> getattr_, dir_ = lazy_exports("bayes_jackal._runtime", {"as_rng": ".rng"})
    >>> getattr_("as_rng").__name__, "as_rng" in dir_()
    ('as_rng', True)
    """
    namespace = importlib.import_module(package).__dict__

    def __getattr__(name: str) -> object:
        if name in subpackages:
            return importlib.import_module(f".{name}", package)  # binds itself
        if name not in homes:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(homes[name], package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(homes) | set(subpackages))

    return __getattr__, __dir__
