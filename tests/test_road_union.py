"""The union CG on height maps: its box cut to the cells with material, and the mixed
precision's second stage in float32 products about one exact product; both against the
full-grid reference (double precision, the map's own grid)."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import crowded
from twoscale import Material
from twoscale.driver import solve_twoscale
from twoscale.indenters import surface_on
from twoscale.influence import HalfSpace
from twoscale.influence.convolution import ConvolutionOperator, _SingleConvolution
from twoscale.reference import solve_cg
from twoscale.reference.on_scene import reference_grid
from twoscale.scene import Scene
from twoscale.surface import RawMap, SurfaceOptions, build_surface
from twoscale.surface.texture import road

MAT = Material(E=10.0, nu=0.5)
HS = HalfSpace(MAT)


@pytest.mark.parametrize("size,seed,p0", [(12.0, 4, False), (16.0, 3, False), (12.0, 4, True)])
def test_union_box_of_a_road_stays_on_the_map_and_gives_the_references_forces(size, seed, p0):
    # the edge stones' patches reach past the map, where no cell has material: the box the
    # CG runs on is cut back to the map, and the answer is the full map's
    surface = build_surface(RawMap(road(size, 0.1, seed=seed), 0.1, "mm", None, "road"), SurfaceOptions())
    grid, load = surface.hmap.grid, 0.2 * size**2
    # p0: eq. 7 pressures on the uncut box start the CG and are reported on the cut one
    res = solve_twoscale(HS, surface.asperities, h=0.1, total_load=load, iteration="union-cg", p0=p0)
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


@pytest.mark.parametrize("load", [{"total_load": 20.0}, {"penetration": 0.12}, {"total_load": 20.0, "tilt": True}])
def test_mixed_second_stage_takes_one_double_product_and_meets_the_tolerance_on_exact_products(load, monkeypatch):
    asps = crowded(3, 10)
    grid = reference_grid(Scene(material=MAT, asperities=asps, h=0.08, **load), 0.08)
    surf = surface_on(grid, asps)
    double = solve_cg(HS, surf, tol=1e-9, **load)
    calls = {"double": 0}
    apply = ConvolutionOperator.apply

    def counted(self, p):
        calls["double"] += self.target == self.source  # not the cropped grid's final product
        return apply(self, p)

    anchor = _SingleConvolution.exact

    def counted_anchor(self, p):  # the float32 operator's float64 product (the anchor's)
        calls["double"] += 1
        return anchor(self, p)

    monkeypatch.setattr(ConvolutionOperator, "apply", counted)
    monkeypatch.setattr(_SingleConvolution, "exact", counted_anchor)
    mixed = solve_cg(HS, surf, tol=1e-9, precision="mixed", precondition=True, **load)
    monkeypatch.undo()
    assert double.converged and mixed.converged
    second = mixed.iterations["cg"] - mixed.details.single_precision_iterations
    assert second > 0
    # one float64 product: the anchor of the second stage (its refreshes are float32)
    assert calls["double"] == 1
    p = mixed.fields[0].pressure
    assert np.linalg.norm(p - double.fields[0].pressure) <= 1e-6 * np.linalg.norm(double.fields[0].pressure)
    # the KKT conditions on an exact product of the answer: the float32 rounding did not
    # stay in the displacement the CG stopped on
    work = mixed.fields[0].grid
    u = HS.grid_operator(work).apply(p)
    gap = u + surf.height[work.window_in(grid)]
    on = p > 0
    if load.get("tilt"):  # the rigid motion is a plane: fitted on the loaded cells
        y, x = np.meshgrid(work.y, work.x, indexing="ij")
        B = np.column_stack([np.ones(on.sum()), x[on], y[on]])
        c = np.linalg.lstsq(B, gap[on], rcond=None)[0]
        gap -= c[0] + c[1] * x + c[2] * y
    else:
        gap -= mixed.penetration
    scale = np.abs(u).max()
    assert np.abs(gap[on]).max() <= 1e-8 * scale
    assert gap[np.isfinite(gap) & ~on].min() >= -1e-8 * scale


def test_a_map_sampled_on_its_lattice_by_windows_is_its_per_point_look_up():
    # a grid reaching past the map (as a union box does), a subset of the basins, and a
    # grid off the lattice, which keeps the look-up per point
    from twoscale.grid import Grid

    surface = build_surface(RawMap(road(12.0, 0.1, seed=4), 0.1, "mm", None, "road"), SurfaceOptions())
    basins, g = surface.asperities[0].basins, surface.hmap.grid
    index = {a.label: k for k, a in enumerate(surface.asperities) if k % 2 == 0}
    box = Grid(g.x0 - 7 * g.h, g.y0 + 5 * g.h, g.h, g.nx + 3, g.ny - 2)
    fast = basins.union_on_grid(box, index)
    assert fast is not None
    X, Y = box.centres()
    height, owner = basins.union_on(X, Y, index)
    assert np.array_equal(fast[1], owner) and np.array_equal(fast[0], height)
    assert np.any(owner >= 0) and np.any(owner < 0) and np.isinf(fast[0][:, :7]).all()
    off = Grid(g.x0 + 0.3 * g.h, g.y0, g.h, 20, 20)
    assert basins.union_on_grid(off, index) is None
    sampled = surface_on(off, surface.asperities)
    X, Y = off.centres()
    assert np.array_equal(
        sampled.owner, basins.union_on(X, Y, {a.label: k for k, a in enumerate(surface.asperities)})[1]
    )
