"""The sweep's ContactMechanics comparator (benchmarks/sweep.py: run_cm) under penetration
control: on a single paraboloid whose apex falls between grid cells it used to stop at its
iteration cap 62 % above the answer; lifted so that its highest sampled point is at zero it
solves the same problem, and its force equals the full-grid reference's and Hertz's."""

from __future__ import annotations

import pytest

from benchmarks.sweep import run_cm, run_one
from twoscale.analytic import hertz
from twoscale.scenespace import build, draw

pytest.importorskip("ContactMechanics")


def test_contactmechanics_under_a_given_approach_meets_the_reference_and_hertz():
    spec = draw(169).to_dict()  # one paraboloid, penetration control, apex off the cell centres
    h = 0.0039
    cm = run_cm(spec, h)
    ref = run_one("reference", spec, h)
    scene = build(draw(169))
    (tip,) = scene.asperities
    expected = hertz.load(tip.R, scene.penetration - tip.z, scene.material.E_star)
    assert cm["converged"]
    assert cm["forces"][0] == pytest.approx(ref["forces"][0], rel=1e-5)
    # the grid of 55 x 55 cells of 0.0039 mm over a contact radius of ~0.07 mm: 1 % of Hertz
    assert cm["forces"][0] == pytest.approx(expected, rel=0.01)
