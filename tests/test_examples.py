"""Every script in examples/ runs (quick settings) and prints what it promises."""

import ast
import contextlib
import io
import runpy
import subprocess
import sys
import traceback
import warnings
from pathlib import Path

import pytest

import bayes_jackal as bj

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run_example(script: Path, out: Path) -> subprocess.CompletedProcess:
    """Run an example with its quick settings, writing into ``out``, as ``python script`` would.

    In this process, as ``__main__`` with its own ``sys.argv``: a fresh
    interpreter's imports took longer than the quick examples' work. The
    script gets a namespace of its own, so it still imports what it uses.
    Its warnings are not this suite's errors (they would only be printed).
    """
    argv = [str(script), "--quick", "--out", str(out)]
    stdout, stderr = io.StringIO(), io.StringIO()
    code = 0
    with (
        contextlib.redirect_stdout(stdout),
        contextlib.redirect_stderr(stderr),
        warnings.catch_warnings(record=True),
    ):
        warnings.resetwarnings()
        saved, sys.argv = sys.argv, argv
        try:
            runpy.run_path(str(script), run_name="__main__")
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else int(stop.code is not None)
        except Exception:
            traceback.print_exc()
            code = 1
        finally:
            sys.argv = saved
    return subprocess.CompletedProcess(argv, code, stdout.getvalue(), stderr.getvalue())


@pytest.fixture(scope="module")
def example_run(tmp_path_factory):
    """``example_run(script) -> (result, out)``: each example run once per module."""
    done = {}

    def run(script: Path) -> tuple[subprocess.CompletedProcess, Path]:
        if script not in done:
            out = tmp_path_factory.mktemp(script.stem)
            done[script] = (run_example(script, out), out)
        return done[script]

    return run


@pytest.mark.parametrize("script", sorted(EXAMPLES.glob("*.py")), ids=lambda p: p.name)
def test_example_runs(script, example_run):
    result, out = example_run(script)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert any(out.iterdir()), "the example wrote nothing"


def test_thesis_example_prints_table_6_1(example_run):
    result, _ = example_run(EXAMPLES / "thesis_chapters_5_6.py")
    assert "table 6-1 zoh  : 0.0000 0.0144 0.0274 0.0392" in result.stdout


def test_workflow_example_uses_top_level_names_only():
    # The promise: the whole workflow with `import bayes_jackal as bj` alone.
    tree = ast.parse((EXAMPLES / "bayesian_workflow.py").read_text())
    imported = [
        (node.module if isinstance(node, ast.ImportFrom) else alias.name, alias.asname)
        for node in ast.walk(tree)
        if isinstance(node, ast.Import | ast.ImportFrom)
        for alias in node.names
    ]
    assert [i for i in imported if "bayes_jackal" in (i[0] or "")] == [("bayes_jackal", "bj")]
    used = {
        node.attr
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute) and getattr(node.value, "id", None) == "bj"
    }
    assert {"load_experiments", "sample", "export_prior", "write_report", "compare"} <= used
    assert used <= set(bj.__all__), used - set(bj.__all__)
