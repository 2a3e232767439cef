"""Sums over blocks laid end to end, the blocks' shared box windows, and a matrix's
symmetric part taken without a copy.

Independent checks: each block's own ``np.sum`` (to the rounding of a sum), Love's rectangle
kernel at each pair of cells' centre offset, and ``(M + M^T) / 2`` written out."""

import numpy as np
import pytest

from twoscale import Material
from twoscale.analytic.halfspace import love_rectangle
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.influence.cached import CachedBody, OperatorCaches
from twoscale.macro.system import symmetric_part
from twoscale.micro.localblock import LocalBlock
from twoscale.micro.patches import Patch
from twoscale.micro.segments import laid_end_to_end, segment_sums, starts_of

MAT = Material(10.0, 0.5)
H = 0.02


def test_segment_sums_are_each_blocks_sum_with_empty_blocks_anywhere():
    rng = np.random.default_rng(3)
    sizes = [0, 5, 1, 0, 0, 130, 7, 0]  # empty first, last and in a run
    values = [rng.normal(size=n) for n in sizes]
    starts = starts_of(values)
    assert starts.tolist() == np.concatenate([[0], np.cumsum(sizes)]).tolist()
    got = segment_sums(laid_end_to_end(values), starts)
    want = np.array([float(np.sum(v)) for v in values])
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14)
    assert got[0] == got[3] == got[4] == got[7] == 0.0
    # booleans count, as a block's count_nonzero
    masks = [v > 0.0 for v in values]
    assert segment_sums(laid_end_to_end(masks, bool), starts).tolist() == [int(np.count_nonzero(m)) for m in masks]
    assert segment_sums(laid_end_to_end([]), starts_of([])).size == 0


def _patch(k: int, i0: int, j0: int, nx: int, ny: int) -> Patch:
    g = Grid(0.1 + i0 * H, -0.2 + j0 * H, H, nx, ny)
    return Patch(k, g, np.zeros(g.shape), np.full(g.shape, k))


def test_blocks_of_one_shape_share_a_window_with_the_kernels_entries():
    body = CachedBody(HalfSpace(MAT), OperatorCaches())
    windows: dict = {}
    patches = [_patch(0, 0, 0, 6, 4), _patch(1, 17, -9, 6, 4), _patch(2, 3, 30, 5, 4)]
    blocks = [LocalBlock(body, pt, windows=windows) for pt in patches]
    shared = [blk._box_window() for blk in blocks]
    assert shared[0] is shared[1] and shared[2] is not shared[0] and len(windows) == 2
    for blk, pt in zip(blocks, patches):
        X, Y = pt.grid.centres()
        x, y = X.ravel(), Y.ravel()
        rows, cols = np.arange(3), np.array([0, 5, pt.grid.size - 1])
        want = love_rectangle(
            x[rows, None] - x[None, cols], y[rows, None] - y[None, cols], 0.5 * H, 0.5 * H, MAT.E_star
        )
        np.testing.assert_allclose(blk._box_window().entries(rows, cols), want, rtol=1e-12)
        alone = LocalBlock(body, pt)._box_window()  # without the shared windows: the same numbers
        assert np.array_equal(alone.entries(rows, cols), blk._box_window().entries(rows, cols))


@pytest.mark.parametrize("symmetric", [True, False])
def test_symmetric_part_is_the_matrix_itself_only_where_it_is_symmetric(symmetric):
    rng = np.random.default_rng(5)
    M = rng.normal(size=(7, 7))
    if symmetric:
        M = M + M.T
    got = symmetric_part(M)
    assert (got is M) == symmetric
    assert np.array_equal(got, 0.5 * (M + M.T))
