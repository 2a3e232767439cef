"""Sampling indenters on a grid (``surface_on``): spheres are evaluated only on the cells
within their radius; the result must equal evaluating every indenter on every cell."""

from __future__ import annotations

import math

import numpy as np
from helpers import every_tip_on_every_cell
import pytest

from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on


def scattered(rng, n, x, y, z_max, radii, shapes):
    """``n`` asperities at random in ``x`` by ``y`` (mm, ranges), heights up to ``z_max``,
    radii in the range ``radii``, shapes in the order given."""
    return [
        Asperity(float(a), float(b), float(c), float(R), shape)
        for a, b, c, R, shape in zip(
            rng.uniform(*x, n), rng.uniform(*y, n), rng.uniform(0, z_max, n), rng.uniform(*radii, n), shapes
        )
    ]


def test_windowed_sampling_equals_sampling_every_cell():
    rng = np.random.default_rng(3)
    grid = Grid.covering(-5.0, 5.0, -4.0, 4.0, 0.1)
    asps = scattered(rng, 25, (-7, 7), (-6, 6), 0.2, (0.3, 3.0), ["sphere"] * 20 + ["paraboloid"] * 5)
    asps.append(Asperity(20.0, 0.0, 0.0, 1.0))  # a sphere that misses the grid
    height, owner = every_tip_on_every_cell(grid, asps)
    s = surface_on(grid, asps)
    assert np.array_equal(s.height, height)
    assert np.array_equal(s.owner, owner)
    assert s.n_asperities == len(asps)


def test_batched_sampling_equals_one_by_one_with_ties(monkeypatch):
    """Small grids sample their spheres and paraboloids together (``SAMPLE_BATCH``): the
    same heights and owners as one asperity at a time, a tie going to the earlier index,
    batches split anywhere."""
    import twoscale.indenters as ind

    rng = np.random.default_rng(5)
    grid = Grid.covering(-1.0, 1.0, -1.0, 1.0, 0.05)
    asps = scattered(rng, 40, (-2, 2), (-2, 2), 0.1, (0.2, 2.0), ["sphere", "paraboloid"] * 20)
    asps += [asps[3], asps[6], Asperity(0.0, 0.0, 0.09, 1e9, "paraboloid")]  # exact ties, a flat one
    batched = surface_on(grid, asps)
    monkeypatch.setattr(ind, "SAMPLE_BATCH", 7 * grid.size)  # batches of 7: below the minimum
    one_by_one = surface_on(grid, asps)
    monkeypatch.setattr(ind, "SAMPLE_BATCH", 9 * grid.size)  # batches of 9, split anywhere
    split = surface_on(grid, asps)
    owners = set(np.unique(one_by_one.owner).tolist())
    assert {3, 6, 42} <= owners and not {40, 41} & owners
    for other in (batched, split):
        assert np.array_equal(other.height, one_by_one.height)
        assert np.array_equal(other.owner, one_by_one.owner)


@pytest.mark.parametrize("shapes", [("sphere",), ("paraboloid",), ("sphere", "paraboloid")])
def test_a_large_box_sampled_tile_by_tile_from_the_tip_arrays_equalsevery_tip_on_every_cell(shapes, monkeypatch):
    """A union box of plain tips is sampled tile by tile from the table's arrays
    (``TipTable.sample``, one formula a shape, squared distances per axis): the owners of
    every asperity evaluated on every cell (a tie going to the earlier index), and their
    heights to rounding."""
    from twoscale.micro import sampling
    from twoscale.micro.patches import TipTable
    from twoscale.micro.sampling import SAMPLE_WHOLE_CELLS, box_surface

    monkeypatch.setattr(sampling, "WINDOW_SETUP", math.inf)  # never sphere by sphere

    rng = np.random.default_rng(7)
    grid = Grid.covering(-3.0, 3.0, -3.0, 3.0, 0.02)
    assert grid.size > SAMPLE_WHOLE_CELLS
    n = 60
    asps = scattered(rng, n, (-3.5, 3.5), (-3.5, 3.5), 0.05, (0.3, 2.0), [shapes[k % len(shapes)] for k in range(n)])
    asps.append(asps[5])  # an exact tie: the earlier index keeps the cells
    height, owner = every_tip_on_every_cell(grid, asps)
    table = TipTable(asps)
    assert table.plain
    s = box_surface(grid, table)
    assert np.array_equal(s.owner, owner)
    # the tiles' own cell centres: the heights to rounding
    assert np.array_equal(np.isinf(s.height), np.isinf(height))
    finite = np.isfinite(height)
    assert np.allclose(s.height[finite], height[finite], rtol=0.0, atol=1e-12)
    assert 5 in owner and n not in owner


