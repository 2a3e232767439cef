"""Block mesh recipe and the meshio reader/writer."""

import numpy as np
import pytest

from meshes import block_mesh, graded_axis, read_block_mesh, write_block_mesh
from meshes.block import MAX_MESH_NODES, axis_cells_bound


def test_graded_axis_spacing():
    x = graded_axis(-70.0, 70.0, fine_lo=-20.0, fine_hi=20.0, h_fine=5.0, h_coarse=12.0)
    assert x[0] == -70.0 and x[-1] == 70.0
    dx = np.diff(x)
    assert np.all(dx > 0)
    inside = (x[:-1] >= -20.0) & (x[1:] <= 20.0)
    assert np.all(dx[inside] <= 5.0 + 1e-12)
    assert dx.max() <= 1.5 * 12.0  # last interval may stretch to reach the end
    # neighbouring elements differ by at most the growth ratio (plus the end stretch)
    assert np.all(dx[1:] / dx[:-1] < 1.5 * 1.3) and np.all(dx[:-1] / dx[1:] < 1.5 * 1.3)


def test_graded_axis_invalid():
    with pytest.raises(ValueError, match="h_fine"):
        graded_axis(0.0, 1.0, fine_lo=0.0, fine_hi=1.0, h_fine=2.0, h_coarse=1.0)
    with pytest.raises(ValueError, match="growth"):
        graded_axis(0.0, 1.0, fine_lo=0.0, fine_hi=1.0, h_fine=0.1, h_coarse=1.0, growth=1.0)


def test_block_mesh_extent_and_volume():
    m = block_mesh((140.0, 100.0, 20.0))
    lo, hi = m.p.min(axis=1), m.p.max(axis=1)
    np.testing.assert_allclose(lo, [-70.0, -50.0, 0.0])
    np.testing.assert_allclose(hi, [70.0, 50.0, 20.0])
    from skfem import CellBasis, ElementHex1

    vol = CellBasis(m, ElementHex1()).dx.sum()
    assert vol == pytest.approx(140.0 * 100.0 * 20.0, rel=1e-12)


@pytest.mark.parametrize("length", [1.0, 30.0, 50.0, 60.0, 140.0, 1000.0, 12345.6])
@pytest.mark.parametrize("h", [(5.0, 12.0), (1.0, 20.0), (5.0, 5.0)])
def test_the_counted_elements_bound_the_axis_built(length, h):
    """The count made before a mesh is built is never below the elements built."""
    x = graded_axis(-length / 2, length / 2, fine_lo=-25.0, fine_hi=25.0, h_fine=h[0], h_coarse=h[1])
    bound = axis_cells_bound(length, fine=50.0, h_fine=h[0], h_coarse=h[1], growth=1.3)
    assert len(x) - 1 <= bound
    if length >= 10000.0:  # where the cap matters (metres), the count is close to the mesh
        assert bound <= 1.1 * (len(x) - 1)


@pytest.mark.parametrize(
    "size", [(3.5e16, 60.0, 10.0), (60.0, 60.0, 1e16), (60.0, float("inf"), 10.0), (4e4, 4e4, 20.0)]
)
def test_a_block_too_large_to_mesh_is_refused_before_it_is_built(size):
    # a 3.5e16 mm block was once meshed element by element until the machine ran out of memory
    with pytest.raises(ValueError, match=r"block size .* more than the 2,000,000") as err:
        block_mesh(size)
    assert "\n" not in str(err.value)
    # the largest square 20 mm block under the cap is built
    side = 2000.0
    m = block_mesh((side, side, 20.0))
    assert m.p.shape[1] < MAX_MESH_NODES


@pytest.mark.parametrize("suffix", [".vtu", ".msh"])
def test_meshio_roundtrip(tmp_path, suffix):
    # write in the file frame (top face at z = 0, body below) and read back: the
    # block frame is restored exactly (float64 formats; .msh ascii keeps 16 digits)
    m = block_mesh((60.0, 40.0, 10.0), h_fine=5.0, h_coarse=10.0, fine_box=(-5.0, 15.0, -5.0, 5.0))
    path = tmp_path / f"block{suffix}"
    write_block_mesh(m, path)
    r = read_block_mesh(path)
    assert r.nelements == m.nelements
    np.testing.assert_allclose(np.sort(r.p, axis=1), np.sort(m.p, axis=1), atol=1e-9)
    from skfem import CellBasis, ElementHex1

    dx = CellBasis(r, ElementHex1()).dx
    assert np.all(dx > 0)
    assert dx.sum() == pytest.approx(60.0 * 40.0 * 10.0, rel=1e-10)


def test_reader_recentres_top_face(tmp_path):
    import meshio

    m = block_mesh((20.0, 20.0, 5.0), h_fine=5.0, h_coarse=5.0)
    p = m.p.T.copy()
    p[:, 2] = -p[:, 2] + 7.0  # top face at z = 7
    p[:, 0] += 100.0  # footprint centred at x = 100
    from skfem.io.meshio import HEX_MAPPING

    meshio.write(tmp_path / "b.vtu", meshio.Mesh(p, [("hexahedron", m.t.T[:, HEX_MAPPING[:8]])]))
    r = read_block_mesh(tmp_path / "b.vtu")
    np.testing.assert_allclose(r.p.min(axis=1), [-10.0, -10.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(r.p.max(axis=1), [10.0, 10.0, 5.0], atol=1e-12)


def test_reader_rejects_non_hex(tmp_path):
    import meshio

    meshio.write(tmp_path / "t.vtu", meshio.Mesh(np.eye(3), [("triangle", np.array([[0, 1, 2]]))]))
    with pytest.raises(ValueError, match="hexahedron"):
        read_block_mesh(tmp_path / "t.vtu")
