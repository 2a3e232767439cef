"""Many asperities: far-field coupling of the micro step and faster patch building.

Independent checks: the far-field displacement is compared with the exact cell-by-cell
product (Love blocks via ``provider.cell_block``, no FFT, no stencil), and whole solves with
the far field approximated are compared with the same solves with every pair exact; the
patch sampling is compared with :func:`surface_on` over all asperities.
"""

import math

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace
from twoscale.micro.blocks import Coupling
from twoscale.micro.farfield import FarFieldCoupling
from twoscale.micro.patches import make_patch
from twoscale.driver import solve_twoscale

from helpers import spaced_spheres

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)


def _hertz_block(pt, a=0.4):
    """A Hertz-like pressure (MPa) on the owned cells of a patch, centred off the patch centre."""
    X, Y = pt.grid.centres()
    xmin, xmax, ymin, ymax = pt.grid.bounds
    cx, cy = 0.5 * (xmin + xmax) + 0.1, 0.5 * (ymin + ymax) - 0.05
    r2 = (X - cx) ** 2 + (Y - cy) ** 2
    return np.sqrt(np.maximum(a * a - r2, 0.0))[pt.owned]


@pytest.mark.parametrize("far_tol", [0.05, 0.01])
def test_far_pair_error_within_tolerance(far_tol):
    # two patches just beyond the near/far cut: the displacement from the far one is
    # within far_tol (relative, in the max norm) of the exact cell-by-cell sum
    h = 0.05
    asp = [Asperity(0.0, 0.0, 0.0, 4.0), Asperity(1.0, 0.0, 0.0, 4.0)]
    pk = make_patch(0, Grid.covering(-0.6, 0.6, -0.6, 0.6, h), asp)
    r = 0.5 * math.hypot(*(np.array(pk.grid.bounds[1::2]) - np.array(pk.grid.bounds[::2])))
    dist = 1.05 * 2.0 * r / math.sqrt(far_tol)
    asp = [Asperity(0.0, 0.0, 0.0, 4.0), Asperity(dist, 0.0, 0.0, 4.0)]
    pk = make_patch(0, Grid.covering(-0.6, 0.6, -0.6, 0.6, h), asp)
    pl = make_patch(1, Grid.covering(dist - 0.6, dist + 0.6, -0.6, 0.6, h), asp)
    cp = FarFieldCoupling(HS, [pk, pl], far_tol=far_tol)
    assert len(cp.near(0)) == 0
    v = [np.zeros(int(pk.owned.sum())), _hertz_block(pl)]
    approx = -cp.rhs(0, v, np.zeros(len(v[0])))
    tk = pk.grid.points()[pk.owned.ravel()]
    tl = pl.grid.points()[pl.owned.ravel()]
    exact = HS.cell_block(tk, tl, h) @ v[1]
    err = np.max(np.abs(approx - exact)) / np.max(np.abs(exact))
    assert err <= far_tol
    # and it is a real approximation: a point force at the patch centre does worse or equal
    assert err > 0.0


def test_near_pairs_are_exact():
    asp = spaced_spheres(12, 1, 8.0)
    pts = [
        make_patch(k, Grid.covering(a.x - 0.5, a.x + 0.5, a.y - 0.5, a.y + 0.5, 0.05), asp) for k, a in enumerate(asp)
    ]
    values = [_hertz_block(pt) for pt in pts]
    exact = Coupling(HS, pts)
    near_all = FarFieldCoupling(HS, pts, far_tol=1e-6)  # cut beyond the scene: every pair near
    for k in range(len(pts)):
        b = np.zeros(len(values[k]))
        assert np.allclose(near_all.rhs(k, values, b), exact.rhs(k, values, b), rtol=1e-12, atol=1e-15)
        assert np.allclose(
            near_all.patch_displacement(k, values), exact.patch_displacement(k, values), rtol=1e-12, atol=1e-15
        )


def test_far_tol_validated():
    asp = [Asperity(0.0, 0.0, 0.0, 4.0)]
    pt = make_patch(0, Grid.covering(-0.5, 0.5, -0.5, 0.5, 0.05), asp)
    for bad in (0.0, 1.0, -0.1, float("nan"), True):
        with pytest.raises(ValueError, match="far_tol"):
            FarFieldCoupling(HS, [pt], far_tol=bad)


def test_patch_sampling_matches_all_asperities():
    asp = spaced_spheres(40, 2, 20.0) + [Asperity(10.0, 10.0, 0.3, 3.0, shape="paraboloid")]
    grid = Grid.covering(8.0, 12.0, 9.0, 11.5, 0.05)
    pt = make_patch(3, grid, asp)
    ref = surface_on(grid, asp)
    assert np.array_equal(pt.owner, ref.owner)
    assert np.array_equal(pt.height, ref.height)


@pytest.mark.parametrize("seed", [0, 1])
def test_far_field_solve_matches_exact(seed):
    # 60 spheres on 24 mm (h = R/40): forces with the far field approximated at
    # far_tol = 0.01 stay within 0.5 % of the exact coupling (measured ~0.01 %)
    asp = spaced_spheres(60, seed, 24.0)
    kw = dict(h=0.1, total_load=3.0, tol=1e-7, max_sweeps=200)
    exact = solve_twoscale(HS, asp, **kw)
    approx = solve_twoscale(HS, asp, far_tol=0.01, coarse=False, **kw)  # block-by-block far field
    assert exact.converged and approx.converged
    fe, fa = np.asarray(exact.asperities.forces), np.asarray(approx.asperities.forces)
    touching = fe > 0.05 * fe[fe > 0].mean()
    assert 0.3 <= np.mean(fe > 0) <= 0.9
    assert np.max(np.abs(fa - fe)[touching] / fe[touching]) <= 5e-3
    assert abs(fa.sum() - 3.0) <= 1e-6 * 3.0


def test_sizing_approaches_validated_and_used():
    from twoscale.micro import MicroProblem, solve_micro

    # second tip: geometric approach 1e-4 mm, but the first one's load (~0.2 N) lowers the
    # body there by P / (pi E* r) ~ 1e-3 mm, so it does not touch
    asp = [Asperity(0.0, 0.0, 0.0, 4.0), Asperity(5.0, 0.0, 0.0199, 4.0)]
    kw = dict(h=0.05, forces=np.array([0.2, 0.0]), penetration=0.02)
    with pytest.raises(ValueError, match="sizing_approaches"):
        solve_micro(HS, asp, MicroProblem(sizing_approaches=np.zeros(3), **kw))
    full = solve_micro(HS, asp, MicroProblem(**kw))
    small = solve_micro(HS, asp, MicroProblem(sizing_approaches=np.array([0.02, -1.0]), **kw))
    # the second tip gets a patch only by default, and carries nothing either way
    assert len(full.patches) == 2 and len(small.patches) == 1
    assert full.converged and small.converged
    p_full = sum(0.05**2 * p.sum() for p in full.pressures)
    p_small = sum(0.05**2 * p.sum() for p in small.pressures)
    assert p_small == pytest.approx(p_full, rel=1e-9)
    assert np.all(full.pressures[1] == 0.0)
