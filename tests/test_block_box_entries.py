"""The finite block's own entries of a small box (:mod:`fem_influence.box_entries`): the
whole matrix's cut, and the local blocks that take them."""

import numpy as np
import pytest

from fem_influence import BlockProvider
from twoscale.grid import Grid
from twoscale.material import Material
from helpers import paraboloid_patch_problems

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
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.patches import Patch

    grid = Grid(0.2, -0.3, 0.02, 20, 20)
    X, Y = grid.centres()
    owned = (X - X.mean()) ** 2 + (Y - Y.mean()) ** 2 < 0.18**2  # n |S| above the kept columns
    height = np.where(owned, (X - X.mean()) ** 2 + (Y - Y.mean()) ** 2, np.inf)
    blk = LocalBlock(block, Patch(0, grid, height, np.where(owned, 0, -1)))
    assert blk.dense and blk._box_window() is not None
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


def test_a_boxs_product_is_its_entries_times_the_vector(block):
    box = Grid(2.2, 1.3, 0.05, 15, 12)
    win = block.box_window(box)
    rng = np.random.default_rng(3)
    rows, cols = np.arange(box.size), np.sort(rng.permutation(box.size)[:40])
    v = rng.random(40)
    want = block.grid_matrix(box)[np.ix_(rows, cols)] @ v
    np.testing.assert_allclose(win.product(rows, cols, v), want, rtol=1e-13, atol=1e-15 * np.abs(want).max())


def test_eq7_first_passes_in_stacks_on_the_block_give_the_one_block_pressures(block, monkeypatch):
    # the block's windows are not exactly symmetric: the stacks solve by LU and keep no
    # Cholesky factor, and the blocks' pressures are those of the one-block loop
    from twoscale.micro import local_batch
    from twoscale.micro.local import initial_pressure, initial_pressures
    from twoscale.micro.localblock import LocalBlock

    h, E_star = 0.02, MAT.E / (1 - MAT.nu**2)
    rng = np.random.default_rng(10)
    patches, z, forces, approaches = paraboloid_patch_problems(rng, 12, (6, 16), 8.0, h, E_star)
    adopted = []
    monkeypatch.setattr(LocalBlock, "adopt_factor", lambda self, *a, **k: adopted.append(a))
    stacked = [LocalBlock(block, pt) for pt in patches]
    assert all(local_batch.batchable(b) for b in stacked)
    passes = local_batch.first_passes(stacked, z, forces, approaches, h)
    assert len(passes) == len(patches) and {res[0] for res in passes.values()} == {"done", "next"}
    assert not adopted
    got = initial_pressures(stacked, z, forces, approaches, h, rtol=1e-8)
    for pt, zk, P, a, p in zip(patches, z, forces, approaches, got):
        one = initial_pressure(LocalBlock(block, pt), zk, P, h, approach=a)
        assert one.converged and np.array_equal(p > 0.0, one.pressure > 0.0)
        np.testing.assert_allclose(p, one.pressure, rtol=1e-9, atol=1e-12 * one.pressure.max())
