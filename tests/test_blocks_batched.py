"""The near pairs' dense blocks made together (:func:`twoscale.micro.pair_entries.pair_blocks`,
:meth:`twoscale.micro.blocks.Coupling.prepare_dense`) against the one-pair route.

Independent check: each entry of a pair's block is Love's rectangle kernel at the two cells'
centre offset (:func:`twoscale.analytic.halfspace.love_rectangle`), and the batched blocks
equal the provider's own gather for that pair of grids bit for bit."""

import numpy as np

from twoscale import Material
from twoscale.analytic.halfspace import love_rectangle
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.influence.cached import CachedBody, OperatorCaches
from twoscale.micro import pair_entries
from twoscale.micro.blocks import Coupling
from twoscale.micro.pair_entries import pair_blocks
from twoscale.micro.patches import Patch
from helpers import paraboloid_patch_problems

MAT = Material(10.0, 0.5)
H = 0.02


def _patches(seed: int, n: int = 6) -> list:
    """Patches of random sizes on one lattice, each owning a random part of its grid."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        nx, ny = rng.integers(3, 12, 2)
        i0, j0 = rng.integers(-15, 15, 2)
        g = Grid(0.1 + i0 * H, -0.3 + j0 * H, H, int(nx), int(ny))
        owner = np.where(rng.random(g.shape) < 0.7, k, -1)
        owner.flat[0] = k
        out.append(Patch(k, g, np.zeros(g.shape), owner))
    return out


def test_batched_pair_blocks_are_the_kernel_at_each_cell_offset():
    patches = _patches(0)
    pairs = [(k, l) for k in range(len(patches)) for l in range(len(patches)) if k != l]
    body = CachedBody(HalfSpace(MAT), OperatorCaches())
    blocks = pair_blocks(body, patches, pairs)
    assert set(blocks) == set(pairs)
    for (k, l), M in blocks.items():
        pk, pl = patches[k], patches[l]
        xk, yk = (c[pk.owned] for c in pk.grid.centres())
        xl, yl = (c[pl.owned] for c in pl.grid.centres())
        want = love_rectangle(xk[:, None] - xl[None, :], yk[:, None] - yl[None, :], 0.5 * H, 0.5 * H, MAT.E_star)
        assert M.shape == want.shape
        assert np.allclose(M, want, rtol=1e-10, atol=0.0)
        one = body.grid_entries(pk.grid, pl.grid, np.flatnonzero(pk.owned), np.flatnonzero(pl.owned))
        assert np.array_equal(M, one)


def test_pairs_beyond_the_window_are_left_to_the_one_pair_route(monkeypatch):
    patches = _patches(1, 3)
    far = Grid(patches[0].grid.x0 + 400 * H, patches[0].grid.y0, H, 4, 4)
    patches.append(Patch(3, far, np.zeros(far.shape), np.full(far.shape, 3)))
    monkeypatch.setattr(pair_entries, "WINDOW_MAX_ENTRIES", 101 * 101)
    blocks = pair_blocks(HalfSpace(MAT), patches, [(0, 1), (3, 0), (1, 2)])
    assert set(blocks) == {(0, 1), (1, 2)}


def test_a_coupling_with_prepared_pairs_gives_the_same_sums_as_one_made_pair_by_pair():
    patches = _patches(2, 8)
    rng = np.random.default_rng(3)
    values = [rng.random(int(pt.owned.sum())) for pt in patches]
    lazy = Coupling(CachedBody(HalfSpace(MAT), OperatorCaches()), patches)
    ready = Coupling(CachedBody(HalfSpace(MAT), OperatorCaches()), patches)
    ready.prepare_dense([(k, l) for k in range(len(patches)) for l in range(k)])
    assert len(ready._ops) == len(patches) * (len(patches) - 1) // 2
    for k in range(len(patches)):
        rhs = rng.random(len(values[k]))
        assert np.allclose(ready.rhs(k, values, rhs), lazy.rhs(k, values, rhs), rtol=1e-13, atol=1e-16)
    assert len(ready._ops) == len(patches) * (len(patches) - 1)  # the reverse pairs as views


def test_a_box_window_gives_the_providers_entries_of_the_box_bit_for_bit():
    from twoscale.micro.pair_entries import BoxWindow

    body = CachedBody(HalfSpace(MAT), OperatorCaches())
    rng = np.random.default_rng(5)
    for nx, ny in [(1, 1), (7, 3), (12, 17)]:
        box = Grid(0.3 + 3 * H, -0.1, H, nx, ny)
        win = BoxWindow.of(body, box)
        rows = rng.choice(box.size, min(box.size, 9), replace=False)
        cols = rng.choice(box.size, min(box.size, 5), replace=False)
        assert np.array_equal(win.entries(rows, cols), body.grid_entries(box, box, rows, cols))
        X, Y = (c.ravel() for c in box.centres())
        want = love_rectangle(X[rows][:, None] - X[cols], Y[rows][:, None] - Y[cols], 0.5 * H, 0.5 * H, MAT.E_star)
        assert np.allclose(win.entries(rows, cols), want, rtol=1e-10, atol=0.0)
    assert BoxWindow.of(body, Grid(0.0, 0.0, H, 40, 40)) is None  # larger than a block keeps
    assert BoxWindow.of(MAT, Grid(0.0, 0.0, H, 4, 4)) is None  # no translation-invariant kernel


def test_dense_local_solves_with_the_box_window_are_those_without(monkeypatch):
    from twoscale.micro import localblock
    from twoscale.micro.local import contact_solve

    patches = _patches(6, 4)
    rng = np.random.default_rng(7)
    rhs = [1e-3 * (rng.random(int(pt.owned.sum())) - 0.4) for pt in patches]

    def solves():
        body = CachedBody(HalfSpace(MAT), OperatorCaches())
        blocks = [localblock.LocalBlock(body, pt) for pt in patches]
        return blocks, [contact_solve(blk, b, np.zeros(blk.n)) for blk, b in zip(blocks, rhs)]

    windowed, one = solves()
    monkeypatch.setattr(localblock.BoxWindow, "of", staticmethod(lambda provider, box: None))
    plain, two = solves()
    for a, b, blk, other in zip(one, two, windowed, plain):
        assert a.active.any() and np.array_equal(a.active, b.active)
        assert np.array_equal(a.pressure, b.pressure)
        assert blk._window is not None and other._window is None


def test_active_columns_beyond_the_kept_size_are_gathered_not_transformed(monkeypatch):
    from twoscale.micro import localblock

    g = Grid(0.0, 0.0, H, 14, 12)
    pt = Patch(0, g, np.zeros(g.shape), np.zeros(g.shape, dtype=int))
    blk = localblock.LocalBlock(CachedBody(HalfSpace(MAT), OperatorCaches()), pt)
    active = np.random.default_rng(8).random(blk.n) < 0.3
    assert localblock.COLUMNS_MAX_ENTRIES < blk.n * active.sum() <= localblock.COLUMNS_GATHER_MAX_ENTRIES
    v = np.where(active, np.random.default_rng(9).random(blk.n), 0.0)
    want = blk.matvec(v)  # the box's FFT product

    def no_fft(*args):
        raise AssertionError("the box's FFT product was taken")

    monkeypatch.setattr(blk, "matvec", no_fft)
    got = blk.product_on(active, v)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-15 * np.abs(want).max())
    assert blk._columns is None  # gathered for the product, not kept


def test_eq7_first_passes_in_stacks_give_the_one_block_pressures(monkeypatch):
    from twoscale.micro import local_batch
    from twoscale.micro.local import initial_pressure, initial_pressures
    from twoscale.micro.localblock import LocalBlock

    rng = np.random.default_rng(10)
    patches, z, forces, approaches = paraboloid_patch_problems(rng, 24, (5, 16), 1.0, H, MAT.E_star)

    def blocks():
        body = CachedBody(HalfSpace(MAT), OperatorCaches())
        return [LocalBlock(body, pt) for pt in patches]

    batched = blocks()
    assert all(local_batch.batchable(b) for b in batched)
    passes = local_batch.first_passes(batched, z, forces, approaches, H)
    kinds = {res[0] for res in passes.values()}
    assert len(passes) == len(patches) and kinds == {"done", "next"}  # both ways taken
    # stacks bounded in bytes (one or two blocks a stack here) give the same first passes
    monkeypatch.setattr(local_batch, "STACK_BYTES", 20_000)
    assert len(local_batch._stacks(list(range(24)), [8 * (3 * 16 * 16 + 225 * 16)] * 24)) == 24
    small = local_batch.first_passes(blocks(), z, forces, approaches, H)
    assert small.keys() == passes.keys()
    for k, res in passes.items():
        assert small[k][0] == res[0] and np.allclose(small[k][1], res[1], rtol=1e-12, atol=0)
    monkeypatch.undo()
    got = initial_pressures(blocks(), z, forces, approaches, H, rtol=1e-8)
    for blk, zk, P, a, p in zip(blocks(), z, forces, approaches, got):
        one = initial_pressure(blk, zk, P, H, approach=a)
        assert one.converged and np.array_equal(p > 0.0, one.pressure > 0.0)
        assert np.allclose(p, one.pressure, rtol=1e-9, atol=1e-12 * one.pressure.max())
        assert np.isclose(H * H * p.sum(), P, rtol=1e-12) and p.min() >= 0.0
