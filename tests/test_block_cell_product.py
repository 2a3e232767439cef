"""The block's float32 product on a part of its grid (the half-space part's product on the
cells plus the low-rank correction), against the whole grid's product at those cells and
against the block's dense matrix."""

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.material import Material
from helpers import small_block

MAT = Material(E=2.0, nu=0.5)
H = 0.02


@pytest.fixture(scope="module")
def operators():
    block = small_block(MAT)
    grid = Grid(-0.3, -0.2, H, 40, 36)
    op = block.grid_operator(grid)
    return grid, op, op.single_precision(), block.grid_matrix(grid)


def _part(grid, seed=3, fraction=0.2):
    rng = np.random.default_rng(seed)
    cells = np.flatnonzero(rng.random(grid.size) < fraction)
    return cells, rng.random(cells.size)


def test_the_product_on_cells_is_the_whole_grids_at_those_cells(operators):
    grid, _, single, _ = operators
    cells, v = _part(grid)
    product = single.on_cells(cells)
    p = np.zeros(grid.size)
    p[cells] = v
    whole = single.apply(p.reshape(grid.shape)).ravel()
    assert np.array_equal(product(v), whole[cells])
    every = single.on_cells(None)
    assert np.array_equal(every(p), whole)


def test_the_halves_give_the_energy_and_the_product(operators):
    grid, _, single, dense = operators
    cells, v = _part(grid, seed=5)
    product = single.on_cells(cells)
    exact = dense[np.ix_(cells, cells)] @ v  # float64, the block's matrix
    begun = product.forward(v)
    assert begun.energy() == pytest.approx(float(v @ exact), rel=1e-5)  # float32 transforms
    assert np.max(np.abs(begun.finish() - exact)) < 1e-5 * np.max(np.abs(exact))
    with pytest.raises(RuntimeError):
        product.finish()


def test_the_model_adds_the_correction_to_the_torus_energy(operators):
    grid, op, single, dense = operators
    cells, v = _part(grid, seed=7)
    model = single.on_cells(cells).model_energy()
    torus = single._hs.on_cells(cells).model_energy()
    assert model is not None and torus is not None
    # the correction's energy exactly: the block's matrix less the half-space part's
    hs = op._hs
    p = np.zeros(grid.size)
    p[cells] = v
    correction = float(v @ (dense @ p)[cells]) - float(p @ hs.apply(p.reshape(grid.shape)).ravel())
    assert model(v) - torus(v) == pytest.approx(correction, rel=1e-8, abs=1e-12 * abs(correction))


def test_the_double_precision_operator_keeps_the_grid_route(operators):
    _, op, _, _ = operators
    assert op.on_cells(np.arange(5)) is None
