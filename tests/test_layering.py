"""Import direction: ``fem_influence`` builds on ``twoscale``, never the reverse.

``twoscale`` reaches the finite block only through its body registry
(:mod:`twoscale.influence.registry`, by module name on first use) or a provider passed in.
Checked two ways: no import statement in ``twoscale`` names ``fem_influence``, and every
``twoscale`` module imports with ``fem_influence`` made unimportable; also no module
outside the command line imports from ``twoscale.cli``, and no module imports a private
name (``_x``) of another package folder.
"""

import ast
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "twoscale"
REGISTRY = PACKAGE / "influence" / "registry.py"


def _imports(path: pathlib.Path):
    """(module imported, names, level) of every import statement of ``path``."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, (), 0
        elif isinstance(node, ast.ImportFrom):
            yield node.module or "", tuple(a.name for a in node.names), node.level


def _modules():
    return sorted(PACKAGE.rglob("*.py"))


def test_no_twoscale_module_imports_fem_influence():
    offenders = [
        str(p.relative_to(ROOT))
        for p in _modules()
        for module, _, _ in _imports(p)
        if module.split(".")[0] == "fem_influence"
    ]
    assert offenders == []
    # the registry is the one place that names the package, as data
    named = [
        str(p.relative_to(ROOT))
        for p in _modules()
        if any(
            isinstance(n, ast.Constant) and n.value == "fem_influence"
            for n in ast.walk(ast.parse(p.read_text(encoding="utf-8")))
        )
    ]
    assert named == [str(REGISTRY.relative_to(ROOT))]


def test_library_modules_do_not_import_the_command_line():
    offenders = []
    for p in _modules():
        if p.parent.name == "cli" or p.name == "__main__.py":
            continue
        for module, _, level in _imports(p):
            if module.startswith("twoscale.cli") or (level > 0 and module.split(".")[0] == "cli"):
                offenders.append(str(p.relative_to(ROOT)))
    assert offenders == []


def test_commands_import_no_private_names_of_each_other():
    offenders = [
        (str(p.relative_to(ROOT)), names)
        for p in (PACKAGE / "cli").glob("*.py")
        for module, names, _ in _imports(p)
        if any(n.startswith("_") and n != "__version__" for n in names)
    ]
    assert offenders == []


_BLOCKED = """
import importlib, pkgutil, sys
sys.modules["fem_influence"] = None          # any import of it now fails
import twoscale
names = [m.name for m in pkgutil.walk_packages(twoscale.__path__, "twoscale.") if m.name != "twoscale.__main__"]
for name in names:
    importlib.import_module(name)
try:
    twoscale.FiniteBlock
except ImportError as exc:
    assert "fem_influence" in str(exc), exc
else:
    raise SystemExit("FiniteBlock imported although fem_influence is blocked")
print(len(names))
"""

_LIGHT = """
import sys
import twoscale
assert "scipy" not in sys.modules and "skfem" not in sys.modules, "import twoscale is not light"
res = twoscale.solve([[0.0, 0.0, 5.0], [4.0, 0.0, 5.0]], material=twoscale.Material(10.0, 0.5), total_load=2.0)
assert res.converged
assert "fem_influence" not in sys.modules, "a half-space solve imported fem_influence"
block = twoscale.FiniteBlock
assert block.__module__.startswith("fem_influence"), block
"""


def _run(code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=str(ROOT), env=env
    )


def test_every_twoscale_module_imports_without_fem_influence():
    proc = _run(_BLOCKED)
    assert proc.returncode == 0, proc.stderr
    assert int(proc.stdout.split()[-1]) > 50  # the walk reached the whole package


def test_import_twoscale_is_light_and_the_block_comes_on_first_use():
    proc = _run(_LIGHT)
    assert proc.returncode == 0, proc.stderr
