"""Penetration control's crop of the CG's grid to the cells that can touch, and the union
CG's threshold for it (``solve_cg(crop_below=...)``)."""

from __future__ import annotations

import numpy as np

from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace


def _sphere_on_a_wide_grid():
    """One sphere (R 10 mm) at x = 1 on a 3 mm square grid of 91 x 91 cells."""
    from twoscale.reference import solve_cg

    g = Grid.covering(-1.5, 1.5, -1.5, 1.5, 3.0 / 90)
    surface = surface_on(g, [Asperity(1.0, 0.0, 0.0, 10.0)])
    return solve_cg, HalfSpace(Material(10.0, 0.5)), surface, g


def test_the_crop_is_taken_only_below_the_asked_fraction_of_the_cells():
    solve_cg, hs, surface, g = _sphere_on_a_wide_grid()
    d = 0.02  # cells below d: a disc of radius sqrt(2 R d) = 0.63 mm, about 40 of 91 cells across
    cut = solve_cg(hs, surface, penetration=d, tol=1e-9)
    whole = solve_cg(hs, surface, penetration=d, tol=1e-9, crop_below=0.1)
    assert cut.details.working_grid[0] < 0.6 * g.nx  # the default crops
    assert whole.details.working_grid == (g.nx, g.ny)  # a crop keeping 20 % of the cells is not below 10 %
    p_cut, p_whole = cut.fields[0].pressure, whole.fields[0].pressure
    assert p_cut.shape == p_whole.shape == g.shape
    assert np.abs(p_cut - p_whole).max() <= 1e-6 * p_whole.max()
    g_cut, g_whole = cut.fields[0].gap, whole.fields[0].gap  # on the whole grid either way
    assert np.all(np.isfinite(g_cut)) and np.abs(g_cut - g_whole).max() <= 1e-7 * np.abs(g_whole).max()
    assert abs(cut.total_load - whole.total_load) <= 1e-7 * whole.total_load


def test_the_union_cg_keeps_a_box_whose_crop_would_keep_most_of_it():
    from twoscale.micro.union import CROP_BELOW
    from twoscale.reference._problem import make_problem
    from twoscale.reference._start import cropped

    _, _, surface, g = _sphere_on_a_wide_grid()
    deep = make_problem(surface, penetration=0.28)  # below 0.28 mm: x > -1.37, all but the first 4 columns
    shallow = make_problem(surface, penetration=0.02)
    assert cropped(deep).grid != g  # the reference's rule: any cut
    assert cropped(deep, CROP_BELOW) is deep
    assert cropped(shallow, CROP_BELOW).grid.size < 0.3 * g.size
