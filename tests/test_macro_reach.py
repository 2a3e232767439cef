"""The macro step among the tips that reach the body (:mod:`twoscale.macro.reach`): the same
answer as the step over every tip, and closed forms where the others carry nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twoscale import Material
from twoscale.control import Loading
from twoscale.influence.halfspace import HalfSpace
from twoscale.laws import HertzLaw
from twoscale.macro import solve_macro
from twoscale.macro.reach import reaching

MAT = Material(10.0, 0.5)


class RisingHalfSpace(HalfSpace):
    """The half-space declared as a body whose surface can rise: the macro step then keeps
    every tip (the same kernel, so the two answers must agree)."""

    surface_rises = True


def test_one_reaching_sphere_among_tips_above_the_approach_is_hertz():
    # one sphere reaches; eight tips around it stand above the approach: the sphere carries
    # the Hertz force 4/3 E* R^1/2 d^3/2, the others nothing, and their local penetration is
    # d - z_k less the Boussinesq displacement P / (pi E* r) of that force
    d, R = 0.004, 2.0
    angles = np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)
    ring = 0.3 * np.column_stack([np.cos(angles), np.sin(angles)])
    tips = np.vstack([[0.0, 0.0], ring])
    z = np.concatenate([[0.0], np.full(8, 0.005)])
    laws = [HertzLaw(R, MAT.E_star)] * 9
    provider = HalfSpace(MAT)
    assert list(reaching(provider, tips, z, laws, Loading(d, None))) == [0]
    out = solve_macro(provider, tips, z, laws, Loading(d, None))
    hertz = 4.0 / 3.0 * MAT.E_star * math.sqrt(R) * d**1.5
    assert out.converged
    assert out.forces[0] == pytest.approx(hertz, rel=1e-10)
    assert np.all(out.forces[1:] == 0.0) and not np.any(out.in_contact[1:])
    boussinesq = d - z[1:] - hertz / (math.pi * MAT.E_star * 0.3)
    assert np.max(np.abs(out.local_penetrations[1:] - boussinesq)) <= 1e-12


def test_a_field_of_tips_solved_among_those_that_reach_gives_the_answer_over_every_tip():
    # 300 paraboloids at random heights, about half above the approach: the same forces and
    # local penetrations as the step over every tip (the same kernel declared rising)
    rng = np.random.default_rng(3)
    tips = rng.uniform(-6.0, 6.0, (300, 2))
    z = rng.uniform(0.0, 0.01, 300)
    laws = [HertzLaw(float(R), MAT.E_star) for R in rng.uniform(1.0, 3.0, 300)]
    loading = Loading(0.005, None)
    keep = reaching(HalfSpace(MAT), tips, z, laws, loading)
    assert keep is not None and 100 < keep.size < 200
    fewer = solve_macro(HalfSpace(MAT), tips, z, laws, loading)
    every = solve_macro(RisingHalfSpace(MAT), tips, z, laws, loading)
    assert reaching(RisingHalfSpace(MAT), tips, z, laws, loading) is None
    assert fewer.converged and every.converged
    assert np.count_nonzero(fewer.forces) > 50
    assert np.max(np.abs(fewer.forces - every.forces)) <= 1e-9 * every.forces.max()
    assert np.max(np.abs(fewer.local_penetrations - every.local_penetrations)) <= 1e-9 * np.ptp(z)
    assert np.array_equal(fewer.in_contact, every.in_contact)


def test_every_tip_is_kept_under_load_control_or_when_all_reach():
    tips = np.array([[0.0, 0.0], [1.0, 0.0]])
    laws = [HertzLaw(1.0, MAT.E_star)] * 2
    provider = HalfSpace(MAT)
    assert reaching(provider, tips, np.array([0.0, 0.01]), laws, Loading(None, 0.1)) is None
    assert reaching(provider, tips, np.array([0.0, 0.001]), laws, Loading(0.002, None)) is None
    assert reaching(provider, tips, np.array([0.0, np.nan]), laws, Loading(0.002, None)) is None
