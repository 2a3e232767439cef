"""The micro step's policy (twoscale.micro.policy) on clear cases, and the driver's record."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from twoscale import Material
from twoscale.indenters import Asperity
from twoscale.influence import HalfSpace
from twoscale.micro.sampling import build_patches
from twoscale.micro.costmodel import FITTED
from twoscale.micro.policy import AUTO_FAR_TOL, UNION_MIN_COVERAGE, choose, decide, estimate_costs
from twoscale.micro.union import box_of
from twoscale.driver import solve_twoscale

MAT = Material(E=6.0, nu=0.5)


def _patches(asps, force, d, h):
    z = np.array([a.z for a in asps])
    pts = build_patches(asps, h=h, forces=np.full(len(asps), force), approaches=d - z, E_star=MAT.E_star)
    return pts, box_of([p.grid for p in pts], h, (0.0, 0.0)).size


def test_one_patch_is_one_constrained_cg_on_it():
    pts, box = _patches([Asperity(0.0, 0.0, 0.0, 5.0)], 2.0, 0.2, 0.05)
    c = choose(pts, box)
    assert c.iteration == "union-cg" and c.far_tol is None and not c.by_caller
    assert box == pts[0].grid.size  # the box is the patch
    # with the tilt (a pivot off the tip) the block iteration's local solve and sensitivities
    assert choose(pts, box, load_control=True, tilt=True).iteration == "block-gs"


def test_few_separated_asperities_take_block_iterations_with_the_far_field():
    # the paper's seven spheres at d/2R = 5: patches are specks in a large box, solved by
    # block iterations (not the union CG over the box); with the sweeps expected from the
    # scene the far-field two-level one, as measured (penetration 1 mm, h 0.25 mm,
    # interleaved, CPU s of the whole solve: 4 sweeps and 0.034 s against block
    # Gauss-Seidel's 5 and 0.049 s)
    R, dc = 10.0, 100.0
    asps = [Asperity(0.0, 0.0, 0.0, R)] + [
        Asperity(dc * math.cos(k * math.pi / 3), dc * math.sin(k * math.pi / 3), 0.0, R) for k in range(6)
    ]
    pts, box = _patches(asps, 20.0, 1.0, 0.25)
    c = choose(pts, box)
    assert c.iteration == "two-level" and c.far_tol == AUTO_FAR_TOL
    assert c.estimates["coverage"] < 0.05
    # the expected counts make the difference: at ten sweeps each, block Gauss-Seidel
    fixed = dataclasses.replace(FITTED, sweeps=None)
    assert choose(pts, box, model=fixed).iteration == "block-gs"
    assert c.estimates["seconds"]["two-level"] < c.estimates["seconds"]["block-gs"]


def test_thousands_of_scattered_asperities_take_the_far_field():
    rng = np.random.default_rng(0)
    asps = [Asperity(*map(float, rng.uniform(-50, 50, 2)), 0.0, 5.0) for _ in range(1000)]
    pts, box = _patches(asps, 0.05, 0.05, 0.05)
    c = choose(pts, box)
    assert c.iteration == "two-level" and c.far_tol == AUTO_FAR_TOL
    assert "scattered" in c.reason
    # merged contacts (the macro step's safe path) rule nothing out: the block iterations
    # solve merged patches as one block, and a box this empty is never the union CG's
    merged = choose(pts, box, merged_contacts=True)
    assert merged.iteration == "two-level" and merged.far_tol == AUTO_FAR_TOL
    assert merged.estimates["coverage"] < UNION_MIN_COVERAGE


def test_crowded_merged_contacts_take_the_union_cg():
    # 12 x 12 spheres 2.5 mm apart with 1.5 mm contact radii: the macro step meets merged contacts
    asps = [Asperity(2.5 * i, 2.5 * j, 0.0, 5.0) for i in range(12) for j in range(12)]
    pts, box = _patches(asps, 3.0, 0.3, 0.05)
    c = choose(pts, box, merged_contacts=True)
    assert c.iteration == "union-cg" and c.far_tol is None
    assert c.estimates["coverage"] > 0.5 and c.estimates["merged_contacts"]
    assert c.estimates["work"]["union-cg"] < c.estimates["work"]["block-gs"]


def test_exact_pairs_grow_as_n_squared_and_union_as_its_box():
    asps = [Asperity(10.0 * (i % 20), 10.0 * (i // 20), 0.0, 5.0) for i in range(320)]
    pts, _ = _patches(asps, 1.0, 0.2, 0.1)

    def cost(n):
        return estimate_costs(pts[:n], box_of([p.grid for p in pts[:n]], 0.1, (0.0, 0.0)).size)

    c20, c40, c320 = cost(20), cost(40), cost(320)
    # local solves grow as n, pairs as n(n-1): the ratio tends to 4 per doubling from above 2
    assert 2.0 < c40["block-gs"] / c20["block-gs"] < 4.0
    assert 3.5 < cost(320)["block-gs"] / cost(160)["block-gs"] < 4.0
    # the far field grows about linearly, the union CG as its box's FFT
    assert c320["two-level"] / cost(160)["two-level"] < 2.2
    assert c320["union-cg"] > c40["union-cg"]


def test_caller_choice_is_recorded_as_such_and_checked():
    asps = [Asperity(0.0, 0.0, 0.0, 5.0), Asperity(4.0, 0.0, 0.0, 5.0)]
    hs = HalfSpace(MAT)
    res = solve_twoscale(hs, asps, h=0.1, penetration=0.2, iteration="union-cg")
    assert res.details.micro.choice.by_caller and res.details.micro.strategy == "union-cg"
    assert [a.iteration for a in res.details.micro.attempts] == ["union-cg"]
    with pytest.raises(ValueError, match="iteration"):
        solve_twoscale(hs, asps, h=0.1, penetration=0.2, iteration="newton")
    with pytest.raises(ValueError, match="far_tol"):
        solve_twoscale(hs, asps, h=0.1, penetration=0.2, far_tol=1.5)
    with pytest.raises(ValueError, match="not both"):
        solve_twoscale(hs, asps, h=0.1, penetration=0.2, iteration="block-gs", coarse=True)


def test_the_driver_composes_iteration_and_coupling_objects():
    from twoscale.micro.driver import TWO_LEVEL_SWEEPS, _order
    from twoscale.micro.policy import Choice
    from twoscale.micro.couplings import Exact, FarField
    from twoscale.micro.strategies import BlockGaussSeidel, TwoLevel, UnionCG

    with pytest.raises(ValueError, match="far-field tol"):
        FarField(1.5)
    # the policy's far field: capped, then the union CG where it stalls
    far = _order(Choice("two-level", 0.1, "r", {}))
    assert far == [(TwoLevel(trial_sweeps=TWO_LEVEL_SWEEPS), FarField(0.1)), (UnionCG(), None)]
    # the caller's far field: exactly what was asked, no trial, no fallback
    fixed = _order(Choice("two-level", 0.1, "r", {}, by_caller=True))
    assert fixed == [(TwoLevel(), FarField(0.1))]
    # the policy's exact two-level (load control): on trial, then the paper's iteration
    exact = _order(Choice("two-level", None, "r", {}))
    assert exact == [(TwoLevel(trial_sweeps=TWO_LEVEL_SWEEPS), Exact()), (BlockGaussSeidel(), Exact())]
    assert [(type(i), c) for i, c in _order(Choice("block-gs", None, "r", {}))] == [(BlockGaussSeidel, Exact())]
    # block Gauss-Seidel takes a far-field coupling too (orthogonal choices)
    assert [(type(i), c) for i, c in _order(Choice("block-gs", 0.2, "r", {}, by_caller=True))] == [
        (BlockGaussSeidel, FarField(0.2))
    ]


def test_near_neighbours_follow_the_far_field_rule():
    # a square lattice of equal patches: the count is the lattice points within the rule's
    # distance (r_k + r_l) / sqrt(far_tol) = 2 r / sqrt(far_tol), counted independently here
    from twoscale.micro.policy import near_neighbours

    FAR_TOL = 0.1  # reaches several lattice rows (the policy's own is larger)

    asps = [Asperity(10.0 * i, 10.0 * j, 0.0, 5.0) for i in range(15) for j in range(15)]
    pts, _ = _patches(asps, 1.0, 0.2, 0.1)
    b = pts[0].grid.bounds
    r = 0.5 * math.hypot(b[1] - b[0], b[3] - b[2])
    reach = 2.0 * r / math.sqrt(FAR_TOL)
    centre = 7  # the middle patch sees the whole disc of lattice points
    expected = sum(
        1
        for i in range(15)
        for j in range(15)
        if (i, j) != (centre, centre) and 10.0 * math.hypot(i - centre, j - centre) < reach
    )
    got_all = near_neighbours(pts, FAR_TOL)
    assert 0 < got_all <= expected  # edges and corners see fewer
    # crowding the same patches twice as close raises the count, which the two-level cost follows
    close = [Asperity(5.0 * i, 5.0 * j, 0.0, 5.0) for i in range(15) for j in range(15)]
    pts_close, box_close = _patches(close, 1.0, 0.2, 0.1)
    assert near_neighbours(pts_close, FAR_TOL) > 2.0 * got_all
    far = estimate_costs(pts, box_of([p.grid for p in pts], 0.1, (0.0, 0.0)).size)["two-level"]
    crowded = estimate_costs(pts_close, box_close)["two-level"]
    assert crowded > far


@pytest.mark.parametrize("far_tol", [0.01, AUTO_FAR_TOL, 0.9])
def test_near_neighbours_count_the_far_field_couplings_near_lists(far_tol):
    # the policy counts the pairs at once; the two-level iteration lists them patch by
    # patch: the same pairs, on patches of unequal sizes scattered at random
    from twoscale.micro.farfield import near_lists, patch_frames
    from twoscale.micro.policy import near_neighbours

    rng = np.random.default_rng(11)
    asps = [
        Asperity(float(x), float(y), float(z), float(R))
        for x, y, z, R in zip(
            rng.uniform(0, 60, 300), rng.uniform(0, 60, 300), rng.uniform(0, 0.05, 300), rng.uniform(1, 9, 300)
        )
    ]
    pts, _ = _patches(asps, 1.0, 0.2, 0.1)
    radii = patch_frames(pts)[1]
    assert radii.max() > 1.5 * radii.min()
    lists = near_lists(*patch_frames(pts), far_tol)
    assert near_neighbours(pts, far_tol) == pytest.approx(sum(len(c) for c in lists) / len(pts), rel=1e-15)


def test_the_far_field_iteration_has_a_union_margin_of_its_own():
    # the margin of 1.7 is on the exact block iterations: against the far-field two-level
    # iteration (now converging where contacts merge) the union CG has a margin of its own
    asps = [Asperity(3.0 * i, 3.0 * j, 0.0, 5.0) for i in range(2) for j in range(2)]
    pts, box = _patches(asps, 3.0, 0.3, 0.05)
    work = choose(pts, box).estimates["work"]

    def model(union, exact, far):
        return _model_predicting(
            work,
            {"union-cg": union, "block-gs": exact, "two-level": far},
            union_margin=1.7,
            far_union_margin=1.25,
            far_field_min_patches=2,
            union_min_coverage=0.0,
        )

    # union 1.3 s against the far field's 1.0 s (exact 10 s): the far field
    picked = choose(pts, box, model=model(1.3, 10.0, 1.0))
    assert picked.iteration == "two-level" and picked.far_tol is not None
    # union 1.3 s against exact block iterations' 1.0 s (far field 10 s): the margin keeps the union CG
    picked = choose(pts, box, model=model(1.3, 1.0, 10.0))
    assert picked.iteration == "union-cg" and "far-field" in picked.reason
    # union 0.9 s: cheapest, taken; 1.2 s: within the far-field margin
    assert choose(pts, box, model=model(0.9, 10.0, 1.0)).iteration == "union-cg"
    assert choose(pts, box, model=model(1.2, 10.0, 1.0)).iteration == "union-cg"


def test_the_cost_model_decides_and_its_margin_works_both_ways():
    import dataclasses

    from twoscale.micro.costmodel import FITTED, CostModel

    # four spheres crowding their box, penetration control: exact block iterations and the union CG
    asps = [Asperity(3.0 * i, 3.0 * j, 0.0, 5.0) for i in range(2) for j in range(2)]
    pts, box = _patches(asps, 3.0, 0.3, 0.05)
    work = choose(pts, box).estimates["work"]
    ratio = work["union-cg"] / work["block-gs"]
    # a model where the union CG is predicted 1.3x the block iterations (their sweeps and its
    # iterations fixed)
    model = dataclasses.replace(
        FITTED,
        ns_per_unit={"union-cg": 1.3 / ratio, "block-gs": 1.0, "two-level": 1.0},
        fixed_seconds={"union-cg": 0.0, "block-gs": 0.0, "two-level": 0.0},
        union_work_exponent=0.0,
        sweeps=None,
        union_iterations=None,
    )
    assert choose(pts, box, model=dataclasses.replace(model, union_margin=1.0)).iteration == "block-gs"
    picked = choose(pts, box, model=dataclasses.replace(model, union_margin=1.7))
    assert picked.iteration == "union-cg" and "1.7x" in picked.reason
    assert picked.estimates["seconds"]["union-cg"] == pytest.approx(
        1.3 * picked.estimates["seconds"]["block-gs"], rel=0.01
    )
    # load control makes the block iterations' work dearer: the same model then prefers the union CG
    assert (
        choose(
            pts, box, load_control=True, model=dataclasses.replace(model, union_margin=1.0, load_factor=2.0)
        ).iteration
        == "union-cg"
    )
    with pytest.raises(ValueError, match="ns_per_unit"):
        CostModel(ns_per_unit={"union-cg": 1.0})


def test_the_union_margins_hold_only_where_the_patches_fill_their_box():
    work = {"union-cg": 1e9, "block-gs": 1e9, "two-level": 1e9}
    flat = {"load_factor": 1.0, "sensitivity_factor": 1.0, "union_margin": 1.7, "union_margin_min_coverage": 0.17}
    flat["far_union_margin"] = 1.85  # above the union CG's 1.3x: the exact iterations' margin decides
    model = _model_predicting(work, {"union-cg": 1.3, "block-gs": 1.0, "two-level": 1.0}, **flat)

    def figures(coverage: float, **extra) -> dict:
        box = 1_000_000
        return {"patches": 27, "carried_cells": int(coverage * box), "box_cells": box, "coverage": coverage, **extra}

    # 27 patches at 15 % of their box, the union CG predicted 1.3x: the exact block iterations
    # (the sweep's 27 paraboloids: union CG 3.9 s and 487 MB against 3.0 s and 166 MB)
    low = decide(figures(0.15), work, model=model)
    assert low.iteration == "block-gs" and "x the exact" not in low.reason
    # from the bound up the margin takes the union CG
    assert decide(figures(0.17), work, model=model).iteration == "union-cg"
    assert "1.7x" in decide(figures(0.25), work, model=model).reason
    # a map's stones and merged contacts under load keep the margin below it
    assert decide(figures(0.15, height_map=True), work, model=model).iteration == "union-cg"
    merged = decide(figures(0.15), work, load_control=True, merged_contacts=True, model=model)
    assert merged.iteration == "union-cg"
    # predicted the cheapest, the union CG is taken at 15 % too
    cheap = _model_predicting(work, {"union-cg": 0.9, "block-gs": 1.0, "two-level": 1.0}, **flat)
    assert decide(figures(0.15), work, model=cheap).iteration == "union-cg"
    # without the bound (0) the margin holds everywhere, as before it
    assert (
        decide(
            figures(0.15),
            work,
            model=_model_predicting(
                work, {"union-cg": 1.3, "block-gs": 1.0, "two-level": 1.0}, **{**flat, "union_margin_min_coverage": 0.0}
            ),
        ).iteration
        == "union-cg"
    )
    with pytest.raises(ValueError, match="union_margin_min_coverage"):
        _model_predicting(work, {"union-cg": 1.0, "block-gs": 1.0, "two-level": 1.0}, union_margin_min_coverage=1.5)


def test_the_union_prediction_grows_faster_than_its_work():
    from twoscale.micro.costmodel import FITTED, UNION_REFERENCE_WORK

    small, large = (
        FITTED.seconds({"union-cg": w})["union-cg"] for w in (UNION_REFERENCE_WORK, 30 * UNION_REFERENCE_WORK)
    )
    # a 7 M-cell box (about 28 x the reference work) ran at 3.7 ns a unit, the reference's at 1-1.5
    assert large / small > 30 * 1.8


def _model_predicting(work: dict, seconds: dict, **fields):
    """The fitted cost model with no fixed costs, a linear union CG of fixed iterations and
    the block iterations' sweeps fixed, its nanoseconds per unit set so that it predicts ``seconds``
    for the candidates' ``work``; ``fields`` on top."""
    import dataclasses

    from twoscale.micro.costmodel import FITTED

    return dataclasses.replace(
        FITTED,
        fixed_seconds={"union-cg": 0.0, "block-gs": 0.0, "two-level": 0.0},
        union_work_exponent=0.0,
        ns_per_unit={k: 1e9 * v / work[k] for k, v in seconds.items()},
        **{"sweeps": None, "union_iterations": None, **fields},
    )


