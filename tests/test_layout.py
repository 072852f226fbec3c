"""The package's shape: a short top level, and one home for each name.

The layers of the data path and the absence of import cycles are checked by
import-linter (``[tool.importlinter]`` in pyproject.toml; ``lint-imports``
in .ci/run). Here: the folder tree stays small enough to read, every public
name is defined by the module that lists it, and no two modules (nor two
subpackages) offer the same name.
"""

from __future__ import annotations

import ast
import importlib
from collections import Counter
from pathlib import Path

import bayes_jackal

PACKAGE = Path(bayes_jackal.__file__).parent
#: The subpackages with public names (the command line and the runtime aside).
PUBLIC = sorted(
    folder.name
    for folder in PACKAGE.iterdir()
    if (folder / "__init__.py").exists()
    and not folder.name.startswith("_")
    and folder.name not in ("cli", "data")
)


def _modules() -> list[Path]:
    """Every module of the package but the packages' ``__init__`` files."""
    return sorted(p for p in PACKAGE.rglob("*.py") if p.name != "__init__.py")


def _listed(tree: ast.Module) -> list[str]:
    """The names a module's ``__all__`` lists (none without one).

    Only a plain list of strings is read; any other form of ``__all__`` (an
    annotation, ``+=``, a computed list) fails here rather than pass unread.
    """
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        if not any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            continue
        if not isinstance(node, ast.Assign) or not isinstance(node.value, ast.List):
            raise TypeError(f"line {node.lineno}: __all__ is not a plain list")
        names = [element.value for element in node.value.elts if isinstance(element, ast.Constant)]
        if len(names) != len(node.value.elts):
            raise TypeError(f"line {node.lineno}: __all__ lists more than strings")
        return names
    return []


def _defined(tree: ast.Module) -> set[str]:
    """The names a module binds at its top level by def, class or assignment."""
    names = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                elements = target.elts if isinstance(target, ast.Tuple) else [target]
                names |= {e.id for e in elements if isinstance(e, ast.Name)}
    return names


def test_the_top_level_has_at_most_16_entries():
    entries = [p.name for p in PACKAGE.iterdir() if p.name != "__pycache__"]
    assert len(entries) <= 16, sorted(entries)


def test_every_listed_name_is_defined_where_it_is_listed():
    # No module re-exports: what a module's __all__ offers, it defines. (The
    # runtime's arviz_quiet offers arviz itself, imported once with its import
    # warning silenced.)
    offered_elsewhere = {}
    for path in _modules():
        tree = ast.parse(path.read_text())
        foreign = set(_listed(tree)) - _defined(tree)
        if path.name == "arviz_quiet.py":
            foreign -= {"az"}
        if foreign:
            offered_elsewhere[str(path.relative_to(PACKAGE))] = sorted(foreign)
    assert not offered_elsewhere


def test_no_name_is_offered_by_two_modules():
    counts = Counter(name for path in _modules() for name in _listed(ast.parse(path.read_text())))
    assert not [name for name, count in counts.items() if count > 1]


def test_each_public_name_has_one_subpackage():
    owners = Counter(
        name
        for package in PUBLIC
        for name in importlib.import_module(f"bayes_jackal.{package}").__all__
    )
    assert not [name for name, count in owners.items() if count > 1]


def test_a_subpackage_offers_exactly_its_modules_public_names():
    for package in PUBLIC:
        listed = {
            name
            for path in sorted((PACKAGE / package).glob("*.py"))
            if path.name != "__init__.py" and not path.name.startswith("_")
            for name in _listed(ast.parse(path.read_text()))
        }
        assert set(importlib.import_module(f"bayes_jackal.{package}").__all__) == listed, package


def test_each_top_level_name_is_a_subpackages_or_the_runtimes():
    # bj's names are those of the subpackages, and the errors and defaults
    # (bayes_jackal._runtime) a user catches or reads.
    offered = {
        name: package
        for package in [*PUBLIC, "_runtime.errors", "_runtime.defaults"]
        for name in importlib.import_module(f"bayes_jackal.{package}").__all__
    }
    missing = [name for name in bayes_jackal.__all__ if name not in {"__version__", *offered}]
    assert not missing
