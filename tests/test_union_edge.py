"""The union CG's early test for pressure on its box's edge (:mod:`twoscale.micro.union_edge`)
and the kernel's ``stop`` test it rides on."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.api import solve_scene
from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace
from twoscale.micro import union
from twoscale.micro.union_edge import EDGE_RESIDUAL, SETTLED, EdgeWatch, box_edge_cells
from twoscale.reference import solve_cg
from twoscale.scenespace import build, sweep


def test_the_edge_cells_are_those_on_the_sides_shared_with_the_box():
    box = Grid(0.0, 0.0, 0.1, 10, 8)
    inner = box.subgrid(0, 2, 6, 6)  # the box's left and top sides; right and bottom cut away
    cells = box_edge_cells(inner, box)
    expected = np.zeros(inner.shape, dtype=bool)
    expected[:, 0] = True
    expected[-1, :] = True
    assert np.array_equal(cells, expected)
    assert box_edge_cells(box, box).sum() == 2 * (10 + 8) - 4


def test_the_watch_fires_once_the_edge_has_settled_at_a_small_residual():
    box = Grid(0.0, 0.0, 0.1, 5, 5)
    watch = EdgeWatch(box, box)
    loaded, empty = np.ones(4), np.zeros(4)
    # loaded but the residual large, then loaded once after an empty step: no
    assert not watch(0, 1.0, loaded)
    assert not watch(1, 0.1 * EDGE_RESIDUAL, empty)
    for it in range(2, 2 + SETTLED - 1):
        assert not watch(it, 0.1 * EDGE_RESIDUAL, loaded)
    assert watch(2 + SETTLED - 1, 0.1 * EDGE_RESIDUAL, loaded) and watch.fired


def test_the_callers_stop_ends_the_cg_unconverged_where_it_asks():
    material = Material(E=10.0, nu=0.5)
    grid = Grid.covering(-1.0, 1.0, -1.0, 1.0, 2.0 / 96)
    surface = surface_on(grid, [Asperity(0.0, 0.0, 0.0, 10.0)])

    class Stop:
        cells = np.ones(grid.shape, dtype=bool)
        seen: list = []

        def __call__(self, it, res, values):
            self.seen.append(float(values.max()))
            return it == 4

    stop = Stop()
    result = solve_cg(HalfSpace(material), surface, total_load=2.0, stop=stop)
    whole = solve_cg(HalfSpace(material), surface, total_load=2.0)
    assert whole.converged and whole.iterations["cg"] > 4
    assert not result.converged and result.iterations["cg"] == 4 and "stopped" in result.message
    assert len(stop.seen) == 5 and stop.seen[-1] == pytest.approx(result.fields[0].pressure.max())


def test_a_first_box_too_small_grows_early_with_the_reference_forces(monkeypatch):
    # seed 1's #65 (penetration control): its contact runs past the patches' box, whose
    # converged CG took 19 iterations before the box grew (20 more on the grown box)
    (spec,) = [s for s in sweep(200, 1) if s.index == 65]
    scene = build(spec)
    result = solve_scene(scene)
    micro = result.details.micro
    assert result.converged and micro.strategy == "union-cg" and micro.growths >= 1
    reference = solve_scene(scene, method="reference", tol=1e-10)
    F, Fr = result.asperities.forces, reference.asperities.forces
    assert np.max(np.abs(F - Fr)) <= 1e-6 * Fr.max()

    class Never(EdgeWatch):  # the first box solved to convergence before it grows
        def __call__(self, iteration, residual, values):
            return False

    monkeypatch.setattr(union, "EdgeWatch", Never)
    late = solve_scene(scene)
    assert late.converged and late.details.micro.growths == micro.growths
    assert micro.attempts[-1].sweeps < late.details.micro.attempts[-1].sweeps
    assert np.max(np.abs(late.asperities.forces - F)) <= 1e-6 * Fr.max()


def _tilted_four():
    """Four small paraboloids under load, tilted about a pivot outside them (the sweep's
    seed 8, #80): the macro step's tilt leaves the fourth tip, 0.3 mm past the others,
    without force and outside the union CG's first box; the full grid gives it 0.5 % of the
    load at the answer's tilt."""
    (spec,) = [s for s in sweep(200, 8) if s.index == 80]
    return build(spec)


def test_a_tip_the_answers_tilt_reaches_outside_the_box_is_taken_in():
    scene = _tilted_four()
    default = solve_scene(scene)
    reference = solve_scene(scene, method="reference")
    assert default.converged and reference.converged
    assert reference.forces[3] > 1e-3 * reference.forces.max()  # it touches: the case is the one meant
    # the default's per-tip forces equal the full grid's (1.05 % off on the fourth without
    # the check: it had no cell)
    np.testing.assert_allclose(default.forces, reference.forces, rtol=0, atol=1e-6 * reference.forces.max())
    assert default.tilt == pytest.approx(reference.tilt, rel=1e-6)


def test_reached_outside_covers_the_reached_tip_and_nothing_else():
    from types import SimpleNamespace

    from twoscale.micro.union_edge import reached_outside

    material = Material(E=1.0, nu=0.5)
    tips = [Asperity(0.0, 0.0, 0.0, 1.0), Asperity(2.0, 0.0, 0.0, 1.0), Asperity(-3.0, 0.0, 0.5, 1.0)]
    box = Grid(-0.3, -0.3, 0.05, 13, 13)  # around the first tip only

    def answer(force: float = 0.0, tilt=None):  # the first tip carrying ``force`` N, the others none
        return SimpleNamespace(
            penetration=0.01, tilt=tilt, asperities=SimpleNamespace(forces=np.array([force, 0.0, 0.0]))
        )

    hs = HalfSpace(material)
    grown = reached_outside(box, tips, answer(), hs, (0.0, 0.0))  # no pressure: the second tip (z 0) is reached
    assert grown is not None
    xmin, xmax, ymin, ymax = grown.bounds
    assert xmax >= 2.0 + tips[1].reach(0.02) and xmin == pytest.approx(box.bounds[0])  # the third (z 0.5) is not
    assert (ymin, ymax) == pytest.approx(box.bounds[2:])
    # a tilt about the first tip that lifts the second by 0.02 mm (beta x): nothing to cover
    assert reached_outside(box, tips, answer(tilt=(0.0, 0.01)), hs, (0.0, 0.0)) is None
    # the first tip's force sinks the surface at the second by F / (pi E* r): 0.02 N at 2 mm
    # sinks it 0.0024 mm (E* 4/3 MPa), short of its approach 0.01: still reached
    assert reached_outside(box, tips, answer(0.02), hs, (0.0, 0.0)) is not None
    # 0.1 N sinks it 0.012 mm: past its approach, not reached
    assert reached_outside(box, tips, answer(0.1), hs, (0.0, 0.0)) is None


def test_tip_positions_are_the_tips_own_numbers():
    """The tips' (x, y) as two columns: the same float64 values as an array of pairs, for
    integer and float positions and for no tips."""
    from twoscale.indenters import Asperity, tip_positions

    tips = [Asperity(1, -2.5, 0.0, 1.0), Asperity(0.1 + 0.2, 1e-300, 0.0, 2.0, "paraboloid")]
    xy = tip_positions(tips)
    assert xy.dtype == np.float64 and xy.shape == (2, 2)
    assert np.array_equal(xy, np.array([[a.x, a.y] for a in tips], dtype=float))
    assert tip_positions([]).shape == (0, 2)
