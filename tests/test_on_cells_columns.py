"""The float32 product on a part of the grid whose cells hold a few bands of columns
(:func:`twoscale.influence.on_cells.column_runs`): the transforms along y of those columns
only give the product of the whole grid at the cells, bit for bit, and its Parseval sum."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.influence.on_cells import column_runs

HS = HalfSpace(Material(E=10.0, nu=0.5))


def test_column_runs_keep_the_held_columns_and_narrow_gaps():
    nx = 1000
    cells = np.r_[np.arange(10, 90), np.arange(120, 130), np.arange(600, 700)] + 3 * nx
    assert column_runs(cells, nx) == [(10, 130), (600, 700)]  # (a 30-column gap kept)
    assert column_runs(np.arange(nx), nx) is None  # every column: the whole transforms


@pytest.mark.parametrize("nx,ny", [(301, 207), (256, 180)])
def test_the_product_on_a_few_bands_is_the_whole_grids(nx, ny):
    grid = Grid(0.0, 0.0, 0.05, nx, ny)
    single = HS.grid_operator(grid).single_precision()
    rng = np.random.default_rng(nx)
    mask = np.zeros(grid.shape, bool)
    mask[:, 10:90] = rng.random((ny, 80)) < 0.4
    mask[:, 200:250] = rng.random((ny, 50)) < 0.4
    cells = np.flatnonzero(mask)
    product = single.on_cells(cells)
    assert product.runs == [(10, 90), (200, 250)]
    for _ in range(2):  # (the spectrum's other columns are cleared again after another product)
        v = rng.random(cells.size)
        field = np.zeros(grid.size)
        field[cells] = v
        whole = single.apply(field.reshape(grid.shape)).ravel()[cells]
        energy = product.forward(v).energy()
        assert np.array_equal(product.finish(), whole)
        single.apply(rng.random(grid.shape))  # another product through the shared buffers
    assert energy == pytest.approx(float(v @ whole), rel=1e-5)


def test_the_product_on_every_cell_is_the_whole_grids():
    grid = Grid(0.0, 0.0, 0.05, 97, 64)
    single = HS.grid_operator(grid).single_precision()
    p = np.random.default_rng(0).random(grid.size)
    product = single.on_cells(None)
    assert product.runs is None
    assert np.array_equal(product.forward(p).finish(), single.apply(p.reshape(grid.shape)).ravel())
