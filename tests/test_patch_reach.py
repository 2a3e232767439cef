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
