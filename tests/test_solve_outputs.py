"""`twoscale solve --out DIR` also writes fields.vtm, pressure.png and forces.png."""
import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("meshio")
pytest.importorskip("matplotlib")

from twoscale import __version__
from twoscale.cli.main import main
from twoscale.io.vtk import read_vtk
from twoscale.results import summarise

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.mark.parametrize("method", ["reference", "twoscale"])
def test_solve_writes_fields_and_figures(tmp_path, method):
    out = tmp_path / "run"
    assert main(["solve", str(EXAMPLES / "paper_two_spheres.toml"), "--method", method,
                 "--out", str(out), "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["fields", "fields.vtm", "forces.png", "pressure.png", "result.json"]
    res = json.loads((out / "result.json").read_text())
    back = read_vtk(out / "fields.vtm")
    # the per-asperity forces integrated from the written fields are result.json's forces
    s = summarise(back.fields, 2)
    np.testing.assert_allclose(s.forces, [a["force"] for a in res["asperities"]], rtol=1e-12)
    assert back.metadata["version"] == __version__
    assert back.metadata["scene"] == res["scene"]
    # indenter height at each tip is the tip recess (0): the exact cap starts there
    for f, z in zip(back.fields, back.indenter_height):
        assert np.nanmin(np.where(np.isfinite(z), z, np.nan)) == pytest.approx(0.0, abs=f.grid.h ** 2 / 10)
    for name in ("pressure.png", "forces.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_input_writes_none_of_them(tmp_path):
    out = tmp_path / "run"
    assert main(["solve", str(EXAMPLES / "paper_two_spheres.toml"), "--h", "0", "--out", str(out), "--quiet"]) == 2
    assert not out.exists()
