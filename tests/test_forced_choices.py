"""The forced runs' tools: rows of any seed, the variant the policy runs for each candidate,
the choices made again against the measured costs, and the block iterations' expected sweep
counts: their closed form, the installed model's use of them, and their fit."""

from __future__ import annotations

import dataclasses
import math

import pytest

from benchmarks.calibrate_policy import forced_samples, policy_runs
from benchmarks.sweep_counts import fit_counts, fit_model
from benchmarks.forced_choices import pick, right, score
from twoscale.micro.costmodel import FITTED
from twoscale.micro.sweepcount import SweepCount
from twoscale.micro.policy import decide
from twoscale.scenespace import sweep

#: seed 0's #198 as the sweep recorded it (tests/test_policy_sweep.py): 102 spheres,
#: penetration, merged contacts at 36 % of the box; work of each candidate
FIGURES = {"patches": 102, "coverage": 0.364, "box_cells": 0, "carried_cells": 0, "largest_patch": 0}
WORK = {"union-cg": 4.17e9, "block-gs": 1.39e10, "two-level": 2.23e9}


def _row(seed: int, index: int, variant: str, micro_s: float, control: str = "penetration") -> dict:
    figures = {**FIGURES, "merged_contacts": True, "height_map": False}
    return {"seed": seed, "scene": index, "variant": variant, "micro_s": micro_s, "converged": True} | {
        "work": WORK,
        "figures": figures,
        "control": control,
        "tilt": False,
    }


def test_forced_rows_build_their_own_seeds_spec():
    # the same index in two seeds is two scenes: each sample names its seed's draw
    rows = [_row(5, 105, "union-cg", 0.5), _row(0, 105, "union-cg", 0.5)]
    got = forced_samples(rows)
    for seed, sample in zip((5, 0), got):
        (spec,) = [s for s in sweep(200, seed) if s.index == 105]
        assert sample["scene"] == f"seed {seed} {spec.label} (forced)"
        assert sample["control"] == ("tilt" if spec.tilt else spec.control)


def test_a_variant_run_again_replaces_its_earlier_row_when_asked(tmp_path):
    import json

    from benchmarks.calibrate_policy import forced_rows

    first, again = tmp_path / "first.jsonl", tmp_path / "again.jsonl"
    old = [_row(0, 198, "union-cg", 4.0), _row(0, 198, "far", 2.0), _row(5, 198, "union-cg", 1.0)]
    first.write_text("".join(json.dumps(r) + "\n" for r in old))
    again.write_text(json.dumps(_row(0, 198, "union-cg", 3.0)) + "\n")
    # by default every row counts; with latest one a seed, scene and variant, the last read
    assert [r["micro_s"] for r in forced_rows([first, again])] == [4.0, 2.0, 1.0, 3.0]
    got = forced_rows([first, again], latest=True)
    assert sorted((r["seed"], r["variant"], r["micro_s"]) for r in got) == [
        (0, "far", 2.0),
        (0, "union-cg", 3.0),
        (5, "union-cg", 1.0),
    ]


def test_the_exact_candidate_is_charged_to_the_variant_the_policy_runs():
    # decide sends the exact candidate under load control without merged contacts to the
    # exact two-level iteration, otherwise to block Gauss-Seidel
    cheap_exact = {"union-cg": 1e12, "block-gs": 1e6, "two-level": 1e12}
    few = {**FIGURES, "patches": 3}
    for control, merged in (("load", False), ("load", True), ("penetration", False)):
        choice = decide(few, cheap_exact, load_control=control == "load", merged_contacts=merged)
        ran = "two-level" if choice.iteration == "two-level" and choice.far_tol is None else choice.iteration
        row = {"control": control, "figures": {"merged_contacts": merged}}
        assert policy_runs(row)["block-gs"] == ran


def test_choices_are_scored_against_the_measured_fastest():
    scene = {"seed": 0, "scene": 198, "auto": _row(0, 198, "auto", 0.0)}
    chosen = pick(scene, FITTED)
    assert chosen == decide(FIGURES, WORK, merged_contacts=True, model=FITTED).iteration
    other = "two-level" if chosen == "union-cg" else "union-cg"
    faster = {**scene, "measured": {chosen: 1.0, other: 2.0}}
    slower = {**scene, "measured": {chosen: 2.0, other: 1.0}}
    assert score([faster], FITTED, 1.1)[:2] == (1, 1)
    assert score([slower], FITTED, 1.1)[:2] == (0, 1)
    assert score([faster, slower], FITTED, 1.1)[3] == (1.0 + 2.0) / (1.0 + 1.0)
    # within the ratio, or within the clock's slack on the smallest steps
    assert right({"a": 1.05, "b": 1.0}, "a", 1.1) and not right({"a": 1.2, "b": 1.0}, "a", 1.1)
    assert right({"a": 0.015, "b": 0.008}, "a", 1.1)


