"""The default route's full-grid solve runs the reference's grid and tolerance with the union
CG's settings where they pay: the same discrete answer as the plain reference (to the CG's
tolerance), the closed form within the grid's error, fewer iterations."""

from __future__ import annotations

import math

import numpy as np
import pytest

import twoscale
from twoscale import Material, Scene
from twoscale.analytic import hertz
from twoscale.full_grid import FULL_GRID_DENSE_CELLS, full_grid_settings
from twoscale.indenters import Asperity
from twoscale.micro.full_grid_rule import FULL_GRID_MAX_CELLS, FULL_GRID_MAX_CELLS_PENETRATION
from twoscale.reference.on_scene import reference_grid
from twoscale.resources import full_grid_route

MATERIAL = Material(E=10.0, nu=0.5)


def _forces_agree(res, ref) -> None:
    f, f_ref = res.asperities.forces, ref.asperities.forces
    assert np.max(np.abs(f - f_ref)) <= 1e-6 * np.max(f_ref)


@pytest.mark.parametrize("h", [0.025, 0.02])
def test_one_sphere_on_its_full_grid_is_hertz_in_fewer_iterations(h):
    # R 10 mm pressed 0.01 mm: contact radius sqrt(R d) = 0.32 mm, 25 and 32 cells across
    R, d = 10.0, 0.01
    scene = Scene(material=MATERIAL, asperities=(Asperity(0.0, 0.0, 0.0, R, "paraboloid"),), penetration=d)
    cells = reference_grid(scene, h).size
    assert FULL_GRID_DENSE_CELLS < cells and full_grid_route(scene, h) is not None
    res = twoscale.solve(scene, h=h)
    ref = twoscale.solve(scene, h=h, method="reference")
    assert res.converged and "preconditioned CG" in res.message
    assert res.iterations["cg"] < ref.iterations["cg"]
    _forces_agree(res, ref)
    # the closed form within the grid's error, of order (h / a)^2 (0.6 % and 0.4 % here;
    # measured with the reference 0.02 % at h 0.02, 0.007 % at 0.01)
    exact = hertz.load(R, d, MATERIAL.E_star)
    assert res.total_load == pytest.approx(exact, rel=(h / math.sqrt(R * d)) ** 2)


# the face turns 0.15 rad to bring the pressure's centre onto the pivot: past the linear
# tilt's small angles (warned), the same model in both solvers
@pytest.mark.filterwarnings("ignore::twoscale.errors.TiltWarning")
def test_a_tilt_about_a_pivot_outside_the_tips_agrees_with_the_reference():
    # four paraboloids, the pivot 0.9 mm outside their square (contact radii ~0.55 mm): the full grid's route, its CG
    # preconditioned; the forces and the tilt those of the plain reference CG
    tips = tuple(Asperity(x, y, 0.002 * x, 6.0, "paraboloid") for x in (-3.0, 3.0) for y in (-3.0, 3.0))
    scene = Scene(material=MATERIAL, asperities=tips, total_load=2.0, tilt=True, pivot=(3.9, 0.0))
    h = 0.05
    assert "pivot" in (full_grid_route(scene, h) or "")
    res = twoscale.solve(scene, h=h)
    ref = twoscale.solve(scene, h=h, method="reference")
    assert res.converged and "preconditioned CG" in res.message
    assert res.iterations["cg"] < ref.iterations["cg"]
    _forces_agree(res, ref)
    assert np.allclose(res.tilt, ref.tilt, rtol=1e-5, atol=1e-9)


def test_the_settings_follow_the_grid_and_the_tips():
    # the reference's own choice on the smallest grids; no preconditioner where the tips
    # crowd the grid; float32 directions from the union CG's 10,000 cells
    assert full_grid_settings(FULL_GRID_DENSE_CELLS, 1).solver == "auto"
    small = full_grid_settings(FULL_GRID_DENSE_CELLS + 1, 1)
    assert (small.solver, small.precondition, small.precision) == ("cg", True, "double")
    crowded = full_grid_settings(55_696, 5_220)
    assert (crowded.precondition, crowded.precision) == (False, "single-directions")
    assert full_grid_settings(738_783, 4).precondition


def test_the_smallest_grid_keeps_the_dense_solver():
    scene = Scene(material=MATERIAL, asperities=(Asperity(0.0, 0.0, 0.0, 10.0, "paraboloid"),), penetration=0.01)
    h = 0.08
    assert reference_grid(scene, h).size <= FULL_GRID_DENSE_CELLS
    res = twoscale.solve(scene, h=h)
    ref = twoscale.solve(scene, h=h, method="reference")
    assert "the reference's own solver" in res.message
    assert np.array_equal(res.asperities.forces, ref.asperities.forces)


def test_the_message_names_the_solver_that_ran():
    # the route's sentence must not promise a CG where the dense solver ran, nor the reverse
    scene = Scene(material=MATERIAL, asperities=(Asperity(0.0, 0.0, 0.0, 10.0, "paraboloid"),), penetration=0.01)
    for h, ran in ((0.08, "dense"), (0.02, "cg")):
        res = twoscale.solve(scene, h=h)
        assert res.message.startswith("default route:")
        assert res.solver == ran
        assert ("dense" in res.message) == (ran == "dense")
        assert ("CG" in res.message) == (ran == "cg")


def test_a_block_passed_as_provider_takes_the_block_scenes_route():
    # the full grid's larger bound under penetration was measured on the half-space: a
    # block given as ``provider=`` (the scene saying nothing of it) must not take it
    from helpers import small_block

    tips = (Asperity(-3.0, 0.0, 0.0, 5.0, "sphere"), Asperity(3.0, 0.0, 0.0, 5.0, "sphere"))
    scene = Scene(material=MATERIAL, asperities=tips, penetration=0.1)
    h = 0.05
    assert FULL_GRID_MAX_CELLS < reference_grid(scene, h).size <= FULL_GRID_MAX_CELLS_PENETRATION
    assert full_grid_route(scene, h) is not None  # the half-space's route
    res = twoscale.solve(scene, provider=small_block(MATERIAL), h=h)
    assert res.solver == "twoscale" and not res.message.startswith("default route")
