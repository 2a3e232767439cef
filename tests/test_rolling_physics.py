"""Elastic rolling: each position equals a static solve of the road at that shift (built
here from the height array alone, without the driver's stones), the drag of a stone under
a tilted face has its closed form, and the mean drag over a periodic road is zero."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import Asperity, Surface
from twoscale.influence import HalfSpace
from twoscale.reference import solve_reference
from twoscale.rolling import RollingOptions, RollingSpec, road_strip, roll
from twoscale.scene import Scene
from twoscale.surface import RawMap, build_surface

MAT = Material(10.0, 0.5)


@pytest.fixture(scope="module")
def strip():
    return build_surface(RawMap(road_strip(60.0, 20.0, 0.25, seed=3), spacing=0.25, units="mm"))


def _static_on_map(surface, shift: float, spec: RollingSpec, **load):
    """The full-grid reference of the whole map moved by ``shift`` under the face: built from
    the conditioned heights only (recess below the highest sample, + the tyre's face, no
    material outside the footprint)."""
    hm = surface.hmap
    g = hm.grid
    grid = Grid(g.x0 + shift, g.y0, g.h, g.nx, g.ny)
    X, Y = grid.centres()
    recess = float(np.nanmax(hm.heights)) - hm.heights + spec.face(X)
    L, W = spec.footprint
    recess = np.where((np.abs(X) <= L / 2) & (np.abs(Y) <= W / 2), recess, np.inf)
    owner = np.where(np.isfinite(recess), 0, -1)
    result = solve_reference(HalfSpace(MAT), Surface(grid, recess, owner, 1), tol=1e-9, **load)
    rx = float(np.nanmax(hm.heights)) - hm.heights
    slope = np.gradient(rx, g.h, axis=1)
    drag = float(np.sum(result.fields[0].pressure * slope)) * g.h**2
    return result, drag


@pytest.mark.parametrize("load", [{"total_load": 60.0}, {"penetration": 0.9}])
def test_each_position_is_the_static_solve(strip, load):
    spec = RollingSpec(start=-6.0, end=-4.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    scene = Scene(material=MAT, surface=strip, rolling=spec, **load)
    run = roll(scene, options=RollingOptions(tol=1e-8))
    assert run.all_converged
    for k, s in enumerate(run.shifts):
        ref, drag = _static_on_map(strip, float(s), spec, **load)
        W = ref.total_load
        assert run.total_load[k] == pytest.approx(W, rel=1e-5)
        assert run.penetration[k] == pytest.approx(ref.penetration, abs=1e-6)
        # the contact area counts cells: one cell either way at most per stone's edge
        assert run.contact_area[k] == pytest.approx(ref.contact_area, abs=2 * 0.25**2)
        # the drag is a small difference of large terms: to the tolerance of the load
        assert run.drag[k] == pytest.approx(drag, abs=1e-4 * W)


def test_drag_of_a_stone_under_a_tilted_face():
    """A paraboloid of radius R at body x = c under a tyre of radius Rt: the gap
    (x - c)^2 / (2R) + x^2 / (2Rt) is a paraboloid about x* = c Rt / (R + Rt), so the
    pressure is Hertz's about x* and the drag, sum p (x - c) / R, is P (x* - c) / R =
    -P c / (R + Rt): the road pushes the body away from the tyre's lowest point."""
    R, Rt = 20.0, 400.0
    stone = Asperity(0.0, 0.0, 0.0, R, "paraboloid")
    spec = RollingSpec(start=-24.0, end=24.0, step=24.0, speed=10.0, tyre_radius=Rt, footprint=(200.0, 60.0))
    scene = Scene(material=MAT, asperities=(stone,), total_load=20.0, rolling=spec, h=0.1)
    run = roll(scene)
    assert run.all_converged
    for k, c in enumerate(run.shifts):
        assert run.drag[k] == pytest.approx(-20.0 * c / (R + Rt), rel=0.01, abs=1e-6 * 20.0)
    assert run.drag[0] > 0 > run.drag[2]


