"""What makes the constrained CG cheap on boxes of millions of cells, each against an
independent answer: the constraint fit by normal equations against ``lstsq`` on the loaded
cells, the plane restoring the load and moments, the pivot's hull test from the rows' end
cells against the hull of every cell, Love's table gathered from a window's own quadrant
against Love's closed form, and the union CG that keeps its conjugate directions when a
few cells enter against the full-grid reference."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from helpers import crowded
from twoscale import Material
from twoscale.analytic.halfspace import love_rectangle
from twoscale.grid import Grid
from twoscale.indenters import Surface, surface_on
from twoscale.influence import HalfSpace, halfspace
from twoscale.micro.union import KEEP_CONJUGACY, UnionSettings
from twoscale.reference import solve_cg
from twoscale.reference.on_scene import reference_grid
from twoscale.scene import Scene
from twoscale.pk.projection import fit, masked_sum, project, restore
from twoscale.reference._problem import _check_pivot_inside

MAT = Material(E=6.0, nu=0.5)
HS = HalfSpace(MAT)


def _plane_basis(nx: int, ny: int, pivot=(0.3, -0.2)) -> np.ndarray:
    X, Y = np.meshgrid(np.arange(nx) * 0.1, np.arange(ny) * 0.1)
    return np.column_stack([np.ones(nx * ny), X.ravel() - pivot[0], Y.ravel() - pivot[1]])


@pytest.mark.parametrize("n", [60, 6000])  # short rows (lstsq) and long ones (normal equations)
def test_constraint_fit_equals_least_squares_on_the_loaded_cells(n):
    rng = np.random.default_rng(1)
    basis = _plane_basis(n // 20, 20)
    v = rng.normal(size=(2, basis.shape[0]))
    on = rng.uniform(size=v.shape) < 0.3
    c = fit(v, basis, on)
    for i in range(2):
        ref = np.linalg.lstsq(basis[on[i]], v[i, on[i]], rcond=None)[0]
        assert np.allclose(c[i], ref, rtol=1e-12, atol=1e-12)
    w = v.copy()
    project(w, basis, on)
    for i in range(2):  # the projected rows are orthogonal to the basis on their cells
        assert np.abs(basis[on[i]].T @ w[i, on[i]]).max() <= 1e-12 * np.abs(v).sum()
    assert np.allclose(masked_sum(v, on), np.where(on, v, 0.0).sum(axis=1), rtol=1e-13)


def test_constraint_fit_on_cells_in_a_line_falls_back_to_least_squares():
    basis = _plane_basis(300, 20)  # a long row: the normal equations' branch
    v = np.random.default_rng(2).normal(size=(1, basis.shape[0]))
    on = np.zeros_like(v, dtype=bool)
    on[0, 5 * 300 : 6 * 300] = True  # one row of the grid: y constant, the normal equations singular
    c = fit(v, basis, on)
    ref = np.linalg.lstsq(basis[on[0]], v[0, on[0]], rcond=1e-13)[0]
    assert np.allclose(c[0], ref, rtol=1e-10, atol=1e-12)


def test_plane_restore_meets_load_and_moments_and_keeps_pressure_non_negative():
    basis = _plane_basis(40, 30)
    rng = np.random.default_rng(3)
    p = np.maximum(rng.normal(size=(1, basis.shape[0])), 0.0)
    # a target that a positive plane factor reaches: the load and moments of p times one
    plane = 1.2 + 0.05 * basis[:, 1] - 0.03 * basis[:, 2]
    assert plane.min() > 0.0
    target = (p * plane) @ basis
    restore(p, basis, target)
    assert p.min() >= 0.0
    assert np.allclose(p[0] @ basis, target[0], rtol=1e-10, atol=1e-10 * target[0, 0])


def test_pivot_test_from_the_rows_end_cells_equals_the_hull_of_every_cell():
    rng = np.random.default_rng(4)
    grid = Grid(-3.0, -2.0, 0.1, 60, 50)
    X, Y = grid.centres()
    height = np.where(((X - 0.5) ** 2 / 4 + (Y + 0.3) ** 2 / 2.5) < 1.0, 0.0, np.inf)  # an ellipse of material
    height[rng.uniform(size=height.shape) < 0.2] = np.inf  # and holes
    surface = Surface(grid, height, np.zeros(grid.shape, int), 1)
    cand = np.isfinite(height)
    hull = ConvexHull(np.column_stack([X[cand], Y[cand]]))
    for pivot in rng.uniform((-3.5, -2.5), (3.5, 3.5), size=(40, 2)):
        inside = np.all(hull.equations[:, :2] @ pivot + hull.equations[:, 2] <= 1e-9 * grid.h)
        if inside:
            _check_pivot_inside(surface, tuple(pivot))
        else:
            with pytest.raises(ValueError, match="pivot"):
                _check_pivot_inside(surface, tuple(pivot))


def test_a_table_beyond_the_kept_quadrant_is_loves_closed_form(monkeypatch):
    monkeypatch.setattr(halfspace, "QUADRANT_MAX_ENTRIES", 100)  # every table here is beyond it
    grid = Grid(0.0, 0.0, 0.05, 23, 17)
    op = HS.grid_operator(grid)
    p = np.random.default_rng(5).uniform(size=grid.shape)
    X, Y = grid.centres()
    dx = X.ravel()[:, None] - X.ravel()[None, :]
    dy = Y.ravel()[:, None] - Y.ravel()[None, :]
    dense = love_rectangle(dx, dy, 0.025, 0.025, MAT.E_star)
    assert np.allclose(op.apply(p).ravel(), dense @ p.ravel(), rtol=1e-12, atol=0.0)
    far = Grid(3.0, 2.0, 0.05, 9, 7)  # a pair whose offsets do not straddle 0: computed directly
    cross = HS.grid_matrix(far, grid)
    Xf, Yf = far.centres()
    ref = love_rectangle(
        Xf.ravel()[:, None] - X.ravel()[None, :], Yf.ravel()[:, None] - Y.ravel()[None, :], 0.025, 0.025, MAT.E_star
    )
    # (Love's corner sums lose digits at a distance: the two coordinate roundings differ)
    assert np.allclose(cross, ref, rtol=1e-10, atol=0.0)


@pytest.mark.parametrize("load", [{"total_load": 60.0}, {"total_load": 60.0, "tilt": True, "pivot": (0.5, -0.4)}])
def test_cg_keeping_its_directions_in_both_stages_gives_the_classical_answer(load):
    asps = crowded(7, 30)
    grid = reference_grid(Scene(material=MAT, asperities=asps, h=0.08, total_load=60.0), 0.08)
    surf = surface_on(grid, asps)
    classical = solve_cg(HS, surf, tol=1e-10, **load)
    runs = {
        keep: solve_cg(HS, surf, tol=1e-9, precision="mixed", precondition=True, keep_conjugacy=keep, **load)
        for keep in (0.0, KEEP_CONJUGACY)
    }
    assert classical.converged and all(r.converged for r in runs.values())
    Fr = classical.asperities.forces
    for r in runs.values():
        assert np.max(np.abs(r.asperities.forces - Fr)) <= 1e-6 * Fr.max()
    assert UnionSettings(tol=1e-8).keep_conjugacy == KEEP_CONJUGACY  # what the union CG runs with
