"""Patches skip the indenters that cannot own a cell of them, and come out as if every
indenter had been sampled (heights and owners cell for cell)."""

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.micro.patches import TipTable, make_patch


def _tips(n, seed, shapes):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-2.0, 2.0, (n, 2))
    R = rng.uniform(0.3, 3.0, n)
    z = rng.uniform(0.0, 0.02, n)
    return [
        Asperity(float(x), float(y), float(zk), float(r), str(rng.choice(shapes))) for (x, y), zk, r in zip(xy, z, R)
    ]


@pytest.mark.parametrize("shapes", [("sphere",), ("paraboloid",), ("sphere", "paraboloid")])
def test_pruned_patch_equals_brute_force(shapes):
    tips = _tips(150, 3, shapes)  # more than the tree's threshold: the k-d tree route
    table = TipTable(tips)
    pruned_some = False
    for k in range(0, 150, 7):
        a = tips[k]
        for w in (0.03, 0.15, 0.6):
            grid = Grid.covering(a.x - w, a.x + w, a.y - w, a.y + w, 0.01)
            fast = make_patch(k, grid, table)
            brute = surface_on(grid, tips)
            assert np.array_equal(fast.height, brute.height)
            assert np.array_equal(fast.owner, brute.owner)
            reach = table.reaching(grid.bounds, below=float(np.max(surface_on(grid, [a]).height)))
            pruned_some |= len(reach) < len(table.reaching(grid.bounds))
    assert pruned_some  # the lower bound did skip indenters somewhere


def test_no_tree_route_agrees():
    tips = _tips(40, 5, ("sphere", "paraboloid"))  # below the tree's threshold
    for k in range(0, 40, 5):
        a = tips[k]
        grid = Grid.covering(a.x - 0.2, a.x + 0.2, a.y - 0.2, a.y + 0.2, 0.01)
        fast, brute = make_patch(k, grid, TipTable(tips)), surface_on(grid, tips)
        assert np.array_equal(fast.owner, brute.owner) and np.array_equal(fast.height, brute.height)


