"""The code's shape stays readable: no module over 400 lines, no function over 60 lines
without a docstring saying what it does (in both packages), no public function of twoscale
with more than 8 parameters, and test modules that share helpers through
``tests/helpers.py`` or ``conftest.py``, never by importing one another."""

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


MAX_PUBLIC_PARAMETERS = 8
#: Functions still over the limit while their own rework is under way; an entry that is
#: within the limit fails the test, so that it is removed.
OVER_FOR_NOW: set = set()


def test_no_public_function_takes_more_than_8_parameters():
    # a longer list means an options object or a smaller function is missing; self and cls
    # are not counted, *args and **keywords count one each
    found, seen = [], set()
    for p in sorted(PACKAGE.rglob("*.py")):
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


def test_test_modules_do_not_import_one_another():
    found = []
    for p in sorted((ROOT / "tests").glob("test_*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            names = (
                [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else ([a.name for a in node.names] if isinstance(node, ast.Import) else [])
            )
            found += [
                f"{p.name}:{node.lineno} {n}"
                for n in names
                if n.split(".")[-1].startswith("test_") or n.startswith("tests.test_")
            ]
    assert not found, f"test modules importing other test modules (use tests/helpers.py): {found}"


#: Names each module defines for itself in the same role, with its own value: the units,
#: column descriptions, titles and case columns of the file a module writes, the top-level
#: keys of the file format it reads, its limits, and its fields file's name.
SAME_ROLE_NAMES = {
    "UNITS",
    "DESCRIPTIONS",
    "TITLES",
    "CASE_COLUMNS",
    "TOP_KEYS",
    "MAX_ROWS",
    "MAX_CASES",
    "FIELDS_NAME",
}


def test_no_constant_name_means_different_things():
    # a module-level constant defined in several modules holds the same value in each,
    # unless its name is one of the same-role names above
    values: dict = {}
    for p in sorted(PACKAGE.rglob("*.py")):
        for node in ast.parse(p.read_text()).body:
            targets = (
                node.targets
                if isinstance(node, ast.Assign)
                else [node.target]
                if isinstance(node, ast.AnnAssign)
                else []
            )
            for target in targets:
                if (
                    isinstance(target, ast.Name)
                    and target.id.isupper()
                    and len(target.id) > 1
                    and node.value is not None
                ):
                    values.setdefault(target.id, {})[str(p.relative_to(ROOT))] = ast.dump(node.value)
    clashes = {
        name: sorted(where)
        for name, where in values.items()
        if name not in SAME_ROLE_NAMES and len(set(where.values())) > 1
    }
    assert not clashes, f"constant names holding different things in different modules: {clashes}"
