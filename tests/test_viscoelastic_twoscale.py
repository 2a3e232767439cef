"""Viscoelastic histories with the two-scale solver: against the full-grid reference with
the same steps on seeded random scenes (growing and shrinking contacts), and the
correspondence principle on multi-asperity scenes (step load: the elastic answer at
modulus 1 / J(t); step penetration: every force scales as E(t))."""

import dataclasses

import numpy as np
import pytest

import twoscale
from twoscale.material import Material
from twoscale.synthetic import random_scene
from twoscale.viscoelastic import (
    LoadHistory,
    TimeSteps,
    creep_compliance,
    relaxation_modulus,
    solve_history,
)

PRONY = ((10.0, 0.01), (20.0, 1.0))


def _visco(scene, kind, points, **hist):
    m = Material(scene.material.E, scene.material.nu, prony=PRONY)
    return dataclasses.replace(
        scene, material=m, total_load=None, penetration=None, history=LoadHistory(kind, points, **hist)
    )


@pytest.mark.parametrize("seed", [3, 11])
def test_twoscale_matches_the_reference_with_the_same_steps(seed):
    base = random_scene(6, seed=seed, h=0.15)
    W = base.total_load
    scene = _visco(base, "total", ((0.0, 0.0), (0.5, W), (2.0, W), (3.0, 0.3 * W)), steps=TimeSteps(count=8))
    ts = solve_history(scene, method="twoscale")
    ref = solve_history(scene, method="cg")
    assert ts.converged and ref.converged
    np.testing.assert_array_equal(ts.times, ref.times)
    scale = ref.forces.max()
    assert np.abs(ts.forces - ref.forces).max() < 2e-4 * scale
    assert np.abs(ts.penetration - ref.penetration).max() < 1e-4 * np.abs(ref.penetration).max()
    # the contact did shrink on unloading (the case the correspondence principle misses)
    assert ts.contact_area[-1] < 0.8 * ts.contact_area.max()


def test_step_load_is_elastic_at_the_creep_compliance():
    # the approach and the contact are the elastic ones at modulus 1 / J(t); the forces
    # are not (each is int E(t - s) dF_k(d(s)) of the unit-modulus law F_k, which is
    # non-linear in d), except in the relaxed limit
    base = random_scene(6, seed=5, h=0.12)
    W = base.total_load
    out = (0.0, 0.05, 1.0, 20.0)
    scene = _visco(base, "total", ((0.0, W), (20.0, W)), output=out)
    r = solve_history(scene, method="twoscale")
    J = creep_compliance(scene.material)
    for k, t in enumerate(out):
        el = twoscale.solve(dataclasses.replace(base, material=Material(1.0 / float(J(t)), 0.5)))
        assert r.penetration[k] == pytest.approx(el.penetration, rel=2e-3)
        assert r.contact_area[k] == pytest.approx(float(np.sum(el.asperities.contact_areas)), rel=2e-2)
    assert np.abs(r.forces[-1] - el.forces).max() < 3e-3 * el.forces.max()


def test_step_penetration_scales_every_force_as_the_relaxation_modulus():
    base = random_scene(6, seed=7, h=0.12, control="penetration")
    d = base.penetration
    scene = _visco(base, "penetration", ((0.0, d), (20.0, d)), output=(0.0, 0.02, 0.5, 20.0))
    r = solve_history(scene, method="twoscale")
    el = twoscale.solve(base)  # at the relaxed modulus E_inf = the base scene's E
    ratio = relaxation_modulus(scene.material, r.times) / scene.material.E
    assert np.abs(r.forces - ratio[:, None] * el.forces[None, :]).max() < 2e-3 * ratio[0] * el.forces.max()


def test_an_elastic_history_is_the_elastic_solve():
    base = random_scene(6, seed=2, h=0.1)
    W = base.total_load
    scene = dataclasses.replace(base, total_load=None, history=LoadHistory("total", ((0.0, W), (1.0, W))))
    r = twoscale.solve(scene)
    el = twoscale.solve(base)
    # the same problem through the history path (load scaled by E J = 1, u_H = 0): equal to
    # the solver's tolerance (the elastic path itself is unchanged)
    assert r.penetration[0] == pytest.approx(el.penetration, rel=1e-9)
    np.testing.assert_allclose(r.forces[-1], el.forces, rtol=1e-5)
