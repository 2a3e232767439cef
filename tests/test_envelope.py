"""The lower envelope of many plain asperities by small tiles evaluated at once
(:func:`twoscale.micro.envelope.envelope_on`) against every asperity on every cell."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.micro.envelope import envelope_on
from twoscale.micro.patches import TipTable


def _scene(rng, n, shapes):
    tips = [
        Asperity(float(x), float(y), float(z), float(r), shapes[k % len(shapes)])
        for k, (x, y, z, r) in enumerate(
            zip(rng.uniform(-3.3, 3.3, n), rng.uniform(-3.3, 3.3, n), rng.uniform(0, 0.05, n), rng.uniform(0.1, 1.0, n))
        )
    ]
    tips.append(tips[5])  # an exact tie: the earlier index keeps the cells
    tips.append(Asperity(40.0, 40.0, 0.0, 1.0))  # far off the grid: owns nothing
    return tips


@pytest.mark.parametrize("tile, sub, group", [(5, 5, 7), (6, 2, 7), (16, 8, 4096), (16, 1, 4096)])
@pytest.mark.parametrize("shapes", [("sphere",), ("paraboloid",), ("sphere", "paraboloid")])
def test_the_envelope_is_every_tip_on_every_cell(shapes, tile, sub, group, monkeypatch):
    # a grid whose sides are no multiple of the tile (edge tiles repeat the last cell),
    # spheres leaving cells without material (inf, owner -1); tiles in groups of 7 too
    from twoscale.micro import envelope

    monkeypatch.setattr(envelope, "ENVELOPE_GROUP", group)
    rng = np.random.default_rng(11)
    tips = _scene(rng, 60, shapes)
    grid = Grid.covering(-3.0, 3.1, -2.9, 3.0, 0.023)
    assert grid.nx % tile and grid.ny % tile
    got = envelope_on(grid, TipTable(tips), tile=tile, sub=sub)
    want = surface_on(grid, tips)  # every tip on every cell, in batches
    assert np.array_equal(got.owner, want.owner)
    assert np.array_equal(got.height, want.height)  # the grid's cell centres, the same arithmetic
    assert 5 in want.owner and len(tips) - 2 not in want.owner and len(tips) - 1 not in want.owner
    if shapes == ("sphere",):
        assert np.any(want.owner == -1) and np.all(np.isinf(got.height[got.owner == -1]))


def test_a_tile_bounded_by_a_near_tip_recessed_far_below_keeps_the_low_tips_around():
    # the tips nearest a tile's centre are high (z = 0.5 mm): its bound is high, and the
    # low tips farther away still own its cells
    rng = np.random.default_rng(2)
    low = [Asperity(float(x), float(y), 0.0, 2.0) for x, y in rng.uniform(-2.0, 2.0, (40, 2))]
    high = [Asperity(float(x), float(y), 0.5, 0.3) for x, y in rng.uniform(-0.2, 0.2, (6, 2))]
    tips = high + low
    grid = Grid.covering(-2.0, 2.0, -2.0, 2.0, 0.02)
    got, want = envelope_on(grid, TipTable(tips)), surface_on(grid, tips)
    assert np.array_equal(got.owner, want.owner) and np.array_equal(got.height, want.height)


def _direct(grid, tips):
    """Every tip's own :meth:`Asperity.height` on every cell, the lowest kept (the first of
    equals): the surface by definition."""
    X, Y = grid.centres()
    heights = np.stack([a.height(X, Y) for a in tips])
    owner = np.argmin(heights, axis=0)
    low = np.take_along_axis(heights, owner[None], axis=0)[0]
    return low, np.where(np.isfinite(low), owner, -1)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("tile, sub", [(16, 8), (16, 4), (8, 2), (12, 3)])
def test_clustered_tips_sub_tiles_keep_every_owner(seed, tile, sub, monkeypatch):
    # hundreds of spheres and paraboloids in tight clusters, tips within a micron of each
    # other: a tile's candidates are many, and each sub-tile keeps fewer of them; a few
    # tiny spheres leave cells without material, and every sub-tile's owner must survive
    from twoscale.micro import envelope

    monkeypatch.setattr(envelope, "ENVELOPE_CELLS", 256)  # several slot groups
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-0.5, 0.5, (6, 2))
    xy = centres[rng.integers(0, 6, 300)] + rng.normal(0.0, 0.05, (300, 2))
    tips = [
        Asperity(float(x), float(y), float(z), float(r), "sphere" if k % 3 else "paraboloid")
        for k, ((x, y), z, r) in enumerate(zip(xy, rng.uniform(0.0, 0.001, 300), rng.uniform(1.0, 2.5, 300)))
    ]
    grid = Grid.covering(-0.8, 0.8, -0.75, 0.8, 0.006)
    tied = int(_direct(grid, tips)[1][grid.ny // 2, grid.nx // 2])
    tips += [Asperity(0.7, 0.7, 0.0, 0.01), tips[tied]]  # a tiny sphere; a tie (the earlier keeps it)
    got = envelope_on(grid, TipTable(tips), tile=tile, sub=sub)
    low, owner = _direct(grid, tips)
    assert np.array_equal(got.owner, owner) and np.array_equal(got.height, low)
    assert tied in owner and len(tips) - 1 not in owner


def test_a_sub_tile_that_does_not_divide_the_tile_is_refused():
    grid = Grid.covering(-1.0, 1.0, -1.0, 1.0, 0.1)
    with pytest.raises(ValueError, match="divide"):
        envelope_on(grid, TipTable([Asperity(0.0, 0.0, 0.0, 1.0)]), tile=16, sub=6)


@pytest.mark.parametrize("seed", range(4))
def test_small_random_grids_even_narrower_than_a_tile(seed):
    # grids from one cell wide to a few tiles, tips of both shapes: sub-tiles past the
    # grid's edge repeat its last cell, and every cell is still its lowest tip's
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 60))
    tips = [
        Asperity(float(x), float(y), float(z), float(r), ("sphere", "paraboloid")[k % 2])
        for k, (x, y, z, r) in enumerate(
            zip(rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(0, 0.02, n), rng.uniform(0.05, 2, n))
        )
    ]
    for nx, ny in ((1, 40), (37, 3), (int(rng.integers(17, 70)), int(rng.integers(17, 70)))):
        grid = Grid(-0.5, -0.4, 0.013, nx, ny)
        low, owner = _direct(grid, tips)
        for tile, sub in ((16, 8), (12, 3)):
            got = envelope_on(grid, TipTable(tips), tile=tile, sub=sub)
            assert np.array_equal(got.owner, owner) and np.array_equal(got.height, low)
