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


def _patches(rng, n: int, spread: float):
    """``n`` patches of 8-24 cells a side on one lattice, some owning part of their grid."""
    out = []
    for k in range(n):
        nx, ny = (int(v) for v in rng.integers(8, 25, 2))
        i0, j0 = (int(v) for v in rng.integers(0, int(spread / H), 2))
        g = Grid(i0 * H, j0 * H, H, nx, ny)
        owner = np.full(g.shape, k)
        if rng.random() < 0.3:  # a neighbour owns a corner
            owner[: ny // 3, : nx // 3] = -1
        out.append(Patch(k, g, np.zeros(g.shape), owner))
    return out


def _values(rng, patches):
    """Random pressures (MPa) on the owned cells, zero on some cells and on one block."""
    vals = []
    for pt in patches:
        v = rng.random(int(pt.owned.sum())) * (rng.random(int(pt.owned.sum())) < 0.6)
        vals.append(v)
    vals[1] = np.zeros_like(vals[1])
    return vals


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_level_rhs_equal_the_block_by_block_ones(seed):
    rng = np.random.default_rng(seed)
    patches = _patches(rng, 40, 6.0)
    values = _values(rng, patches)
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
    patches = _patches(rng, 12, 1.0)
    values = _values(rng, patches)
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
    patches = _patches(rng, 6, 2.0)
    W, rows, starts = stacked_weights(patches, [4, 1, 2], lambda g: grid_interpolation(g.ny, g.nx))
    for i, k in enumerate([4, 1, 2]):
        g, own = patches[k].grid, patches[k].owned.ravel()
        assert np.array_equal(W[starts[i] : starts[i + 1]], grid_interpolation(g.ny, g.nx)[own])
        assert np.all(rows[starts[i] : starts[i + 1]] == k)
    assert starts[-1] == len(W) == len(rows)