def _scattered(n: int, side: float, seed: int) -> list:
    """``n`` spheres of radius 4 mm at least 5 mm apart on a square of ``2 side`` mm."""
    rng = np.random.default_rng(seed)
    xy: list = []
    while len(xy) < n:
        c = rng.uniform(-side, side, 2)
        if not xy or np.min(np.hypot(*(np.array(xy) - c).T)) > 5.0:
            xy.append(c)
    return [Asperity(float(x), float(y), float(z), 4.0) for (x, y), z in zip(xy, rng.uniform(0.0, 0.02, n))]


def test_tens_of_scattered_patches_take_the_far_field():
    # 70 patches on a box they cover 11 % of: the union CG is ruled out, and the far field
    # is considered from model.sparse_far_field_min_patches (2) instead of 100 patches
    from dataclasses import replace

    from twoscale.micro.costmodel import FITTED

    pts, box = _patches(_scattered(70, 30.0, 1), 1.0, 0.2, 0.1)
    c = choose(pts, box)
    assert c.estimates["coverage"] < UNION_MIN_COVERAGE
    assert c.iteration == "two-level" and c.far_tol == AUTO_FAR_TOL
    assert choose(pts, box, model=replace(FITTED, sparse_far_field_min_patches=71)).far_tol is None
    # where the box is crowded the far field still waits for far_field_min_patches (the
    # far field's own bound, far_field_sparse_coverage, crowded too)
    crowded = replace(FITTED, union_min_coverage=0.01, union_margin=1e-6)
    assert choose(pts, box, model=crowded).far_tol == AUTO_FAR_TOL
    assert choose(pts, box, model=replace(crowded, far_field_sparse_coverage=0.01)).far_tol is None
    # above the union CG's bound, merged contacts keep it waiting too
    assert choose(pts, box, model=crowded, merged_contacts=True).far_tol is None


