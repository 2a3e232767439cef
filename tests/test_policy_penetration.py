"""The micro-step policy on thousands of small patches under penetration control on a box
they cover 8-14 % of: the union CG stays a candidate there and the prediction decides;
under load control the coverage bound rules it out as before. On such a scene the far field,
forced, runs its coarse step by conjugate gradients on the tips' point operator."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from twoscale.errors import ResolutionWarning

from twoscale.micro.costmodel import FITTED
from twoscale.micro.policy import decide

#: figures recorded on seed 5's scenes (the policy's estimates of a default solve): patches,
#: coverage, box cells, load control, tilt, each candidate's work units (union CG, exact
#: block iterations, far-field two-level) and the route that ran faster forced both ways
#: (CPU s of the whole solve, fresh processes: docs/records/sweep.md)
RECORDED = {
    # 9,580 paraboloids: union CG 4.37 s against 8.35 s for the far field
    49: (9580, 0.0836, 3_822_025, False, False, (1.46e10, 4.62e11, 3.00e10), "union-cg"),
    # 3,904 paraboloids: 2.08 s against 2.49 s
    165: (3904, 0.1166, 1_775_556, False, False, (6.47e9, 1.37e11, 1.24e10), "union-cg"),
    # 2,103 spheres: 16.0 s against 3.28 s
    109: (2103, 0.1162, 6_487_193, False, False, (2.56e10, 3.40e11, 8.56e9), "two-level"),
    # 7,567 spheres under load with the tilt: 14.9 s against 10.6 s (union predicted cheaper)
    5: (7567, 0.1130, 4_036_081, True, True, (1.55e10, 5.70e11, 2.42e10), "two-level"),
}


def _decide(scene: int, model=FITTED, **changes):
    n, coverage, cells, load, tilt, (union, exact, far), _ = RECORDED[scene]
    figures = {"patches": n, "coverage": coverage, "box_cells": cells, "carried_cells": 0, "largest_patch": 0}
    figures.update(changes)
    work = {"union-cg": union, "block-gs": exact, "two-level": far}
    return decide(figures, work, load_control=load, tilt=tilt, model=model)


def test_the_faster_route_of_each_recorded_scene_is_chosen():
    for scene, (*_, faster) in RECORDED.items():
        assert _decide(scene).iteration == faster, scene


def test_the_lower_coverage_bound_is_for_many_patches_under_penetration_alone():
    # without the bound, or on fewer patches, the coverage rules the union CG out as before
    before = dataclasses.replace(FITTED, union_penetration_min_coverage=None)
    assert _decide(49, model=before).iteration == "two-level"
    assert _decide(49, patches=FITTED.union_penetration_min_patches - 1).iteration == "two-level"
    # and below the bound itself
    assert _decide(49, coverage=0.99 * FITTED.union_penetration_min_coverage).iteration == "two-level"
    assert FITTED.union_coverage(True, 10_000) == FITTED.union_min_coverage
    assert FITTED.union_coverage(False, 10_000) == FITTED.union_penetration_min_coverage


@pytest.fixture(scope="module")
def small_contacts():
    """2,025 paraboloids on a jittered lattice under penetration control, patches of about
    60 cells covering 9.8 % of their box, and the full-grid reference's forces."""
    from twoscale import Material, solve

    rng = np.random.default_rng(3)
    n, spacing, d = 45, 1.25, 0.012
    X, Y = np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing)
    jitter = rng.uniform(-0.2, 0.2, (2, X.size)) * spacing
    tips = np.column_stack(
        [X.ravel() + jitter[0], Y.ravel() + jitter[1], rng.uniform(0.8, 1.2, X.size), rng.uniform(0, 0.3 * d, X.size)]
    )
    kw = dict(material=Material(10.0, 0.3), penetration=d, h=0.05, shape="paraboloid")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResolutionWarning)  # coarse on purpose: small patches
        return tips, kw, solve(tips, method="reference", **kw).forces


@pytest.mark.filterwarnings("ignore::twoscale.errors.ResolutionWarning")
def test_many_small_contacts_under_penetration_take_the_union_cg_and_the_references_forces(small_contacts):
    # the far field before (1.60 s of CPU), the union CG now (1.39 s); its forces are the
    # full grid's (1.1e-8 of the largest when measured), where the far field's nine-point
    # sources leave 2.4e-5
    from twoscale import solve

    tips, kw, ref = small_contacts
    res = solve(tips, **kw)
    choice = res.details.micro.choice
    assert FITTED.union_penetration_min_coverage <= choice.estimates["coverage"] < FITTED.union_min_coverage
    assert choice.iteration == "union-cg" and not choice.by_caller
    assert np.abs(res.forces - ref).max() <= 1e-6 * np.abs(ref).max()


@pytest.mark.filterwarnings("ignore::twoscale.errors.ResolutionWarning")
def test_the_far_field_with_a_coarse_step_by_conjugate_gradients_keeps_the_references_forces(small_contacts):
    # more patches in contact than the coarse step solves densely: its conjugate gradients
    # run on the tips' Ewald point operator, asked for a tenth of their tolerance; the
    # fixed point is the far field's (2.4e-5 of the largest force from the full grid's)
    from twoscale import solve
    from twoscale.micro.twolevel import COARSE_DENSE_MAX

    tips, kw, ref = small_contacts
    res = solve(tips, iteration="two-level", far_tol=0.3, **kw)
    (attempt,) = res.details.micro.attempts
    assert attempt.converged and attempt.sweeps <= 5
    assert np.count_nonzero(res.forces) > COARSE_DENSE_MAX
    assert np.abs(res.forces - ref).max() <= 1e-4 * np.abs(ref).max()
