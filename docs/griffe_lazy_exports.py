"""Griffe extension: the names a package imports lazily (PEP 562), for the API reference.

``bayes_jackal/__init__.py`` imports its public names on first use: a
dictionary ``_LAZY`` maps each name to the module that defines it, relative
to the package (``"sample": ".inference"``), ``__getattr__`` imports it,
and ``__all__`` is built from the dictionary at run time. Griffe reads the
source without running it, so it sees neither the names nor ``__all__``.
This extension reads ``_LAZY`` from the source of any module that has one,
adds each name as an alias of its definition and makes ``__all__`` the
names, so that ``::: bayes_jackal`` with ``filters: public`` lists them.
A module without ``_LAZY`` is left alone. mkdocs.yml loads it (the
mkdocstrings handler's ``extensions``); it is not part of the package.
"""

from __future__ import annotations

import ast
from typing import Any

import griffe


def lazy_names(source: str) -> dict[str, str]:
    """The ``_LAZY`` dictionary of a module's source: name -> relative module.

    Examples
    --------
    >>> lazy_names('_LAZY = {"sample": ".inference"}\\n__all__ = sorted(_LAZY)')
    {'sample': '.inference'}
    >>> lazy_names("x = 1")
    {}
    """
    for statement in ast.parse(source).body:
        if isinstance(statement, ast.Assign):
            targets, value = statement.targets, statement.value
        elif isinstance(statement, ast.AnnAssign) and statement.value is not None:
            targets, value = [statement.target], statement.value
        else:
            continue
        if any(isinstance(target, ast.Name) and target.id == "_LAZY" for target in targets):
            try:
                names = ast.literal_eval(value)
            except ValueError:
                return {}
            if isinstance(names, dict):
                return {str(name): str(module) for name, module in names.items()}
    return {}


class LazyExports(griffe.Extension):
    """Alias each name of a module's ``_LAZY`` to its definition, and export the names."""

    def on_module_members(self, *, mod: griffe.Module, **kwargs: Any) -> None:
        if mod.filepath is None or isinstance(mod.filepath, list):
            return
        names = lazy_names(mod.filepath.read_text(encoding="utf-8"))
        if not names:
            return
        for name, module in names.items():
            if name in mod.members:
                continue
            # ".inference" relative to the package "bayes_jackal".
            target = f"{mod.path}{module}" if module.startswith(".") else module
            mod.set_member(name, griffe.Alias(name, f"{target}.{name}", parent=mod))
        kept = [export for export in mod.exports or [] if isinstance(export, str)]
        mod.exports = sorted(set(kept) | set(names))
