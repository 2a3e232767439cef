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
    from twoscale.micro.patches import build_patches
    from twoscale.micro.sampling import SAMPLE_TILE, box_surface, crowded, shared_box
    from twoscale.micro.union import box_of

    tips = _tips(n, 11, ("sphere", "paraboloid"))
    table = TipTable(tips)
    h = 0.01 if tiled else 0.02
    patches = build_patches(
        table, h=h, forces=np.full(n, np.inf), approaches=np.full(n, 0.03), E_star=1.0, anchor=(0.001, 0.002)
    )
    box = box_of([pt.grid for pt in patches], h, (0.001, 0.002))
    assert crowded([pt.grid for pt in patches], box) and (box.size > 4 * SAMPLE_TILE**2) == tiled
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
