"""The finite block's half-space self-operators kept per grid shape, and the stacked local
solves' canvas masks kept per level: each against the route it replaces, bit for bit."""

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.material import Material
from helpers import disc_patches, small_block

MAT = Material(E=2.0, nu=0.5)
H = 0.02
#: Tips of five patches of 24 x 24 cells, a few near each other (spectral pairs).
TIPS = [(-0.9, 0.0), (-0.4, 0.1), (0.1, -0.05), (0.55, 0.2), (3.0, 3.0)]


@pytest.fixture(scope="module")
def block():
    return small_block(MAT)


def _patches(tips=TIPS):
    return disc_patches(tips, H)


def test_a_kept_self_operator_moved_is_the_grids_own(block):
    from twoscale.influence import HalfSpace

    st = block._state
    a, b = Grid(-1.0, 0.4, H, 17, 13), Grid(2.3, -0.7, H, 17, 13)
    p = np.random.default_rng(2).random(b.shape)
    st.halfspace_operator(block._halfspace, a, a)  # kept for the shape
    moved = st.halfspace_operator(block._halfspace, b, b)
    fresh = HalfSpace(MAT).grid_operator(b, b)
    assert moved.target == b and moved.source == b
    assert np.array_equal(moved.apply(p), fresh.apply(p))
    # the block's own grid operator (half-space part plus correction) against its dense matrix
    full = block.grid_operator(b).apply(p).ravel()
    ref = block.grid_matrix(b) @ p.ravel()
    assert np.max(np.abs(full - ref)) < 1e-9 * np.max(np.abs(ref))


def test_stacked_canvases_are_placed_member_by_member(block):
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.pk_stack import BlockStacks

    patches = _patches(tips=TIPS[:3])
    blocks = [LocalBlock(block, pt) for pt in patches]
    stacks = BlockStacks(block)
    key = stacks.canvas(blocks[0])[0]
    members = [0, 1, 2]
    vec = {k: np.arange(blk.n, dtype=float) + k for k, blk in enumerate(blocks)}
    for _ in range(2):  # made, then kept
        mask, (a,) = stacks._stack(blocks, members, key, vec)
        for i, k in enumerate(members):
            want = np.zeros(key)
            want[blocks[k].canvas_mask(key)] = vec[k]
            assert np.array_equal(a[i], want)
            assert np.array_equal(mask[i], blocks[k].canvas_mask(key))
