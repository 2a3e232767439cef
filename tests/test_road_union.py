"""The union CG on height maps: its box cut to the cells with material, and the mixed
precision's second stage in float32 products about one exact product; both against the
full-grid reference (double precision, the map's own grid)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.driver import solve_twoscale
from twoscale.indenters import surface_on
from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg
from twoscale.surface import RawMap, SurfaceOptions, build_surface
from twoscale.surface.texture import road

MAT = Material(E=10.0, nu=0.5)
HS = HalfSpace(MAT)


@pytest.mark.parametrize("size,seed", [(12.0, 4), (16.0, 3)])
def test_union_box_of_a_road_stays_on_the_map_and_gives_the_references_forces(size, seed):
    # the edge stones' patches reach past the map, where no cell has material: the box the
    # CG runs on is cut back to the map, and the answer is the full map's
    surface = build_surface(RawMap(road(size, 0.1, seed=seed), 0.1, "mm", None, "road"), SurfaceOptions())
    grid, load = surface.hmap.grid, 0.2 * size**2
    res = solve_twoscale(HS, surface.asperities, h=0.1, total_load=load, iteration="union-cg")
    assert res.converged, res.message
    (field,) = res.fields
    box = field.grid
    assert box.x0 >= grid.x0 - 1e-9 and box.y0 >= grid.y0 - 1e-9
    assert box.x0 + box.nx * box.h <= grid.x0 + grid.nx * grid.h + 1e-9
    assert box.y0 + box.ny * box.h <= grid.y0 + grid.ny * grid.h + 1e-9
    ref = solve_cg(HS, surface_on(grid, surface.asperities), total_load=load, tol=1e-10)
    F, Fr = res.asperities.forces, ref.asperities.forces
    assert np.max(np.abs(F - Fr)) <= 1e-7 * Fr.max()
    p, pr = res.pressure_on(grid), ref.pressure_on(grid)
    assert np.linalg.norm(p - pr) <= 1e-6 * np.linalg.norm(pr)