def _periodic_road(period: float, h: float, length: float, width: float) -> np.ndarray:
    """Bumps along x of period ``period`` (not symmetric: a second harmonic out of phase),
    in two rows across; an integer number of periods long."""
    x = (np.arange(int(round(length / h))) + 0.5) * h
    y = (np.arange(int(round(width / h))) + 0.5) * h
    X, Y = np.meshgrid(x, y)
    k = 2 * math.pi / period
    along = np.cos(k * X) + 0.45 * np.sin(2 * k * X + 0.9)
    return 0.6 * np.maximum(along, -0.2) * (0.6 + 0.4 * np.cos(2 * math.pi * Y / width))


def _periodic_run(h: float):
    period = 8.0
    surface = build_surface(RawMap(_periodic_road(period, h, 96.0, 16.0), spacing=h, units="mm"))
    spec = RollingSpec(
        start=-8.0, end=-8.0 + period - 0.5, step=0.5, speed=20.0, tyre_radius=20.0, footprint=(40.0, 16.0)
    )
    return roll(Scene(material=MAT, surface=surface, penetration=0.5, rolling=spec))


def test_mean_drag_over_a_periodic_road_is_zero():
    """Over one period of the road the body's elastic energy comes back, so the work of the
    drag, its mean times the period, is zero; on the grid the mean is a discretisation
    error that falls about as h^2 (measured: 7 %, 1.4 %, 0.4 % of the largest drag at
    h = 0.5, 0.25, 0.125 mm)."""
    coarse, fine = _periodic_run(0.25), _periodic_run(0.125)
    for run in (coarse, fine):
        assert run.all_converged
        assert len(run.shifts) == 16
    spread = float(np.max(np.abs(coarse.drag)))
    assert spread > 0.05 * float(np.mean(coarse.total_load))  # the drag does swing
    assert abs(coarse.mean_drag) < 0.02 * spread
    assert abs(fine.mean_drag) < 0.5 * abs(coarse.mean_drag)


@pytest.mark.slow
def test_block_positions_are_static_solves():
    """A finite block (bonded base): each position equals twoscale.solve of the tips moved
    by the shift on the same block (a flat face: the block's top face)."""
    import dataclasses

    import twoscale

    tips = tuple(
        Asperity(x, y, z, 8.0, "paraboloid")
        for x, y, z in [(-12, 0, 0), (-4, 5, 0.02), (4, -4, 0.05), (12, 3, 0.01), (20, -2, 0.0)]
    )
    spec = RollingSpec(start=-6.0, end=6.0, step=6.0, speed=20.0)
    scene = Scene(
        material=MAT,
        asperities=tips,
        total_load=30.0,
        rolling=spec,
        h=0.2,
        influence={"kind": "block", "size": (80.0, 40.0, 10.0), "base": "bonded"},
    )
    provider = scene.provider(progress=False)
    run = roll(scene, provider=provider)
    assert run.all_converged and run.body.startswith("block 80 x 40 x 10")
    for k, s in enumerate(run.shifts):
        moved = Scene(
            material=MAT,
            asperities=tuple(dataclasses.replace(a, x=a.x + s) for a in tips),
            total_load=30.0,
            h=0.2,
            influence=scene.influence,
        )
        static = twoscale.solve(moved, provider=provider)
        assert run.penetration[k] == pytest.approx(static.penetration, abs=1e-7)
        assert run.contact_area[k] == pytest.approx(static.contact_area, abs=1e-9)


def test_chunks_give_the_sequential_run(strip):
    """An elastic run split into chunks (each started cold) gives the sequential run's
    signals to the solver's tolerance, with the whole run's times and stone numbers."""
    from twoscale.rolling.chunks import roll_chunks

    spec = RollingSpec(start=-6.0, end=-3.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    scene = Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0)
    whole = roll(scene)
    split = roll_chunks(scene, chunks=2, scheduler="synchronous")
    assert np.array_equal(split.shifts, whole.shifts) and np.allclose(split.times, whole.times)
    assert np.allclose(split.penetration, whole.penetration, atol=1e-6)
    assert np.allclose(split.contact_area, whole.contact_area, atol=2 * 0.25**2)
    assert np.allclose(split.drag, whole.drag, atol=1e-4 * 60.0)
    assert np.array_equal(split.asperities.position, whole.asperities.position)
    assert np.array_equal(split.asperities.stone, whole.asperities.stone)
    assert split.line_load.shape[0] == 4
    assert np.allclose(split.line_load.sum(axis=1) * split.h, whole.line_load.sum(axis=1) * whole.h, rtol=1e-6)