@pytest.mark.slow
def test_the_far_field_on_tens_of_scattered_patches_is_the_full_grids_answer():
    from twoscale import Scene, solve

    scene = Scene(MAT, _scattered(70, 30.0, 1), penetration=0.2, h=0.1)
    res, ref = solve(scene), solve(scene, method="reference")
    assert res.details.micro.choice.far_tol == AUTO_FAR_TOL
    f, fr = np.asarray(res.asperities.forces), np.asarray(ref.asperities.forces)
    assert np.max(np.abs(f - fr)) <= 1e-3 * np.max(fr)


def test_few_merged_patches_under_load_weigh_the_union_cg_against_sensitivity_sweeps():
    # merged contacts under load control run block Gauss-Seidel with sensitivity sweeps
    # (dearer than its prediction by model.sensitivity_factor); with no far field in the
    # running (a bound on the patches above theirs) the union CG is weighed against it even
    # on a mostly empty box
    import dataclasses

    pts, box = _patches(_scattered(12, 12.0, 2), 1.0, 0.2, 0.05)
    work = choose(pts, box).estimates["work"]
    # the union CG predicted 2.5x the exact block iterations (far field 10x)
    secs = {"union-cg": 2.5, "block-gs": 1.0, "two-level": 10.0}
    model = _model_predicting(
        work, secs, load_factor=1.0, union_margin=1.7, sensitivity_factor=1.9, sparse_far_field_min_patches=45
    )
    merged = choose(pts, box, load_control=True, merged_contacts=True, model=model)
    assert merged.estimates["coverage"] < UNION_MIN_COVERAGE and len(pts) < model.sparse_far_field_min_patches
    assert merged.iteration == "union-cg"
    assert merged.estimates["seconds"]["block-gs"] == pytest.approx(1.9, rel=0.01)
    # not merged: the two-level variant of the exact iteration (no sensitivity sweeps), the
    # union CG ruled out by the coverage; nor under penetration control
    plain = choose(pts, box, load_control=True, model=model)
    assert plain.iteration == "two-level" and plain.far_tol is None
    assert choose(pts, box, merged_contacts=True, model=model).iteration == "block-gs"
    # without the factor the margin of 1.7 does not reach 2.5x
    flat = dataclasses.replace(model, sensitivity_factor=1.0)
    assert choose(pts, box, load_control=True, merged_contacts=True, model=flat).iteration == "block-gs"


