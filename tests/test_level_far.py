"""A sweep level's right-hand sides at once (:meth:`LaggedFarField.rhs_level`).

Checks: on random patches (sizes, places, owned cells and pressures drawn at random) the
level's right-hand sides equal the block-by-block ones to rounding (the far field by one
row-wise product instead of a small matrix product a block); and where every pair is near,
they equal the exact coupling's (:class:`~twoscale.micro.blocks.Coupling`, dense blocks and
FFT operators of the Love kernel) to rounding, the pairs past the dense blocks' size
gathered from the kernel's window.
"""

import numpy as np
import pytest

from helpers import lattice_patches, lattice_values

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.micro.blocks import Coupling
from twoscale.micro.farfield import LaggedFarField
from twoscale.micro.level_far import stacked_weights
from twoscale.micro.patches import Patch
from twoscale.micro.sources import grid_interpolation
from twoscale.micro.twolevel import sweep_levels

HS = HalfSpace(Material(10.0, 0.5))
H = 0.02


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_level_rhs_equal_the_block_by_block_ones(seed):
    rng = np.random.default_rng(seed)
    patches = lattice_patches(rng, 40, 6.0, H)
    values = lattice_values(rng, patches)
    b = [rng.normal(size=len(v)) * 1e-3 for v in values]
    kw = dict(far_tol=0.3, dense_max_entries=20_000, cache_bytes=2e5)  # some pairs past the dense blocks
    one, many = LaggedFarField(HS, patches, **kw), LaggedFarField(HS, patches, **kw)
    one.refresh(values)
    many.refresh(values)
    levels = sweep_levels(many)
    assert len(levels) > 1 and sum(len(v) for v in levels) == len(patches)
    assert any(len(many.near(k)) for k in range(len(patches)))  # the near pairs are exercised
    for level in levels:
        got = many.rhs_level(level, values, b)
        for k in level:
            want = one.rhs(k, values, b[k])
            scale = np.abs(want - b[k]).max() + np.abs(b[k]).max()
            assert np.abs(got[k] - want).max() <= 1e-13 * scale


def test_level_rhs_equal_the_exact_coupling_where_every_pair_is_near():
    rng = np.random.default_rng(5)
    patches = lattice_patches(rng, 12, 1.0, H)
    values = lattice_values(rng, patches)
    b = [np.zeros(len(v)) for v in values]
    held = LaggedFarField(HS, patches, far_tol=1e-6, dense_max_entries=20_000, cache_bytes=1e5)
    assert all(len(held.near(k)) == len(patches) - 1 for k in range(len(patches)))
    exact = Coupling(HS, patches, separated_rtol=None)
    held.refresh(values)
    got = held.rhs_level(list(range(len(patches))), values, b)
    for k in range(len(patches)):
        want = exact.rhs(k, values, b[k])
        assert np.abs(got[k] - want).max() <= 1e-10 * np.abs(want).max()


def test_stacked_weights_are_each_blocks_rows():
    rng = np.random.default_rng(3)
    patches = lattice_patches(rng, 6, 2.0, H)
    W, rows, starts = stacked_weights(patches, [4, 1, 2], lambda g: grid_interpolation(g.ny, g.nx))
    for i, k in enumerate([4, 1, 2]):
        g, own = patches[k].grid, patches[k].owned.ravel()
        assert np.array_equal(W[starts[i] : starts[i + 1]], grid_interpolation(g.ny, g.nx)[own])
        assert np.all(rows[starts[i] : starts[i + 1]] == k)
    assert starts[-1] == len(W) == len(rows)


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (5, 1), (3, 3), (17, 40), (64, 33)])
def test_separable_far_is_the_weight_tables_product(shape):
    """The tensor-product form against the (ny nx, 9) weights themselves, on the whole grid
    and on a random set of owned cells."""
    from twoscale.micro.level_far import separable_far

    rng = np.random.default_rng(sum(shape))
    ny, nx = shape
    g = Grid(0.0, 0.0, H, nx, ny)
    stencil = rng.normal(size=9)
    want = grid_interpolation(ny, nx) @ stencil
    scale = np.abs(stencil).max()
    assert np.abs(separable_far(g, None, stencil) - want).max() <= 1e-14 * scale
    owned = rng.random((ny, nx)) < 0.5
    owned.flat[0] = True
    assert np.abs(separable_far(g, owned, stencil) - want[owned.ravel()]).max() <= 1e-14 * scale
    columns = rng.normal(size=(9, 3))  # several right-hand sides at once
    want = grid_interpolation(ny, nx) @ columns
    assert np.abs(separable_far(g, owned, columns) - want[owned.ravel()]).max() <= 1e-14 * np.abs(columns).max()


@pytest.mark.parametrize("seed", [0, 1])
def test_level_rhs_after_a_patch_change_equal_a_fresh_far_fields(seed):
    """A patch replaced (grown, moved) in a far field that kept its levels' weights: every
    level's right-hand sides equal those of a far field made anew on the changed patches
    (the levels without the patch keep their weights, the others are made again)."""
    from twoscale.micro.sources import SEPARABLE_CELLS

    rng = np.random.default_rng(10 + seed)
    patches = lattice_patches(rng, 30, 6.0, H, largest=60)
    assert any(pt.owned.sum() >= SEPARABLE_CELLS for pt in patches)
    assert any(pt.owned.sum() < SEPARABLE_CELLS for pt in patches)
    kw = dict(far_tol=0.3, dense_max_entries=20_000, cache_bytes=2e5)
    kept = LaggedFarField(HS, patches, **kw)
    values = lattice_values(rng, patches)
    kept.refresh(values)
    for level in sweep_levels(kept):  # every level's weights kept
        kept.rhs_level(level, values, [np.zeros(len(v)) for v in values])
    for _ in range(3):
        k = int(rng.integers(len(patches)))
        old = patches[k].grid
        nx, ny = (int(v) for v in rng.integers(8, 61, 2))
        g = Grid(old.x0 + H * int(rng.integers(-3, 4)), old.y0 + H * int(rng.integers(-3, 4)), H, nx, ny)
        patches[k] = Patch(k, g, np.zeros(g.shape), np.full(g.shape, k))
        kept.replace(k, patches[k])
    values = lattice_values(rng, patches)
    b = [rng.normal(size=len(v)) * 1e-3 for v in values]
    fresh = LaggedFarField(HS, list(patches), **kw)
    kept.refresh(values)
    fresh.refresh(values)
    levels = sweep_levels(fresh)
    assert levels == sweep_levels(kept)
    for level in levels:
        got, want = kept.rhs_level(level, values, b), fresh.rhs_level(level, values, b)
        for k in level:
            one = fresh.rhs(k, values, b[k])  # the block-by-block far field, weights or separable
            scale = np.abs(one - b[k]).max() + np.abs(b[k]).max()
            # (the near pairs may take other routes than a fresh engine's: rounding apart)
            assert np.abs(got[k] - want[k]).max() <= 1e-13 * scale
            assert np.abs(got[k] - one).max() <= 1e-13 * scale
