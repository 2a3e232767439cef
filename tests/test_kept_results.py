"""Products and preconditioners that hand back arrays they keep (overwritten by their next
call; fresh arrays of millions of cells page-fault every time): the Polonsky-Keer kernel
must copy what it keeps, so that a solve through kept results is the solve through fresh
ones, bit for bit; and the float32 product on a part of the grid, kept, is the product of
the whole grid at those cells."""

from __future__ import annotations

import numpy as np

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.pk import Constraint, Products, Tolerance, pk_solve

HS = HalfSpace(Material(E=10.0, nu=0.5))
GRID = Grid(-2.0, -2.0, 0.05, 80, 80)  # 6,400 cells: the kernel's long-row route


def _heights() -> np.ndarray:
    """Three paraboloids (R 4-8 mm) at different heights, mm."""
    x, y = GRID.centres()
    z = np.full(GRID.shape, np.inf)
    for cx, cy, r, dz in ((-1.0, -0.8, 4.0, 0.0), (0.9, 0.2, 8.0, 0.004), (-0.3, 1.1, 6.0, 0.002)):
        z = np.minimum(z, ((x - cx) ** 2 + (y - cy) ** 2) / (2 * r) + dz)
    return z


class _Kept:
    """``f``'s result copied into one array kept for every call (the aliasing a kept
    result brings, with ``f``'s values)."""

    def __init__(self, f):
        self.f, self.out = f, None

    def __call__(self, *args):
        r = self.f(*args)
        if self.out is None:
            self.out = np.empty_like(r)
        np.copyto(self.out, r)
        return self.out


def _solve(kept: bool):
    op = HS.grid_operator(GRID)
    single, inverse = op.single_precision(), op.preconditioner()
    fast = lambda v: single.apply(v[0])[None]  # noqa: E731
    pc = lambda v, on: inverse.apply(v[0])[None]  # noqa: E731
    if kept:
        fast, pc = _Kept(fast), _Kept(pc)
    z = _heights().reshape(1, -1)
    products = Products(lambda v: op.apply(v[0])[None], fast, op.columns())
    return pk_solve(
        products,
        z.reshape(1, *GRID.shape),
        np.maximum(0.01 - z, 0.0).reshape(1, *GRID.shape),  # (the interference at 0.01 mm)
        None,
        Tolerance(residual=1e-9, max_iter=400),
        constraint=Constraint(np.ones((GRID.size, 1)), np.array([[0.8 / GRID.h**2]])),
        precondition=pc,
    )


def test_a_solve_through_kept_results_is_the_solve_through_fresh_ones():
    fresh, kept = _solve(False), _solve(True)
    assert fresh.converged[0] and kept.converged[0]
    assert fresh.iterations[0] > 5  # (refreshes by the fast product and preconditioned steps ran)
    assert np.array_equal(kept.pressure, fresh.pressure)
    assert np.array_equal(kept.displacement, fresh.displacement)


def test_the_kept_product_on_cells_is_the_whole_grids_product_there():
    """Two products in turn through one :class:`~twoscale.influence.on_cells.CellProduct`
    (one kept result), each against the float32 product of the whole grid at the cells,
    and the preconditioner's on the cells against its product of the torus likewise."""
    op = HS.grid_operator(GRID)
    single = op.single_precision()
    rng = np.random.default_rng(3)
    cells = np.flatnonzero(rng.random(GRID.size) < 0.3)
    product = single.on_cells(cells)
    for _ in range(2):
        v = rng.random(cells.size)
        field = np.zeros(GRID.size)
        field[cells] = v
        got = product(v)
        assert np.array_equal(got, single.apply(field.reshape(GRID.shape)).ravel()[cells])
    inverse = single.preconditioner()
    on_cells = inverse.on_cells(cells)
    if on_cells is not None:  # (the torus larger than the grid: the pruned route)
        first = on_cells(v).copy()
        field[cells] = v
        whole = inverse.apply(field.reshape(GRID.shape)).ravel()[cells]
        assert np.max(np.abs(first - whole)) <= 1e-6 * np.max(np.abs(whole))
        again = on_cells(2.0 * v)
        assert np.max(np.abs(again - 2.0 * whole)) <= 1e-6 * np.max(np.abs(whole))