@pytest.mark.parametrize("n, tiled", [(150, False), (600, True)])
def test_crowded_patches_are_cut_from_one_sampled_box(n, tiled):
    # patches sized by the indenters' reach (no usable macro force) overlap many times over:
    # the box covering them is sampled once (tile by tile when large) and each patch is a
    # window of it; the same heights (the box's cell centres: rounding only) and owners
    from twoscale.micro.sampling import build_patches
    from twoscale.micro.sampling import SAMPLE_WHOLE_CELLS, box_surface, crowded, shared_box
    from twoscale.micro.union import box_of

    tips = _tips(n, 11, ("sphere", "paraboloid"))
    table = TipTable(tips)
    h = 0.01 if tiled else 0.02
    patches = build_patches(
        table, h=h, forces=np.full(n, np.inf), approaches=np.full(n, 0.03), E_star=1.0, anchor=(0.001, 0.002)
    )
    box = box_of([pt.grid for pt in patches], h, (0.001, 0.002))
    assert crowded([pt.grid for pt in patches], box) and (box.size > SAMPLE_WHOLE_CELLS) == tiled
    for pt in patches[:: max(1, n // 40)]:
        own = make_patch(pt.asperity, pt.grid, table)
        assert np.array_equal(pt.owner, own.owner)
        assert np.array_equal(np.isinf(pt.height), np.isinf(own.height))
        finite = np.isfinite(own.height)
        assert np.allclose(pt.height[finite], own.height[finite], rtol=0.0, atol=1e-12)
        assert not pt.height.flags.writeable
    # the union CG takes the sampled box from the patches instead of sampling it again
    lent = shared_box(patches, n, (0.001, 0.002))
    assert lent is not None and lent.grid == box and lent.n_asperities == n
    again = box_surface(box, table)
    assert np.array_equal(lent.owner, again.owner) and np.array_equal(lent.height, again.height)
    assert (
        shared_box(patches[1:], n, (0.001, 0.002)) is None
        or box_of([pt.grid for pt in patches[1:]], h, (0.001, 0.002)) == box
    )
    assert shared_box([make_patch(pt.asperity, pt.grid, table) for pt in patches[:3]], n, (0.001, 0.002)) is None


@pytest.mark.parametrize("tilt", [False, True])
def test_the_union_cg_on_the_box_its_crowded_patches_lent_matches_the_full_grid(monkeypatch, tilt):
    # a macro step far from a solution (as if: SIZING_RESIDUAL 0) sizes the patches by
    # reach: 30 merged spheres under 300 N have patches of 148 K cells over a 67 K-cell
    # box; the union CG runs on the box they were cut from, and its forces are the full
    # grid's
    import twoscale.micro.problem as problem
    import twoscale.micro.union as union
    from helpers import crowded
    from twoscale import Material
    from twoscale.driver import solve_twoscale
    from twoscale.influence import HalfSpace
    from twoscale.reference import solve_cg

    lent = []
    shared = union.shared_box
    monkeypatch.setattr(union, "shared_box", lambda *a: lent.append(shared(*a)) or lent[-1])
    monkeypatch.setattr(problem, "SIZING_RESIDUAL", 0.0)
    body, asps, h = HalfSpace(Material(10.0, 0.5)), crowded(2, 30), 0.08
    load = dict(total_load=300.0, tilt=tilt, pivot=(1.0, -0.5))
    res = solve_twoscale(body, asps, h=h, iteration="union-cg", macro_max_iter=1, **load)
    assert res.converged and not res.details.macro.converged and lent and lent[0] is not None
    x, y = [a.x for a in asps], [a.y for a in asps]
    grid = Grid.covering(min(x) - 4, max(x) + 4, min(y) - 4, max(y) + 4, h)
    ref = solve_cg(body, surface_on(grid, asps), tol=1e-10, **load)
    f, r = np.asarray(res.asperities.forces), np.asarray(ref.asperities.forces)
    assert np.max(np.abs(f - r)) <= 1e-6 * np.max(r)


@pytest.mark.parametrize("h, force, shared", [(0.012, 1e-3, True), (0.004, 1e-3, True), (0.004, 1e-4, False)])
def test_small_patches_of_many_tips_are_cut_from_their_box(h, force, shared):
    # patches that do not crowd their box but are small against it per tip (a light load on
    # 600 tips on 4 x 4 mm: building each costs more than sampling its share of the box),
    # or that together cover at least BOX_MIN_PATCH_SHARE of it (where the union CG may run
    # on that box), are cut from the box sampled once, cell for cell as built one by one; at
    # a finer h and a lighter load neither holds and each patch is built on its own
    from twoscale.micro.sampling import BOX_CELLS_PER_PATCH, BOX_MIN_PATCH_SHARE, build_patches, crowded, shared_box
    from twoscale.micro.union import box_of

    n, anchor = 600, (0.001, 0.002)
    table = TipTable(_tips(n, 13, ("sphere", "paraboloid")))
    patches = build_patches(
        table, h=h, forces=np.full(n, force), approaches=np.full(n, 0.03), E_star=100.0, anchor=anchor
    )
    grids = [pt.grid for pt in patches]
    box = box_of(grids, h, anchor)
    assert not crowded(grids, box)
    assert (box.size <= BOX_CELLS_PER_PATCH * n or crowded(grids, box, BOX_MIN_PATCH_SHARE)) == shared
    assert (shared_box(patches, n, anchor) is not None) == shared
    for pt in patches[::37]:
        own = make_patch(pt.asperity, pt.grid, table)
        assert np.array_equal(pt.owner, own.owner)
        finite = np.isfinite(own.height)
        assert np.array_equal(np.isfinite(pt.height), finite)
        assert np.allclose(pt.height[finite], own.height[finite], rtol=0.0, atol=1e-12)


def test_patches_covering_a_share_of_their_box_lend_it_to_the_union_cg_sampled_once(monkeypatch):
    # nine spheres on a 1 mm lattice at a light penetration: their patches cover about half
    # of their box (not crowded) and the box has over BOX_CELLS_PER_PATCH cells a patch, but
    # the share is over BOX_MIN_PATCH_SHARE: the patches are cut from the box sampled once,
    # the union CG runs on it without sampling it again, and its forces are the full grid's
    import twoscale.micro.sampling as sampling
    import twoscale.micro.union as union
    from twoscale import Material
    from twoscale.driver import solve_twoscale
    from twoscale.influence import HalfSpace
    from twoscale.reference import solve_cg

    sampled, lent = [], []
    box_surface, shared = sampling.box_surface, union.shared_box
    counted = lambda grid, asps: sampled.append(grid.size) or box_surface(grid, asps)  # noqa: E731
    monkeypatch.setattr(sampling, "box_surface", counted)
    monkeypatch.setattr(union, "box_surface", counted)
    monkeypatch.setattr(union, "shared_box", lambda *a: lent.append(shared(*a)) or lent[-1])
    body, h = HalfSpace(Material(10.0, 0.5)), 0.02
    asps = [Asperity(float(i), float(j), 0.002 * ((i + 2 * j) % 3), 5.0) for i in range(3) for j in range(3)]
    res = solve_twoscale(body, asps, h=h, iteration="union-cg", penetration=0.012)
    assert res.converged and len(sampled) == 1 and lent and lent[0] is not None
    box = union.box_of([Grid.covering(a.x - 0.5, a.x + 0.5, a.y - 0.5, a.y + 0.5, h) for a in asps], h, (0.0, 0.0))
    assert sampled[0] > sampling.BOX_CELLS_PER_PATCH * len(asps) and sampled[0] < box.size
    grid = Grid.covering(-1.0, 3.0, -1.0, 3.0, h)
    ref = solve_cg(body, surface_on(grid, asps), tol=1e-10, penetration=0.012)
    f, r = np.asarray(res.asperities.forces), np.asarray(ref.asperities.forces)
    assert np.max(np.abs(f - r)) <= 1e-6 * np.max(r)


def test_highest_over_one_tip_is_the_whole_grid_sampled():
    # one plain sphere or paraboloid is sampled at the cell farthest from its tip only:
    # the same number as the largest height of the grid sampled whole (inf beyond a sphere)
    from twoscale.micro.patches import highest_over

    rng = np.random.default_rng(0)
    infinite = 0
    for i in range(600):
        a = Asperity(
            *rng.uniform(-1, 1, 2), rng.uniform(0, 0.01), rng.uniform(0.2, 5), shape=("sphere", "paraboloid")[i % 2]
        )
        h, r = rng.uniform(0.005, 0.05), rng.uniform(0.01, 1.0)
        g = Grid.covering(a.x - r + rng.uniform(-0.1, 0.1), a.x + r, a.y - r, a.y + r * rng.uniform(0.5, 1.5), h)
        whole = float(np.max(surface_on(g, [a]).height))
        assert highest_over(g, [a]) == whole
        infinite += np.isinf(whole)
    assert 0 < infinite < 600


@pytest.mark.parametrize("shapes", [("sphere",), ("paraboloid",), ("sphere", "paraboloid")])
def test_the_candidates_of_all_patches_at_once_are_each_patchs(shapes):
    # one query of the tips' tree for every patch (the same arithmetic on arrays): the
    # candidates patch_candidates gives one patch at a time, patches of every size, some
    # whose farthest cell is beyond their sphere's material (nothing skipped by height)
    from twoscale.micro.candidates import candidates_of
    from twoscale.micro.patches import patch_candidates

    tips = _tips(150, 5, shapes)
    table = TipTable(tips)
    wanted = [
        (k, Grid.covering(tips[k].x - w, tips[k].x + w + 0.013, tips[k].y - w, tips[k].y + w, 0.01, anchor=(0.003, 0)))
        for k, w in zip(range(0, 150, 2), np.resize([0.02, 0.07, 0.2, 0.45, 0.9], 75))
    ]
    together = candidates_of(table, wanted)
    assert together is not None and len(together) == len(wanted)
    sizes = set()
    for (k, grid), got in zip(wanted, together):
        np.testing.assert_array_equal(got, patch_candidates(grid, table, (k,)))
        sizes.add(len(got))
    assert len(sizes) > 5  # patches with few and with many candidates
    assert candidates_of(TipTable(tips[:40]), wanted[:3]) is None  # few tips: no tree, one by one


def test_scattered_patches_the_far_field_can_take_are_not_cut_from_a_sampled_box(monkeypatch):
    # the sweep's ten paraboloids (#109) on 14.3 % of their 155 K-cell box, no merged
    # contacts: over the union CG's least coverage, but the far field can take them (it
    # does), so the box is not sampled for them; the patches built one by one are the same
    # cells, and the answer is the one from patches cut from the box
    import twoscale
    import twoscale.micro.driver as micro_driver
    import twoscale.micro.sampling as sampling
    from twoscale.scenespace import build, sweep

    (spec,) = [s for s in sweep(200, 0) if s.index == 109]
    scene = build(spec)
    boxes = []
    cut = sampling.patches_cut_from_box
    monkeypatch.setattr(sampling, "patches_cut_from_box", lambda *a: boxes.append(a[1].size) or cut(*a))
    alone = twoscale.solve(scene)
    estimates = alone.details.micro.choice.estimates
    assert sampling.BOX_MIN_PATCH_SHARE <= estimates["coverage"] < 0.2 and not estimates["merged_contacts"]
    assert alone.details.micro.choice.iteration == "two-level" and alone.details.micro.choice.far_tol is not None
    assert boxes == []
    monkeypatch.setattr(micro_driver, "_box_share", lambda merged: sampling.BOX_MIN_PATCH_SHARE)
    from_box = twoscale.solve(scene)
    assert boxes == [estimates["box_cells"]]
    assert from_box.details.micro.choice == alone.details.micro.choice
    # heights sampled on a patch or on the box's tiles differ in their last bits; far patches
    # act through low-rank operators accurate to separated_rtol, so the two answers are held
    # to that accuracy, not to rounding (1.1e-9 of the largest on one host, under 1e-9 on
    # another)
    f, g = np.asarray(alone.asperities.forces), np.asarray(from_box.asperities.forces)
    assert np.max(np.abs(f - g)) <= twoscale.MicroOptions().separated_rtol * np.max(g)
    assert alone.iterations == from_box.iterations
