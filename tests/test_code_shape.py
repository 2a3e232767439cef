"""The code's shape stays readable: no module over 400 lines, no function over 60 lines
without a docstring saying what it does (in both packages), and test modules that share
helpers through ``tests/helpers.py`` or ``conftest.py``, never by importing one another."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "twoscale"
PACKAGES = (PACKAGE, ROOT / "fem_influence")
MAX_MODULE_LINES = 400
MAX_UNDOCUMENTED_FUNCTION_LINES = 60


def _modules():
    return sorted(p for package in PACKAGES for p in package.rglob("*.py"))


def test_no_module_is_over_400_lines():
    long = {str(p.relative_to(ROOT)): p.read_text().count("\n") for p in _modules()}
    over = {k: v for k, v in long.items() if v > MAX_MODULE_LINES}
    assert not over, f"modules over {MAX_MODULE_LINES} lines (split them by concept): {over}"


def test_no_long_function_goes_without_a_docstring():
    found = []
    for p in _modules():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_UNDOCUMENTED_FUNCTION_LINES and not ast.get_docstring(node):
                    found.append(f"{p.relative_to(ROOT)}:{node.lineno} {node.name} ({lines} lines)")
    assert not found, f"functions over {MAX_UNDOCUMENTED_FUNCTION_LINES} lines without a docstring: {found}"


def test_test_modules_do_not_import_one_another():
    found = []
    for p in sorted((ROOT / "tests").glob("test_*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            names = [node.module or ""] if isinstance(node, ast.ImportFrom) else (
                [a.name for a in node.names] if isinstance(node, ast.Import) else [])
            found += [f"{p.name}:{node.lineno} {n}" for n in names
                      if n.split(".")[-1].startswith("test_") or n.startswith("tests.test_")]
    assert not found, f"test modules importing other test modules (use tests/helpers.py): {found}"
