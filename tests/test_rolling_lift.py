"""The lower bound of a half-space's lift (twoscale.rolling.lift) against the exact product of
the pressure: never above it, near it far from the load, and the cells it keeps off."""

from __future__ import annotations

import numpy as np

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.influence.cached import CachedBody, OperatorCaches
from twoscale.rolling.lift import half_space_modulus, kept_off, lower_displacement

HS = HalfSpace(Material(10.0, 0.5))


def _load_and_window():
    """A patchy pressure on a 40 x 30 cut in the middle of a 70 x 50 window, and the
    window's displacement from it by the half-space's own product (Love's cells)."""
    window = Grid(-5.0, -3.0, 0.25, 70, 50)
    cut = window.subgrid(15, 10, 40, 30)
    rng = np.random.default_rng(11)
    p = rng.random(cut.shape) * (rng.random(cut.shape) < 0.3)
    u = HS.grid_operator(window).apply(cut.embed_in(p, window))
    return window, cut, p, u


def test_the_bound_lies_below_the_exact_lift_and_near_it_far_away():
    window, cut, p, u = _load_and_window()
    X, Y = window.centres()
    outside = np.ones(window.shape, bool)
    outside[cut.window_in(window)] = False
    x, y, exact = X[outside], Y[outside], u[outside]
    for tile in (4, 16, 64):
        bound = lower_displacement(p, cut, x, y, HS.E_star, tile)
        assert np.all(bound <= exact) and np.all(bound > 0.0)
    fine = lower_displacement(p, cut, x, y, HS.E_star, 1)  # a tile a cell: the farthest corner only
    assert np.all(fine <= exact) and np.all(fine >= 0.9 * exact)


def test_cells_are_kept_off_only_when_the_bound_lifts_them():
    window, cut, p, u = _load_and_window()
    X, Y = window.centres()
    x, y, exact = X[0, :5], Y[0, :5], u[0, :5]  # a corner row of the window, off the cut
    e_star = half_space_modulus(HS)
    assert kept_off(p, cut, x, y, -0.5 * exact, e_star)  # half the lift below: off
    assert not kept_off(p, cut, x, y, -1.01 * exact, e_star)  # below the exact lift: touching
    assert half_space_modulus(CachedBody(HS, OperatorCaches())) == e_star
