"""The coarse step of the two-level iteration on the finite block: the FFT blocks' ``s_k``
solved on the canvases' half-space kernel, with each tip's smooth compliance on itself
added to ``1 / kappa_k`` (:meth:`twoscale.micro.coarse.CoarseSpace.smooth_self`)."""

import numpy as np
import pytest
import scipy.sparse as sp

from twoscale.grid import Grid
from twoscale.material import Material
from helpers import small_block

MAT = Material(E=2.0, nu=0.5)
H = 0.02


@pytest.fixture(scope="module")
def two_patches():
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.patches import Patch

    block = small_block(MAT)
    tips = np.array([[-3.0, 0.5], [3.0, -0.5]])
    blocks, patches = [], []
    for k, (x, y) in enumerate(tips):
        grid = Grid(x - 0.3, y - 0.3, H, 30, 30)
        X, Y = grid.centres()
        r2 = (X - x) ** 2 + (Y - y) ** 2
        owned = r2 < 0.29**2
        patches.append(Patch(k, grid, np.where(owned, r2, np.inf), np.where(owned, k, -1)))
        blocks.append(LocalBlock(block, patches[-1]))
    return block, tips, blocks, patches


def _step(block, tips, blocks, patches, stacks):
    from twoscale.micro.coarse import CoarseSpace
    from twoscale.micro.constraints import Control

    for blk in blocks:
        blk.coarse_shape = None
    coarse = CoarseSpace(block, tips, sp.csr_matrix((2, 2)))
    active = [np.ones(blk.n, bool) for blk in blocks]
    pressures = [np.zeros(blk.n) for blk in blocks]
    return coarse.correct(blocks, patches, pressures, active, np.array([0.0, 1e-2]), np.zeros(3), Control(), stacks)


def test_the_coarse_step_on_the_block_is_the_whole_kernels(two_patches):
    from twoscale.micro.pk_stack import BlockStacks

    block, tips, blocks, patches = two_patches
    assert not any(blk.dense for blk in blocks)
    stacks = BlockStacks(block)
    assert not stacks.whole_kernel
    got = _step(block, tips, blocks, patches, stacks).forces
    # the step from each block's s_k on the whole kernel (its own solve, the correction in)
    ones = [np.ones(blk.n, bool) for blk in blocks]
    kappa = np.array([H * H * blk.solve(a, np.ones(blk.n), rtol=1e-10).sum() for blk, a in zip(blocks, ones)])
    T = np.array(block.point_compliance(tips, tips))
    T[np.diag_indices(2)] = 0.0
    dF = np.array([0.0, 1e-2])
    want = np.linalg.solve(T + np.diag(1.0 / kappa), -(T @ dF))
    np.testing.assert_allclose(got, want, rtol=2e-3)
    # the half-space's s_k alone (no correction of the tips on themselves) is visibly off
    love = np.array([H * H * blk.coarse_shape[1].sum() for blk in blocks])
    off = np.linalg.solve(T + np.diag(1.0 / love), -(T @ dF))
    assert np.abs(off - want).max() > 1e-2 * np.abs(want).max()
    # and the step of the blocks' own solves (no stacks) agrees with it
    alone = _step(block, tips, blocks, patches, None).forces
    np.testing.assert_allclose(alone, want, rtol=2e-3)


def test_the_blocks_pair_compliance_is_its_point_compliance_at_the_pairs():
    block = small_block(MAT)
    rng = np.random.default_rng(5)
    P = rng.uniform(-20.0, 20.0, (40, 2))
    i, j = rng.integers(0, 40, 300), rng.integers(0, 40, 300)  # rows in no order
    keep = i != j
    i, j = i[keep], j[keep]
    want = np.asarray(block.point_compliance(P, P))[i, j]
    got = block.pair_compliance(P, i, j)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # not Boussinesq's alone
    love = np.asarray(block._halfspace.point_compliance(P, P))[i, j]
    assert np.abs(got - love).max() > 1e-3 * np.abs(love).max()


@pytest.mark.parametrize(
    "grid", [Grid(1.1, 0.3, 0.05, 23, 17), Grid(4.3, -5.4, 0.1, 11, 17), Grid(0.0, 0.0, 0.02, 1, 1)]
)
def test_a_grids_correction_of_itself_is_the_correction_in_two_calls(grid):
    block = small_block(MAT)
    halfspace, correction = block.split()
    p = np.random.default_rng(7).random(grid.shape)
    want = correction.evaluate(grid, correction.coefficients(grid, p))
    got = correction.on_itself(grid, p)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14 * np.abs(want).max())
    # the whole kernel's product less the half-space's
    whole = (block.grid_matrix(grid) - halfspace.grid_matrix(grid)) @ p.ravel()
    np.testing.assert_allclose(got.ravel(), whole, rtol=1e-10, atol=1e-12 * np.abs(whole).max())
    assert np.abs(got).max() > 0.0
