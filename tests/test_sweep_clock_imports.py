"""The sweep's clock and ``ab_trees``'s: the block body's modules are imported before it,
so a block scene's first solve does not time their import (0.07-0.08 s of CPU a solve,
both solvers alike). A fresh interpreter imports the listed modules, then makes the
finite block as a scene does: nothing of the block's packages is left to import."""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CHILD = textwrap.dedent(
    """
    import importlib, sys
    sys.path[:0] = [{root!r}, {bench!r}]
    from {module} import BODY_MODULES
    for name in BODY_MODULES:
        importlib.import_module(name)
    before = set(sys.modules)
    from twoscale.influence.registry import make_body
    from twoscale.material import Material
    make_body("block", Material(E=2.0, nu=0.5), size=(60.0, 60.0, 10.0), h_fine=5.0, h_coarse=10.0,
              fine_half_width=10.0, use_cache=False, progress=False)
    new = sorted(m for m in set(sys.modules) - before if m.split(".")[0] in ("fem_influence", "meshes", "skfem"))
    print(",".join(new))
    """
)


@pytest.mark.parametrize("module", ["benchmarks.sweep", "ab_trees"])
def test_the_block_modules_are_imported_before_the_clock(module):
    pytest.importorskip("skfem")
    code = CHILD.format(root=str(ROOT), bench=str(ROOT / "benchmarks"), module=module)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip().splitlines()[-1:] in ([""], []), out.stdout