@pytest.mark.slow
def test_sweep_scene_of_15_merged_paraboloids_under_load_is_the_full_grids_answer():
    # the sweep's #51: 15 paraboloids under load, merged contacts on 12 % of their box;
    # block Gauss-Seidel with sensitivity sweeps took 2.0-2.6 s of CPU, the union CG
    # 1.1-2.2 s, the far-field two-level iteration 1.0 s (forced, interleaved with the union CG)
    from twoscale import scenespace, solve

    (spec,) = [s for s in scenespace.sweep(200, 0) if s.index == 51]
    scene = scenespace.build(spec)
    res, ref = solve(scene), solve(scene, method="reference")
    assert res.details.micro.choice.iteration == "two-level" and res.details.micro.choice.far_tol == AUTO_FAR_TOL
    f, fr = np.asarray(res.asperities.forces), np.asarray(ref.asperities.forces)
    # the far field's approximation (of order (r / d)^3): 3.3e-5 of the largest force from the union CG's
    assert np.max(np.abs(f - fr)) <= 2e-4 * np.max(fr)


@pytest.mark.parametrize("merged, load", [(False, False), (True, True), (False, True)])
def test_a_choice_is_made_again_from_what_its_estimates_keep(merged, load):
    # what a sweep record keeps (the figures and each candidate's work) gives the same
    # choice without the patches, so a refitted cost model can be replayed on old runs
    asps = [Asperity(2.5 * i, 2.5 * j, 0.0, 5.0) for i in range(6) for j in range(6)]
    asps += [Asperity(60.0 + 9.0 * i, 0.0, 0.0, 5.0) for i in range(8)]
    pts, box = _patches(asps, 3.0, 0.3, 0.05)
    c = choose(pts, box, merged_contacts=merged, load_control=load)
    again = decide(c.estimates, c.estimates["work"], merged_contacts=merged, load_control=load)
    assert (again.iteration, again.far_tol, again.reason) == (c.iteration, c.far_tol, c.reason)
    # and a model that makes the union CG dear moves it away from it
    dear = _model_predicting(c.estimates["work"], {"union-cg": 100.0, "block-gs": 1.0, "two-level": 2.0})
    assert (
        decide(c.estimates, c.estimates["work"], merged_contacts=merged, load_control=load, model=dear).iteration
        != "union-cg"
    )


def test_the_calibration_replays_recorded_choices_under_a_new_model(capsys):
    from benchmarks.calibrate_policy import replay
    from twoscale.scenespace import draw

    asps = [Asperity(2.5 * i, 2.5 * j, 0.0, 5.0) for i in range(6) for j in range(6)]
    pts, box = _patches(asps, 3.0, 0.3, 0.05)
    c = choose(pts, box)
    spec = {**draw(3).to_dict(), "control": "penetration", "tilt": False}
    ts = {"work": c.estimates["work"], "coverage": c.estimates["coverage"], "reason": c.reason, "choice": c.iteration}
    from twoscale.micro.costmodel import FITTED

    replay([{"spec": spec, "ts": ts}], FITTED)
    assert "0 choices change" in capsys.readouterr().out
    others = {k: 1.0 for k in c.estimates["work"]}
    dear = _model_predicting(c.estimates["work"], {**others, c.iteration: 100.0})
    replay([{"spec": spec, "ts": ts}], dear)
    out = capsys.readouterr().out
    assert "1 choices change" in out and f"{c.iteration} -> " in out