def test_a_large_box_of_small_spheres_is_sampled_sphere_by_sphere_asevery_tip_on_every_cell(monkeypatch):
    """Spheres whose windows together are small against the box are sampled one by one on
    them (``WINDOW_SETUP``), on the box's own cell centres: the owners and the heights of
    every sphere evaluated on every cell, a tie going to the earlier index."""
    import twoscale.indenters as ind
    from twoscale.micro import sampling
    from twoscale.micro.patches import TipTable

    rng = np.random.default_rng(9)
    grid = Grid.covering(-3.0, 3.0, -3.0, 3.0, 0.02)
    asps = scattered(rng, 300, (-3.2, 3.2), (-3.2, 3.2), 0.02, (0.05, 0.3), ["sphere"] * 300)
    asps.append(asps[7])  # an exact tie: the earlier index keeps the cells
    table = TipTable(asps)
    cost = sampling.WINDOW_SETUP * len(asps) + sampling.WINDOW_SHARE * ind.window_cells(grid, table)
    assert grid.size > sampling.SAMPLE_WHOLE_CELLS and cost < grid.size
    calls = []
    monkeypatch.setattr(sampling, "surface_by_windows", lambda g, a: calls.append(g) or ind.surface_by_windows(g, a))
    s = sampling.box_surface(grid, table)
    height, owner = every_tip_on_every_cell(grid, asps)
    assert calls == [grid]
    assert np.array_equal(s.owner, owner) and np.array_equal(s.height, height)
    assert 7 in owner and len(asps) - 1 not in owner


def test_spheres_sampled_at_once_on_their_windows_equal_every_sphere_on_every_cell_over_a_prior_surface(monkeypatch):
    """Plain spheres on their windows all at once (``_sphere_windows``): spheres over the
    grid's edges, one missing it, exact ties among them and with a surface already there
    (its cells kept on a tie), in a non-increasing order of indices: the heights and owners
    of every sphere evaluated on every cell in that order."""
    import twoscale.indenters as ind

    at_once = ind._sphere_windows
    rng = np.random.default_rng(11)
    grid = Grid.covering(-2.0, 2.0, -1.5, 1.5, 0.05)
    asps = scattered(rng, 80, (-2.3, 2.3), (-1.8, 1.8), 0.05, (0.05, 0.4), ["sphere"] * 80)
    asps += [asps[4], Asperity(9.0, 0.0, 0.0, 0.3)]
    X, Y = grid.centres()
    prior = np.where(X > 0.5, 0.02, np.inf)  # another indenter's heights on part of the grid
    prior[np.isfinite(asps[10].height(X, Y))] = asps[10].height(X, Y)[np.isfinite(asps[10].height(X, Y))]
    order = list(range(len(asps)))[::-1]
    height, owner = prior.copy(), np.full(grid.shape, -1)
    for k in order:
        hk = asps[k].height(X, Y)
        better = hk < height
        height[better], owner[better] = hk[better], k
    got_h, got_o = prior.copy(), np.full(grid.shape, -1)
    calls = []
    monkeypatch.setattr(ind, "_sphere_windows", lambda *a: calls.append(1) or at_once(*a))
    ind._sample_windows(grid, X, Y, asps, order, got_h, got_o)
    assert calls == [1]  # (windows of about 100 cells: at once)
    assert np.array_equal(got_h, height) and np.array_equal(got_o, owner)
    # asps[80] is asps[4], earlier in this order: it keeps their cells; asps[81] misses the grid
    assert 80 in owner and 4 not in owner and 81 not in owner and len(np.unique(owner)) > 40
    assert np.any((owner == -1) & np.isfinite(prior))  # the prior surface kept where lower or tied
