"""The second position's start: the first answer moved with the road and advanced by its
linearised change over the step (:mod:`twoscale.rolling.shiftstep`)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import Surface
from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg
from twoscale.rolling.shiftstep import ShiftStep
from twoscale.rolling.window import GAP_STIFFNESS, KeptBody

MAT = Material(10.0, 0.5)
GRID = Grid(-8.0, -2.0, 0.25, 64, 16)


def _cylinder(x):
    return np.asarray(x) ** 2 / 100.0  # a tyre's face of radius 50 mm


@pytest.mark.parametrize("preconditioned", [False, True])
@pytest.mark.parametrize("load", [{"total_load": 13.0}, {"penetration": 0.1}])
def test_a_flat_road_under_a_moving_face_keeps_its_answer_in_the_body(load, preconditioned):
    """A flat road under a cylinder: the contact is fixed in the body, so the answer moved
    with the road by a cell is off by the pressure's slope times the step, which the
    linearised step restores to first order (not at the contact's edges, where the
    pressure's slope is infinite and the contact set changes): inside the contact the
    start must be several times closer than the moved answer, and closer overall."""
    ref = solve_cg(
        HalfSpace(MAT), Surface(GRID, _cylinder(GRID.centres()[0]), np.zeros(GRID.shape, int), 1), tol=1e-10, **load
    )
    f = ref.fields[0]
    stiffness = GAP_STIFFNESS / HalfSpace(MAT).self_compliance(GRID.h)
    signed = np.where(f.pressure > 0.0, f.pressure, -stiffness * np.maximum(f.gap, 0.0))
    one = np.zeros(GRID.shape)
    one[:, 1:] = signed[:, :-1]  # moved with the road by one cell
    body = KeptBody(HalfSpace(MAT))
    step = ShiftStep(body, _cylinder, "total_load" in load, stiffness)
    inverse = body.grid_operator(GRID).preconditioner()  # (the circulant inverse)
    pc = (lambda r, on: inverse.apply(r)) if preconditioned else None
    moved, start = np.maximum(one, 0.0), np.maximum(one + step(one, GRID, GRID.h, pc), 0.0)
    inner = np.abs(GRID.centres()[0]) < 1.5  # the contact's half-width is 3.4 (load) or 2.4 mm
    assert np.linalg.norm((start - f.pressure)[inner]) < 0.25 * np.linalg.norm((moved - f.pressure)[inner])
    assert np.linalg.norm(start - f.pressure) < 0.5 * np.linalg.norm(moved - f.pressure)


def test_a_flat_face_or_no_step_changes_nothing():
    one = np.zeros(GRID.shape)
    one[5:8, 30:34] = 1.0
    one[5:8, 34] = -0.5
    body = KeptBody(HalfSpace(MAT))
    assert not np.any(ShiftStep(body, np.zeros_like, True, 1.0)(one, GRID, 0.5))
    assert not np.any(ShiftStep(body, _cylinder, True, 1.0)(one, GRID, 0.0))


def test_the_second_position_takes_fewer_iterations_and_the_same_answer():
    """A tyre rolled over a chip-seal strip: the second position's CG from the advanced
    start against the one from the moved answer alone, the same static problem."""
    from twoscale.rolling import RollingOptions, RollingSpec, road_strip
    from twoscale.rolling.run import step, window_state
    from twoscale.rolling.track import prepare
    from twoscale.scene import Scene
    from twoscale.surface import RawMap, build_surface

    strip = build_surface(RawMap(road_strip(60.0, 20.0, 0.25, seed=3), spacing=0.25, units="mm"))
    spec = RollingSpec(start=-6.0, end=-5.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    track = prepare(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0))
    options = RollingOptions(solver="window")
    second = []
    for advanced in (True, False):
        state = window_state(track, options)
        if not advanced:
            state.ahead = None
        first = step(track, 0, None, options, state)
        second.append(step(track, 1, first, options, state).result)
    assert all(r.converged for r in second)
    assert second[0].iterations["cg"] < second[1].iterations["cg"]
    assert second[0].penetration == pytest.approx(second[1].penetration, abs=1e-9)
