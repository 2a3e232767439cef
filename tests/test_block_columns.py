"""The finite block's grid operator by columns (a few changed cells at a time) against its
full product, on the whole target and on a set of target cells, as the PK kernel uses it
on the cells near contact."""

from __future__ import annotations

import numpy as np

from fem_influence.operators import BlockGridOperator
from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace


def test_the_block_operator_by_columns_is_its_product_on_every_target_and_on_given_targets():
    grid = Grid.covering(-1.0, 1.0, -1.0, 1.0, 0.1)
    rng = np.random.default_rng(0)
    U, W = rng.normal(size=(grid.size, 3)), rng.normal(size=(3, grid.size))  # a rank-3 correction
    op = BlockGridOperator(HalfSpace(Material(E=10.0, nu=0.5)).grid_operator(grid), U, W, 0.01)
    cells, values = np.array([3, 50, 200]), np.array([1.0, -0.5, 2.0])
    p = np.zeros(grid.size)
    p[cells] = values
    product = op.apply(p.reshape(grid.shape)).ravel()
    whole = np.zeros(grid.size)
    op.columns()(whole, cells, values)
    assert np.max(np.abs(whole - product)) <= 1e-12 * np.max(np.abs(product))
    targets = np.array([0, 7, 50, 399])
    part = np.zeros(targets.size)
    op.columns(targets)(part, cells, values)
    assert np.max(np.abs(part - product[targets])) <= 1e-12 * np.max(np.abs(product))
