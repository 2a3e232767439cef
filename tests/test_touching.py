"""Contacts that touch become one block of the two-level iteration with far-field coupling.

Checks: which patches :func:`touching_groups` joins (loaded cells next to cells another
asperity owns; an empty start of the nearer tip still joins; contacts a few cells apart do
not); on a seeded scene of tight pairs the far-field two-level iteration converges in a
quarter of the sweeps it needed with one block per asperity, to the full-grid reference's
forces; the merged block's patch covers its members' grids.
"""

import numpy as np
import pytest

import twoscale
from twoscale import Material
from twoscale.driver import solve_twoscale
from twoscale.influence import HalfSpace
from twoscale.micro import setup, workset
from twoscale.micro.patches import merge_groups
from twoscale.micro.touching import touching_groups

from helpers import random_scene, disc_on_patch, patches_on_x

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)
H = 0.02


def _patches(tips):
    return patches_on_x(tips, H, 0.5, (-0.5, 0.5))


def test_loaded_cells_next_to_a_neighbours_cells_join_the_two():
    # tips 0.05 mm apart share a contact of radius 0.2 mm: the line where their surfaces
    # cross is at x = 0.025; the third tip is 3 mm away
    asps, patches = _patches([0.0, 0.05, 3.0])
    empty = np.zeros(int(patches[1].owned.sum()))
    # the nearer tip's start is empty (the macro step gave the pair's force to one tip)
    starts = [disc_on_patch(patches[0], 0.0, 0.2), empty, disc_on_patch(patches[2], 3.0, 0.2)]
    assert touching_groups(patches, starts) == [[0, 1], [2]]
    # a contact of one cell at the first tip is two cells from the crossing line: apart
    starts[0] = disc_on_patch(patches[0], 0.0, 0.01)
    assert touching_groups(patches, starts) == [[0], [1], [2]]
    # reached through a third patch: all three join
    asps, patches = _patches([0.0, 0.3, 0.6])
    starts = [disc_on_patch(pt, 0.3 * k, 0.2) for k, pt in enumerate(patches)]
    assert touching_groups(patches, starts) == [[0, 1, 2]]


def test_a_merged_group_covers_its_members_grids():
    asps, patches = _patches([0.0, 0.05, 3.0])
    merged, covers = merge_groups(patches, asps, [[1, 0], [2]])
    assert covers == [(0, 1), (2,)] and merged[0].members == (0, 1) and merged[1] is patches[2]
    g = merged[0].grid
    assert g.h == H and g.nx == patches[0].grid.nx + 2 and g.ny == patches[0].grid.ny
    # every cell either asperity owns on its own patch is in the merged block
    assert int(merged[0].owned.sum()) >= int(patches[0].owned.sum())


TIGHT = dict(h=0.15, total_load=108.0, tol=1e-8, iteration="two-level", far_tol=0.3, max_sweeps=100)


def test_far_field_two_level_on_tight_pairs_converges_as_one_block_each():
    # 18 spheres, a third in tight pairs (the seeded scene of the merged-contacts tests):
    # one block per asperity needed 32 sweeps of the far-field two-level iteration (the
    # pairs' force passed back and forth); the pairs as one block, 8
    asps = random_scene(2, 18)
    res = solve_twoscale(HS, asps, **TIGHT)
    attempt = res.details.micro.attempts[0]
    assert res.converged and attempt.sweeps <= 12, (res.message, attempt)
    assert res.details.micro.merged_patches, "no pair was solved as one block"
    ref = twoscale.solve(asps, method="reference", material=MAT, h=TIGHT["h"], total_load=TIGHT["total_load"])
    fe, fa = np.asarray(ref.asperities.forces), np.asarray(res.asperities.forces)
    assert np.max(np.abs(fa - fe)) <= 1e-3 * fe.max()


