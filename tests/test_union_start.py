"""The union CG's start (:mod:`twoscale.micro.union_start`): each tip's interference cap
scaled to carry its macro force, checked against the closed form (a cap's integral is the
force asked), and the union CG from it against the full-grid reference on separated tips
under penetration control, the scenes the scaling is for."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twoscale import Material
from twoscale.api import solve_scene
from twoscale.driver import solve_twoscale
from twoscale.grid import Grid
from twoscale.indenters import Asperity, Surface, surface_on
from twoscale.influence import HalfSpace
from twoscale.micro import union
from twoscale.micro.union_start import START_FRACTION, interference_start
from twoscale.scene import Scene

MAT = Material(E=4.0, nu=0.5)


def _two_tips():
    g = Grid(-2.0, -1.0, 0.05, 81, 41)
    tips = [Asperity(-1.0, 0.0, 0.0, 5.0, "paraboloid"), Asperity(1.0, 0.0, 0.02, 3.0, "paraboloid")]
    return surface_on(g, tips), tips


def test_each_cap_carries_its_macro_force_and_keeps_its_shape():
    surf, tips = _two_tips()
    approaches = np.array([0.05, 0.04])
    forces = np.array([0.3, 0.7])
    cap = interference_start(surf, tips, approaches)
    scaled = interference_start(surf, tips, approaches, forces)
    h2 = surf.grid.h**2
    for k, tip in enumerate(tips):
        mine = surf.owner == k
        # a paraboloid's cap of depth c = START_FRACTION delta on a fine grid: volume pi R c^2
        c = START_FRACTION * approaches[k]
        assert cap[mine].sum() * h2 == pytest.approx(math.pi * tip.R * c * c, rel=0.02)
        assert scaled[mine].sum() * h2 == pytest.approx(forces[k], rel=1e-12)
        on = cap[mine] > 0
        assert np.array_equal(scaled[mine] > 0, on)
        ratio = scaled[mine][on] / cap[mine][on]
        assert np.allclose(ratio, ratio[0], rtol=1e-12)  # one factor a tip


def test_a_cap_without_force_is_dropped_and_unusable_forces_leave_the_caps():
    surf, tips = _two_tips()
    approaches = np.array([0.05, 0.04])
    cap = interference_start(surf, tips, approaches)
    dropped = interference_start(surf, tips, approaches, np.array([0.5, 0.0]))
    assert np.all(dropped[surf.owner == 1] == 0.0)
    assert dropped[surf.owner == 0].sum() * surf.grid.h**2 == pytest.approx(0.5, rel=1e-12)
    for forces in (np.array([np.nan, 1.0]), np.array([0.0, 0.0])):
        assert np.array_equal(interference_start(surf, tips, approaches, forces), cap)


def test_cells_no_tip_owns_start_unloaded_and_the_caps_follow_their_definition():
    # two small spheres far apart: most cells have no material (owner -1, height inf); a cell
    # a tip owns starts at max(z_k + START_FRACTION delta_k - z, 0), scaled to the tip's force
    g = Grid(-2.0, -1.0, 0.05, 81, 41)
    tips = [Asperity(-1.0, 0.0, 0.0, 0.4), Asperity(1.0, 0.1, 0.01, 0.3)]
    surf = surface_on(g, tips)
    assert np.any(surf.owner < 0) and np.any(~np.isfinite(surf.height))
    approaches, forces = np.array([0.05, 0.06]), np.array([0.2, 0.1])
    cap = interference_start(surf, tips, approaches)
    scaled = interference_start(surf, tips, approaches, forces)
    assert np.all(cap[surf.owner < 0] == 0.0) and np.all(scaled[surf.owner < 0] == 0.0)
    for k, tip in enumerate(tips):
        mine = surf.owner == k
        expected = np.maximum(tip.z + START_FRACTION * approaches[k] - surf.height[mine], 0.0)
        assert np.array_equal(cap[mine], expected) and np.any(expected > 0)
        assert scaled[mine].sum() * g.h**2 == pytest.approx(forces[k], rel=1e-12)
    # material no tip owns (as a surface may hold) carries no start either
    owner = surf.owner.copy()
    owner[:, : g.nx // 2] = np.where(owner[:, : g.nx // 2] == 0, -1, owner[:, : g.nx // 2])
    orphan = Surface(g, surf.height, owner, len(tips))
    assert np.any((owner < 0) & np.isfinite(surf.height))
    for given, full in ((None, cap), (forces, scaled)):
        left = interference_start(orphan, tips, approaches, given)
        assert np.all(left[owner < 0] == 0.0) and np.array_equal(left[owner == 1], full[owner == 1])


def _separated(n: int, seed: int) -> list:
    """n paraboloids on a jittered lattice 2 mm apart, R 2-4 mm, tips 0-0.03 mm deep:
    separated contacts of a few tens of cells at h 0.04 mm."""
    rng = np.random.default_rng(seed)
    side = int(math.ceil(math.sqrt(n)))
    out = []
    for k in range(n):
        x, y = 2.0 * (k % side) + rng.uniform(-0.3, 0.3), 2.0 * (k // side) + rng.uniform(-0.3, 0.3)
        out.append(
            Asperity(float(x), float(y), float(rng.uniform(0.0, 0.03)), float(rng.uniform(2.0, 4.0)), "paraboloid")
        )
    return out


def test_the_union_cg_from_the_scaled_caps_gives_the_full_grid_answer(monkeypatch):
    tips = _separated(36, 3)
    kw = dict(h=0.04, penetration=0.05)
    seen = []
    start = union.interference_start

    def recorded(surface, asperities, approaches, forces=None):
        seen.append(forces is not None)
        return start(surface, asperities, approaches, forces)

    monkeypatch.setattr(union, "interference_start", recorded)
    res = solve_twoscale(HalfSpace(MAT), tips, iteration="union-cg", tol=1e-8, **kw)
    assert res.converged, res.message
    assert seen == [True]  # the macro step came near a solution: the caps were scaled
    ref = solve_scene(Scene(material=MAT, asperities=tips, **kw), method="reference", tol=1e-10)
    assert ref.converged
    F, Fr = res.asperities.forces, ref.asperities.forces
    assert np.count_nonzero(Fr > 0) >= 30
    assert np.max(np.abs(F - Fr)) <= 1e-6 * Fr.max()
    assert res.total_load == pytest.approx(ref.total_load, rel=1e-8)
