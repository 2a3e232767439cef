"""The precorrected-FFT product on a sparse part of a grid (:mod:`twoscale.influence.precorrected`)
against the exact zero-padded product, its near table against the pairs evaluated one by one,
and the union CG's solve with it (the kernel's :class:`~twoscale.pk.products.Cheap` rule)
against the same solve on the exact route."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace
from twoscale.influence.precorrected import MAX_FRACTION, Precorrected
from twoscale.reference import solve_cg

MAT = Material(E=6.0, nu=0.5)
HS = HalfSpace(MAT)


def _operator(ny: int, nx: int, h: float = 0.1):
    return HS.grid_operator(Grid(0.0, 0.0, h, nx, ny))


def _exact(op, cells: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The exact product at ``cells`` (float64 padded FFT of the whole grid)."""
    field = np.zeros(op.source.ny * op.source.nx)
    field[cells] = v
    return op.apply(field.reshape(op.source.shape)).ravel()[cells]


def _clustered(ny: int, nx: int, spacing: int, radius: float, rng) -> np.ndarray:
    """Small discs of cells on a jittered lattice (a lattice of tips' contacts)."""
    y, x = np.mgrid[0:ny, 0:nx]
    on = np.zeros((ny, nx), bool)
    for cy in range(spacing // 2, ny, spacing):
        for cx in range(spacing // 2, nx, spacing):
            jy, jx = rng.integers(-2, 3, 2)
            on |= (y - cy - jy) ** 2 + (x - cx - jx) ** 2 <= radius**2
    return np.flatnonzero(on)


def _error(pc, op, cells, v) -> float:
    exact = _exact(op, cells, v)
    return float(np.linalg.norm(pc(v) - exact) / np.linalg.norm(exact))


def test_a_coarse_grid_of_the_cells_themselves_gives_the_exact_product():
    """c = 1: every cell is a node (weights 1 and 0), the coarse route is the exact
    convolution and every near correction vanishes."""
    op, rng = _operator(57, 64), np.random.default_rng(1)
    cells = np.sort(rng.choice(57 * 64, 300, replace=False))
    pc = Precorrected(op.offset_table(), op.source.shape, cells, coarse=1, radius=3)
    assert np.abs(pc.near.data).max() <= 1e-12 * np.abs(op.offset_table()).max()
    assert _error(pc, op, cells, rng.random(300)) < 1e-12


def test_near_pairs_covering_every_pair_give_the_exact_product():
    """A radius past the grid: every pair is precorrected, the coarse route cancels."""
    op, rng = _operator(45, 52), np.random.default_rng(2)
    cells = np.sort(rng.choice(45 * 52, 400, replace=False))
    pc = Precorrected(op.offset_table(), op.source.shape, cells, coarse=5, radius=52)
    assert pc.near.nnz == 400 * 400
    assert _error(pc, op, cells, rng.random(400)) < 1e-12


@pytest.mark.parametrize("layout", ["scattered", "clustered"])
def test_the_products_error_on_sparse_parts_is_within_its_bound_and_falls_with_the_radius(layout):
    """Parts of about 2 % of a 400 x 400 grid, random pressures: relative L2 error within
    2e-3 at the default (c 7, r 21; measured 1.2e-3 scattered, 1.0e-3 clustered here, 4.2e-4
    on a lattice of 8,772 contacts), and smaller with a wider near field or a finer coarse
    grid (measured 0.52x and 0.31-0.37x)."""
    ny = nx = 400
    op, rng = _operator(ny, nx), np.random.default_rng(3)
    if layout == "scattered":
        cells = np.sort(rng.choice(ny * nx, ny * nx // 50, replace=False))
    else:
        cells = _clustered(ny, nx, 14, 1.0, rng)
    assert cells.size < MAX_FRACTION * ny * nx
    table, v = op.offset_table(), rng.random(cells.size)
    default = _error(Precorrected(table, (ny, nx), cells), op, cells, v)
    wider = _error(Precorrected(table, (ny, nx), cells, radius=35), op, cells, v)
    finer = _error(Precorrected(table, (ny, nx), cells, coarse=4, radius=21), op, cells, v)
    assert default < 2e-3
    assert wider < 0.7 * default
    assert finer < 0.7 * default


def _coarse_kernel_direct(table, shape, c, node_offset):
    (ny, nx), (dy, dx) = shape, node_offset
    oy, ox = c * dy, c * dx
    assert abs(oy) < ny and abs(ox) < nx  # (the test's pairs stay inside the table)
    return table[oy + ny - 1, ox + nx - 1]


def test_the_near_matrix_holds_each_pair_within_the_radius_with_its_exact_less_coarse_coefficient():
    """Every pair of part cells within the Chebyshev radius, and no other, with the kernel
    at its offset less the sum over both cells' four nodes of their bilinear weights times
    the kernel between the nodes, evaluated pair by pair here."""
    ny, nx, c, r = 90, 80, 6, 9
    op, rng = _operator(ny, nx), np.random.default_rng(4)
    cells = np.sort(rng.choice(ny * nx, 250, replace=False))
    table = op.offset_table()
    pc = Precorrected(table, (ny, nx), cells, coarse=c, radius=r)
    y, x = np.divmod(cells, nx)
    near = (np.abs(y[:, None] - y[None, :]) <= r) & (np.abs(x[:, None] - x[None, :]) <= r)
    dense = pc.near.toarray()
    assert pc.near.nnz == near.sum()
    assert np.all(dense[~near] == 0.0)

    def nodes(k):
        iy, sy = divmod(int(y[k]), c)
        ix, sx = divmod(int(x[k]), c)
        return [
            ((iy + a, ix + b), (1 - sy / c if a == 0 else sy / c) * (1 - sx / c if b == 0 else sx / c))
            for a in (0, 1)
            for b in (0, 1)
        ]

    pairs = np.argwhere(near)
    for i, j in pairs[rng.choice(len(pairs), 60, replace=False)]:
        exact = table[y[i] - y[j] + ny - 1, x[i] - x[j] + nx - 1]
        coarse = sum(
            wi * wj * _coarse_kernel_direct(table, (ny, nx), c, (ni[0] - nj[0], ni[1] - nj[1]))
            for ni, wi in nodes(i)
            for nj, wj in nodes(j)
        )
        assert dense[i, j] == pytest.approx(exact - coarse, rel=1e-12, abs=1e-14 * np.abs(table).max())


def _pair_by_pair(table, shape, cells, c, r):
    """The near matrix and a window's matrix (``w[dy + r, dx + r]``) written out densely from
    the definition: every pair within the Chebyshev radius, the kernel at its offset less the
    16 node-to-node terms of the bilinear weights (the coarse kernel read from ``table``)."""
    ny, nx = shape
    y, x = np.divmod(cells, nx)
    dy, dx = y[:, None] - y[None, :], x[:, None] - x[None, :]
    near = (np.abs(dy) <= r) & (np.abs(dx) <= r)
    iy, sy = np.divmod(y, c)
    ix, sx = np.divmod(x, c)
    wy, wx = [1 - sy / c, sy / c], [1 - sx / c, sx / c]
    coarse = np.zeros(near.shape)
    for a, b, a2, b2 in np.ndindex(2, 2, 2, 2):
        oy = c * ((iy + a)[:, None] - (iy + a2)[None, :])
        ox = c * ((ix + b)[:, None] - (ix + b2)[None, :])
        k = table[np.clip(oy, 1 - ny, ny - 1) + ny - 1, np.clip(ox, 1 - nx, nx - 1) + nx - 1]
        coarse += (wy[a] * wx[b])[:, None] * (wy[a2] * wx[b2])[None, :] * k
    exact = table[np.clip(dy, 1 - ny, ny - 1) + ny - 1, np.clip(dx, 1 - nx, nx - 1) + nx - 1]
    return near, np.where(near, exact - coarse, 0.0), (dy + r, dx + r)


@pytest.mark.parametrize("layout", ["edges", "dense", "one row", "one cell"])
def test_every_near_pair_and_its_window_entry_against_the_definition_written_out(layout):
    """The whole near matrix, pair by pair: contacts crowding the grid's four edges and
    corners (runs cut by the edges, empty rows), a part of every cell, one grid row, one cell;
    and a window's matrix on the same pairs (:meth:`Precorrected.on_near_pairs`)."""
    ny, nx, c, r = 41, 37, 4, 6
    op, rng = _operator(ny, nx), np.random.default_rng(8)
    table = op.offset_table()
    if layout == "edges":
        y, x = np.mgrid[0:ny, 0:nx]
        edge = np.minimum(np.minimum(y, ny - 1 - y), np.minimum(x, nx - 1 - x))
        cells = np.flatnonzero((edge < 3) & (rng.random((ny, nx)) < 0.6) | (rng.random((ny, nx)) < 0.02))
    else:
        chosen = {"dense": np.arange(ny * nx), "one row": np.arange(5 * nx, 6 * nx), "one cell": np.array([7 * nx])}
        cells = chosen[layout]
    pc = Precorrected(table, (ny, nx), cells, coarse=c, radius=r)
    near, want, (wy, wx) = _pair_by_pair(table, (ny, nx), cells, c, r)
    got = pc.near.toarray()
    assert pc.near.nnz == near.sum() and pc.near.has_sorted_indices
    assert np.allclose(got, want, rtol=1e-12, atol=1e-14 * np.abs(table).max())
    window = rng.random((2 * r + 1, 2 * r + 1)) + 1.0
    on = pc.on_near_pairs(window).toarray()
    assert np.array_equal(on, np.where(near, window[np.clip(wy, 0, 2 * r), np.clip(wx, 0, 2 * r)], 0.0))


def _lattice_surface(n: int, h: float):
    """n x n spheres (R 0.5 mm) 1.2 mm apart, tip recesses 0-0.002 mm, on a grid of h."""
    rng = np.random.default_rng(5)
    side = 1.2 * n
    grid = Grid(-side / 2, -side / 2, h, int(side / h), int(side / h))
    asps = [
        Asperity(-side / 2 + 0.6 + 1.2 * i, -side / 2 + 0.6 + 1.2 * j, float(rng.uniform(0, 0.002)), 0.5)
        for i in range(n)
        for j in range(n)
    ]
    return surface_on(grid, asps)


def test_a_solve_with_the_precorrected_directions_meets_the_same_test_as_the_exact_route():
    """Penetration control on a lattice of 100 spheres, the CG on the cells near the tips
    (under 3 % of the grid): with the precorrected products the same contact as on the exact
    route, to the same KKT tolerance, with precorrected products taken."""
    surf = _lattice_surface(10, 0.025)
    d = 0.01
    reach = np.isfinite(surf.height) & (surf.height < d + 0.001)
    assert reach.mean() < MAX_FRACTION
    settings = dict(penetration=d, tol=1e-8, precondition=True, precision="single-directions", reach=reach)
    start = np.maximum(d - surf.height, 0.0)
    start = np.where(np.isfinite(start), start, 0.0)
    exact = solve_cg(HS, surf, start=start, rough_start=True, **settings)
    cheap = solve_cg(HS, surf, start=start, rough_start=True, precorrected=True, **settings)
    assert exact.converged and cheap.converged
    assert "precorrected" not in exact.iterations
    assert cheap.iterations["precorrected"] > cheap.iterations["cg"]  # every direction, and more
    assert cheap.residuals["gap"][-1] <= 1e-8
    p, q = cheap.fields[0].pressure, exact.fields[0].pressure
    assert np.linalg.norm(p - q) <= 1e-6 * np.linalg.norm(q)
    assert cheap.total_load == pytest.approx(exact.total_load, rel=1e-7)


def test_the_torus_inverses_kernel_cut_at_the_near_radius_is_its_impulse_response_and_positive_definite():
    """The inverse's kernel at the offsets within r is its product with a unit impulse (its
    own pruned transforms), and on a sparse part the cut kernel is an M-matrix (off-diagonal
    entries not positive, rows summing above 0): symmetric positive definite on any cells."""
    ny = nx = 300
    op, rng = _operator(ny, nx), np.random.default_rng(6)
    inverse = op.single_precision().preconditioner()
    r = 12
    window = inverse.offsets(r)
    impulse = np.zeros((ny, nx))
    impulse[150, 140] = 1.0
    response = inverse.apply(impulse)[150 - r : 151 + r, 140 - r : 141 + r]
    assert np.allclose(window, response, rtol=0, atol=1e-6 * np.abs(window).max())
    cells = _clustered(ny, nx, 14, 1.0, rng)
    pc = Precorrected(op.offset_table(), (ny, nx), cells, radius=r)
    m = pc.on_near_pairs(window).toarray()
    assert np.allclose(m, m.T)
    off = m - np.diag(np.diag(m))
    assert off.max() <= 0.0 and m.sum(axis=1).min() > 0.0
    assert np.linalg.eigvalsh(m).min() > 0.0


def _hertz_kernel_inputs():
    """Penetration control on a Hertz paraboloid (R 10 mm, d 0.1 mm, 48 cells across the
    contact): the kernel's inputs and the exact and float32 products."""
    from twoscale.pk.products import OneRow

    a, h = 1.0, 2.0 / 48
    grid = Grid.covering(-1.2 * a, 1.2 * a, -1.2 * a, 1.2 * a, h, anchor=(0.5 * h, 0.5 * h))
    X, Y = grid.centres()
    z = (X**2 + Y**2) / 20.0
    op = HS.grid_operator(grid)
    return op, (z - 0.1)[None], np.maximum(0.1 - z, 0.0)[None], OneRow(op), OneRow(op.single_precision())


@pytest.mark.parametrize("noise", [3e-4, 3e-2])
def test_the_kernel_with_a_cheap_product_meets_the_exact_test_and_leaves_a_cheap_product_worse_than_said(noise):
    """A ``cheap`` product of relative error ``noise`` (the exact one plus a fixed random
    operator's share), said to be within 5e-4: the kernel converges to the exact route's
    pressure under the same tolerance either way; the product worse than said is left after
    its residual stops halving (a stall of the whole solve otherwise)."""
    from twoscale.pk import Tolerance, pk_solve
    from twoscale.pk.products import Products

    op, z, start, exact, fast = _hertz_kernel_inputs()
    rng = np.random.default_rng(7)
    mix = rng.standard_normal((z.size, z.size)) / np.sqrt(z.size)
    calls = []

    def cheap(v):
        calls.append(1)
        u = exact(v)
        return u + noise * float(np.linalg.norm(u)) * (mix @ v.ravel() / np.linalg.norm(v)).reshape(u.shape)

    tol = Tolerance(residual=1e-9, max_iter=500)
    plain = pk_solve(Products(exact, fast), z, start, None, tol)
    out = pk_solve(Products(exact, fast, cheap=cheap, cheap_error=5e-4), z, start, None, tol)
    assert plain.converged.all() and out.converged.all(), out.message(0)
    assert out.residual[0] <= 1e-9 and len(calls) > 0
    p, q = out.pressure[0], plain.pressure[0]
    assert np.linalg.norm(p - q) <= 1e-6 * np.linalg.norm(q)
    assert out.iterations[0] <= 2 * plain.iterations[0] + 10
