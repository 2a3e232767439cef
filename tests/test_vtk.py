"""VTK image data output: write -> read round trip, metadata, owner numbering, indenter height,
atomic writing, and VTK itself (through pyvista) reading the files."""

import json
import math

import numpy as np
import pytest

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
    gap1[0, 0] = np.inf  # no indenter material there
    f1 = PressureField(g1, rng.random(g1.shape), np.zeros(g1.shape), gap1)
    f2 = PressureField(g2, rng.random(g2.shape) * 1e-7, np.ones(g2.shape), rng.random(g2.shape))
    fields = (f1, f2)
    s = summarise(fields, 2)
    return ContactResult("twoscale", fields, 0.1, tilt, float(s.forces.sum()), s, True)


@pytest.mark.parametrize("binary", [True, False])
def test_round_trip_patches(tmp_path, binary):
    res = _two_patch_result()
    path = write_vtk(res, tmp_path / "out" / "fields.vtm", scene={"name": "two patches"}, binary=binary)
    back = read_vtk(path)
    # binary arrays are the float64 bytes themselves; ASCII writes each float by repr,
    # which reads back as the same double: both exact.
    rtol = 0.0
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
    path = write_vtk(res, tmp_path / "f.vtm", scene={"note": "a--b"})
    text = path.read_text()
    head = text.splitlines()[1]
    assert head.startswith("<!-- twoscale ") and head.endswith("-->")
    # the comment holds the same JSON; "--" inside it was escaped and reads back equal
    meta = json.loads(head[head.index("{") : -3])
    assert meta["scene"] == {"note": "a--b"} and meta["version"] == __version__
    assert "--" not in head[4:-3]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f", "f.vtm"]
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == ["patch_001.vti", "patch_002.vti"]


def test_indenter_height_with_tilt(tmp_path):
    alpha, beta, pivot = 0.01, -0.02, (0.3, -0.1)
    res = _two_patch_result(tilt=(alpha, beta))
    asp = [Asperity(0.2, 0.1, 0.0, 5.0), Asperity(1.2, 0.1, 0.01, 3.0, shape="paraboloid")]
    back = read_vtk(write_vtk(res, tmp_path / "h.vtm", asperities=asp, pivot=pivot))
    for f, z in zip(back.fields, back.indenter_height):
        X, Y = f.grid.centres()
        # independent evaluation: lower envelope of the exact cap and the paraboloid, + tilt
        r1 = (X - 0.2) ** 2 + (Y - 0.1) ** 2
        z1 = 5.0 - np.sqrt(5.0**2 - r1)
        z2 = 0.01 + ((X - 1.2) ** 2 + (Y - 0.1) ** 2) / 6.0
        expected = np.minimum(z1, z2) + beta * (X - pivot[0]) + alpha * (Y - pivot[1])
        np.testing.assert_allclose(z, expected, rtol=1e-12, atol=1e-15)


def test_union_layout(tmp_path):
    res = _two_patch_result()
    back = read_vtk(write_vtk(res, tmp_path / "u.vtm", layout="union"))
    (f,) = back.fields
    xmin, xmax, ymin, ymax = f.grid.bounds
    assert (xmin, ymin) == pytest.approx((0.0, -0.2)) and (xmax, ymax) == pytest.approx((1.3, 0.3))
    np.testing.assert_array_equal(f.pressure, res.pressure_on(f.grid))
    assert f.pressure.sum() * f.grid.h**2 == pytest.approx(res.total_load, rel=1e-12)
    # cells covered by no patch have no owner and an infinite gap
    assert f.owner[0, 5] == -1 and math.isinf(f.gap[0, 5])
    assert back.metadata["layout"] == "union"


def test_bad_arguments_write_nothing(tmp_path):
    res = _two_patch_result()
    with pytest.raises(ValueError, match=".vtm"):
        write_vtk(res, tmp_path / "f.vtu")
    with pytest.raises(ValueError, match="layout"):
        write_vtk(res, tmp_path / "f.vtm", layout="mosaic")
    assert list(tmp_path.iterdir()) == []


def test_reader_rejects_foreign_file(tmp_path):
    from twoscale.io.vti import write_multiblock

    write_multiblock(tmp_path / "other.vtm", [])
    with pytest.raises(ValueError, match="not written by twoscale"):
        read_vtk(tmp_path / "other.vtm")


def test_owner_numbered_from_one_in_the_file(tmp_path):
    # in memory owner is 0-based with -1 for "none"; a person reading the file sees the
    # asperity numbers of the tables (from 1) and 0 for "none"
    from twoscale.io.vti import read_image

    res = _two_patch_result()
    owner0 = np.array(res.fields[0].owner)
    owner0[0, 1] = -1
    f1 = PressureField(res.fields[0].grid, res.fields[0].pressure, owner0, res.fields[0].gap)
    res = ContactResult("twoscale", (f1, res.fields[1]), 0.1, None, res.total_load, res.asperities, True)
    path = write_vtk(res, tmp_path / "f.vtm")
    img1, img2 = read_image(tmp_path / "f" / "patch_001.vti"), read_image(tmp_path / "f" / "patch_002.vti")
    assert img1.cell_data["owner"][0, 1] == 0 and img1.cell_data["owner"][0, 0] == 1
    assert np.all(img2.cell_data["owner"] == 2)
    assert np.all(img1.cell_data["patch"] == 1) and np.all(img2.cell_data["patch"] == 2)
    back = read_vtk(path)
    np.testing.assert_array_equal(back.fields[0].owner, owner0)


