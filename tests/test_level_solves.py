"""A sweep level's dense first passes together (:class:`twoscale.micro.local_levels.LevelSolves`),
its right-hand sides over flat arrays (:class:`twoscale.micro.level_rhs.LevelRhs`) and the
near pairs' products by their loaded columns (:class:`twoscale.micro.pair_columns.ActiveColumns`),
against the one-block route.

Independent checks: each block's result against :func:`twoscale.micro.local.contact_solve`
on the same block and right-hand side (its whole active-set loop), and the products against
the dense block times the whole vector; a two-level solve with the level's passes taken
against the same solve with every local solve and right-hand side one by one; the flat
right-hand sides against the coupling's own, block by block.
"""

import numpy as np
import pytest

from twoscale import Material
from twoscale.driver import solve_twoscale
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.influence.cached import CachedBody, OperatorCaches
from twoscale.micro import local_levels, twolevel
from twoscale.micro.local import contact_solve
from twoscale.micro.local_levels import LevelSolves
from twoscale.micro.localblock import LocalBlock
from twoscale.micro.pair_columns import ActiveColumns
from twoscale.micro.patches import Patch

from helpers import spaced_spheres

MAT = Material(10.0, 0.5)
H = 0.02


def _scene(seed: int, count: int = 30):
    """Blocks of random sizes (a few owning part of their grid), with indentation
    right-hand sides ``d - z`` and previous pressures on a nearby right-hand side."""
    rng = np.random.default_rng(seed)
    body = CachedBody(HalfSpace(MAT), OperatorCaches())
    blocks, rhs, previous = [], {}, []
    for k in range(count):
        n = int(rng.integers(5, 16))
        g = Grid(rng.uniform(-1, 1), rng.uniform(-1, 1), H, n, n)
        owner = np.full(g.shape, k)
        if k % 5 == 4:
            owner[:, : n // 4] = -1  # a neighbour owns part of the patch
        blk = LocalBlock(body, Patch(k, g, np.zeros(g.shape), owner))
        X, Y = g.centres()
        c = np.array([g.x0, g.y0]) + rng.uniform(0.3, 0.7, 2) * (n - 1) * H
        z = (((X - c[0]) ** 2 + (Y - c[1]) ** 2) / (2 * rng.uniform(2.0, 8.0)))[blk.patch.owned]
        d = rng.uniform(0.1, 0.4) * float(np.ptp(z)) + float(z.min())
        b = d - z
        before = b * (1.0 + rng.uniform(-0.15, 0.15)) + rng.normal(0, 0.01 * np.ptp(z), b.size)
        previous.append(contact_solve(blk, before, np.zeros(blk.n)).pressure)
        blocks.append(blk)
        rhs[k] = b
    previous[3] = np.zeros(blocks[3].n)  # no contact before: left to the one-block loop
    return blocks, rhs, previous


@pytest.mark.parametrize("seed", [0, 1])
def test_a_levels_first_passes_give_the_one_block_solves(seed):
    blocks, rhs, previous = _scene(seed)
    got = LevelSolves(blocks).solve(list(range(len(blocks))), rhs, previous)
    assert 3 not in got
    for k, blk in enumerate(blocks):
        one = contact_solve(blk, rhs[k], previous[k])
        assert one.converged
        if k in got:
            pressure, active = got[k]
            assert one.iterations == 1
            assert np.array_equal(active, one.active) and np.array_equal(pressure > 0.0, one.pressure > 0.0)
            assert np.allclose(pressure, one.pressure, rtol=1e-9, atol=1e-12 * one.pressure.max())
        elif k != 3:
            assert one.iterations > 1  # a first pass that is not final is left out
    assert 3 <= len(got) < len(blocks) - 1  # both outcomes taken


def test_a_level_keeps_its_stacks_while_the_contacts_stay(monkeypatch):
    blocks, rhs, previous = _scene(2)
    flat = LevelSolves(blocks)
    level = list(range(len(blocks)))
    first = flat.solve(level, rhs, previous)
    made, group = [], local_levels._group
    monkeypatch.setattr(local_levels, "_group", lambda *a: made.append(1) or group(*a))
    again = flat.solve(level, {k: 1.01 * b for k, b in rhs.items()}, [p.copy() for p in previous])
    assert not made  # the same contacts: the level's stacks are kept
    for k, (pressure, _) in first.items():
        if k in again:
            assert np.allclose(again[k][0], 1.01 * pressure, rtol=1e-9)
    # a block whose contact changed takes a new piece, and the level new stacks
    previous[0] = np.where(np.arange(blocks[0].n) == np.argmax(previous[0]), 1.0, 0.0)
    flat.solve(level, rhs, previous)
    assert made


def test_a_pairs_product_by_its_loaded_columns_is_the_whole_product():
    rng = np.random.default_rng(3)
    M = rng.normal(size=(40, 30))
    cols = ActiveColumns()
    for loaded in (0, 5, 9, 5, 20):
        v = np.zeros(30)
        v[rng.choice(30, loaded, replace=False)] = rng.uniform(0.1, 1.0, loaded)
        assert np.allclose(cols.product(0, 1, M, v), M @ v, rtol=1e-13, atol=1e-13)
        assert np.allclose(cols.product(0, 1, M.T[:30, :30], v), M.T[:30, :30] @ v, rtol=1e-13, atol=1e-13)
    assert cols.nbytes == sum(kept[2].nbytes for kept in cols._pairs.values()) > 0
    cols.drop(1)
    assert cols.nbytes == 0 and not cols._pairs
    # beyond the budget: the whole block, nothing kept
    tight = ActiveColumns(budget=0)
    v = np.zeros(30)
    v[:4] = 1.0
    assert np.allclose(tight.product(0, 1, M, v), M @ v) and tight.nbytes == 0


def test_two_level_with_the_levels_passes_and_flat_rhs_is_the_one_block_solve(monkeypatch):
    asp = spaced_spheres(60, 0, 24.0)
    kw = dict(h=0.1, total_load=3.0, tol=1e-7, max_sweeps=200, far_tol=0.01, coarse=True)
    flat = solve_twoscale(HalfSpace(MAT), asp, **kw)
    monkeypatch.setattr(LevelSolves, "solve", lambda self, level, rhs, p: {})
    monkeypatch.setattr(twolevel, "LevelRhs", lambda coupling, levels: None)  # the coupling's rhs
    one = solve_twoscale(HalfSpace(MAT), asp, **kw)
    assert flat.converged and one.converged
    assert flat.iterations == one.iterations
    f1, f2 = np.asarray(flat.asperities.forces), np.asarray(one.asperities.forces)
    assert np.max(np.abs(f1 - f2)) <= 1e-9 * f2.max()


def test_a_levels_flat_right_hand_sides_are_the_couplings():
    from twoscale.micro.couplings import FarField
    from twoscale.micro.level_rhs import LevelRhs
    from twoscale.micro.sampling import build_patches
    from twoscale.micro.twolevel import sweep_levels

    asp = spaced_spheres(20, 3, 8.0)
    patches = build_patches(
        asp, h=0.05, forces=np.full(20, np.inf), approaches=np.full(20, 0.05), E_star=MAT.E_star, anchor=(0.0, 0.0)
    )
    engine = FarField(0.3).build(HalfSpace(MAT), patches, held=True, dense_max_entries=40_000, separated_rtol=None)
    assert sum(len(engine.near(k)) for k in range(len(patches))) >= 10
    rng = np.random.default_rng(4)

    def pressures(share):  # loaded on a random part of each block
        return [np.where(rng.random(int(pt.owned.sum())) < share, rng.uniform(0.1, 1.0), 0.0) for pt in patches]

    p, b = pressures(0.3), [rng.normal(size=int(pt.owned.sum())) for pt in patches]
    levels = sweep_levels(engine)
    assert len(levels) > 1
    flat = LevelRhs(engine, levels)
    for sweep in range(2):
        engine.refresh(p)
        flat.start(p, b)
        for i, level in enumerate(levels):
            got = flat.rhs(i, level, p, b)
            assert sorted(got) == sorted(level)
            for k in level:
                want = engine.rhs(k, p, b[k])
                assert np.allclose(got[k], want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
            new = pressures(0.6)  # new loaded cells: the kept columns grow
            for k in level:
                p[k] = new[k]
            flat.update(level, p)
