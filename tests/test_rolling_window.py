"""The rolling path on a kept window (twoscale.rolling.window): the same answers as the
two-scale solver per position, its FFT operator built once for the run, the start the
previous pressures moved with the road by whole cells."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.rolling import RollingOptions, RollingSpec, road_strip, roll
from twoscale.rolling.boxes import CUT_MARGIN_CELLS, CUT_SIDE_MARGIN_CELLS, cut_grid
from twoscale.rolling.window import WindowState, fast_grid
from twoscale.scene import Scene
from twoscale.surface import RawMap, build_surface

MAT = Material(10.0, 0.5)


@pytest.fixture(scope="module")
def strip():
    return build_surface(RawMap(road_strip(60.0, 20.0, 0.25, seed=3), spacing=0.25, units="mm"))


class CountingHalfSpace(HalfSpace):
    """A half-space that counts the square FFT operators asked of it."""

    def __init__(self, material):
        super().__init__(material)
        self.square = 0

    def grid_operator(self, target, source=None):
        if source is None or source == target:
            self.square += 1
        return super().grid_operator(target, source)


@pytest.mark.parametrize("load", [{"total_load": 60.0}, {"penetration": 0.9}])
def test_window_and_two_scale_give_the_same_positions(strip, load):
    """Two solvers of the same static problems: the window's CG and the two-scale solver."""
    spec = RollingSpec(start=-6.0, end=-3.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    scene = Scene(material=MAT, surface=strip, rolling=spec, **load)
    window = roll(scene, options=RollingOptions(solver="window"))
    two = roll(scene, options=RollingOptions(solver="twoscale"))
    assert window.all_converged and two.all_converged
    np.testing.assert_allclose(window.total_load, two.total_load, rtol=1e-5)
    np.testing.assert_allclose(window.penetration, two.penetration, atol=1e-6)
    np.testing.assert_allclose(window.contact_area, two.contact_area, atol=2 * 0.25**2)
    np.testing.assert_allclose(window.drag, two.drag, atol=1e-4 * np.max(two.total_load))


def test_the_operator_is_built_once_for_the_run(strip):
    """Load control: the window holds from position to position, so the body builds its
    FFT operator once (or again only when the contact leaves the window); the cut's is
    made from the window's offset table, not asked of the body again."""
    spec = RollingSpec(start=-6.0, end=0.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    body = CountingHalfSpace(MAT)
    run = roll(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0), provider=body)
    assert run.all_converged and len(run.shifts) == 7
    assert body.square == 1


@pytest.mark.parametrize("load", [{"total_load": 60.0}, {"penetration": 0.9}])
def test_every_window_position_is_the_classical_static_solve(strip, load):
    """Each warm-started position (float32 search directions, column corrections, kept
    conjugate directions, solved on a cut of the window and checked on all of it) against
    Polonsky & Keer's classical CG from cold, in double precision, on the whole window
    (every cell the stones can touch) and the same stones: the same pressure to the
    tolerance's scale."""
    from twoscale.rolling.run import step, window_state
    from twoscale.rolling.track import prepare

    spec = RollingSpec(start=-6.0, end=-2.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    track = prepare(Scene(material=MAT, surface=strip, rolling=spec, **load))
    options = RollingOptions(solver="window")
    state, previous = window_state(track, options), None
    cut = []
    for k in range(len(track.shifts)):
        pos = step(track, k, previous, options, state)
        _assert_classical(track, pos, state.grid, load, k)
        cut.append(pos.result.fields[0].grid.size < state.grid.size)
        previous = pos
    assert any(cut)  # the later positions were solved on a cut


def _assert_classical(track, pos, window, load, k):
    from twoscale.indenters import surface_on
    from twoscale.reference import solve_cg

    assert pos.result.converged, pos.result.message
    ref = solve_cg(track.provider, surface_on(window, pos.selection.stones), tol=1e-10, **load)
    f = pos.result.fields[0]
    p, pr = f.grid.embed_in(f.pressure, window), ref.fields[0].pressure
    # the run stops at a KKT residual of 1e-8 (pressure within ~2e-7 of the exact
    # discrete answer, measured 3e-9 - 1.5e-8 here); a run that stopped on float32
    # products (rounding ~1e-7 of the largest displacement) is 5e-7 off
    assert np.linalg.norm(p - pr) <= 1e-7 * np.linalg.norm(pr), k
    assert pos.result.penetration == pytest.approx(ref.penetration, abs=2e-9)
    assert pos.result.total_load == pytest.approx(ref.total_load, rel=1e-7)


def test_the_first_position_is_solved_on_the_cut_over_the_estimated_footprint(strip):
    """With no last contact, the first position is solved on the window's columns over the
    tyre's estimated footprint (with a margin) and the rows of the cells that can touch
    (with the side's margin), not on the whole window (its operator is then the second
    position's when the contact fills it), checked on the window: the classical static
    solve all the same. Without the estimate, the whole window."""
    from twoscale.rolling.run import step, window_state
    from twoscale.rolling.track import prepare, tyre_contact_length

    spec = RollingSpec(start=-6.0, end=-5.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    load = {"total_load": 60.0}
    track = prepare(Scene(material=MAT, surface=strip, rolling=spec, **load))
    options = RollingOptions(solver="window")
    state = window_state(track, options)
    half = 0.5 * tyre_contact_length(track)
    assert state.footprint == pytest.approx((-half, half))
    first = step(track, 0, None, options, state)
    g = first.result.fields[0].grid
    assert g.ny <= state.grid.ny and g.nx < state.grid.nx
    rows = np.flatnonzero((first.result.fields[0].pressure > 0.0).any(axis=1))
    assert rows[0] >= CUT_SIDE_MARGIN_CELLS and rows[-1] < g.ny - CUT_SIDE_MARGIN_CELLS
    assert g.x0 <= -half and g.x0 + g.nx * g.h >= half
    _assert_classical(track, first, state.grid, load, 0)
    whole = window_state(track, options)
    whole.footprint = None
    assert step(track, 0, None, options, whole).result.fields[0].grid == whole.grid


def test_a_cut_too_small_is_found_by_the_check_and_grown(strip):
    """The cut is built around the last contact; when it leaves out cells that touch, the
    check on the whole window finds them and the position is solved again on a cut that
    takes them in: here the last contact is made a single cell, so the first cut misses
    almost all of the contact, and the answer is still the classical static solve."""
    from twoscale.rolling.run import step, window_state
    from twoscale.rolling.track import prepare

    spec = RollingSpec(start=-6.0, end=-5.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    load = {"total_load": 60.0}
    track = prepare(Scene(material=MAT, surface=strip, rolling=spec, **load))
    options = RollingOptions(solver="window")
    state = window_state(track, options)
    first = step(track, 0, None, options, state)
    f = first.result.fields[0]
    one = np.zeros(f.grid.shape)
    rows, cols = np.nonzero(f.pressure)
    middle = np.argmin(np.hypot(rows - f.grid.ny / 2, cols - f.grid.nx / 2))  # the loaded cell nearest the middle
    one[rows[middle], cols[middle]] = f.pressure.sum()
    state.past, state.cut = [(f.grid, one, float(track.shifts[0]))], None
    small = state.cut_in(state.grid)
    assert small.size < 0.25 * state.grid.size
    pos = step(track, 1, first, options, state)
    assert pos.result.fields[0].grid.size > small.size
    _assert_classical(track, pos, state.grid, load, 1)


def test_start_is_the_pressure_moved_by_whole_cells():
    """A pressure moved with the road by two steps of 3 cells; two positions give the linear
    extrapolation in the road's frame (clipped at 0)."""
    g = Grid(-2.0, -1.0, 0.5, 12, 5)
    p = np.zeros(g.shape)
    p[2, 4] = 3.0
    state = WindowState(body=None, grid=g)
    state.past = [(g, p, 0.0)]
    moved = state.start(g, 1.5)
    assert moved[2, 7] == 3.0 and moved.sum() == 3.0
    q = np.zeros(g.shape)
    q[2, 7] = 4.0  # the same cell of the road one step later carries 4
    state.past = [(g, p, 0.0), (g, q, 1.5)]
    ahead = state.start(g, 3.0)
    assert ahead[2, 10] == pytest.approx(5.0) and ahead.sum() == pytest.approx(5.0)


def test_a_cell_whose_gap_closes_starts_loaded():
    """Two answers kept one step (3 cells) apart: a road cell off the contact whose gap fell
    from 3 to 1 um is extrapolated to -1 um, a pressure of 1 um times GAP_STIFFNESS over a
    cell's self-compliance; one whose gap stays or opens starts unloaded, a loaded cell
    keeps the pressures' extrapolation."""
    from types import SimpleNamespace

    from twoscale.rolling.window import GAP_STIFFNESS, KeptBody

    g = Grid(-2.0, -1.0, 0.5, 12, 5)
    state = WindowState(body=KeptBody(HalfSpace(MAT)), grid=g)
    for shift, gap, p in ((0.0, (3e-3, 2e-3, 0.0), 2.0), (1.5, (1e-3, 2e-3, 0.0), 3.0)):
        gaps, pressure = np.full(g.shape, 5e-3), np.zeros(g.shape)
        at = 2 + int(shift / 0.5)  # the road's cells 2, 3 and 4 of the first answer, moved
        gaps[1, at], gaps[2, at] = gap[:2]
        pressure[3, at + 2] = p  # a loaded cell
        gaps[3, at + 2] = 0.0
        field = SimpleNamespace(grid=g, pressure=pressure, gap=gaps)
        state.keep(SimpleNamespace(fields=[field]), shift)
    start = state.start(g, 3.0)
    a00 = HalfSpace(MAT).self_compliance(g.h)
    assert start[1, 8] == pytest.approx(1e-3 * GAP_STIFFNESS / a00)
    assert start[2, 8] == 0.0 and start[3, 10] == pytest.approx(4.0)
    assert np.count_nonzero(start) == 2


def test_window_sides_are_fft_friendly():
    g = fast_grid(Grid(0.0, 0.0, 0.25, 383, 617))
    assert (g.nx, g.ny) == (384, 625)
    assert g.x0 <= 0.0 and g.x0 + (g.nx - 1) * g.h >= 382 * 0.25


def test_a_cut_across_the_rolling_direction_is_as_wide_as_its_transform_allows():
    """The cut around a contact's box: along x the margin and a 5-smooth side; along y at
    least the side's margin, then the largest side with the same zero-padded transform
    length (the tyre's 601 loaded rows: 608 rows, a transform of 1215; 5-smooth, 625 and
    1250), centred on the box."""
    from scipy.fft import next_fast_len

    box = Grid(1.0, -75.0, 0.25, 285, 601)
    cut = cut_grid(box)
    assert (cut.nx, cut.ny) == (320, 608)
    assert next_fast_len(2 * cut.ny - 1, real=True) == 1215 < next_fast_len(2 * 625 - 1, real=True)
    assert next_fast_len(2 * cut.ny + 1, real=True) > 1215  # a row more: a longer transform
    rows, cols = box.window_in(cut)
    assert rows.start >= CUT_SIDE_MARGIN_CELLS and cut.ny - rows.stop >= CUT_SIDE_MARGIN_CELLS
    assert abs(rows.start - (cut.ny - rows.stop)) <= 1 and cols.start >= CUT_MARGIN_CELLS
    small = cut_grid(Grid(0.0, 0.0, 0.25, 20, 30))
    assert small.ny >= 30 + 2 * CUT_SIDE_MARGIN_CELLS and small.nx >= 20 + 2 * CUT_MARGIN_CELLS


def test_the_kept_operator_gives_the_cg_its_float32_operators_own_routes():
    """The window's kept float32 operator passes on the anchor's float64 product through
    its buffers (``exact``: the double-precision product to the bit) and the product on a
    part of the grid (``on_cells``: the grid's product at those cells, also in halves)."""
    from twoscale.rolling.window import KeptBody

    g = Grid(0.0, 0.0, 0.25, 40, 36)
    op = KeptBody(HalfSpace(MAT)).grid_operator(g)
    single = op.single_precision()
    p = np.random.default_rng(3).random(g.shape)
    assert single.exact is not None and np.array_equal(single.exact(p), op.apply(p))
    q = np.where(p > 0.5, 1.0 - p, 0.0)  # (the buffers kept from the first: still the product to the bit)
    assert np.array_equal(single.exact(q), op.apply(q))
    cells = np.flatnonzero(p.ravel() > 0.6)
    on = single.on_cells(cells)
    part = np.where(p > 0.6, p, 0.0)
    assert np.array_equal(on(p.ravel()[cells]), single.apply(part).ravel()[cells])
    halves = on.forward(p.ravel()[cells])
    assert halves.energy() == pytest.approx(float(part.ravel() @ op.apply(part).ravel()), rel=1e-6)


def test_unknown_solver_is_refused():
    with pytest.raises(ValueError, match="solver"):
        RollingOptions(solver="fast")


def test_stones_mapped_from_kept_samples_equal_a_fresh_roads(strip):
    """The road keeps each stone's samples while it is within reach: stones picked at
    shifts visited in any order (the kept samples dropped and gathered again) are those a
    road prepared afresh picks, summit, recess and reach table alike."""
    from twoscale.rolling.track import prepare

    spec = RollingSpec(start=-6.0, end=6.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    scene = Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0)
    kept = prepare(scene).road
    for shift in (-6.0, -5.0, 6.0, -6.0, 0.5):
        a, b = kept.stones_at(shift, 1.0), prepare(scene).road.stones_at(shift, 1.0)
        assert a.stones and np.array_equal(a.numbers, b.numbers)
        for s, t in zip(a.stones, b.stones):
            assert (s.x, s.y, s.z, s.extent) == (t.x, t.y, t.z, t.extent)
            assert np.array_equal(s.fall, t.fall) and np.array_equal(s.dist, t.dist)


def test_a_rolled_stone_made_at_once_is_the_constructors(strip):
    """``RolledStone.of`` (the fields written at once) gives the stone the constructor
    gives: every field the same object, the same type, the same reach."""
    import dataclasses

    from twoscale.rolling.stones import RolledStone
    from twoscale.rolling.track import prepare

    spec = RollingSpec(start=-6.0, end=-5.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    stone = (
        prepare(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0)).road.stones_at(-6.0, 1.0).stones[0]
    )
    values = [getattr(stone, f.name) for f in dataclasses.fields(RolledStone)]
    made, built = RolledStone.of(*values), RolledStone(*values)
    assert type(made) is RolledStone and vars(made).keys() == vars(built).keys()
    assert all(getattr(made, f.name) is getattr(built, f.name) for f in dataclasses.fields(RolledStone))
    assert made.reach(0.05) == built.reach(0.05) > 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.x = 0.0


def test_a_cut_grown_to_the_whole_window_shrinks_back_around_the_contact():
    g = fast_grid(Grid(-20.0, -10.0, 0.25, 160, 80))
    p = np.zeros(g.shape)
    p[30:50, 60:90] = 1.0  # the last contact: 20 x 30 cells
    state = WindowState(body=None, grid=g, cut=g)
    state.past = [(g, p, 0.0)]
    cut = state.cut_in(g)
    assert cut.size < 0.5 * g.size
    rows, cols = cut.window_in(g)
    assert p[rows, cols].sum() == p.sum()  # the contact inside, with a margin
    assert state.cut_in(g) == cut  # kept while the contact stays


def test_the_stones_of_a_flat_face_keep_their_reach_and_the_window_their_heights(strip):
    """A flat face (no tyre) wider than the strip, the road moved by 12 cells: every stone
    wholly inside the face's window is its segmented basin moved by the shift, so its
    summit is the basin's moved, and its reach at any depth is the basin's (``MapAsperity.reach``, the sorted
    table) although found on the unsorted samples; the stones' heights sampled on a grid
    of the map's lattice as windows of the map equal the look-up point by point."""
    from twoscale.indenters import surface_on
    from twoscale.rolling.track import prepare

    spec = RollingSpec(start=3.0, end=4.0, step=1.0, speed=30.0, footprint=(40.0, 30.0))
    track = prepare(Scene(material=MAT, surface=strip, rolling=spec, penetration=0.5))
    road, shift = track.road, 3.0
    selection = road.stones_at(shift, 2.0)
    inside = (road.box[:, 0] + shift > -19.0) & (road.box[:, 1] + shift < 19.0)
    assert np.count_nonzero(inside[selection.numbers]) > 20
    for k, stone in zip(selection.numbers, selection.stones):
        if not inside[k]:
            continue
        tip = road.tips[k]
        assert (stone.x, stone.y, stone.z) == (tip.x + shift, tip.y, tip.z)
        for depth in (1e-3, 0.05, 0.3, 1.0, np.inf):
            assert stone.reach(depth) == tip.reach(depth)
    grid = Grid(-20.0, -8.0, 0.25, 120, 64)
    fast = surface_on(grid, selection.stones)
    index = {s.label: n for n, s in enumerate(selection.stones)}
    height, owner = selection.stones[0].basins.union_on(*grid.centres(), index)
    assert np.array_equal(fast.height, height) and np.array_equal(fast.owner, owner)


def test_the_stones_reaches_at_once_are_each_stones(strip):
    """:func:`~twoscale.rolling.stones.reaches` (all the basins' samples in one pass) gives each
    stone's own ``reach`` at its own depth, none (0) at a depth of 0 or below, and takes
    other indenters one by one."""
    from twoscale.indenters import Asperity
    from twoscale.rolling.stones import reaches
    from twoscale.rolling.track import prepare

    spec = RollingSpec(start=-6.0, end=6.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    road = prepare(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0)).road
    stones = road.stones_at(0.5, 1.0).stones
    assert len(stones) > 10
    rng = np.random.default_rng(0)
    for depths in (rng.uniform(-0.1, 1.0, len(stones)), np.full(len(stones), np.inf), np.zeros(len(stones))):
        own = [s.reach(d) for s, d in zip(stones, depths)]
        assert reaches(stones, depths).tolist() == own
    assert not any(own) and max(reaches(stones, np.full(len(stones), 0.2))) > 0.5  # (depth 0: none)
    tips = [Asperity(0.0, 0.0, 0.0, 5.0), Asperity(2.0, 1.0, 0.1, 3.0)]
    assert reaches(tips, np.array([0.05, 0.2])).tolist() == [tips[0].reach(0.05), tips[1].reach(0.2)]


def test_a_window_covering_the_stones_extents_covers_their_reach_at_any_bound(strip):
    """The window's cover checked first on the basins' extents (:func:`covers_extents`): an
    extent is never less than the stone's reach at any depth, so a grid that covers the
    extents' box covers :func:`reference_grid` at every bound; a grid a few cells short of
    that box fails the check (the reach at the bound then decides)."""
    from twoscale.rolling.boxes import covers
    from twoscale.rolling.track import prepare
    from twoscale.rolling.reach import covers_extents, reach_grid, reference_grid

    spec = RollingSpec(start=-6.0, end=6.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    track = prepare(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0))
    selection = track.road.stones_at(0.5, 1.0)
    assert all(s.reach(np.inf) <= s.extent for s in selection.stones)
    grid = reach_grid(track, selection, np.array([s.extent for s in selection.stones]))
    assert covers_extents(grid, track, selection)
    for bound in (0.0, 0.3, 1.0, 10.0):
        assert covers(grid, reference_grid(track, selection, bound))
    short = Grid(grid.x0 + 2 * grid.h, grid.y0, grid.h, grid.nx - 2, grid.ny)
    assert not covers_extents(short, track, selection)


def test_thestones_surface_on_the_maps_lattice_is_surface_ons(strip):
    """The window's surface of the basins of one shifted map (:func:`stones_surface`: the
    map's windows themselves) is :func:`~twoscale.indenters.surface_on`'s, heights and
    owners alike, on the map's lattice (a grid partly off the strip too) and off it (the
    general sampling)."""
    from twoscale.indenters import surface_on
    from twoscale.rolling.track import prepare
    from twoscale.rolling.stones import stones_surface

    spec = RollingSpec(start=-6.0, end=6.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    road = prepare(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0)).road
    for shift in (-3.0, 2.0):
        stones = road.stones_at(shift, 1.0).stones
        assert len(stones) > 10
        for grid in (
            Grid(-20.0, -8.0, 0.25, 120, 64),
            Grid(-40.0, -14.0, 0.25, 200, 120),
            Grid(-20.1, -8.0, 0.25, 60, 32),
        ):
            mine, theirs = stones_surface(grid, stones), surface_on(grid, stones)
            assert np.isfinite(mine.height).any() and mine.n_asperities == theirs.n_asperities
            assert np.array_equal(mine.height, theirs.height) and np.array_equal(mine.owner, theirs.owner)
            assert mine.owner.dtype == theirs.owner.dtype