@pytest.mark.slow
def test_strip_on_a_tread_block(strip):
    """A chip-seal strip under a bonded tread block (flat face: the block's top face): the
    window keeps every stone's patch inside the region the block answers for, and the load
    is carried at every position."""
    spec = RollingSpec(start=-6.0, end=-2.0, step=2.0, speed=30.0)
    scene = Scene(
        material=MAT,
        surface=strip,
        rolling=spec,
        total_load=100.0,
        influence={"kind": "block", "size": (50.0, 40.0, 10.0), "base": "bonded", "source_spacing": 2.0},
    )
    run = roll(scene)
    assert run.all_converged
    assert np.allclose(run.total_load, 100.0, rtol=1e-6)
    assert np.all(run.contact_area > 0)


def test_step_not_a_multiple_of_the_spacing_resamples_the_road(strip):
    """A 0.6 mm step on a 0.25 mm map: the road is resampled at 0.2 mm (three samples a
    step), and each position is the static solve of the resampled map at that shift."""
    spec = RollingSpec(start=-5.0, end=-3.8, step=0.6, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    run = roll(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0))
    assert run.h == pytest.approx(0.2)
    assert np.allclose(run.shifts, [-5.0, -4.4, -3.8])
    fine = strip.at(0.2)
    for k in (0, 2):
        ref, _ = _static_on_map(fine, float(run.shifts[k]), spec, total_load=60.0)
        assert run.penetration[k] == pytest.approx(ref.penetration, abs=1e-6)
        assert run.contact_area[k] == pytest.approx(ref.contact_area, abs=2 * 0.2**2)


def test_tips_whose_centre_leaves_the_window_do_not_touch():
    """Tips on the half-space under a flat footprint: a tip whose box overlaps the window
    but whose centre lies outside it (x = 13 mm against the window's end at 10 mm) stays out,
    as a static study's tips outside the footprint; each position is then the static
    twoscale.solve of the tips whose centre is inside, moved by the shift."""
    import dataclasses

    import twoscale

    tips = (
        Asperity(0.0, 0.0, 0.0, 3.0, "paraboloid"),
        Asperity(-5.0, 2.0, 0.05, 3.0, "paraboloid"),
        Asperity(13.0, 0.0, 0.0, 3.0, "paraboloid"),
    )
    spec = RollingSpec(start=-2.0, end=2.0, step=1.0, speed=20.0, footprint=(20.0, 10.0))
    run = roll(Scene(material=MAT, asperities=tips, penetration=0.3, rolling=spec, h=0.1))
    assert run.all_converged and len(run.shifts) == 5
    assert 3 not in set(run.asperities.stone.tolist())  # numbered from 1: the third tip
    for k, s in enumerate(run.shifts):
        inside = tuple(dataclasses.replace(a, x=a.x + s) for a in tips[:2])
        static = twoscale.solve(Scene(material=MAT, asperities=inside, penetration=0.3, h=0.1))
        assert run.total_load[k] == pytest.approx(static.total_load, rel=1e-5)


