"""The forced runs' tools: rows of any seed, the variant the policy runs for each candidate,
the choices made again against the measured costs, and the cost model's common scale."""

from __future__ import annotations

import dataclasses

from benchmarks.calibrate_policy import forced_samples, policy_runs
from benchmarks.forced_choices import pick, right, score
from twoscale.micro.costmodel import CANDIDATES, FITTED, SPEEDUP
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


def _choices(model) -> list:
    """The choices on a grid of figures and work around the recorded scene's: patch counts,
    coverages, sizes, the union CG's work against the block iterations', both controls."""
    out = []
    for patches in (2, 5, 20, 102, 500):
        for coverage in (0.05, 0.15, 0.36, 0.8):
            for scale in (1e-3, 1e-2, 0.1, 1.0, 10.0):
                for union in (0.3, 0.6, 1.0, 1.5, 2.2, 4.0):
                    figures = {**FIGURES, "patches": patches, "coverage": coverage}
                    work = {k: v * scale * (union if k == "union-cg" else 1.0) for k, v in WORK.items()}
                    for load in (False, True):
                        kw = {"load_control": load, "merged_contacts": coverage > 0.3}
                        choice = decide(figures, work, model=model, **kw)
                        out.append((choice.iteration, choice.far_tol))
    return out


def test_the_installed_scale_keeps_every_choice_of_the_model_it_scales():
    # one factor on every coefficient's seconds: the same choice everywhere
    unscaled = lambda per: dataclasses.replace(  # noqa: E731
        FITTED,
        ns_per_unit={k: FITTED.ns_per_unit[k] / per[k] for k in CANDIDATES},
        fixed_seconds={k: FITTED.fixed_seconds[k] / per[k] for k in CANDIDATES},
    )
    now = _choices(FITTED)
    assert len(set(now)) == 4  # the union CG, block Gauss-Seidel, both two-level iterations
    assert _choices(unscaled(dict.fromkeys(CANDIDATES, SPEEDUP))) == now
    # a factor per candidate (as measured: 0.49, 0.41, 0.45) would move some
    moved = _choices(unscaled({"union-cg": 0.49, "block-gs": 0.41, "two-level": 0.45}))
    assert moved != now