def test_a_sweep_count_is_its_closed_form():
    # rho = sqrt(coverage): at a quarter of the box rho = 1/2 and log(1 / (1 - rho)) = log 2
    count = SweepCount(4.0, 2.0, 1.0, 3.0)
    assert count(0.0) == pytest.approx(4.0)
    assert count(0.25) == pytest.approx(4.0 + 2.0 * math.log(2.0))
    # the load's sweeps under load control, the tilt's instead of them with the tilt
    assert count(0.25, load_control=True) == pytest.approx(count(0.25) + 1.0)
    assert count(0.25, load_control=True, tilt=True) == pytest.approx(count(0.25) + 3.0)
    # more sweeps as the patches crowd their box, bounded where they fill it
    got = [count(c) for c in (0.01, 0.1, 0.3, 0.6, 0.9)]
    assert got == sorted(got) and count(1.0) == count(0.9) < 20.0


def test_the_installed_model_charges_the_block_iterations_their_expected_sweeps():
    # a candidate's seconds over its fixed part scale with its count: the far field's
    # prediction on crowded patches against sparse ones is the ratio of their counts
    work = {"union-cg": 1e9, "block-gs": 1e9, "two-level": 1e9}
    for key in ("block-gs", "two-level"):
        count = FITTED.sweeps[key]
        for load, tilt in ((False, False), (True, False), (True, True)):
            at = lambda c: FITTED.seconds(work, load_control=load, tilt=tilt, coverage=c)[key]  # noqa: E731
            fixed = FITTED.fixed_seconds[key]
            want = count(0.6, load_control=load, tilt=tilt) / count(0.02, load_control=load, tilt=tilt)
            assert (at(0.6) - fixed) / (at(0.02) - fixed) == pytest.approx(want)
    # without a coverage (no figures) the fixed count of the work estimate
    plain = FITTED.seconds(work)["two-level"]
    assert plain == pytest.approx(FITTED.fixed_seconds["two-level"] + FITTED.ns_per_unit["two-level"])


def _sample(key: str, coverage: float, control: str, seconds: float, sweeps: float) -> dict:
    row = {"candidate": key, "iteration": key, "work": 1e9, "control": control, "seconds": seconds}
    return row | {"converged": True, "sweeps": sweeps, "scene": "s", "seed": 0, "coverage": coverage}


def test_the_fit_recovers_a_known_sweep_law_and_its_cost():
    # sweeps and seconds made by a known law: the fit finds its coefficients again
    law = {"block-gs": SweepCount(6.0, 3.0, 2.0, 4.0), "two-level": SweepCount(4.0, 2.0, 1.0, 0.5)}
    ns, fixed = {"block-gs": 1.2, "two-level": 1.8}, {"block-gs": 0.01, "two-level": 0.02}
    rows = []
    for key, count in law.items():
        for coverage in (0.01, 0.05, 0.15, 0.3, 0.5, 0.7, 0.85):
            for control in ("penetration", "load", "tilt"):
                n = count(coverage, load_control=control != "penetration", tilt=control == "tilt")
                rows.append(_sample(key, coverage, control, fixed[key] + ns[key] * n / FITTED.gs_sweeps, n))
    assert {k: dataclasses.astuple(c) for k, c in fit_counts(rows).items()} == {
        k: pytest.approx(dataclasses.astuple(c), rel=1e-3) for k, c in law.items()
    }
    model = fit_model(rows)
    for key in law:
        assert model.ns_per_unit[key] == pytest.approx(ns[key], rel=1e-2)
        assert model.fixed_seconds[key] == pytest.approx(fixed[key], rel=1e-2)
    assert model.ns_per_unit["union-cg"] == FITTED.ns_per_unit["union-cg"]  # the union CG's kept


def test_the_far_fields_seconds_a_patch_replace_its_products_overhead():
    # work made as estimate_costs makes it: transforms plus one overhead a local product,
    # gs_sweeps sweeps; with far_patch_seconds the overhead is out and s a patch and sweep in
    model = dataclasses.replace(FITTED, far_patch_seconds=2e-4)
    n, transforms, coverage = 3000, 4e9, 0.2
    overhead = FITTED.gs_sweeps * FITTED.local_products * FITTED.product_overhead * n
    work = {"two-level": transforms + overhead}
    factor = FITTED.block_factor("two-level", coverage, False, False)
    want = FITTED.fixed_seconds["two-level"] + factor * (
        1e-9 * FITTED.ns_per_unit["two-level"] * transforms + FITTED.gs_sweeps * 2e-4 * n
    )
    got = model.seconds(work, coverage=coverage, patches=n)["two-level"]
    assert got == pytest.approx(want, rel=1e-12)
    # the product overhead's size no longer matters; without it (None) the overhead is charged
    other = dataclasses.replace(model, product_overhead=2 * FITTED.product_overhead)
    moved = {"two-level": transforms + 2 * overhead}
    assert other.seconds(moved, coverage=coverage, patches=n)["two-level"] == pytest.approx(got, rel=1e-12)
    plain = FITTED.seconds(work, coverage=coverage, patches=n)["two-level"]
    assert plain == pytest.approx(
        FITTED.fixed_seconds["two-level"] + factor * 1e-9 * FITTED.ns_per_unit["two-level"] * work["two-level"]
    )
    # the exact block iterations keep their overhead
    exact = {"block-gs": transforms + overhead}
    assert model.seconds(exact, coverage=coverage, patches=n) == FITTED.seconds(exact, coverage=coverage, patches=n)


