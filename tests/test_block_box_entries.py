"""The finite block's own entries of a small box (:mod:`fem_influence.box_entries`): the
whole matrix's cut, and the local blocks that take them."""

import numpy as np
import pytest

from fem_influence import BlockProvider
from twoscale.grid import Grid
from twoscale.material import Material

MAT = Material(E=2.0, nu=0.5)
SMALL = dict(size=(60.0, 60.0, 10.0), h_fine=5.0, h_coarse=10.0, fine_half_width=10.0)


@pytest.fixture(scope="module")
def block():
    return BlockProvider(material=MAT, use_cache=False, progress=False, **SMALL)


@pytest.mark.parametrize(
    "box",
    [
        Grid(1.1, 0.3, 0.05, 13, 9),  # inside one element
        Grid(4.3, -5.4, 0.1, 11, 17),  # across an element's edge each way (nodes at 2.5 mm)
        Grid(-0.4, -0.2, 0.02, 1, 1),  # one cell
    ],
)
def test_a_boxs_entries_are_its_whole_matrixs_cut(block, box):
    win = block.box_window(box)
    assert win is not None and not win.symmetric
    A = block.grid_matrix(box)
    rng = np.random.default_rng(0)
    rows = rng.permutation(box.size)[: max(1, box.size // 2)]
    cols = rng.permutation(box.size)[: max(1, box.size // 3)]
    got = win.entries(rows, cols)
    np.testing.assert_allclose(got, A[np.ix_(rows, cols)], rtol=1e-13, atol=1e-15 * np.abs(A).max())
    # the correction is in them (not Love's alone), and they are not exactly symmetric
    love = block._halfspace.grid_matrix(box)
    assert np.abs(got - love[np.ix_(rows, cols)]).max() > 1e-6 * np.abs(love).max()
    full = win.entries(np.arange(box.size), np.arange(box.size))
    assert box.size == 1 or not np.array_equal(full, full.T)


def test_a_large_box_has_no_window(block):
    assert block.box_window(Grid(0.0, 0.0, 0.01, 40, 40)) is None


def test_local_blocks_on_the_block_solve_from_their_window_without_an_fft(block, monkeypatch):
    from twoscale.micro import local_batch
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.patches import Patch

    grid = Grid(0.2, -0.3, 0.02, 20, 20)
    X, Y = grid.centres()
    owned = (X - X.mean()) ** 2 + (Y - Y.mean()) ** 2 < 0.18**2  # n |S| above the kept columns
    height = np.where(owned, (X - X.mean()) ** 2 + (Y - Y.mean()) ** 2, np.inf)
    blk = LocalBlock(block, Patch(0, grid, height, np.where(owned, 0, -1)))
    assert blk.dense and blk._box_window() is not None
    assert not local_batch.batchable(blk)  # the stacked Cholesky pass needs exact symmetry
    calls = []
    monkeypatch.setattr(type(block), "grid_operator", lambda *a, **k: calls.append(a) or None)
    A = block.grid_matrix(blk.box)[np.ix_(blk._idx, blk._idx)]
    active = np.zeros(blk.n, bool)
    active[: blk.n // 2] = True
    rhs = np.linspace(1.0, 2.0, int(active.sum()))
    x = blk.solve(active, rhs)
    np.testing.assert_allclose(A[np.ix_(active, active)] @ x, rhs, rtol=1e-10)
    v = np.where(active, 1.0, 0.0)
    np.testing.assert_allclose(blk.product_on(active, v), A @ v, rtol=1e-12)
    assert not calls
