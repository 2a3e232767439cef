"""The kernel's columns from its offset table in chunks of targets
(twoscale.influence.table_columns): against the FFT product of the sparse pressure (to
rounding), and against the sum column by column written out here (to the bit: each
target's terms in the same order)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace, table_columns

HS = HalfSpace(Material(E=6.0, nu=0.5))


def _case(seed: int):
    grid = Grid(0.0, 0.0, 0.1, 23, 17)
    op = HS.grid_operator(grid)
    rng = np.random.default_rng(seed)
    cells = rng.choice(grid.size, 9, replace=False)
    return grid, op, cells, rng.standard_normal(9)


def _column_by_column(table, shape, cells, values, targets=None, start=0.0):
    ny, nx = shape
    out = np.full(shape, start)
    for c, v in zip(cells, values):
        j, i = divmod(int(c), nx)
        out += table[ny - 1 - j : 2 * ny - 1 - j, nx - 1 - i : 2 * nx - 1 - i] * v
    return out.ravel() if targets is None else out.ravel()[targets]


@pytest.mark.parametrize("chunk", [1 << 17, 40, 7])
@pytest.mark.parametrize("seed", [0, 1])
def test_the_columns_in_chunks_are_the_product_and_the_sum_column_by_column(monkeypatch, chunk, seed):
    monkeypatch.setattr(table_columns, "COLUMN_CHUNK", chunk)
    grid, op, cells, values = _case(seed)
    p = np.zeros(grid.size)
    p[cells] = values
    product = op.apply(p.reshape(grid.shape)).ravel()
    table = op.offset_table()
    out = np.zeros(grid.size)
    op.columns()(out, cells, values)
    assert np.array_equal(out, _column_by_column(table, grid.shape, cells, values))
    assert np.max(np.abs(out - product)) <= 1e-13 * np.max(np.abs(product))
    # on some targets: the gathered columns, the same numbers there; added to what is there
    targets = np.sort(np.random.default_rng(seed + 5).choice(grid.size, 150, replace=False))
    on_targets = np.full(len(targets), 0.5)
    op.columns(targets)(on_targets, cells, values)
    assert np.array_equal(on_targets, _column_by_column(table, grid.shape, cells, values, targets, start=0.5))
    assert np.max(np.abs(on_targets - 0.5 - product[targets])) <= 1e-13 * np.max(np.abs(product))
