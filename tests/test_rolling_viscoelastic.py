"""A viscoelastic body under a rolling road (through the moving-indenter stepping): the
limits. Far slower than every branch it answers as the relaxed elastic body at every
position; far faster (every relaxation time far above the run), as the glassy one."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.rolling import RollingSpec, road_strip, roll
from twoscale.scene import Scene
from twoscale.surface import RawMap, build_surface

PRONY = ((20.0, 1e-3), (10.0, 1e-2))


@pytest.fixture(scope="module")
def strip():
    return build_surface(RawMap(road_strip(50.0, 14.0, 0.25, seed=7), spacing=0.25, units="mm"))


def _scene(strip, speed: float, material: Material) -> Scene:
    spec = RollingSpec(start=-3.0, end=-1.0, step=1.0, speed=speed, tyre_radius=150.0, footprint=(24.0, 12.0))
    return Scene(material=material, surface=strip, penetration=0.9, rolling=spec)


@pytest.mark.parametrize(
    "speed, taus, modulus",
    [
        (1e-6, None, "relaxed"),  # 1 mm in an hour against tau of 1-10 ms
        (100.0, (1e5, 1e6), "glassy"),  # 1 mm in 36 us against tau of a day and more
    ],
)
def test_limits_are_the_elastic_rollings(strip, speed, taus, modulus):
    prony = PRONY if taus is None else tuple((E, t) for (E, _), t in zip(PRONY, taus))
    run = roll(_scene(strip, speed, Material(10.0, 0.5, prony=prony)))
    E = 10.0 if modulus == "relaxed" else 10.0 + sum(E for E, _ in prony)
    elastic = roll(_scene(strip, speed, Material(E, 0.5)))
    assert run.all_converged and elastic.all_converged
    assert run.body.endswith("viscoelastic")
    assert np.allclose(run.total_load, elastic.total_load, rtol=2e-3)
    assert np.allclose(run.contact_area, elastic.contact_area, atol=4 * 0.25**2)
    assert np.allclose(run.drag, elastic.drag, atol=2e-3 * float(np.max(elastic.total_load)))


def test_viscoelastic_drag_resists_the_rolling(strip):
    """A step time of half the relaxation time (1.8 km/h, 0.5 mm steps, tau = 2 ms): the
    rubber lags behind the road and the road drags it along, above the relaxed elastic
    body's drag at every position after the ramp-in (measured: 7.2 N against 0.65 N at the
    last position; 3.3 N for the glassy elastic body)."""
    import dataclasses

    scene = _scene(strip, 1.8, Material(10.0, 0.5, prony=((40.0, 2e-3),)))
    scene = dataclasses.replace(scene, rolling=dataclasses.replace(scene.rolling, start=-3.0, end=0.0, step=0.5))
    visco = roll(scene)
    relaxed = roll(dataclasses.replace(scene, material=Material(10.0, 0.5)))
    assert visco.all_converged and len(visco.shifts) == 7
    assert np.all(visco.drag[2:] > relaxed.drag[2:])
    assert visco.mean_drag > 3.0 * abs(relaxed.mean_drag)


def test_drag_work_is_the_energy_stored_and_dissipated(strip):
    """Under penetration control the axle does no work: the drag's work from the first
    position on is the change of the stored energy plus what the branches dissipated (two
    routes: pressure x the road's slope against the branches' internal variables). Measured:
    0.9 % and 1.2 % apart at 0.5 and 0.25 mm steps: the slope's central differences on the
    0.25 mm samples, not the step, set the difference."""
    import dataclasses

    scene = _scene(strip, 1.8, Material(10.0, 0.5, prony=((40.0, 2e-3),)))
    for step in (0.5, 0.25):
        spec = dataclasses.replace(scene.rolling, start=-3.0, end=0.0, step=step)
        run = roll(dataclasses.replace(scene, rolling=spec))
        energy = run.stored[-1] - run.stored[0] + float(np.sum(run.dissipated[1:]))
        assert run.all_converged and energy > 0
        assert abs(run.drag_work() / energy - 1.0) < 0.02


def test_viscoelastic_run_records_the_line_load(strip):
    """The space-time picture's line load (pressure summed across y) of a viscoelastic run:
    far slower than every branch it is the relaxed elastic run's, column by column on the
    lattice of cell h, and over x it sums to the run's total load at every position."""
    slow = roll(_scene(strip, 1e-6, Material(10.0, 0.5, prony=PRONY)))
    elastic = roll(_scene(strip, 1e-6, Material(10.0, 0.5)))
    assert slow.line_load.shape == (len(slow.shifts), slow.line_x.size) and slow.line_x.size > 0
    assert np.allclose(slow.line_load.sum(axis=1) * slow.h, slow.total_load, rtol=1e-9)
    lo = int(round(min(slow.line_x[0], elastic.line_x[0]) / slow.h))
    hi = int(round(max(slow.line_x[-1], elastic.line_x[-1]) / slow.h)) + 1
    on = np.zeros((2, len(slow.shifts), hi - lo))
    for k, run in enumerate((slow, elastic)):
        i = int(round(run.line_x[0] / run.h)) - lo
        on[k, :, i : i + run.line_x.size] = run.line_load
    assert np.allclose(on[0], on[1], atol=5e-3 * float(on[1].max()))


