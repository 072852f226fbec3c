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


def _offered(folder: Path) -> set[str]:
    """The names a package's public modules offer beyond it (their ``__all__``).

    A private module (``_lockstep``) serves its own package only.
    """
    return {
        name
        for path in sorted(folder.glob("*.py"))
        if not path.name.startswith("_")
        for name in _listed(ast.parse(path.read_text()))
    }


def test_a_subpackage_imports_what_its_modules_offer_and_lists_what_users_need():
    # The later stages import a subpackage's names from its __init__ (never
    # from its modules: import-linter's "entered through its __init__"
    # contracts), so it imports every name its modules offer; its __all__ is
    # the part a user of the stage needs, documented in the API reference.
    for package in PUBLIC:
        module = importlib.import_module(f"bayes_jackal.{package}")
        imported = {
            alias.asname or alias.name
            for node in ast.parse((PACKAGE / package / "__init__.py").read_text()).body
            if isinstance(node, ast.ImportFrom)
            for alias in node.names
        }
        assert imported == _offered(PACKAGE / package), package
        assert set(module.__all__) <= imported, package


def test_the_runtime_offers_what_its_modules_offer():
    from bayes_jackal import _runtime

    assert set(_runtime.__all__) == _offered(PACKAGE / "_runtime") - {"lazy_exports"}


def test_the_public_surface_stays_small():
    # Issue 38: at most 40 names at the top level and 120 in all (the top
    # level's and every stage's __all__), a surface a user can learn;
    # benchmarks/surface.py counts them with the rest of the package's shape.
    stages = [importlib.import_module(f"bayes_jackal.{package}").__all__ for package in PUBLIC]
    assert len(bayes_jackal.__all__) <= 40
    assert len(bayes_jackal.__all__) + sum(len(names) for names in stages) <= 120


def test_the_top_level_reaches_every_stage():
    assert sorted(bayes_jackal._STAGES) == PUBLIC
    assert all(getattr(bayes_jackal, package).__all__ for package in PUBLIC)


def test_each_top_level_name_is_a_subpackages_or_the_runtimes():
    # bj's names are those of the subpackages' __all__, and the errors and
    # defaults (bayes_jackal._runtime) a user catches or reads.
    offered = {
        name: package
        for package in [*PUBLIC, "_runtime"]
        for name in importlib.import_module(f"bayes_jackal.{package}").__all__
    }
    missing = [name for name in bayes_jackal.__all__ if name not in {"__version__", *offered}]
    assert not missing
