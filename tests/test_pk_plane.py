"""The tilt's constraint algebra by sums along the grid's rows (twoscale.pk.plane) against
least squares written out on the loaded cells, and the CG with it against the general one."""

from __future__ import annotations

import numpy as np

from helpers import crowded
from twoscale import Material
from twoscale.indenters import surface_on
from twoscale.influence import HalfSpace
from twoscale.pk.plane import PlaneBasis
from twoscale.pk.projection import SHORT_ROW, denominator, fit, project, restore
from twoscale.reference import solve_cg
from twoscale.reference.on_scene import reference_grid
from twoscale.scene import Scene


def _grid(ny=37, nx=53, h=0.2, px=-41.0, py=17.5):
    x = 400.0 + h * np.arange(nx) - px  # far from the pivot: an uncentred basis
    y = -120.0 + h * np.arange(ny) - py
    X, Y = np.meshgrid(x, y)
    return x, y, np.column_stack([np.ones(X.size), X.ravel(), Y.ravel()])


def test_the_fit_is_least_squares_on_the_loaded_cells():
    rng = np.random.default_rng(3)
    x, y, basis = _grid()
    plane = PlaneBasis(x, y)
    assert plane.matches(basis) and not plane.matches(basis[:, [0, 2, 1]])
    v = rng.normal(size=(2, len(basis))) + basis @ np.array([0.3, -2e-3, 5e-3])
    on = rng.random(v.shape) < 0.2
    c = fit(v, basis, on, plane=plane)
    for i in range(2):
        expected = np.linalg.lstsq(basis[on[i]], v[i, on[i]], rcond=None)[0]
        assert np.allclose(c[i], expected, rtol=1e-9, atol=1e-12)
    w = v.copy()
    project(w, basis, on, plane=plane)
    assert np.allclose(w, v - c @ basis.T, atol=1e-10)
    assert np.allclose(basis[on[0]].T @ w[0, on[0]], 0.0, atol=1e-8)  # orthogonal on the loaded cells


def test_cells_on_a_line_fall_back_to_the_general_fit():
    x, y, basis = _grid()
    plane = PlaneBasis(x, y)
    on = np.zeros((1, len(basis)), bool)
    on[0, 5 * len(x) : 6 * len(x)] = True  # one row of the grid: the y column is constant on it
    v = np.random.default_rng(4).normal(size=(1, len(basis)))
    assert plane.fit(v[0], on[0]) is None
    c = fit(v, basis, on, plane=plane)
    assert np.allclose(basis[on[0]] @ c[0], basis[on[0]] @ np.linalg.lstsq(basis[on[0]], v[0, on[0]], rcond=None)[0])


def test_restoring_meets_the_load_and_moments():
    rng = np.random.default_rng(5)
    x, y, basis = _grid()
    plane = PlaneBasis(x, y)
    p = np.where(rng.random((1, len(basis))) < 0.3, rng.random((1, len(basis))), 0.0)
    target = (p @ basis) * np.array([1.3, 1.29, 1.31])
    q = p.copy()
    restore(q, basis, target, plane=plane)
    assert q.min() >= 0.0
    assert np.allclose(q @ basis, target, rtol=1e-12)
    general = p.copy()
    restore(general, basis, target)
    assert np.array_equal(q > 0, general > 0)
    assert np.abs(q - general).max() <= 1e-8 * general.max()  # (the general one is uncentred)


def test_the_cg_with_plane_sums_gives_the_general_answer():
    mat = Material(E=6.0, nu=0.5)
    scene = Scene(material=mat, asperities=crowded(2, 12), h=0.1, total_load=24.0, tilt=True)
    grid = reference_grid(scene, 0.1)
    surf = surface_on(grid, crowded(2, 12))
    kw = dict(total_load=24.0, tilt=True, tol=1e-9, precondition=True, precision="single-directions")
    general = solve_cg(HalfSpace(mat), surf, **kw)
    sums = solve_cg(HalfSpace(mat), surf, plane_sums=True, **kw)
    assert general.converged and sums.converged
    p, q = general.pressure_on(grid), sums.pressure_on(grid)
    assert np.linalg.norm(p - q) <= 1e-7 * np.linalg.norm(p)
    assert np.allclose(sums.tilt, general.tilt, atol=1e-9)


def test_a_fit_over_loaded_cells_changed_in_place_is_their_own():
    # the Gram matrix is kept between fits over the same cells: an array changed in place
    # (the iteration's loaded cells are one buffer) must not reuse it
    rng = np.random.default_rng(6)
    x, y, basis = _grid()
    plane = PlaneBasis(x, y)
    v = rng.normal(size=len(basis))
    on = rng.random(len(basis)) < 0.4
    for _ in range(3):
        c = plane.fit(v, on)
        assert c is not None
        assert np.allclose(c, np.linalg.lstsq(basis[on], v[on], rcond=None)[0], rtol=1e-9, atol=1e-12)
        on[rng.integers(0, len(on), 40)] ^= True


def test_the_load_and_moments_held_are_the_basis_sums():
    rng = np.random.default_rng(7)
    x, y, basis = _grid()
    p = np.where(rng.random(len(basis)) < 0.3, rng.random(len(basis)), 0.0)
    assert np.allclose(PlaneBasis(x, y).moments(p), basis.T @ p, rtol=1e-12)


def test_long_rows_sum_without_the_matrix_product_to_the_same_values():
    # above SHORT_ROW cells the rows' sums are passes of their own (no BLAS threads): the
    # fit, the moments, the restoring and a step's denominator against the written-out algebra
    rng = np.random.default_rng(8)
    x, y, basis = _grid(ny=71, nx=90)
    assert len(basis) > SHORT_ROW
    plane = PlaneBasis(x, y)
    on = rng.random((1, len(basis))) < 0.3
    v = rng.normal(size=(1, len(basis))) + basis @ np.array([0.3, -2e-3, 5e-3])
    c = fit(v, basis, on, plane=plane)
    assert np.allclose(c[0], np.linalg.lstsq(basis[on[0]], v[0, on[0]], rcond=None)[0], rtol=1e-9, atol=1e-12)
    p = np.where(on, rng.random(on.shape), 0.0)
    assert np.allclose(plane.moments(p[0]), basis.T @ p[0], rtol=1e-12)
    target = (p @ basis) * np.array([1.3, 1.29, 1.31])
    restore(p, basis, target, plane=plane)
    assert p.min() >= 0.0 and np.allclose(p @ basis, target, rtol=1e-12)
    t, r = np.where(on, rng.normal(size=on.shape), 0.0), rng.normal(size=on.shape)
    written = r[0] @ t[0] - np.linalg.lstsq(basis[on[0]], r[0, on[0]], rcond=None)[0] @ (basis.T @ t[0])
    bt = np.ascontiguousarray(basis.T)
    assert np.isclose(denominator(r, t, on, None, basis, bt, plane)[0], written, rtol=1e-9)
