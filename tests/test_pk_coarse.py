"""The union CG's coarse correction over squares (:mod:`twoscale.pk.coarse`): its coarse
matrix against the kernel's pair sums written out, the preconditioner symmetric positive
definite, and the constrained CG with it against the classical Polonsky-Keer CG."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from twoscale import Material
from twoscale.analytic import hertz
from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace
from twoscale.pk import coarse
from twoscale.pk.coarse import CoarseSpace, SquaresCorrection, coarse_matrix, near_sums
from twoscale.reference import solve_cg

MAT = Material(E=6.0, nu=0.5)
HS = HalfSpace(MAT)


def _loaded(shape, fraction, seed):
    rng = np.random.default_rng(seed)
    at = np.flatnonzero(rng.random(shape[0] * shape[1]) < fraction)
    return at, np.divmod(at, shape[1])


def _exact(table, shape, y, x, index, k):
    """``Z^T A Z`` from every pair of loaded cells (the kernel's table, entry by entry)."""
    ny, nx = shape
    a = table[np.abs(y[:, None] - y[None, :]) + ny - 1, np.abs(x[:, None] - x[None, :]) + nx - 1]
    z = np.zeros((len(y), k))
    z[np.arange(len(y)), index] = 1.0
    return z.T @ a @ z


@pytest.mark.parametrize("side,shape", [(7, (47, 53)), (6, (30, 31))])
def test_near_sums_are_the_pair_sums_written_out(side, shape):
    g = Grid(0.0, 0.0, 0.01, shape[1], shape[0])
    table = HS.grid_operator(g).offset_table()
    _, (y, x) = _loaded(shape, 0.2, side)
    columns = -(-shape[1] // side)
    keys, index = np.unique((y // side) * columns + x // side, return_inverse=True)
    exact = _exact(table, shape, y, x, index, len(keys))
    a, b, values = near_sums(table, shape, side, keys, index, y, x)
    # squares at most one apart in both directions, each pair once (the mirror's too: 5 of 9)
    ky, kx = np.divmod(keys, columns)
    assert np.all((np.abs(ky[a] - ky[b]) <= 1) & (np.abs(kx[a] - kx[b]) <= 1))
    # complex64 spectra: sums to about 1e-7 of the largest
    assert np.max(np.abs(values - exact[a, b])) <= 1e-6 * np.abs(exact).max()
    # the squares farther apart as point loads: the whole matrix within 1 %, positive definite
    energy = coarse_matrix(table, shape, side, keys, index, y, x)
    assert np.linalg.norm(energy - exact) <= 0.01 * np.linalg.norm(exact)
    assert np.linalg.eigvalsh(energy).min() > 0.0


def test_the_corrected_preconditioner_is_symmetric_positive_definite(monkeypatch):
    """``P = Q^T C Q + Z E^-1 Z^T`` on the loaded cells, some loaded cells off the squares of
    the set it was built on (cells that entered since) and some of those left."""
    monkeypatch.setattr(coarse, "MIN_CELLS", 0)  # (a grid small enough for P written out)
    shape = (40, 44)
    g = Grid(0.0, 0.0, 0.01, shape[1], shape[0])
    op = HS.grid_operator(g)
    inverse = op.preconditioner()
    owner = SquaresCorrection(inverse, op.offset_table(), shape, side=8)
    cells = np.arange(g.size)
    built, _ = _loaded(shape, 0.08, 3)
    loaded = np.zeros(g.size, bool)
    loaded[built] = True
    space = CoarseSpace.build(owner, cells, loaded)
    assert space is not None and space.k > 10
    now = loaded.copy()
    now[built[::7]] = False
    now[_loaded(shape, 0.02, 4)[0]] = True
    torus = lambda v: inverse.apply(v.reshape(shape)).ravel()  # noqa: E731
    on = np.flatnonzero(now)
    columns = []
    for i in on:
        e = np.zeros(g.size)
        e[i] = 1.0
        columns.append(space.direction(e, now, torus)[on])
    p = np.array(columns).T
    assert np.max(np.abs(p - p.T)) <= 1e-9 * np.abs(p).max()
    assert np.linalg.eigvalsh(0.5 * (p + p.T)).min() > 0.0


def test_a_direction_is_the_balancing_form_written_out(monkeypatch):
    """``direction`` against ``P = (I - Z E^-1 Z^T A) S C S (I - A Z E^-1 Z^T) + Z E^-1 Z^T``
    written out densely: ``S`` the cells loaded now, ``Z`` the squares' indicators and ``A``
    the space's product on ``D`` (cells loaded now and at the build), ``C`` any matrix (here
    random), on a part of a grid's cells with cells entered and left since the build."""
    monkeypatch.setattr(coarse, "MIN_CELLS", 0)
    shape, rng = (40, 44), np.random.default_rng(5)
    op = HS.grid_operator(Grid(0.0, 0.0, 0.01, shape[1], shape[0]))
    owner = SquaresCorrection(None, op.offset_table(), shape, side=8)
    cells = np.flatnonzero(rng.random(shape[0] * shape[1]) < 0.7)
    n = len(cells)
    loaded = rng.random(n) < 0.12
    space = CoarseSpace.build(owner, cells, loaded)
    assert space is not None and space.k > 10
    now = loaded.copy()
    now[np.flatnonzero(loaded)[::5]] = False
    now[rng.choice(n, 20)] = True
    member = now & loaded
    z = np.zeros((n, space.k))
    z[np.flatnonzero(member), space.square[member]] = 1.0
    e_inv = sla.cho_solve(space.factor, np.eye(space.k))
    a_at = np.array([space.product(e) for e in np.eye(len(space.at))]).T
    a = np.zeros((n, n))
    a[np.ix_(space.at, space.at)] = a_at
    a *= np.outer(member, member)
    c = rng.random((n, n))
    c = c @ c.T / n
    s = np.diag(now.astype(float))
    coarse_part = z @ e_inv @ z.T
    p = (np.eye(n) - coarse_part @ a) @ s @ c @ s @ (np.eye(n) - a @ coarse_part) + coarse_part
    v = rng.standard_normal(n) * now
    got = space.direction(v, now, lambda w: c @ w)
    assert np.allclose(got, p @ v, rtol=0, atol=1e-10 * np.abs(p @ v).max())


def _many_tips(n_side: int, spacing: float, radius: float, seed: int):
    rng = np.random.default_rng(seed)
    c = (np.arange(n_side) - 0.5 * (n_side - 1)) * spacing
    X, Y = np.meshgrid(c, c)
    z = rng.uniform(0.0, 0.004, X.size)
    return [Asperity(float(x), float(y), float(zz), radius) for x, y, zz in zip(X.ravel(), Y.ravel(), z)]


def _assert_the_answer_in_fewer_iterations(corrected, torus, plain) -> None:
    """The corrected CG converged to the classical CG's forces (within 1e-6 of the largest) in
    fewer iterations than the torus preconditioner alone."""
    assert plain.converged and torus.converged and corrected.converged
    assert corrected.iterations["cg"] < torus.iterations["cg"], (corrected.iterations, torus.iterations)
    F, Fp = corrected.asperities.forces, plain.asperities.forces
    assert np.max(np.abs(F - Fp)) <= 1e-6 * Fp.max()


@pytest.mark.parametrize("load", [{"penetration": 0.012}, {"total_load": 1.5}])
def test_the_coarse_correction_keeps_the_answer_in_fewer_iterations(load, monkeypatch):
    """400 separated spheres on 261 x 261 cells (4-7 % of them loaded): the preconditioned
    CG with the correction against the classical CG (no preconditioner) and fewer iterations
    than with the torus alone (built on a grid this small only when allowed)."""
    asps = _many_tips(20, 0.6, 2.0, 1)
    g = Grid.covering(-6.5, 6.5, -6.5, 6.5, 0.05)
    surf = surface_on(g, asps)
    plain = solve_cg(HS, surf, tol=1e-9, **load)
    torus = solve_cg(HS, surf, tol=1e-9, precondition=True, **load)
    kept = solve_cg(HS, surf, tol=1e-9, precondition=True, coarse=True, **load)
    assert kept.iterations == torus.iterations  # (below MIN_CELLS: no correction)
    monkeypatch.setattr(coarse, "MIN_CELLS", 0)
    corrected = solve_cg(HS, surf, tol=1e-9, precondition=True, coarse=True, **load)
    _assert_the_answer_in_fewer_iterations(corrected, torus, plain)
    assert corrected.penetration == pytest.approx(plain.penetration, abs=1e-9)


def test_the_coarse_correction_on_a_bonded_block_keeps_the_answer():
    """On a bonded block (10 mm thick under 400 spheres 13 mm across) the correction takes
    the half-space's table (:meth:`BlockGridOperator.coarse_table`), not the block's kernel:
    the balancing preconditioner stays symmetric positive definite, so the CG reaches the
    classical CG's answer, in fewer iterations than with the torus alone."""
    pytest.importorskip("skfem")
    from helpers import small_block

    block = small_block(MAT)
    asps = _many_tips(20, 0.6, 2.0, 1)
    g = Grid.covering(-6.5, 6.5, -6.5, 6.5, 0.05)
    surf = surface_on(g, asps)
    load = {"penetration": 0.012}
    plain = solve_cg(block, surf, tol=1e-9, **load)
    torus = solve_cg(block, surf, tol=1e-9, precondition=True, **load)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(coarse, "MIN_CELLS", 0)
        corrected = solve_cg(block, surf, tol=1e-9, precondition=True, coarse=True, **load)
    _assert_the_answer_in_fewer_iterations(corrected, torus, plain)


@pytest.mark.parametrize("shape,built", [((505, 517), False), ((612, 613), True)])
def test_the_correction_is_built_from_its_least_grid(shape, built):
    """The same contact (sparse squares, 4 % of the cells loaded) on a box of seed 7's #55
    (261 K cells, where the correction cost more than the iterations it saved) gets none,
    on one of #177's (375 K cells, where it saved CPU) it does."""
    ny, nx = shape
    cells = np.arange(ny * nx)
    loaded = np.zeros(ny * nx, bool)
    y, x = np.meshgrid(np.arange(5, ny - 5, 25), np.arange(5, nx - 5, 25), indexing="ij")
    for dy in range(5):
        for dx in range(5):
            loaded[(y + dy).ravel() * nx + (x + dx).ravel()] = True
    table = HS.grid_operator(Grid(0.0, 0.0, 0.01, nx, ny)).offset_table()
    owner = SquaresCorrection(None, table, shape)
    assert (CoarseSpace.build(owner, cells, loaded) is not None) == built


def test_the_whole_grid_rows_take_the_torus_product_of_its_cells():
    """On every cell the preconditioner takes the torus inverse's own product of the field
    (no scatter and gather by index): the same values, to the bit, as the product on the
    same cells given by index (``on_cells``), and as the inverse's field product."""
    shape = (131, 140)  # (sides from 128 cells: a torus longer than the grid, the pruned transforms)
    op = HS.grid_operator(Grid(0.0, 0.0, 0.01, shape[1], shape[0])).single_precision()
    inverse = op.preconditioner()
    owner = SquaresCorrection(inverse, op._parent.offset_table(), shape)
    rng = np.random.default_rng(9)
    v = rng.standard_normal((1, *shape))
    on = rng.random((1, *shape)) < 0.3
    by_rows = owner(v, on)
    by_index = owner.op.on_cells(np.arange(shape[0] * shape[1]))(v.ravel())
    assert np.array_equal(by_rows.ravel(), by_index)
    assert np.array_equal(by_rows[0], inverse.apply(v[0]))


def test_hertz_on_one_sphere_by_the_whole_box_preconditioner(monkeypatch):
    """The union CG's settings on one paraboloid (R 10 mm, d 0.05 mm; 128 cells across the
    contact, 142 a side: the torus longer than the grid) through the whole box's torus
    product: Hertz's load within the discretisation's 0.5 % (O(h^1.5), 0.05 % at this h)
    and the classical CG's pressures within the tolerance's reach (both stop at a KKT
    residual of 1e-8 of the largest displacement: 9e-7 of the largest pressure apart)."""
    R, d = 10.0, 0.05
    a = np.sqrt(R * d)
    h = 2.0 * a / 128
    g = Grid.covering(-1.1 * a, 1.1 * a, -1.1 * a, 1.1 * a, h, anchor=(0.5 * h, 0.5 * h))
    surf = surface_on(g, [Asperity(0.0, 0.0, 0.0, R)])
    calls = []
    whole = SquaresCorrection._every_cell
    monkeypatch.setattr(SquaresCorrection, "_every_cell", lambda self, v: calls.append(1) or whole(self, v))
    union = solve_cg(HS, surf, penetration=d, tol=1e-8, precision="single-directions", precondition=True, coarse=True)
    plain = solve_cg(HS, surf, penetration=d, tol=1e-8)
    assert union.converged and plain.converged and calls  # (the whole box's route, every step)
    p, q = union.fields[0].pressure, plain.fields[0].pressure
    assert np.max(np.abs(p - q)) <= 5e-6 * q.max()
    assert union.total_load == pytest.approx(float(hertz.load(R, d, MAT.E_star)), rel=5e-3)
