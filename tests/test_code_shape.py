"""The package's shape stays readable: no module over 400 lines, no function over 60 lines
without a docstring saying what it does, no public function with more than 8 parameters."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "twoscale"
MAX_MODULE_LINES = 400
MAX_UNDOCUMENTED_FUNCTION_LINES = 60


def _modules():
    return sorted(PACKAGE.rglob("*.py"))


def test_no_module_is_over_400_lines():
    long = {str(p.relative_to(PACKAGE.parent)): p.read_text().count("\n") for p in _modules()}
    over = {k: v for k, v in long.items() if v > MAX_MODULE_LINES}
    assert not over, f"modules over {MAX_MODULE_LINES} lines (split them by concept): {over}"


def test_no_long_function_goes_without_a_docstring():
    found = []
    for p in _modules():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_UNDOCUMENTED_FUNCTION_LINES and not ast.get_docstring(node):
                    found.append(f"{p.relative_to(PACKAGE.parent)}:{node.lineno} {node.name} ({lines} lines)")
    assert not found, f"functions over {MAX_UNDOCUMENTED_FUNCTION_LINES} lines without a docstring: {found}"


MAX_PUBLIC_PARAMETERS = 8
#: Functions still over the limit while their own rework is under way; an entry that is
#: within the limit fails the test, so that it is removed.
OVER_FOR_NOW = {"twoscale/viscoelastic/moving.py solve_moving"}


def test_no_public_function_takes_more_than_8_parameters():
    # a longer list means an options object or a smaller function is missing; self and cls
    # are not counted, *args and **keywords count one each
    found, seen = [], set()
    for p in _modules():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_"):
                a = node.args
                names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
                if names and names[0] in ("self", "cls"):
                    names = names[1:]
                count = len(names) + (a.vararg is not None) + (a.kwarg is not None)
                key = f"{p.relative_to(PACKAGE.parent)} {node.name}"
                if count > MAX_PUBLIC_PARAMETERS:
                    if key in OVER_FOR_NOW:
                        seen.add(key)
                    else:
                        found.append(f"{p.relative_to(PACKAGE.parent)}:{node.lineno} {node.name} ({count})")
    assert not found, f"public functions with more than {MAX_PUBLIC_PARAMETERS} parameters: {found}"
    assert seen == OVER_FOR_NOW, f"within the limit now, remove from OVER_FOR_NOW: {sorted(OVER_FOR_NOW - seen)}"