def test_slow_roll_on_a_tread_block_is_the_relaxed_elastic_roll(strip, tmp_path, monkeypatch):
    """A flat tread block (bonded base) over a strip longer than its face: the stones beyond
    the face at a shift sit out of reach, yet the block is asked only for points on it; far
    slower than every branch the run answers as the relaxed elastic block's at every position."""
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))
    spec = RollingSpec(start=-14.0, end=14.0, step=4.0, speed=1e-6)
    block = {"kind": "block", "size": (44.0, 40.0, 8.0), "base": "bonded", "source_spacing": 4.0}

    def run(material: Material):
        return roll(Scene(material=material, surface=strip, penetration=0.9, rolling=spec, influence=block))

    visco, elastic = run(Material(10.0, 0.5, prony=PRONY)), run(Material(10.0, 0.5))
    assert visco.all_converged and elastic.all_converged
    assert visco.body.startswith("block 44 x 40 x 8") and visco.body.endswith("viscoelastic")
    assert np.allclose(visco.total_load, elastic.total_load, rtol=2e-3)
    assert np.allclose(visco.contact_area, elastic.contact_area, atol=4 * 0.25**2)


def test_roll_on_a_tread_block_is_the_reference_stepping(strip, tmp_path, monkeypatch):
    """A viscoelastic roll on a bonded tread block (a flat face, a step time of about the
    branches' relaxation times): every position equals the full-grid reference's step of the
    same moving road (``solve_moving`` with ``method="reference"``) to the solvers' tolerance
    (measured: loads 2.8e-11, drags 6e-12 of the largest load; 1e-5 with the far-field
    two-level iteration of a history's warm steps)."""
    import dataclasses

    from twoscale.rolling.track import prepare
    from twoscale.rolling.viscous import RoadIndenter, memory_grid, run_stones
    from twoscale.viscoelastic.moving import MovingOptions, solve_moving

    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))
    spec = RollingSpec(start=-6.0, end=6.0, step=1.0, speed=3.0)
    block = {"kind": "block", "size": (60.0, 50.0, 8.0), "base": "bonded", "source_spacing": 4.0}
    material = Material(10.0, 0.5, prony=PRONY)
    scene = Scene(material=material, surface=strip, penetration=0.9, rolling=spec, influence=block)
    track = prepare(scene)
    run = roll(scene, track=track)
    from twoscale.indenters import Asperity

    tip = (Asperity(0.0, 0.0, 0.0, 1.0),)
    bare = dataclasses.replace(scene, material=material.relaxed(), rolling=None, surface=None, asperities=tip)
    body = bare.provider()
    numbers = run_stones(track)
    ref = solve_moving(
        material,
        body,
        RoadIndenter(track.road, numbers),
        track.shifts,
        speed=spec.speed_mm_s,
        grid=memory_grid(track),
        penetration=0.9,
        options=MovingOptions(method="reference", open_edges=True, solver={"tol": 1e-10}),
    )
    assert run.all_converged and len(run.shifts) == 13
    W = float(np.max(ref.total_load))
    assert np.allclose(run.total_load, ref.total_load, rtol=0, atol=1e-7 * W)
    assert np.allclose(run.drag, ref.drag, rtol=0, atol=1e-7 * W)


@pytest.mark.parametrize("prony", [(), PRONY])
def test_timings_count_the_prepared_track(strip, prony):
    """A run handed a prepared track (as the command line does, its checks first) reports the
    preparation's seconds, not the ~1e-5 s between its start and its first position; the
    total is the preparation and the positions."""
    from twoscale.rolling.track import prepare

    track = prepare(_scene(strip, 50.0, Material(10.0, 0.5, prony=prony)))
    run = roll(track.scene, track=track)
    t = run.timings_s
    assert t["prepare"] == track.seconds > 0.0
    assert t["total"] == pytest.approx(t["prepare"] + t["positions"])


@pytest.mark.parametrize("prony", [(), PRONY])
def test_timings_name_the_strips_segmentation(strip, prony):
    """``timings_s["segment"]`` is the rolled strip's own segmentation time, elastic and
    viscoelastic alike."""
    from twoscale.rolling.track import prepare

    track = prepare(_scene(strip, 50.0, Material(10.0, 0.5, prony=prony)))
    run = roll(track.scene, track=track)
    assert run.timings_s["segment"] == track.scene.surface.segment_seconds > 0.0
