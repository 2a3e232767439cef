"""`twoscale solve --out DIR` also writes fields.vtm (+ fields/), asperities.csv, pressure.png and forces.png."""

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
    # an iteration named: the two-scale solver itself (by default two tips on 5,841 cells are
    # their full grid's one CG, whose table has no macro forces)
    chosen = ["--iteration", "union-cg"] if method == "twoscale" else []
    args = ["solve", str(EXAMPLES / "paper_two_spheres.toml"), "--method", method, *chosen]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    names = {p.name for p in out.iterdir()} - {"asperities.parquet"}  # Parquet when pyarrow is installed
    assert sorted(names) == [
        ".twoscale-manifest.json",
        "asperities.csv",
        "asperities.csv-metadata.json",
        "fields",
        "fields.vtm",
        "forces.png",
        "pressure.png",
        "result.json",
    ]
    res = json.loads((out / "result.json").read_text())
    back = read_vtk(out / "fields.vtm")
    # the per-asperity forces integrated from the written fields are result.json's forces
    s = summarise(back.fields, 2)
    np.testing.assert_allclose(s.forces, [a["force"] for a in res["asperities"]], rtol=1e-12)
    assert back.metadata["version"] == __version__
    assert back.metadata["scene"] == res["scene"]
    # indenter height at each tip is the tip recess (0): the exact cap starts there
    for f, z in zip(back.fields, back.indenter_height):
        assert np.nanmin(np.where(np.isfinite(z), z, np.nan)) == pytest.approx(0.0, abs=f.grid.h**2 / 10)
    _check_asperity_csv(out / "asperities.csv", res, macro=(method == "twoscale"))
    for name in ("pressure.png", "forces.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_input_writes_none_of_them(tmp_path):
    out = tmp_path / "run"
    assert main(["solve", str(EXAMPLES / "paper_two_spheres.toml"), "--h", "0", "--out", str(out), "--quiet"]) == 2
    assert not out.exists()


def _check_asperity_csv(path, res, *, macro):
    import csv

    meta = json.loads(path.with_name(path.name + "-metadata.json").read_text())
    assert meta["twoscale"]["version"] == __version__ and meta["twoscale"]["source"].startswith("solve ")
    assert meta["twoscale"]["scene"] == res["scene"] and meta["twoscale"]["units"]["force"] == "N"
    with open(path, newline="", encoding="utf-8") as fh:  # the header on the first line
        rows = list(csv.DictReader(fh))
    assert [int(r["asperity"]) for r in rows] == list(range(1, len(res["asperities"]) + 1))
    assert ("macro_force_N" in rows[0]) == macro
    tips = res["scene"]["asperity"]
    for r, a, t in zip(rows, res["asperities"], tips):
        # written to 10 significant digits: within half a unit of the 10th digit of the double
        assert float(r["force_N"]) == pytest.approx(a["force"], rel=5e-10)
        assert float(r["contact_area_mm2"]) == pytest.approx(a["contact_area"], rel=5e-10)
        assert float(r["max_pressure_MPa"]) == pytest.approx(a["max_pressure"], rel=5e-10)
        assert float(r["mean_pressure_MPa"]) == pytest.approx(a["force"] / a["contact_area"], rel=1e-9)
        assert (float(r["x_mm"]), float(r["y_mm"]), float(r["R_mm"])) == (t["x"], t["y"], t["R"])
    # the tip forces add up to the total load
    assert sum(float(r["force_N"]) for r in rows) == pytest.approx(res["total_load"], rel=1e-9)
