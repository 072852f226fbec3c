"""The package's surface and coupling, counted from its source (issue 38).

Run by hand: ``python benchmarks/surface.py [--ref REF] [--json]``. It reads the
package's modules with :mod:`ast` (nothing is imported) and prints, for the
working tree and for ``REF`` (default: ``main``, read with ``git show``, so the
two are measured in the same run):

- ``public``: the names a user is offered, the top level's ``__all__`` and
  every public subpackage's (``cli``, ``data`` and ``_runtime`` aside);
- ``top_level``: the top level's ``__all__`` alone (``__version__`` too);
- ``constants``: public names written in capitals (``io.STEADY_SMOOTHING``);
- ``bypassing_imports``: imports of one subpackage's module from another
  subpackage that go past its ``__init__`` (``from ..io.bags import x``);
- ``over_8_parameters``: functions (methods too) with more than 8 parameters,
  ``self`` and ``cls`` not counted;
- ``longest_in_workflow``: the longest function of ``workflow``, in code
  lines (its signature and body; the docstring, blank lines and comments
  not counted);
- ``say_parameters``: parameters and dataclass fields named ``say``.

Issue 38's targets are printed beside them: ``public`` at most 120,
``top_level`` at most 40, ``bypassing_imports`` 0, ``longest_in_workflow`` at
most 60 and ``say_parameters`` 0.
"""

from __future__ import annotations

import argparse
import ast
import json
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Issue 38's target for each count (None: to be lowered, no bound given).
TARGETS = {
    "public": 120,
    "top_level": 40,
    "constants": None,
    "bypassing_imports": 0,
    "over_8_parameters": None,
    "longest_in_workflow": 60,
    "say_parameters": 0,
}
_PRIVATE_PACKAGES = {"cli", "data", "_runtime", "models"}


def _sources(ref: str | None) -> dict[str, str]:
    """Module path (relative to the package) -> source, of the tree or of ``ref``."""
    if ref is None:
        return {
            str(path.relative_to(ROOT / "bayes_jackal")): path.read_text()
            for path in sorted((ROOT / "bayes_jackal").rglob("*.py"))
        }
    names = subprocess.run(
        ["git", "-C", str(ROOT), "ls-tree", "-r", "--name-only", ref, "bayes_jackal"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    return {
        name.removeprefix("bayes_jackal/"): subprocess.run(
            ["git", "-C", str(ROOT), "show", f"{ref}:{name}"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        for name in names
        if name.endswith(".py")
    }


def _all(tree: ast.Module) -> list[str]:
    """The strings of a module's ``__all__``, and of a top level's ``_LAZY`` keys."""
    for node in tree.body:
        if not isinstance(node, ast.Assign | ast.AnnAssign):
            continue
        targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        names = {t.id for t in targets if isinstance(t, ast.Name)}
        if "_LAZY" in names and isinstance(node.value, ast.Dict):
            return [k.value for k in node.value.keys if isinstance(k, ast.Constant)]
        if "__all__" in names and isinstance(node.value, ast.List):
            return [e.value for e in node.value.elts if isinstance(e, ast.Constant)]
    return []


def _subpackage(module: str) -> str | None:
    """The subpackage a module (``io/bags.py``) belongs to; None at the top."""
    parts = Path(module).parts
    return parts[0] if len(parts) > 1 else None


def _bypasses(module: str, tree: ast.Module) -> int:
    """Imports in ``module`` of another subpackage's module, past its ``__init__``."""
    home = _subpackage(module)
    count = 0
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom) or (node.module is None and node.level == 0):
            continue
        if node.level == 0:
            if not (node.module or "").startswith("bayes_jackal."):
                continue
            target = node.module.split(".")[1:]
        else:
            depth = len(Path(module).parts) - node.level  # package parts left
            if depth < 0:
                continue
            target = [*Path(module).parts[:depth], *(node.module or "").split(".")]
            target = [t for t in target if t]
        if target and target[0] != home and len(target) >= 2:
            count += 1
    return count


def _functions(tree: ast.Module):
    return [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]


def _code_lines(function: ast.FunctionDef, source: list[str]) -> int:
    """The function's lines but its docstring's, blank lines and comments."""
    body = function.body
    skip = set()
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        skip = set(range(body[0].lineno, body[0].end_lineno + 1))
    lines = range(function.lineno, function.end_lineno + 1)
    return sum(
        1
        for n in lines
        if n not in skip and source[n - 1].strip() and not source[n - 1].strip().startswith("#")
    )


def _parameters(function: ast.FunctionDef) -> list[str]:
    arguments = function.args
    every = [*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs]
    every += [a for a in (arguments.vararg, arguments.kwarg) if a is not None]
    return [a.arg for a in every if a.arg not in ("self", "cls")]


def _say_fields(tree: ast.Module) -> int:
    """Annotated class attributes named ``say`` (dataclass fields)."""
    return sum(
        1
        for node in ast.walk(tree)
        if isinstance(node, ast.ClassDef)
        for item in node.body
        if isinstance(item, ast.AnnAssign)
        and isinstance(item.target, ast.Name)
        and item.target.id == "say"
    )


def counts(sources: dict[str, str]) -> dict[str, int]:
    """Each of the module text's counts, of one version of the package."""
    trees = {module: ast.parse(source) for module, source in sources.items()}
    top = [*_all(trees["__init__.py"]), "__version__"]
    subpackages = {
        _subpackage(m) for m in trees if _subpackage(m) and _subpackage(m) not in _PRIVATE_PACKAGES
    }
    public = set(top)
    for package in subpackages:
        public |= {
            f"{package}.{n}" for n in _all(trees.get(f"{package}/__init__.py", ast.Module()))
        }
    functions = [f for tree in trees.values() for f in _functions(tree)]
    workflow = [
        _code_lines(f, sources[m].splitlines())
        for m, t in trees.items()
        if _subpackage(m) == "workflow"
        for f in _functions(t)
    ]
    return {
        "public": len(public),
        "top_level": len(top),
        "constants": sum(1 for name in public if name.rsplit(".", 1)[-1].isupper()),
        "bypassing_imports": sum(_bypasses(m, t) for m, t in trees.items() if _subpackage(m)),
        "over_8_parameters": sum(1 for f in functions if len(_parameters(f)) > 8),
        "longest_in_workflow": max(workflow, default=0),
        "say_parameters": sum(_parameters(f).count("say") for f in functions)
        + sum(_say_fields(t) for t in trees.values()),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ref", default="main", help="the commit to compare with (git ref)")
    parser.add_argument("--json", action="store_true", help="print the counts as JSON")
    arguments = parser.parse_args(argv)
    before, after = counts(_sources(arguments.ref)), counts(_sources(None))
    if arguments.json:
        print(json.dumps({"ref": arguments.ref, "before": before, "after": after}, indent=2))
        return
    print(f"{'count':<22}{arguments.ref:>10}{'tree':>10}{'target':>10}")
    for name, target in TARGETS.items():
        bound = "-" if target is None else f"<= {target}"
        print(f"{name:<22}{before[name]:>10}{after[name]:>10}{bound:>10}")


if __name__ == "__main__":
    main()
