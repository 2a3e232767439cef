"""The window CG's stone-block preconditioner (twoscale.rolling.blocks): its application
against the dense inverse of the operator it stands for, and rolled positions
preconditioned by it against the circulant inverse's (the same contact, fewer
iterations)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import Surface
from twoscale.influence import HalfSpace
from twoscale.influence.cached import with_caches
from twoscale.reference import solve_cg
from twoscale.rolling.blocks import StoneBlocks
from twoscale.rolling.window import KeptBody

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)


def test_the_blocks_invert_the_stones_exactly_and_couple_them_by_their_centroids():
    """On three stones' loaded cells: D (the operator within each stone) plus Z K Z^T (the
    point compliance between the stones' centroids times h^2 for every pair of cells of two
    stones), built densely from the half-space's Love blocks and inverted by numpy."""
    g = Grid(-1.0, -0.8, 0.1, 20, 16)
    owner = np.zeros(g.shape, int)
    owner[:, 10:] = 1
    owner[12:, 14:] = 2
    rng = np.random.default_rng(3)
    on = rng.random(g.shape) < 0.4
    gap = rng.standard_normal(g.shape) * on
    blocks = StoneBlocks(KeptBody(HS))
    got = blocks(Surface(g, np.zeros(g.shape), owner, 3)).apply(gap, on)
    cells = np.flatnonzero(on.ravel())
    x, y = (c.ravel()[cells] for c in g.centres())
    stone = owner.ravel()[cells]
    a = HS.grid_matrix(g)[np.ix_(cells, cells)]
    cx = np.array([x[stone == k].mean() for k in range(3)])
    cy = np.array([y[stone == k].mean() for k in range(3)])
    k = HS.point_compliance(np.column_stack([cx, cy]), np.column_stack([cx, cy])) * g.h**2
    np.fill_diagonal(k, 0.0)
    same = stone[:, None] == stone[None, :]
    approx = np.where(same, a, k[stone[:, None], stone[None, :]])
    want = np.linalg.solve(approx, gap.ravel()[cells])
    # the blocks are applied in float32: to its rounding times the operator's condition
    tol = np.linalg.cond(approx) * np.finfo(np.float32).eps * np.abs(want).max()
    assert np.abs(got.ravel()[cells] - want).max() <= tol
    assert np.count_nonzero(got.ravel()[~on.ravel()]) == 0


