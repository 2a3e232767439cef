"""Warm starts along a track: a solve started from its neighbour's result gives the cold
solve's answer (to the solver's tolerances) in no more macro Newton steps.

The scene: six spheres (R = 5 mm, recesses 0-0.03 mm) on a 10 mm lattice, on the half-space
(E = 6 MPa, nu = 0.5), 60 N through a ball-and-socket joint at the origin. A track step
shifts the tips by 2 mm along x: the joint stays, so the surface tilts further and every
force changes (the step is not a translation of the solution).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import twoscale
from twoscale.macro import MacroStart
from twoscale.material import Material

MATERIAL = Material(6.0, 0.5)
XY = [(-10.0, -5.0), (0.0, -5.0), (10.0, -5.0), (-10.0, 5.0), (0.0, 5.0), (10.0, 5.0)]
Z = [0.0, 0.01, 0.02, 0.03, 0.0, 0.015]


def _tips(shift: float, keep=None):
    keep = range(len(XY)) if keep is None else keep
    return [twoscale.Asperity(XY[k][0] + shift, XY[k][1], Z[k], 5.0) for k in keep]


def _solve(shift: float, keep=None, start=None):
    return twoscale.solve(_tips(shift, keep), material=MATERIAL, total_load=60.0, tilt=True, h=0.2, start=start)


@pytest.fixture(scope="module")
def first():
    return _solve(0.0)


def test_warm_start_gives_the_cold_answer_in_no_more_newton_steps(first):
    cold, warm = _solve(2.0), _solve(2.0, start=first)
    assert cold.converged and warm.converged
    moved = np.abs(cold.details.macro.forces - first.details.macro.forces)
    assert moved.max() > 0.05 * cold.details.macro.forces.max()  # the step changes the forces
    # the same macro equations: the same forces to the macro tolerance (1e-10 relative)
    np.testing.assert_allclose(warm.details.macro.forces, cold.details.macro.forces, rtol=0, atol=1e-8 * 60)
    # the micro step starts from those forces: the same pressure to its tolerance (1e-6)
    np.testing.assert_allclose(warm.asperities.forces, cold.asperities.forces, rtol=0, atol=1e-5 * 60)
    assert warm.penetration == pytest.approx(cold.penetration, rel=1e-6)
    assert warm.iterations["macro"] <= cold.iterations["macro"]


def test_a_start_is_mapped_by_tip_identity(first):
    # at the next position tip 0 has left the footprint: the start keeps the others' forces
    keep = [1, 2, 3, 4, 5]
    start = MacroStart.from_result(first, np.array(keep))
    assert start.forces == pytest.approx(np.asarray(first.details.macro.forces)[keep])
    cold, warm = _solve(2.0, keep), _solve(2.0, keep, start=start)
    np.testing.assert_allclose(warm.asperities.forces, cold.asperities.forces, rtol=0, atol=1e-5 * 60)
    # a tip new to the footprint (-1) starts unloaded
    entering = MacroStart.from_result(first, np.array([-1, 1, 2, 3, 4, 5]))
    assert entering.forces[0] == 0.0 and entering.forces[1] == first.details.macro.forces[1]


def test_a_start_of_the_wrong_size_is_refused(first):
    with pytest.raises(ValueError, match="start has 6 asperities, this solve 5"):
        _solve(2.0, [1, 2, 3, 4, 5], start=first)
    with pytest.raises(ValueError, match="one entry per asperity"):
        _solve(2.0, [1, 2, 3, 4, 5], start=MacroStart(np.ones(6)))
    with pytest.raises(ValueError, match="index must be 1-D"):
        MacroStart.from_result(first, np.array([0, 6]))
    with pytest.raises(ValueError, match="start must be a ContactResult, a MacroStart or a WarmStart"):
        _solve(2.0, start=dataclasses.asdict(MacroStart(np.ones(6))))
