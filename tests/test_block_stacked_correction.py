"""The block's correction of a stack of grids on themselves, batched on canvases, against
the pointwise correction (the provider's ``correction`` of the cells' centres) and the
stacked local solves' per-block lagged term."""

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.material import Material
from helpers import disc_patches, small_block

MAT = Material(E=2.0, nu=0.5)
H = 0.02


@pytest.fixture(scope="module")
def block():
    return small_block(MAT)


def test_a_stack_of_grids_on_themselves_is_each_grids_pointwise_correction(block):
    _, corr = block.split()
    # shapes and places differ: one inside an element, one across element and lattice lines
    grids = [Grid(-1.0, 0.4, H, 17, 13), Grid(-0.07, -0.13, H, 24, 20), Grid(2.3, -0.7, H, 9, 21)]
    shape = (24, 28)
    stack = corr.own_stack(grids, shape)
    rng = np.random.default_rng(4)
    P = np.zeros((len(grids), *shape))
    for b, g in enumerate(grids):
        P[b, : g.ny, : g.nx] = rng.random(g.shape)
    U = stack.apply(P)
    for b, g in enumerate(grids):
        pts = g.points()
        ref = (g.h**2 * block.correction(pts, pts) @ P[b, : g.ny, : g.nx].ravel()).reshape(g.shape)
        assert np.max(np.abs(U[b, : g.ny, : g.nx] - ref)) < 1e-12 * np.max(np.abs(ref))
        assert not U[b, g.ny :].any() and not U[b, :, g.nx :].any()  # nothing off the grid
        assert np.max(np.abs(ref)) > 0
        same = corr.on_itself(g, P[b, : g.ny, : g.nx])
        assert np.max(np.abs(U[b, : g.ny, : g.nx] - same)) < 1e-13 * np.max(np.abs(ref))


def _patches():
    """Five patches, a few near each other, one alone."""
    return disc_patches([(-0.9, 0.0), (-0.4, 0.1), (0.1, -0.05), (0.55, 0.2), (3.0, 3.0)], H)


def test_stacked_solves_lag_the_same_correction_as_block_by_block(block, monkeypatch):
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.pk_stack import BlockStacks

    patches = _patches()
    blocks = [LocalBlock(block, pt) for pt in patches]
    ks = [k for k, blk in enumerate(blocks) if blk.n]
    rng = np.random.default_rng(5)
    previous = [0.5 * rng.random(blk.n) for blk in blocks]
    rhs = {k: 1e-3 + 1e-3 * rng.random(blocks[k].n) for k in ks}
    batched = BlockStacks(block).solve(blocks, ks, rhs, previous, 1e-10)
    stacks = BlockStacks(block)
    monkeypatch.setattr(stacks, "_own_stack", lambda *a: None)  # the lagged term block by block
    single = stacks.solve(blocks, ks, rhs, previous, 1e-10)
    for k in ks:
        a, b = batched[k][0], single[k][0]
        assert np.max(np.abs(a - b)) < 1e-8 * np.max(np.abs(b)) and np.max(np.abs(b)) > 0
    # the lagged term matters: without it the solves differ
    monkeypatch.setattr(stacks, "_correction", None)
    bare = stacks.solve(blocks, ks, rhs, previous, 1e-10)
    assert max(np.max(np.abs(bare[k][0] - single[k][0])) for k in ks) > 1e-6 * max(
        np.max(np.abs(single[k][0])) for k in ks
    )


def test_near_sums_compact_coefficients_are_the_pointwise_correction(block):
    _, corr = block.split()
    target = Grid(-1.0, 0.4, H, 17, 13)
    sources = [Grid(-0.6, 0.35, H, 12, 15), Grid(-1.3, 0.1, H, 20, 9)]
    rng = np.random.default_rng(6)
    ps = [rng.random(g.shape) for g in sources]
    got = corr.near_sum(target, [(g, corr.compact(g, p)) for g, p in zip(sources, ps)])
    t = target.points()
    ref = sum(g.h**2 * block.correction(t, g.points()) @ p.ravel() for g, p in zip(sources, ps)).reshape(target.shape)
    assert np.max(np.abs(ref)) > 0 and np.max(np.abs(got - ref)) < 1e-12 * np.max(np.abs(ref))
    # the contract's route: one vector over every node, summed
    c = sum(corr.coefficients(g, p) for g, p in zip(sources, ps))
    assert np.max(np.abs(corr.evaluate(target, c) - ref)) < 1e-12 * np.max(np.abs(ref))
    # a second call takes the kept cuts of the pairs: the same numbers
    again = corr.near_sum(target, [(g, corr.compact(g, p)) for g, p in zip(sources, ps)])
    assert np.array_equal(again, got)


def test_a_grids_interpolation_kept_as_axis_factors_is_numpys_kron():
    from fem_influence.grid_factors import KronMatrix

    rng = np.random.default_rng(7)
    for ny, ry, nx, rx, m in [(29, 3, 28, 3, 16), (5, 5, 7, 3, 2), (1, 3, 4, 5, 1)]:
        my, mx = rng.random((ny, ry)), rng.random((nx, rx))
        K, D = KronMatrix(my, mx), np.kron(my, mx)
        V = rng.random((ry * rx, m))
        assert K.shape == D.shape
        assert np.max(np.abs(K @ V - D @ V)) < 1e-14 * np.max(np.abs(D @ V))
        assert np.max(np.abs(K @ V[:, 0] - D @ V[:, 0])) < 1e-14 * np.max(np.abs(D @ V[:, 0]))