def test_the_blocks_are_the_same_through_a_caching_body_and_for_any_stone_numbers():
    """Eighty stones of 4 x 4 cells: the application through a solver's caching wrapper of
    the half-space equals the bare half-space's (to rounding: the wrapper's kernel table is
    its own), and the wrapper keeps no
    compliance among the centroids (they never repeat: the blocks ask the body itself); the
    stones numbered past 2^15 (no 16-bit sort keys) give the same application too."""
    g = Grid(0.0, 0.0, 0.1, 40, 32)
    owner = (np.arange(g.ny)[:, None] // 4) * 10 + np.arange(g.nx)[None, :] // 4
    rng = np.random.default_rng(5)
    on = rng.random(g.shape) < 0.5
    gap = rng.standard_normal(g.shape) * on
    bare = StoneBlocks(KeptBody(HS))(Surface(g, np.zeros(g.shape), owner, 80)).apply(gap, on)
    cached = with_caches(HS)
    through = StoneBlocks(KeptBody(cached))(Surface(g, np.zeros(g.shape), owner, 80)).apply(gap, on)
    assert np.allclose(through, bare, rtol=1e-9, atol=1e-9 * np.abs(bare).max())
    assert cached.caches.operators.get(("compliance",)) is None
    far = StoneBlocks(KeptBody(HS))(Surface(g, np.zeros(g.shape), owner + 40_000, 40_080)).apply(gap, on)
    assert np.array_equal(far, bare)
    assert np.count_nonzero(bare) == np.count_nonzero(on & (gap != 0))


def test_the_blocks_on_a_part_of_the_grid_apply_as_on_the_grid():
    """``on_part(cells)`` (the CG's part: rows of those cells in and out) gives the grid's
    answer on the part, for a first build and for cells entering since it (the kernel's
    diagonal on those), and after the grid's application (rebuilt for the other rows)."""
    g = Grid(-1.0, -0.8, 0.1, 20, 16)
    owner = np.zeros(g.shape, int)
    owner[:, 10:] = 1
    rng = np.random.default_rng(5)
    part = np.flatnonzero(rng.random(g.size) < 0.6)
    on = np.zeros(g.size, bool)
    on[part[rng.random(part.size) < 0.5]] = True
    more = on.copy()
    more[part[~on[part]][:3]] = True  # three cells enter: no rebuild
    gap = rng.standard_normal(g.size)
    surface = Surface(g, np.zeros(g.shape), owner, 2)
    grid, rows = StoneBlocks(KeptBody(HS))(surface), StoneBlocks(KeptBody(HS))(surface).on_part(part)
    for loaded in (on, more):
        want = grid.apply((gap * loaded).reshape(g.shape), loaded.reshape(g.shape)).ravel()
        got = rows(gap[part] * loaded[part], loaded[part])
        assert np.count_nonzero(want) == np.count_nonzero(loaded)
        assert np.array_equal(got, want[part])
    mixed = StoneBlocks(KeptBody(HS))(surface)
    mixed.apply((gap * on).reshape(g.shape), on.reshape(g.shape))
    assert np.array_equal(mixed.on_part(part)(gap[part] * on[part], on[part]), rows(gap[part] * on[part], on[part]))


def test_a_stone_kept_across_positions_is_updated_to_its_new_cells():
    """A stone of ~200 loaded cells (a disc) rolled by 3 cells between two solves, gaining
    two cells and losing two: its kept inverse updated by the Schur complements applies
    as the inverse computed afresh on the new cells does (and as numpy's dense solve)."""
    g = Grid(-2.0, -2.0, 0.1, 40, 40)
    X, Y = g.centres()
    rng = np.random.default_rng(7)
    first = X**2 + Y**2 < 0.8**2
    second = np.roll(first, 3, axis=1)
    rows, cols = np.nonzero(second)
    second[rows[0], cols[0]] = second[rows[-1], cols[-1]] = False  # two lost...
    second[rows[0] - 1, cols[0]] = second[rows[-1] + 1, cols[-1]] = True  # ...two gained
    surface = Surface(g, np.zeros(g.shape), np.zeros(g.shape, int), 1)
    gap = rng.standard_normal(g.shape)
    blocks = StoneBlocks(KeptBody(HS))
    blocks(surface, np.array([7]), 0).apply(gap, first)
    got = blocks(surface, np.array([7]), 3).apply(gap, second)
    assert blocks.updated == 1 and blocks.built == 1
    afresh = StoneBlocks(KeptBody(HS))
    fresh = afresh(surface).apply(gap, second)
    cells = np.flatnonzero(second.ravel())
    a = HS.grid_matrix(g)[np.ix_(cells, cells)]
    want = np.linalg.solve(a, gap.ravel()[cells])
    # applied in float32: to its rounding times the block's condition
    tol = np.linalg.cond(a) * np.finfo(np.float32).eps
    assert np.abs(fresh.ravel()[cells] - want).max() <= tol * np.abs(want).max()
    assert np.abs(got - fresh).max() <= tol * np.abs(fresh).max()
    # the kept inverses themselves (float64): the update is exact to rounding
    updated, made = blocks._kept[7][1], afresh._kept[0][1]
    assert np.abs(updated - made).max() <= 1e-10 * np.abs(made).max()


def _operator_entries(width: int = 41):
    """The half-space's offset table on a 41 x 41 grid of 0.1 mm cells (flat) and its
    centre's place: ``entries[centre + flat_i - flat_j]`` the operator's entry."""
    g = Grid(0.0, 0.0, 0.1, width, width)
    table = KeptBody(HS).grid_operator(g).op.offset_table()
    return table.ravel(), (width - 1) * table.shape[1] + (width - 1), table.shape[1]


@pytest.mark.parametrize(
    "lost, gained",
    [((0,), ()), ((0, 1, 57, 136), ()), ((), (0,)), ((), (0, 60, 143)), ((5, 136), (0, 61)), ((58,), (60,))],
)
def test_an_updated_inverse_is_the_inverse_of_the_new_cells(lost, gained):
    """:func:`~twoscale.rolling.inverses.updated`, cells lost (the first, the last, a run)
    and gained (before the first, between, after the last) alone or together: the
    inverse of the operator on the new cells, full (both triangles) and zero-padded to its
    size class, and its row sums, as :func:`~twoscale.rolling.inverses.fresh_blocks` makes
    it afresh (and numpy's dense inverse)."""
    from twoscale.rolling.inverses import fresh_blocks, size_class, updated

    entries, centre, width = _operator_entries()
    rows, cols = np.divmod(np.arange(144), 12)
    every = rows * width + cols  # a 12 x 12 patch's places in the table's rows, sorted
    old = np.delete(every[1:140], [59, 60])  # 137 cells: every[0], [60], [61], [140:] free
    new = np.union1d(np.delete(old, list(lost)), every[list(gained)])
    ((inverse, _),) = fresh_blocks(entries, centre, [old])
    got = updated(old, inverse, new, new, entries, centre)
    ((want, sums),) = fresh_blocks(entries, centre, [new])
    n = new.size
    assert got is not None and got[0].shape == (size_class(n),) * 2
    assert np.abs(got[0] - want).max() <= 1e-9 * np.abs(want).max()
    assert not np.any(got[0][n:]) and not np.any(got[0][:, n:])
    np.testing.assert_allclose(got[1], sums, rtol=0, atol=1e-9 * np.abs(sums).max())
    dense = np.linalg.inv(entries[centre + new[:, None] - new[None, :]])
    np.testing.assert_allclose(want[:n, :n], dense, rtol=0, atol=1e-9 * np.abs(dense).max())
    np.testing.assert_allclose(sums, dense.sum(axis=1), rtol=0, atol=1e-9 * np.abs(sums).max())


@pytest.mark.parametrize("load", [{"total_load": 150.0}, {"penetration": 1.2}])
def test_rolled_positions_are_the_same_with_fewer_iterations(load):
    """A tyre rolled over a chip-seal strip (stones well apart, ~50 cells of contact each):
    each warm-started position preconditioned by the stones' blocks ends where the one
    preconditioned by the circulant inverse does, in fewer CG iterations over the run."""
    from twoscale.rolling import RollingOptions, RollingSpec, road_strip
    from twoscale.rolling.run import step
    from twoscale.rolling.track import prepare
    from twoscale.rolling.window import WindowState
    from twoscale.scene import Scene
    from twoscale.surface import RawMap, build_surface

    road = build_surface(RawMap(road_strip(70.0, 30.0, 0.25, seed=5), spacing=0.25, units="mm"))
    spec = RollingSpec(start=-3.0, end=2.0, step=1.0, speed=30.0, tyre_radius=200.0, footprint=(40.0, 25.0))
    track = prepare(Scene(material=MAT, surface=road, rolling=spec, **load))
    options = RollingOptions(solver="window")
    runs = {}
    for name in ("circulant", "stones"):
        body = KeptBody(track.provider)
        state = WindowState(body, blocks=StoneBlocks(body) if name == "stones" else None)
        previous, runs[name] = None, []
        for k in range(len(track.shifts)):
            previous = step(track, k, previous, options, state)
            runs[name].append(previous.result)
    for a, b in zip(runs["circulant"], runs["stones"]):
        assert a.converged and b.converged
        p, q = a.fields[0].pressure, b.fields[0].pressure
        assert np.abs(p - q).max() <= 1e-6 * p.max()
        assert a.penetration == pytest.approx(b.penetration, abs=1e-8)
    its = {name: sum(r.iterations["cg"] for r in run[2:]) for name, run in runs.items()}
    assert its["stones"] < 0.8 * its["circulant"], its


def test_a_contact_too_large_for_a_block_takes_the_circulant_inverse(monkeypatch):
    """A sphere's contact of more cells than a block may have: the solve runs on the
    circulant inverse (the same iterations as asked for it directly)."""
    import twoscale.rolling.blocks as blocks

    monkeypatch.setattr(blocks, "MAX_BLOCK_CELLS", 50)
    g = Grid(-1.6, -1.6, 0.1, 32, 32)
    x, y = g.centres()
    surf = Surface(g, (x**2 + y**2) / 10.0, np.zeros(g.shape, int), 1)
    body = KeptBody(HS)
    circ = solve_cg(body, surf, total_load=5.0, precondition=True)
    pc = StoneBlocks(body)
    fallback = solve_cg(body, surf, total_load=5.0, precondition=True, preconditioner=pc)
    assert fallback.converged and fallback.iterations == circ.iterations


def _two_stones_settling():
    """Two stones on a 20 x 16 grid, a wide contact over 60 cells of the first and a small
    one under it on both: ``(grid, surface, x, y, wide, small)``."""
    g = Grid(-1.0, -0.8, 0.1, 20, 16)
    owner = np.zeros(g.shape, int)
    owner[:, 10:] = 1
    surface = Surface(g, np.zeros(g.shape), owner, 2)
    x, y = g.centres()
    wide, small = (x**2 + y**2 < 0.7**2), (x + 0.5) ** 2 + y**2 < 0.35**2
    small |= (x - 0.5) ** 2 + y**2 < 0.3**2
    return g, surface, x, y, wide, small


def test_a_contact_settled_small_enough_takes_the_blocks_again(monkeypatch):
    """A contact too large for the blocks at first (a first position's geometric start) runs
    on the circulant inverse while it shrinks, and on the blocks once it has settled below
    the cells they may have: then as a fresh solve's blocks on that contact."""
    import twoscale.rolling.blocks as blocks

    monkeypatch.setattr(blocks, "MAX_BLOCK_CELLS", 60)
    g, surface, x, y, wide, small = _two_stones_settling()
    assert np.count_nonzero(wide & (surface.owner == 0)) > 60 and np.count_nonzero(small & (surface.owner == 0)) <= 60
    gap = np.random.default_rng(5).standard_normal(g.shape)
    body = KeptBody(HS)
    pc = StoneBlocks(body)(surface)
    circulant = body.grid_operator(g).preconditioner().apply
    assert np.array_equal(pc.apply(gap * wide, wide), circulant(gap * wide))  # too large: circulant
    assert np.array_equal(pc.apply(gap * small, small), circulant(gap * small))  # still shrinking
    fresh = StoneBlocks(KeptBody(HS))(surface).apply(gap * small, small)
    assert pc.circulant is not None and np.array_equal(pc.apply(gap * small, small), fresh)  # settled
    assert pc.circulant is None and not np.array_equal(fresh, circulant(gap * small))


def test_blocks_built_while_the_contact_settles_are_built_once_more_when_it_has(monkeypatch):
    """Blocks taken up again on a contact still settling (above) take the cells it gains by
    the kernel's diagonal while it moves, are built once more on its cells when it has
    settled (the same count twice), as a fresh solve's, and not again after that."""
    import twoscale.rolling.blocks as blocks

    monkeypatch.setattr(blocks, "MAX_BLOCK_CELLS", 60)
    g, surface, x, y, wide, small = _two_stones_settling()
    grown = small | ((x + 0.5) ** 2 + y**2 < 0.42**2) & (y > 0.0)  # a few cells more
    moved = grown.copy()
    moved[np.unravel_index(np.flatnonzero((grown & (x < 0.0)).ravel())[0], g.shape)] = False
    moved[np.unravel_index(np.flatnonzero((~grown & (x < 0.0) & (y > 0.5)).ravel())[0], g.shape)] = True
    assert np.count_nonzero(grown) > np.count_nonzero(small) and np.count_nonzero(moved) == np.count_nonzero(grown)
    gap = np.random.default_rng(5).standard_normal(g.shape)

    def fresh(on):
        return StoneBlocks(KeptBody(HS))(surface).apply(gap * on, on)

    pc = StoneBlocks(KeptBody(HS))(surface)
    for on in (wide, small, small):  # the circulant inverse, then the blocks on ``small``
        pc.apply(gap * on, on)
    assert not np.array_equal(pc.apply(gap * grown, grown), fresh(grown))  # still moving: the diagonal
    assert np.array_equal(pc.apply(gap * grown, grown), fresh(grown))  # settled: built once more
    assert not np.array_equal(pc.apply(gap * moved, moved), fresh(moved))  # not again
