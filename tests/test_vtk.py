"""VTK output: write -> read round trip, metadata, indenter height, atomic writing."""
import json
import math

import numpy as np
import pytest

pytest.importorskip("meshio")

from twoscale import __version__
from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.io.vtk import read_vtk, write_vtk
from twoscale.results import ContactResult, PressureField, summarise


def _two_patch_result(tilt=(0.01, -0.02)):
    rng = np.random.default_rng(7)
    g1 = Grid(0.05, 0.05, 0.1, 4, 3)
    g2 = Grid(1.05, -0.15, 0.1, 3, 5)
    gap1 = rng.random(g1.shape)
    gap1[0, 0] = np.inf                    # no indenter material there
    f1 = PressureField(g1, rng.random(g1.shape), np.zeros(g1.shape), gap1)
    f2 = PressureField(g2, rng.random(g2.shape) * 1e-7, np.ones(g2.shape), rng.random(g2.shape))
    fields = (f1, f2)
    s = summarise(fields, 2)
    return ContactResult("twoscale", fields, 0.1, tilt, float(s.forces.sum()), s, True)


@pytest.mark.parametrize("binary", [True, False])
def test_round_trip_patches(tmp_path, binary):
    res = _two_patch_result()
    path = write_vtk(res, tmp_path / "out" / "fields.vtu", scene={"name": "two patches"}, binary=binary)
    back = read_vtk(path)
    # binary arrays are the float64 bytes themselves (base64 + zlib, lossless): exact.
    # ASCII is written by meshio with "{:.11e}", 12 significant digits, so the relative
    # error is at most half a unit in the 12th digit, 5e-12.
    rtol = 0.0 if binary else 5e-12
    assert len(back.fields) == 2
    for a, b in zip(back.fields, res.fields):
        assert a.grid == b.grid
        np.testing.assert_allclose(a.pressure, b.pressure, rtol=rtol, atol=0)
        np.testing.assert_array_equal(a.owner, b.owner)
        np.testing.assert_array_equal(np.isinf(a.gap), np.isinf(b.gap))
        fin = np.isfinite(b.gap)
        np.testing.assert_allclose(a.gap[fin], b.gap[fin], rtol=rtol, atol=0)
    assert back.indenter_height is None
    m = back.metadata
    assert m["version"] == __version__
    assert m["units"] == {"length": "mm", "force": "N", "pressure": "MPa", "angle": "rad"}
    assert m["scene"] == {"name": "two patches"}
    assert m["result"]["tilt"] == [0.01, -0.02]


def test_metadata_readable_in_text_and_no_temp_left(tmp_path):
    res = _two_patch_result()
    path = write_vtk(res, tmp_path / "f.vtu", scene={"note": "a--b"})
    text = path.read_text()
    head = text.splitlines()[1]
    assert head.startswith("<!-- twoscale ") and head.endswith("-->")
    # the comment holds the same JSON; "--" inside it was escaped and reads back equal
    meta = json.loads(head[head.index("{"):-3])
    assert meta["scene"] == {"note": "a--b"} and meta["version"] == __version__
    assert "--" not in head[4:-3]
    assert [p.name for p in tmp_path.iterdir()] == ["f.vtu"]


def test_indenter_height_with_tilt(tmp_path):
    alpha, beta, pivot = 0.01, -0.02, (0.3, -0.1)
    res = _two_patch_result(tilt=(alpha, beta))
    asp = [Asperity(0.2, 0.1, 0.0, 5.0), Asperity(1.2, 0.1, 0.01, 3.0, shape="paraboloid")]
    back = read_vtk(write_vtk(res, tmp_path / "h.vtu", asperities=asp, pivot=pivot))
    for f, z in zip(back.fields, back.indenter_height):
        X, Y = f.grid.centres()
        # independent evaluation: lower envelope of the exact cap and the paraboloid, + tilt
        r1 = (X - 0.2) ** 2 + (Y - 0.1) ** 2
        z1 = 5.0 - np.sqrt(5.0 ** 2 - r1)
        z2 = 0.01 + ((X - 1.2) ** 2 + (Y - 0.1) ** 2) / 6.0
        expected = np.minimum(z1, z2) + beta * (X - pivot[0]) + alpha * (Y - pivot[1])
        np.testing.assert_allclose(z, expected, rtol=1e-12, atol=1e-15)


def test_union_layout(tmp_path):
    res = _two_patch_result()
    back = read_vtk(write_vtk(res, tmp_path / "u.vtu", layout="union"))
    (f,) = back.fields
    xmin, xmax, ymin, ymax = f.grid.bounds
    assert (xmin, ymin) == pytest.approx((0.0, -0.2)) and (xmax, ymax) == pytest.approx((1.3, 0.3))
    np.testing.assert_array_equal(f.pressure, res.pressure_on(f.grid))
    assert f.pressure.sum() * f.grid.h ** 2 == pytest.approx(res.total_load, rel=1e-12)
    # cells covered by no patch have no owner and an infinite gap
    assert f.owner[0, 5] == -1 and math.isinf(f.gap[0, 5])
    assert back.metadata["layout"] == "union"


def test_bad_arguments_write_nothing(tmp_path):
    res = _two_patch_result()
    with pytest.raises(ValueError, match=".vtu"):
        write_vtk(res, tmp_path / "f.vts")
    with pytest.raises(ValueError, match="layout"):
        write_vtk(res, tmp_path / "f.vtu", layout="mosaic")
    assert list(tmp_path.iterdir()) == []


def test_reader_rejects_foreign_vtu(tmp_path):
    import meshio
    m = meshio.Mesh(np.zeros((3, 3)), [("triangle", np.array([[0, 1, 2]]))])
    m.write(tmp_path / "other.vtu")
    with pytest.raises(ValueError, match="not written by twoscale"):
        read_vtk(tmp_path / "other.vtu")


def test_vtk_itself_reads_the_file(tmp_path):
    # an independent reader (VTK through pyvista, what ParaView uses) sees the same arrays
    pv = pytest.importorskip("pyvista")
    res = _two_patch_result()
    path = write_vtk(res, tmp_path / "f.vtu", scene={"k": 1})
    m = pv.read(str(path))
    assert m.n_cells == sum(f.grid.size for f in res.fields)
    p = np.concatenate([f.pressure.ravel() for f in res.fields])
    np.testing.assert_array_equal(np.asarray(m.cell_data["pressure_MPa"]), p)
    meta = json.loads(bytes(np.asarray(m.field_data["twoscale_metadata"], dtype=np.uint8)))
    assert meta["version"] == __version__ and meta["scene"] == {"k": 1}
    # cell centres of the quads are the grid's cell centres
    c = np.asarray(m.cell_centers().points)[:, :2]
    np.testing.assert_allclose(c, np.vstack([f.grid.points() for f in res.fields]), atol=1e-12)


def test_written_file_has_ordinary_permissions(tmp_path):
    # the temporary file is created owner-only; the result must follow the umask
    import os
    mask = os.umask(0o022)
    try:
        path = write_vtk(_two_patch_result(), tmp_path / "f.vtu")
    finally:
        os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o644
