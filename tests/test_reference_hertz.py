"""Reference solvers against Hertz: R = 10 mm, E = 10 MPa, nu = 0.5, d = 0.5 mm.

The contact radius is a = sqrt(R d) = 2.236 mm; the grid has ``n = 2a/h`` cells across the
contact diameter and covers 1.1 a around the tip. The pressure is compared with Hertz
sampled at the cell centres.

Expected orders (measured and asserted below):

* relative L2 pressure error: first order in h. Inside the contact the collocation error
  is O(h^2), but Hertz's pressure has a square-root edge: in the band of cells cut by the
  edge (relative area ~ h/a) the error is ~ p0 sqrt(h/a), so the L2 error is
  ~ sqrt(h/a * h/a) = h/a.
* total load: that band's errors partly cancel in the integral; their size
  ``p0 sqrt(h/a) * 2 pi a h`` relative to P ~ p0 a^2 gives O(h^1.5) at worst; measured
  1.6-2.1.
* contact area (cells with p > 0): first order (staircase of the circle's edge).

Where the edge falls on the cells matters at the 0.1 % level: with the tip at the corner of
four cells (the grid used for the targets) 2a/h = 64 gives 0.45 % L2 error; with the tip at
a cell centre the same h gives 0.62 % (the 0.5 % target is missed there; see the xfail).

Exact spheres (``shape="sphere"``) rise faster than the paraboloid by about r^4 / (8 R^3):
at the same penetration they carry less load (Segedin: ``P/P_Hertz = 1 - d/(10 R)``,
0.5 % less at d = R/20 as here), and they are checked against Segedin's law, not Hertz.
"""

import math

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.analytic import hertz
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg, solve_dense

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)
R, D = 10.0, 0.5
A = math.sqrt(R * D)
P_HERTZ = float(hertz.load(R, D, MAT.E_star))


def _grid(n: int, corner: bool = True) -> Grid:
    h = 2 * A / n
    L = 1.1 * A
    anchor = (0.5 * h, 0.5 * h) if corner else (0.0, 0.0)
    return Grid.covering(-L, L, -L, L, h, anchor=anchor)


def _errors(result, grid):
    X, Y = grid.centres()
    pe = hertz.pressure(np.hypot(X, Y), R, D, MAT.E_star)
    p = result.fields[0].pressure
    return {
        "load": abs(result.total_load / P_HERTZ - 1),
        "l2": float(np.linalg.norm(p - pe) / np.linalg.norm(pe)),
        "area": abs(float(result.asperities.contact_areas[0]) / (math.pi * A * A) - 1),
    }


def _solve(n, solver=solve_cg, corner=True, shape="paraboloid", **load):
    g = _grid(n, corner)
    s = surface_on(g, [Asperity(0.0, 0.0, 0.0, R, shape)])
    r = solver(HS, s, **(load or {"penetration": D}))
    assert r.converged, r.message
    return r, g


SIZES = (16, 32, 64, 128)


@pytest.fixture(scope="module")
def cg_series():
    return [_errors(*_solve(n)) for n in SIZES]


def _rate(errs, key):
    h = 2 * A / np.array(SIZES[: len(errs)], dtype=float)
    return np.polyfit(np.log(h), np.log([e[key] for e in errs]), 1)[0]


def test_errors_decrease_under_refinement(cg_series):
    for key in ("load", "l2"):
        e = [s[key] for s in cg_series]
        assert all(b < a for a, b in zip(e, e[1:])), (key, e)


def test_pressure_l2_error_is_first_order(cg_series):
    assert 0.85 <= _rate(cg_series, "l2") <= 1.3


def test_load_error_is_at_least_order_1_5(cg_series):
    assert _rate(cg_series, "load") >= 1.4


def test_contact_area_error_is_first_order(cg_series):
    assert 0.8 <= _rate(cg_series, "area") <= 1.6


def test_targets_at_64_cells_across(cg_series):
    e = cg_series[SIZES.index(64)]
    assert e["l2"] <= 0.005
    assert e["load"] <= 0.005
    assert e["area"] <= 0.02


@pytest.mark.xfail(strict=True, reason="tip at a cell centre: measured L2 error 0.62 % > 0.5 % at 2a/h = 64")
def test_l2_target_with_tip_at_cell_centre():
    e = _errors(*_solve(64, corner=False))
    assert e["l2"] <= 0.005


def test_tip_at_cell_centre_still_first_order():
    errs = [_errors(*_solve(n, corner=False)) for n in SIZES]
    assert 0.85 <= _rate(errs, "l2") <= 1.3
    assert all(b["load"] < a["load"] for a, b in zip(errs, errs[1:]))


def test_dense_matches_hertz_and_converges():
    errs = [_errors(*_solve(n, solver=solve_dense)) for n in (16, 32)]
    # first order: halving h at least roughly halves the L2 error
    assert errs[1]["l2"] <= 0.6 * errs[0]["l2"]
    assert errs[1]["load"] <= 0.5 * errs[0]["load"]


def test_load_control_recovers_hertz_penetration():
    r, g = _solve(64, total_load=P_HERTZ)
    # P ~ d^1.5: the 0.5 % load target corresponds to 0.33 % in penetration
    assert abs(r.penetration / D - 1) <= 0.005 / 1.5
    assert r.total_load == pytest.approx(P_HERTZ, rel=1e-12)
    X, Y = g.centres()
    pe = hertz.pressure(np.hypot(X, Y), R, D, MAT.E_star)
    assert np.linalg.norm(r.fields[0].pressure - pe) <= 0.005 * np.linalg.norm(pe)


def test_exact_sphere_follows_segedin_not_hertz():
    r, _ = _solve(64, shape="sphere")
    p_seg = float(hertz.sphere_load(R, D, MAT.E_star))
    assert abs(r.total_load / p_seg - 1) <= 1e-3
    # at d = R/20 the cap carries about 0.5 % less than the paraboloid
    assert -0.006 < r.total_load / P_HERTZ - 1 < -0.004
    assert (
        abs(float(r.asperities.contact_areas[0]) / (math.pi * float(hertz.sphere_contact_radius(R, D)) ** 2) - 1)
        <= 0.02
    )