@pytest.mark.parametrize("solver", ["auto", "twoscale"])
def test_block_positions_take_the_stones_the_bulge_lifts(strip, tmp_path, monkeypatch, solver):
    """A bonded, incompressible tread block bulges beside its contacts: stones whose summits
    lie a little below the held approach touch all the same. Each position equals the
    full-grid reference of the whole strip moved by the shift on the same block (built from
    the height array alone, no material outside the face), whose contact reaches such a
    stone (measured: two at the first position, their summits 6 and 20 um beyond the approach).
    The same on the kept window's CG (the default) and on the two-scale path."""
    from twoscale.rolling.track import prepare

    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))
    spec = RollingSpec(start=-2.0, end=2.0, step=2.0, speed=30.0)
    block = {"kind": "block", "size": (60.0, 50.0, 8.0), "base": "bonded", "source_spacing": 4.0}
    scene = Scene(material=MAT, surface=strip, penetration=0.8, rolling=spec, influence=block)
    provider = scene.provider(progress=False)
    run = roll(scene, options=RollingOptions(tol=1e-8, solver=solver), provider=provider)
    assert run.method == ("window-cg" if solver == "auto" else "twoscale")
    x0, x1, y0, y1 = prepare(scene, provider=provider).road.window
    hm = strip.hmap
    g = hm.grid
    lifted = 0
    for k, s in enumerate(run.shifts):
        X, Y = Grid(g.x0 + float(s), g.y0, g.h, g.nx, g.ny).centres()  # the strip moved
        inside = (X >= x0 - 1e-9) & (X <= x1 + 1e-9) & (Y >= y0 - 1e-9) & (Y <= y1 + 1e-9)
        cols, rows = np.flatnonzero(inside.any(axis=0)), np.flatnonzero(inside.any(axis=1))
        cut = np.ix_(rows, cols)  # the cells on the face: the block answers there only
        grid = Grid(float(X[0, cols[0]]), float(Y[rows[0], 0]), g.h, len(cols), len(rows))
        recess = float(np.nanmax(hm.heights)) - hm.heights[cut]
        ref = solve_reference(
            provider, Surface(grid, recess, np.zeros(recess.shape, int), 1), penetration=0.8, tol=1e-10
        )
        assert run.total_load[k] == pytest.approx(ref.total_load, rel=1e-6)
        assert run.contact_area[k] == pytest.approx(ref.contact_area, abs=1e-9)
        labels = strip.segmentation.labels[cut]
        touched = np.unique(labels[(ref.fields[0].pressure > 0) & (labels >= 0)])
        summits = np.array([recess[labels == n].min() for n in touched])
        lifted += int(np.sum(summits > 0.8))
    assert lifted > 0  # the bulge is what the test is about


def test_tyre_on_a_block_under_load_is_the_reference(strip, tmp_path, monkeypatch):
    """A slick tyre (R 300 mm) on a bonded, incompressible tread block under a held load: at
    every position the approach and the contact area are the full-grid reference's of the
    strip moved by the shift under the tyre's face on the same block (built from the height
    array alone). The two-scale patches had missed a contact the bulge makes at the first
    position (approach 6.3e-4 mm high, area 3 cells short)."""
    from twoscale.rolling.track import prepare

    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))
    spec = RollingSpec(start=-4.0, end=-2.0, step=1.0, speed=30.0, tyre_radius=300.0)
    block = {"kind": "block", "size": (60.0, 50.0, 8.0), "base": "bonded", "source_spacing": 4.0}
    scene = Scene(material=MAT, surface=strip, total_load=150.0, rolling=spec, influence=block)
    provider = scene.provider(progress=False)
    run = roll(scene, options=RollingOptions(tol=1e-8), provider=provider)
    x0, x1, y0, y1 = prepare(scene, provider=provider).road.window
    g = strip.hmap.grid
    for k, s in enumerate(run.shifts):
        X, Y = Grid(g.x0 + float(s), g.y0, g.h, g.nx, g.ny).centres()  # the strip moved
        inside = (X >= x0 - 1e-9) & (X <= x1 + 1e-9) & (Y >= y0 - 1e-9) & (Y <= y1 + 1e-9)
        cols, rows = np.flatnonzero(inside.any(axis=0)), np.flatnonzero(inside.any(axis=1))
        grid = Grid(float(X[0, cols[0]]), float(Y[rows[0], 0]), g.h, len(cols), len(rows))
        recess = float(np.nanmax(strip.hmap.heights)) - strip.hmap.heights[np.ix_(rows, cols)]
        recess = recess + spec.face(grid.centres()[0])
        surface = Surface(grid, recess, np.zeros(recess.shape, int), 1)
        ref = solve_reference(provider, surface, total_load=150.0, tol=1e-10)
        assert run.penetration[k] == pytest.approx(ref.penetration, abs=1e-7)
        assert run.contact_area[k] == pytest.approx(ref.contact_area, abs=1e-9)
