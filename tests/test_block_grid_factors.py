"""The finite block's grid products with separable correction factors, their float32 form
and their columns, against the block's pointwise correction and its float64 products."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid

from helpers import random_spheres, small_block

pytest.importorskip("fem_influence")

MAT = Material(E=4.0, nu=0.5)


@pytest.fixture(scope="module")
def block():
    return small_block(MAT)


def _pointwise(block, target: Grid, source: Grid, p: np.ndarray) -> np.ndarray:
    """Love's convolution plus ``h^2 C(targets, sources) p`` with ``C`` from the block's
    pointwise correction (cubic weights of every source point, Q2 interpolation of every
    target point): the route the separable factors replace."""
    hs = block._halfspace.grid_operator(target, source).apply(p)
    C = block.correction(target.points(), source.points())
    return hs + target.h**2 * (C @ p.ravel()).reshape(target.shape)


def test_a_large_grids_correction_is_separable_and_equals_the_pointwise_one(block):
    from fem_influence.grid_factors import GridTarget, GridWeights

    g = Grid(-6.0, -5.5, 0.04, 300, 288)  # 86,400 cells: above the dense factors' bound
    op = block.grid_operator(g)
    assert isinstance(op._W, GridWeights) and isinstance(op._U, GridTarget)
    p = np.zeros(g.shape)
    p[100:140, 60:90] = np.random.default_rng(0).random((40, 30))
    on = p.ravel() > 0
    src = g.points()[on]
    C = block.correction(g.points(), src)  # (cells, loaded cells): the dense pointwise correction
    expected = block._halfspace.grid_operator(g).apply(p) + g.h**2 * (C @ p.ravel()[on]).reshape(g.shape)
    np.testing.assert_allclose(op.apply(p), expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())


def test_a_large_target_from_a_small_source_matches_the_cell_blocks(block):
    target, source = Grid(-6.0, -5.5, 0.04, 300, 288), Grid(1.0, 0.5, 0.04, 5, 4)
    dense = block.grid_matrix(target, source)  # the separable target factor times columns
    cells = block.cell_block(target.points(), source.points(), 0.04)
    np.testing.assert_allclose(dense, cells, rtol=1e-10, atol=1e-12 * np.abs(cells).max())
    p = np.random.default_rng(1).random(source.shape)
    expected = _pointwise(block, target, source, p)
    u = block.grid_operator(target, source).apply(p)
    np.testing.assert_allclose(u, expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())


def test_the_float32_product_and_the_columns(block):
    g = Grid(-6.0, -5.5, 0.04, 300, 288)
    op = block.grid_operator(g)
    single = op.single_precision()
    assert single is not op
    p = np.random.default_rng(2).random(g.shape)
    exact = op.apply(p)
    assert np.abs(single.apply(p) - exact).max() <= 1e-5 * np.abs(exact).max()
    cells, values = np.array([7, 4_000, 51_234, g.size - 1]), np.array([0.5, -1.0, 2.0, 0.25])
    out = np.zeros(g.size)
    op.columns()(out, cells, values)
    dp = np.zeros(g.size)
    dp[cells] = values
    ref = op.apply(dp.reshape(g.shape)).ravel()
    np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())


def test_the_columns_on_given_targets_of_a_separable_factor(block):
    # the factor's rows cannot be indexed: the correction on the whole grid, then the targets
    g = Grid(-6.0, -5.5, 0.04, 300, 288)
    op = block.grid_operator(g)
    cells, values = np.array([7, 4_000, 51_234]), np.array([0.5, -1.0, 2.0])
    dp = np.zeros(g.size)
    dp[cells] = values
    ref = op.apply(dp.reshape(g.shape)).ravel()
    targets = np.array([0, 3, 4_001, 51_234, g.size - 1])
    out = np.zeros(targets.size)
    op.columns(targets)(out, cells, values)
    np.testing.assert_allclose(out, ref[targets], rtol=1e-9, atol=1e-12 * np.abs(ref).max())


def test_the_cg_with_float32_directions_on_the_block_gives_the_float64_forces(block):
    from twoscale.indenters import surface_on
    from twoscale.reference import solve_cg

    asps = random_spheres(3, 12, 5.0, 3.0)
    g = Grid.covering(-6.5, 6.5, -6.5, 6.5, 0.05)
    surf = surface_on(g, asps)
    f64 = solve_cg(block, surf, total_load=8.0, precondition=True, precision="double")
    f32 = solve_cg(block, surf, total_load=8.0, precondition=True, precision="single-directions")
    assert f64.converged and f32.converged
    F, G = np.asarray(f64.asperities.forces), np.asarray(f32.asperities.forces)
    assert np.abs(G - F).max() <= 1e-7 * np.abs(F).max()
