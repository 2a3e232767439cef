"""A measured surface on the finite block (fem_influence): the two-scale solve against the
full-grid reference on the same block, map and grid.

A 60 x 60 x 10 mm block meshed at 5-10 mm keeps the factorisation to seconds; the map's
laws are the half-space ones and the block's smooth self-compliance enters the macro step,
as for spheres, so only the micro step (the answer) sees the whole block.
"""

import numpy as np
import pytest

from fem_influence import BlockProvider
from twoscale import Material
from twoscale.indenters import surface_on
from twoscale.reference import solve_reference
from twoscale.surface import RawMap, SurfaceOptions, build_surface
from twoscale.surface.texture import road
from twoscale.driver import solve_twoscale

MAT = Material(E=10.0, nu=0.5)
SMALL = dict(size=(60.0, 60.0, 10.0), h_fine=5.0, h_coarse=10.0, fine_half_width=10.0)


def test_road_on_the_block_agrees_with_the_reference():
    block = BlockProvider(material=MAT, use_cache=False, progress=False, **SMALL)
    h = 0.1
    s = build_surface(RawMap(road(12.0, h, seed=5), h, "mm", None, "road"), SurfaceOptions())
    two = solve_twoscale(block, s.asperities, h=h, total_load=30.0)
    ref = solve_reference(block, surface_on(s.hmap.grid, s.asperities), total_load=30.0)
    assert two.converged and ref.converged, (two.message, ref.message)
    assert two.total_load == pytest.approx(ref.total_load, rel=0.005)
    assert two.penetration == pytest.approx(ref.penetration, rel=0.005)
    f, g = two.asperities.forces, ref.asperities.forces
    big = g > 0.01 * g.max()
    assert np.all(np.abs(f - g)[big] <= 0.01 * g[big])
    p, q = two.pressure_on(s.hmap.grid), ref.pressure_on(s.hmap.grid)
    assert np.count_nonzero(p) == pytest.approx(np.count_nonzero(q), rel=0.005)
    assert np.linalg.norm(p - q) <= 0.02 * np.linalg.norm(q)
