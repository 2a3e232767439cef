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


@pytest.mark.parametrize("tile, group", [(5, 7), (16, 4096)])
@pytest.mark.parametrize("shapes", [("sphere",), ("paraboloid",), ("sphere", "paraboloid")])
def test_the_envelope_is_every_tip_on_every_cell(shapes, tile, group, monkeypatch):
    # a grid whose sides are no multiple of the tile (edge tiles repeat the last cell),
    # spheres leaving cells without material (inf, owner -1); tiles in groups of 7 too
    from twoscale.micro import envelope

    monkeypatch.setattr(envelope, "ENVELOPE_GROUP", group)
    rng = np.random.default_rng(11)
    tips = _scene(rng, 60, shapes)
    grid = Grid.covering(-3.0, 3.1, -2.9, 3.0, 0.023)
    assert grid.nx % tile and grid.ny % tile
    got = envelope_on(grid, TipTable(tips), tile=tile)
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
