"""The preconditioned constrained CG (``solve_cg(precondition=True)``, used by the union
iteration) against the classical Polonsky-Keer CG on the same grid, and its
preconditioner (the inverse of the kernel wrapped on the grid's torus) on its own."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import surface_on
from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg
from twoscale.reference.on_scene import reference_grid
from twoscale.scene import Scene

from helpers import crowded, crowded_surface, random_spheres, small_block

MAT = Material(E=6.0, nu=0.5)
HS = HalfSpace(MAT)


@pytest.mark.parametrize(
    "seed,load", [(4, {"penetration": 0.12}), (5, {"total_load": 30.0}), (6, {"total_load": 30.0, "tilt": True})]
)
def test_preconditioned_cg_finds_the_same_contact_in_fewer_iterations(seed, load):
    surf = crowded_surface(MAT, seed, load)
    plain = solve_cg(HS, surf, tol=1e-9, **load)
    pre = solve_cg(HS, surf, tol=1e-9, precondition=True, **load)
    assert plain.converged and pre.converged, (plain.message, pre.message)
    assert pre.iterations["cg"] < 0.8 * plain.iterations["cg"], (pre.iterations, plain.iterations)
    p, pp = pre.fields[0].pressure, plain.fields[0].pressure
    assert np.linalg.norm(p - pp) <= 1e-6 * np.linalg.norm(pp)
    F, Fp = pre.asperities.forces, plain.asperities.forces
    assert np.max(np.abs(F - Fp)) <= 1e-7 * Fp.max()
    assert pre.penetration == pytest.approx(plain.penetration, abs=1e-9)
    if load.get("tilt"):
        assert np.allclose(pre.tilt, plain.tilt, atol=1e-9)
    # mixed precision with the float32 preconditioner meets the same tolerance
    mixed = solve_cg(HS, surf, tol=1e-9, precondition=True, precision="mixed", **load)
    assert mixed.converged and mixed.details.single_precision_iterations > 0
    assert np.linalg.norm(mixed.fields[0].pressure - pp) <= 1e-6 * np.linalg.norm(pp)


@pytest.mark.parametrize("single", [False, True])
def test_circulant_inverse_is_symmetric_positive_and_inverts_the_operator_inside(single):
    g = Grid.covering(-4.0, 4.0, -3.0, 3.0, 0.1)
    op = HS.grid_operator(g)
    op = op.single_precision() if single else op
    pc = op.preconditioner()
    rng = np.random.default_rng(1)
    u, v = rng.standard_normal(g.shape), rng.standard_normal(g.shape)
    rtol = 1e-5 if single else 1e-12
    assert float(np.sum(u * pc.apply(v))) == pytest.approx(float(np.sum(v * pc.apply(u))), rel=rtol)
    assert float(np.sum(v * pc.apply(v))) > 0
    # a smooth pressure far from the grid's edge: the kernel's wrap-around on the grid's
    # torus is all that separates pc(A p) from p (measured 0.17 % in L2 at 0.1 mm cells)
    X, Y = g.centres()
    p = np.maximum(1.0 - (X**2 + Y**2) / 1.5**2, 0.0)
    back = pc.apply(op.apply(p))
    inside = X**2 + Y**2 < 1.2**2
    assert np.linalg.norm((back - p)[inside]) <= 0.01 * np.linalg.norm(p[inside])


def test_no_preconditioner_between_different_grids():
    a = Grid.covering(-1.0, 1.0, -1.0, 1.0, 0.1)
    b = Grid.covering(2.0, 3.0, -1.0, 1.0, 0.1)
    assert HS.grid_operator(a, b).preconditioner() is None


def test_the_block_takes_its_half_space_part_as_preconditioner():
    """On the finite block (half-space + smooth low-rank correction) the half-space kernel's
    inverse preconditions the same constrained CG: same contact, fewer iterations."""
    pytest.importorskip("fem_influence")

    block = small_block(MAT)
    asps = random_spheres(3, 10, 4.0, 4.0)
    grid = Grid.covering(-6.0, 6.0, -6.0, 6.0, 0.1)
    surf = surface_on(grid, asps)
    plain = solve_cg(block, surf, total_load=5.0, tol=1e-9)
    pre = solve_cg(block, surf, total_load=5.0, tol=1e-9, precondition=True)
    assert plain.converged and pre.converged
    p, q = plain.pressure_on(grid), pre.pressure_on(grid)
    assert np.linalg.norm(q - p) <= 1e-6 * np.linalg.norm(p)
    assert pre.iterations["cg"] < 0.8 * plain.iterations["cg"], (pre.iterations, plain.iterations)


def test_a_box_of_prime_sides_wraps_onto_a_fast_torus_and_keeps_its_iterations():
    # a union box's sides are whatever the patches give: 883 cells (a prime) made one
    # application of the wrapped inverse cost 2.8 times that of a 900-cell side
    from twoscale.influence.circulant import FAST_PRIME, _largest_prime_factor, torus_shape

    asps = crowded(4, 16)
    h = 0.05
    inner = reference_grid(Scene(material=MAT, asperities=asps, h=h, penetration=0.12), h)
    grid = Grid(inner.x0, inner.y0, h, 263, 269)  # both sides prime, the contacts inside
    assert grid.nx >= inner.nx and grid.ny >= inner.ny
    ly, lx = torus_shape(grid)
    assert (ly, lx) != grid.shape and ly >= grid.ny and lx >= grid.nx
    assert max(_largest_prime_factor(ly), _largest_prime_factor(lx)) <= FAST_PRIME
    pc = HS.grid_operator(grid).preconditioner()
    rng = np.random.default_rng(2)
    u, v = rng.standard_normal(grid.shape), rng.standard_normal(grid.shape)
    assert float(np.sum(u * pc.apply(v))) == pytest.approx(float(np.sum(v * pc.apply(u))), rel=1e-12)
    assert float(np.sum(v * pc.apply(v))) > 0
    surf = surface_on(grid, asps)
    plain = solve_cg(HS, surf, tol=1e-9, penetration=0.12)
    pre = solve_cg(HS, surf, tol=1e-9, penetration=0.12, precondition=True)
    assert plain.converged and pre.converged
    # on the grid's own torus the crowded tips take 19-22 iterations against 45-59 plain
    assert pre.iterations["cg"] < 0.5 * plain.iterations["cg"], (pre.iterations, plain.iterations)
    assert np.max(np.abs(pre.asperities.forces - plain.asperities.forces)) <= 1e-7 * plain.asperities.forces.max()


def test_a_longer_torus_keeps_a_maps_opposite_edges_apart(monkeypatch):
    # the box of a height map has stones in contact at opposite edges; on the box's own
    # torus the wrapped inverse coupled them as neighbours: 30 iterations against 19
    from twoscale.influence import circulant
    from twoscale.surface import RawMap, SurfaceOptions, build_surface
    from twoscale.surface.texture import road

    size = 16.0
    surface = build_surface(RawMap(road(size, 0.1, seed=3), 0.1, "mm", None, "road"), SurfaceOptions())
    grid = surface.hmap.grid
    assert grid.nx >= circulant.LONGER_TORUS_MIN_SIDE
    ly, lx = circulant.torus_shape(grid)
    assert ly >= circulant.TORUS_MARGIN * grid.ny and lx >= circulant.TORUS_MARGIN * grid.nx
    assert max(circulant._largest_prime_factor(ly), circulant._largest_prime_factor(lx)) <= circulant.FAST_PRIME
    surf = surface_on(grid, surface.asperities)
    load = 0.45 * size**2
    plain = solve_cg(HS, surf, total_load=load, tol=1e-9)
    longer = solve_cg(HS, surf, total_load=load, tol=1e-9, precondition=True)
    monkeypatch.setattr(circulant, "TORUS_MARGIN", 1.0)
    own = solve_cg(HS, surf, total_load=load, tol=1e-9, precondition=True)
    assert circulant.torus_shape(grid) == grid.shape  # 160 cells: already a fast length
    assert plain.converged and longer.converged and own.converged
    assert longer.iterations["cg"] < 0.85 * own.iterations["cg"], (longer.iterations, own.iterations)
    F, Fp = longer.asperities.forces, plain.asperities.forces
    assert np.max(np.abs(F - Fp)) <= 1e-7 * Fp.max()


def test_the_preconditioner_and_the_columns_share_one_inverse_transform_of_the_kernel(monkeypatch):
    # the union CG takes both the float32 preconditioner and the operator's columns: the
    # kernel table comes back from its spectrum once (an inverse transform of the padded
    # grid, 0.45 s on 3.9 M cells), and the circulant multiplier made from the kept offset
    # table equals the one made from the whole padded table (its wrapped offsets lie within)
    from twoscale.influence import circulant, convolution

    grid = Grid.covering(-1.0, 1.0, -0.7, 0.7, 0.02)
    op = HS.grid_operator(grid)
    op = getattr(op, "op", op)
    assert isinstance(op, convolution.ConvolutionOperator)
    expected = {dt: circulant._multiplier(grid, op.padded_table(), dt) for dt in (np.float64, np.float32)}
    inverses = []
    inverse = convolution._inverse
    monkeypatch.setattr(convolution, "_inverse", lambda *a: inverses.append(1) or inverse(*a))
    single = op.single_precision().preconditioner()
    op.columns()
    double = op.preconditioner()
    assert len(inverses) == 1
    assert np.array_equal(single._m, expected[np.float32]) and np.array_equal(double._m, expected[np.float64])