def test_vtk_itself_reads_the_file(tmp_path):
    # an independent reader (VTK through pyvista, what ParaView uses) sees the same arrays
    pv = pytest.importorskip("pyvista")
    res = _two_patch_result()
    asp = [Asperity(0.2, 0.1, 0.0, 5.0), Asperity(1.2, 0.1, 0.01, 3.0)]
    path = write_vtk(res, tmp_path / "f.vtm", scene={"k": 1}, asperities=asp)
    mb = pv.read(str(path))
    assert mb.n_blocks == 2
    back = read_vtk(path)
    for k, (block, f) in enumerate(zip(mb, res.fields)):
        assert block.n_cells == f.grid.size
        np.testing.assert_array_equal(np.asarray(block.cell_data["pressure_MPa"]), f.pressure.ravel())
        np.testing.assert_array_equal(np.asarray(block.cell_data["owner"]), f.owner.ravel() + 1)
        np.testing.assert_array_equal(
            np.asarray(block.cell_data["gap_mm"]), np.where(np.isinf(f.gap), np.nan, f.gap).ravel()
        )
        np.testing.assert_array_equal(
            np.asarray(block.cell_data["indenter_height_mm"]),
            np.where(np.isinf(back.indenter_height[k]), np.nan, back.indenter_height[k]).ravel(),
        )
        meta = json.loads(bytes(np.asarray(block.field_data["twoscale_metadata"], dtype=np.uint8)))
        assert meta["version"] == __version__ and meta["patch"] == k + 1
        # cell centres of the image are the grid's cell centres, in the plane z = 0
        c = np.asarray(block.cell_centers().points)
        np.testing.assert_allclose(c[:, :2], f.grid.points(), atol=1e-12)
        np.testing.assert_array_equal(c[:, 2], 0.0)


def test_rewrite_replaces_the_images(tmp_path):
    res = _two_patch_result()
    write_vtk(res, tmp_path / "f.vtm", layout="patches")
    back = read_vtk(write_vtk(res, tmp_path / "f.vtm", layout="union"))
    assert len(back.fields) == 1
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == ["patch_001.vti"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f", "f.vtm"]
    (tmp_path / "f" / "mine.txt").write_text("x")  # not ours: refused, not deleted
    with pytest.raises(ValueError, match="other files"):
        write_vtk(res, tmp_path / "f.vtm")
    assert (tmp_path / "f" / "mine.txt").exists()


def test_written_file_has_ordinary_permissions(tmp_path):
    # the temporary file is created owner-only; the result must follow the umask
    import os

    mask = os.umask(0o022)
    try:
        path = write_vtk(_two_patch_result(), tmp_path / "f.vtm")
    finally:
        os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "f").stat().st_mode & 0o777 == 0o755
    assert (tmp_path / "f" / "patch_001.vti").stat().st_mode & 0o777 == 0o644


def test_indenter_height_of_many_mixed_tips_is_the_rigid_surface(tmp_path):
    # thousands of tips are evaluated only where they can be lowest: the result must be
    # the full lower envelope that surface_on computes from every indenter on every cell
    from twoscale.indenters import surface_on

    rng = np.random.default_rng(3)
    asp = [
        Asperity(float(x), float(y), float(z), float(R), shape=str(s))
        for x, y, z, R, s in zip(
            rng.uniform(-10, 10, 300),
            rng.uniform(-10, 10, 300),
            rng.uniform(0, 0.3, 300),
            rng.uniform(0.5, 3.0, 300),
            rng.choice(["sphere", "paraboloid"], 300, p=[0.8, 0.2]),
        )
    ]
    grids = [Grid(float(x), float(y), 0.1, 30, 20) for x, y in rng.uniform(-12, 10, (6, 2))]
    fields = tuple(PressureField(g, np.zeros(g.shape), np.zeros(g.shape), np.zeros(g.shape)) for g in grids)
    s = summarise(fields, 300)
    res = ContactResult("twoscale", fields, 0.1, None, 0.0, s, True)
    back = read_vtk(write_vtk(res, tmp_path / "m.vtm", asperities=asp))
    for g, z in zip(grids, back.indenter_height):
        np.testing.assert_array_equal(z, surface_on(g, asp).height)


@pytest.mark.parametrize("which, keep", [("image", 0.02), ("image", 0.6), ("multiblock", 0.5)])
def test_damaged_file_is_a_value_error_naming_it(tmp_path, which, keep):
    """A file cut short (an interrupted copy) is one ValueError naming the file, which the
    command line turns into its one ``error:`` line, not a parser's traceback."""
    write_vtk(_two_patch_result(), tmp_path / "f.vtm")
    victim = sorted((tmp_path / "f").glob("*.vti"))[0] if which == "image" else tmp_path / "f.vtm"
    data = victim.read_bytes()
    victim.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(ValueError, match="damaged") as err:
        read_vtk(tmp_path / "f.vtm")
    assert str(victim) in str(err.value) and "\n" not in str(err.value)