@pytest.mark.slow
def test_one_block_per_asperity_takes_more_than_twice_the_sweeps(monkeypatch):
    asps = random_scene(2, 18)
    merged = solve_twoscale(HS, asps, **TIGHT).details.micro.attempts[0]
    apart_groups = lambda patches, p, **kw: [[k] for k in range(len(patches))]  # noqa: E731
    monkeypatch.setattr(setup, "touching_groups", apart_groups)  # at the start
    monkeypatch.setattr(workset, "touching_groups", apart_groups)  # after sweeps and growths
    apart = solve_twoscale(HS, asps, **TIGHT).details.micro.attempts[0]
    assert apart.sweeps > 2 * merged.sweeps


def test_patches_that_come_to_touch_are_merged_as_the_iteration_goes():
    # a working set of one block per asperity whose first two contacts touch (a patch
    # grown or given to a new asperity can meet a neighbour's contact): merged into one
    # block, the pressure carried over cell by cell, and a new engine for the new patches
    from twoscale.micro.blocks import scatter
    from twoscale.micro.couplings import FarField
    from twoscale.micro.workset import WorkingSet, comes_to_touch, merge_touching

    asps, patches = _patches([0.0, 0.05, 3.0])
    engine = lambda pts: FarField(0.3).build(HS, pts, held=True, dense_max_entries=40_000, separated_rtol=None)  # noqa: E731
    fixed = WorkingSet(HS, asps, patches, engine(patches), dense_max_cells=400)
    state = WorkingSet(HS, asps, patches, engine(patches), dense_max_cells=400, rebuild=engine)
    p = [disc_on_patch(pt, x, 0.2) for pt, x in zip(patches, [0.0, 0.05, 3.0])]
    p0 = [v.copy() for v in p]
    assert merge_touching(fixed, list(p), list(p0)) == 0  # no engine to rebuild: unchanged
    assert not comes_to_touch(fixed, p) and comes_to_touch(state, p)
    total = sum(float(v.sum()) for v in p)
    assert merge_touching(state, p, p0) == 1
    assert not comes_to_touch(state, p)
    assert [pt.members for pt in state.patches] == [(0, 1), (2,)]
    assert len(state.blocks) == len(p) == len(p0) == 2 and len(state.coupling.patches) == 2
    assert sum(float(v.sum()) for v in p) == total
    # the merged block holds each member's pressure on the cells it owns
    merged = scatter(state.patches[0], p[0])
    for k in (0, 1):
        win = patches[k].grid.window_in(state.patches[0].grid)
        np.testing.assert_array_equal(merged[win][patches[k].owned], disc_on_patch(patches[k], [0.0, 0.05][k], 0.2))
    assert merge_touching(state, p, p0) == 0


def test_a_replaced_engine_and_its_far_field_weights_are_released():
    # the growth check's gaps (gaps_of) hold the engine they were taken from; a merge
    # replaces the engine, whose far field keeps per-patch arrays (its table, the source
    # weights and interpolation rows of patches under SEPARABLE_CELLS): the old engine must
    # not outlive the merge
    import gc
    import weakref

    from twoscale.micro.couplings import FarField
    from twoscale.micro.workset import WorkingSet, merge_touching

    asps, patches = _patches([0.0, 0.05, 3.0])
    engine = lambda pts: FarField(0.3).build(HS, pts, held=True, dense_max_entries=40_000, separated_rtol=None)  # noqa: E731
    state = WorkingSet(HS, asps, patches, engine(patches), dense_max_cells=400, rebuild=engine)
    p = [disc_on_patch(pt, x, 0.2) for pt, x in zip(patches, [0.0, 0.05, 3.0])]
    p0 = [v.copy() for v in p]
    state.coupling.refresh(p)
    state.gaps_of([0, 1, 2], p, (0.01, 0.0, 0.0), (0.0, 0.0))
    assert state.coupling._table is not None, "the far field held nothing"
    old = weakref.ref(state.coupling)
    assert merge_touching(state, p, p0) == 1
    gc.collect()
    assert old() is None, f"the replaced engine is still held by {[type(r) for r in gc.get_referrers(old())]}"
