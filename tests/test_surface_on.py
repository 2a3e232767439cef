"""Sampling indenters on a grid (``surface_on``): spheres are evaluated only on the cells
within their radius; the result must equal evaluating every indenter on every cell."""

from __future__ import annotations

import numpy as np

from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on


def test_windowed_sampling_equals_sampling_every_cell():
    rng = np.random.default_rng(3)
    grid = Grid.covering(-5.0, 5.0, -4.0, 4.0, 0.1)
    asps = [
        Asperity(float(x), float(y), float(z), float(R), shape)
        for x, y, z, R, shape in zip(
            rng.uniform(-7, 7, 25),
            rng.uniform(-6, 6, 25),
            rng.uniform(0, 0.2, 25),
            rng.uniform(0.3, 3.0, 25),
            ["sphere"] * 20 + ["paraboloid"] * 5,
        )
    ]
    asps.append(Asperity(20.0, 0.0, 0.0, 1.0))  # a sphere that misses the grid
    X, Y = grid.centres()
    height = np.full(grid.shape, np.inf)
    owner = np.full(grid.shape, -1)
    for k, a in enumerate(asps):
        hk = a.height(X, Y)
        better = hk < height
        height[better], owner[better] = hk[better], k
    s = surface_on(grid, asps)
    assert np.array_equal(s.height, height)
    assert np.array_equal(s.owner, owner)
    assert s.n_asperities == len(asps)
