"""A grid crowded with untilted tips (few cells a tip) is solved by default as the full
grid's one CG, said in the result: there the macro step and the patches cost more than the
whole full-grid CG. A tilt, or tips with more cells each, keep the two-scale route."""

from __future__ import annotations

import numpy as np
import pytest

import twoscale
from twoscale import Material, Scene
from twoscale.indenters import Asperity
from twoscale.micro.full_grid_rule import (
    FULL_GRID_CELLS_PER_TIP,
    FULL_GRID_MAX_CELLS,
    FULL_GRID_MAX_CELLS_PENETRATION,
    FULL_GRID_SMALL_CELLS,
    FULL_GRID_SMALL_CELLS_PER_TIP,
)
from twoscale.reference.on_scene import reference_grid
from twoscale.resources import full_grid_route

# the lattice is on a coarse grid on purpose (a few cells a tip): its resolution warning is expected
pytestmark = pytest.mark.filterwarnings("ignore:cell size h")


def _lattice(side, spacing, **load):
    """``side`` x ``side`` spheres R 2 mm, ``spacing`` mm apart, heights spread by 2 um."""
    rng = np.random.default_rng(7)
    tips = tuple(
        Asperity(spacing * i, spacing * j, float(z), 2.0)
        for (i, j), z in zip(np.ndindex(side, side), rng.uniform(0.0, 0.002, side * side))
    )
    return Scene(material=Material(E=5.0, nu=0.5), asperities=tips, **load)


def test_an_untilted_crowded_grid_takes_its_full_grid_and_says_so():
    scene = _lattice(20, 1.0, penetration=0.06)
    h = 0.25
    cells = reference_grid(scene, h).size
    assert FULL_GRID_MAX_CELLS < cells <= FULL_GRID_CELLS_PER_TIP * 400
    res = twoscale.solve(scene, h=h)
    ref = twoscale.solve(scene, h=h, method="reference")
    assert res.method == "reference" and res.converged
    assert "cells a tip" in res.message
    # at most 25 cells a tip the grid's CG is the reference's own (no preconditioner)
    assert "; CG;" in res.message
    assert np.array_equal(res.asperities.forces, ref.asperities.forces)


def test_a_tilt_or_more_cells_a_tip_keep_the_two_scale_route():
    tilted = _lattice(20, 1.0, total_load=2.0, tilt=True, pivot=(9.5, 9.5))
    assert full_grid_route(tilted, 0.25) is None
    sparse = _lattice(20, 1.0, penetration=0.06)
    h = 0.1  # (1.0 / 0.1)^2 = 100 cells a tip
    assert reference_grid(sparse, h).size > FULL_GRID_CELLS_PER_TIP * 400
    assert full_grid_route(sparse, h) is None
    assert full_grid_route(sparse, 0.25) is not None


def test_a_small_grid_of_many_tips_takes_its_full_grid_below_its_cells_a_tip():
    # 81 spheres 1 mm apart: at h 0.08 the grid has about 175 cells a tip (under 20,000 cells)
    # and the union CG's box would be nearly all of it; at h 0.07 about 230 a tip keep the
    # two-scale route
    scene = _lattice(9, 1.0, penetration=0.06)
    h = 0.08
    cells = reference_grid(scene, h).size
    assert FULL_GRID_CELLS_PER_TIP * 81 < cells <= FULL_GRID_SMALL_CELLS
    res = twoscale.solve(scene, h=h)
    ref = twoscale.solve(scene, h=h, method="reference")
    assert res.method == "reference" and "cells a tip" in res.message
    # over 25 cells a tip the grid's CG is preconditioned: the reference's discrete answer
    # to its tolerance (~2e-7), in fewer iterations
    assert "preconditioned CG" in res.message
    f, f_ref = res.asperities.forces, ref.asperities.forces
    assert np.max(np.abs(f - f_ref)) <= 1e-6 * np.max(f_ref)
    assert res.iterations["cg"] < ref.iterations["cg"]
    assert reference_grid(scene, 0.07).size > FULL_GRID_SMALL_CELLS_PER_TIP * 81
    assert full_grid_route(scene, 0.07) is None


def test_a_few_tips_under_penetration_on_a_larger_grid_take_it_under_load_not():
    """Two paraboloids whose union box is most of their 5,913-cell grid (the sweep's seed 6
    #185, the two-scale solve 1.25-1.28x the reference's CPU) are that grid's one CG under
    penetration control, with the reference's forces; two tips under load on 6,237 cells
    (#117) keep the two-scale route, which ran there at 0.93x the reference against 0.80x."""
    from twoscale import scenespace
    from twoscale.scene import default_h

    specs = {s.index: s for s in scenespace.sweep(200, 6) if s.index in (117, 185)}
    pressed, loaded = scenespace.build(specs[185]), scenespace.build(specs[117])
    assert pressed.penetration is not None and loaded.total_load is not None
    cells = reference_grid(pressed, default_h(pressed)).size
    assert FULL_GRID_MAX_CELLS < cells <= FULL_GRID_MAX_CELLS_PENETRATION
    res = twoscale.solve(pressed)
    ref = twoscale.solve(pressed, method="reference")
    assert res.method == "reference" and f"at most {FULL_GRID_MAX_CELLS_PENETRATION:,}" in res.message
    np.testing.assert_allclose(res.asperities.forces, ref.asperities.forces, rtol=1e-6)
    assert FULL_GRID_MAX_CELLS < reference_grid(loaded, default_h(loaded)).size
    assert twoscale.solve(loaded).method == "twoscale"
