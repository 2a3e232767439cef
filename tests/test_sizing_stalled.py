"""Patches sized by a stalled macro step's local approaches (far-field coupling).

Where the macro step ends far from a solution its forces do not size the patches, and each
indenter's geometric reach at the approach does; with many tips the bulk deflection takes
most of that approach, so the reach is several times the contacts. The macro step's local
approaches (plus a fifth of the largest, never beyond the reach) size them instead. Checked
against the unchanged route: the same micro problem with the patches sized by the reach
gives the same tip forces, on fewer cells (every pair near, so neither has a far-field
error, and both solved to 1e-8).
"""

import dataclasses

import numpy as np

from twoscale import Material
from twoscale.control import Loading
from twoscale.influence import HalfSpace
from twoscale.laws import law_for
from twoscale.macro import solve_macro
from twoscale.micro import MicroProblem, solve_micro
from twoscale.options import MicroOptions

from twoscale.indenters import Asperity

MAT = Material(2.0, 0.5)
HS = HalfSpace(MAT)
H = 0.04


def _lattice(n: int = 6, spacing: float = 2.0, spread: float = 0.003) -> list:
    """``n`` x ``n`` spheres of R 10 mm, ``spacing`` mm apart, tip heights over ``spread`` mm
    (seeded): under 0.02 N each the bulk deflection (~0.02 mm) passes each tip's own
    approach (~0.015 mm), so the reach at the geometric approach is about 1.5x the contacts."""
    rng = np.random.default_rng(3)
    return [
        Asperity(spacing * i, spacing * j, float(rng.uniform(0.0, spread)), 10.0) for i in range(n) for j in range(n)
    ]


def _stalled_macro(asp, load):
    """The macro step of ``asp`` under ``load`` N, then marked as stalled far from a solution
    (its forces and local approaches kept): what a failed line search leaves."""
    tips = np.array([[a.x, a.y] for a in asp])
    z = np.array([a.z for a in asp])
    laws = [law_for(a, MAT) for a in asp]
    macro = solve_macro(HS, tips, z, laws, Loading(total_load=load))
    assert macro.converged
    return dataclasses.replace(macro, converged=False, residuals=(1.0, 0.6, 0.57), message="stalled")


def test_stalled_macro_sizes_patches_by_local_approaches():
    asp, load = _lattice(), 0.72
    macro = _stalled_macro(asp, load)
    problem = MicroProblem.from_macro(macro, h=H, total_load=load, free_tilt=False, pivot=(0.0, 0.0))
    # far from a solution: neither the forces nor the union CG's start come from it
    assert not problem.size_from_forces and problem.local_penetrations is None
    assert np.array_equal(problem.sizing_penetrations, macro.local_penetrations)
    options = MicroOptions(far_tol=0.01, tol=1e-8)  # every pair near: no far-field error
    sized = solve_micro(HS, asp, problem, options, iteration="two-level")
    reach = solve_micro(HS, asp, dataclasses.replace(problem, sizing_penetrations=None), options, iteration="two-level")
    assert sized.converged and reach.converged
    cells = lambda r: sum(pt.grid.size for pt in r.patches)  # noqa: E731
    assert cells(sized) < 0.7 * cells(reach)

    def tip_forces(r):
        out = np.zeros(len(asp))
        for pt, p in zip(r.patches, r.pressures):
            for m in pt.members:
                out[m] += H * H * p[pt.owner == m].sum()
        return out

    fs, fr = tip_forces(sized), tip_forces(reach)
    assert abs(fs.sum() - load) <= 1e-6 * load
    assert np.all(fr > 0.0)
    assert np.max(np.abs(fs - fr)) <= 1e-7 * np.max(fr)
