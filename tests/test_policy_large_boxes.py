"""The micro-step policy on a box of many cells: the far field is a candidate there whatever
the patch count and coverage, and the prediction decides (the union CG runs every product on
the whole box, the far field's blocks are the clusters of touching patches)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from twoscale.micro.costmodel import FITTED
from twoscale.micro.policy import AUTO_FAR_TOL, choose, decide

#: seed 3's #11 as the sweep recorded it: 93 clustered spheres under load, merged contacts,
#: 23.4 % of a box of 17.5 M cells; work units (union CG, exact block iterations, far field)
FIGURES = {"patches": 93, "coverage": 0.234, "box_cells": 17_481_126, "carried_cells": 0, "largest_patch": 0}
WORK = {"union-cg": 7.29e10, "block-gs": 1.49e11, "two-level": 3.33e10}


def _decide(model=FITTED, box: int | None = None):
    figures = dict(FIGURES, box_cells=FIGURES["box_cells"] if box is None else box)
    return decide(figures, WORK, merged_contacts=True, load_control=True, model=model)


def test_a_box_of_many_cells_lets_the_far_field_in():
    # interleaved, fresh processes: the union CG 70.2 and 70.3 s of CPU, the far-field
    # two-level iteration 56.2 and 53.2 s (7 sweeps), forces within 3.6e-4 of the largest
    choice = _decide()
    assert choice.iteration == "two-level" and choice.far_tol == AUTO_FAR_TOL
    # without the bound (or on a box under it) the 93 merged patches keep the union CG
    assert _decide(model=dataclasses.replace(FITTED, far_field_box_cells=0)).iteration == "union-cg"
    assert _decide(box=FITTED.far_field_box_cells - 1).iteration == "union-cg"


def test_separate_clusters_on_the_far_field_give_the_references_forces(monkeypatch):
    # the same rule with its bound under a small box: seed 3's #27 (32 paraboloids, merged
    # contacts at 22 % of a box of 0.5 M cells) takes the far field and its forces are the
    # full-grid reference's to the far field's tolerance
    import twoscale.micro.driver as driver
    from twoscale import scenespace, solve

    model = dataclasses.replace(FITTED, far_field_box_cells=100_000)
    monkeypatch.setattr(driver, "choose", functools.partial(choose, model=model))
    (spec,) = [s for s in scenespace.sweep(200, 3) if s.index == 27]
    scene = scenespace.build(spec)
    res, ref = solve(scene), solve(scene, method="reference")
    choice = res.details.micro.choice
    assert choice.iteration == "two-level" and choice.far_tol == AUTO_FAR_TOL and not choice.by_caller
    assert res.converged
    f, fr = np.asarray(res.asperities.forces), np.asarray(ref.asperities.forces)
    assert np.max(np.abs(f - fr)) <= 5e-3 * np.max(fr)
    # and without the rule it is the union CG's scene
    monkeypatch.setattr(driver, "choose", choose)
    assert solve(scene).details.micro.choice.iteration == "union-cg"