def test_the_far_fit_recovers_a_known_cost_a_unit_and_a_patch():
    from benchmarks.sweep_counts import fit_far

    ns = {**FITTED.ns_per_unit, "two-level": 2.2}
    model = dataclasses.replace(FITTED, far_patch_seconds=1.5e-4, ns_per_unit=ns)
    rows = []
    for n in (3, 30, 300, 3000):
        for transforms in (1e7, 1e9, 3e10):
            work = transforms + FITTED.gs_sweeps * FITTED.local_products * FITTED.product_overhead * n
            for coverage, control in ((0.05, "penetration"), (0.3, "load"), (0.6, "tilt")):
                load, tilt = control != "penetration", control == "tilt"
                t = model.seconds({"two-level": work}, load_control=load, tilt=tilt, coverage=coverage, patches=n)
                rows.append(_sample("two-level", coverage, control, t["two-level"], 6) | {"work": work, "patches": n})
    got = fit_far(rows)
    assert got.ns_per_unit["two-level"] == pytest.approx(2.2, rel=1e-2)
    assert got.far_patch_seconds == pytest.approx(1.5e-4, rel=1e-2)
    # the far field's fixed seconds and sweeps, and the other candidates, kept
    assert got.fixed_seconds == FITTED.fixed_seconds and got.sweeps == FITTED.sweeps
    assert {k: v for k, v in got.ns_per_unit.items() if k != "two-level"} == {
        k: v for k, v in FITTED.ns_per_unit.items() if k != "two-level"
    }


def test_the_union_cgs_seconds_follow_its_expected_iterations():
    from twoscale.micro.costmodel import UNION_REFERENCE_WORK

    count = SweepCount(16.0, 6.0, tilt=12.0)
    model = dataclasses.replace(FITTED, union_iterations=count, union_work_exponent=0.25)
    work = 4e9
    for coverage, load, tilt in ((0.04, False, False), (0.36, True, False), (0.64, True, True)):
        rho = math.sqrt(coverage)
        iterations = 16.0 + 6.0 * math.log(1.0 / (1.0 - rho)) + (12.0 if tilt else 0.0)
        expected = (
            model.fixed_seconds["union-cg"]
            + 1e-9
            * model.ns_per_unit["union-cg"]
            * work
            * (work / UNION_REFERENCE_WORK) ** 0.25
            * iterations
            / model.union_products
        )
        got = model.seconds({"union-cg": work}, load_control=load, tilt=tilt, coverage=coverage)["union-cg"]
        assert got == pytest.approx(expected, rel=1e-12)
    # a box the patches cover sparsely costs fewer iterations than a crowded one
    sparse, crowded = (model.seconds({"union-cg": work}, coverage=c)["union-cg"] for c in (0.05, 0.6))
    assert sparse < crowded
    # without a count, or without the coverage, the fixed products
    fixed = dataclasses.replace(model, union_iterations=None).seconds({"union-cg": work}, coverage=0.3)
    assert model.seconds({"union-cg": work})["union-cg"] == pytest.approx(fixed["union-cg"], rel=1e-12)


def test_the_union_fit_recovers_a_known_iteration_count_and_cost():
    from benchmarks.sweep_counts import fit_union

    count = SweepCount(15.0, 7.0, tilt=10.0)
    fixed = {**FITTED.fixed_seconds, "union-cg": 0.03}
    ns = {**FITTED.ns_per_unit, "union-cg": 0.9}
    model = dataclasses.replace(FITTED, union_iterations=count, fixed_seconds=fixed, ns_per_unit=ns)
    model = dataclasses.replace(model, union_work_exponent=0.2)
    rows = []
    for work in (1e8, 1e9, 1e10, 4e10):
        for coverage in (0.02, 0.1, 0.3, 0.6, 0.85):
            for control in ("penetration", "load", "tilt"):
                load, tilt = control != "penetration", control == "tilt"
                t = model.seconds({"union-cg": work}, load_control=load, tilt=tilt, coverage=coverage)["union-cg"]
                # the iterations taken: the count without the tilt's products
                its = count(coverage, load_control=load)
                rows.append(_sample("union-cg", coverage, control, t, its) | {"work": work})
    got = fit_union(rows)
    assert got.union_iterations.base == pytest.approx(15.0, rel=1e-2)
    assert got.union_iterations.interaction == pytest.approx(7.0, rel=1e-2)
    assert got.union_iterations.tilt == pytest.approx(10.0, rel=2e-2)
    assert got.ns_per_unit["union-cg"] == pytest.approx(0.9, rel=2e-2)
    assert got.fixed_seconds["union-cg"] == pytest.approx(0.03, rel=2e-2)
    assert got.union_work_exponent == pytest.approx(0.2, abs=5e-3)
    # the block candidates kept
    assert got.sweeps == FITTED.sweeps and got.ns_per_unit["two-level"] == FITTED.ns_per_unit["two-level"]
