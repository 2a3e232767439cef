"""The micro step's policy: which iteration and which coupling, from what the scene is.

After the macro step, the patches say where contact is and how much of its bounding box
it covers. The policy estimates the cost of each iteration in grid-product work
(``n log2 n`` per zero-padded FFT of ``n`` points, the unit every strategy spends) and picks
the cheapest that is expected to converge:

* ``union-cg``: one constrained CG over the box of all patches (:mod:`.union`). Cost: about
  ``union_products`` products on the box. Right where patches are many and crowd the box
  (dense, merged contacts): the cross-patch products then cost more than the box's FFT.
* ``block-gs``: block Gauss-Seidel over the (merged) patches with exact coupling, the
  paper's iteration (eq. 8). Cost: sweeps x (local solves + every pair of patches). Right
  for few asperities: the pair count grows as N^2.
* ``two-level`` with far-field coupling: patches far apart act through their resultant
  forces, a coarse correction keeps the sweeps few. Cost grows as N. Right for many
  scattered contacts (sparse scenes of thousands of tips), where the box is mostly empty.

Work units become predicted CPU seconds by the cost model (:mod:`.costmodel`, fitted to the
scene-space sweep's measured attempts). The choice, its reason and the estimates are
recorded in the result; a caller may fix the iteration or coupling instead (``reason`` says so).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .costmodel import FITTED, CostModel
from .patches import Patch, TipTable

ITERATIONS = ("union-cg", "block-gs", "two-level")
#: Rigid-body unknowns under load control with the tilt: the approach and two angles.
RIGID_UNKNOWNS = 3

#: The cost model (:mod:`.costmodel`): fitted coefficients, margin and budgets in one
#: object; the names below are its fields, kept for the modules that read them.
MODEL = FITTED
UNION_MARGIN = MODEL.union_margin
UNION_MIN_COVERAGE = MODEL.union_min_coverage
FAR_FIELD_MIN_PATCHES = MODEL.far_field_min_patches
EXACT_MAX_PATCHES = MODEL.exact_max_patches
#: Far-field tolerance chosen by the policy (relative size of a far pair, see
#: :class:`~.farfield.LaggedFarField`: nine moment-matching sources per patch, error of
#: order ``(r / d)^3``). Measured against the full-grid reference (largest per-tip error,
#: percent of the largest force; time of the default solve, machine shared):
#: 200 dense tips 0.0007 % at 0.1, 0.0039 % at 0.3, 0.015 % at 0.5; 1,000 sparse tips
#: 0.00013 % (2.9 s), 0.0017 % (2.4 s), 0.0023 % (2.4 s); road benchmark's 314 stones, worst
#: stone in its own force, 0.009 %, 0.12 %, 0.3 %; 1,000 dense tips (h 0.06) 92 s at
#: 0.05, 66 s at 0.1, 26 s at 0.3, 18 s at 0.6 (forces within 0.005 % and 0.019 % of the
#: 0.05 run). 0.3 keeps a margin of 40x on the dense scenes' 0.5 % and the measured surfaces' 1 %.
AUTO_FAR_TOL = 0.3


#: A stalled macro Newton (merged contacts) under penetration or load control, no free tilt,
#: defers its safe path where every tip's reach at Newton's last approach fits a box of at most
#: this many cells: the union CG, which the policy picks on such crowded boxes, solves every
#: contact there from Newton's iterate, and the safe path's L-BFGS-B and dual ascent (0.05-0.12
#: s of CPU, 40-70 % of the solve on 49 merged spheres and 34 under load) would cost about what
#: the whole union CG does. Another iteration picked runs the safe path then
#: (``run_micro``'s ``refine``).
DEFER_SAFE_PATH_MAX_CELLS = 40_000


def safe_path_deferral(asperities: Sequence, h: float, penetration: float | None, tilt: bool):
    """The macro step's ``defer_safe_path`` (:func:`twoscale.macro.solve.solve_macro`): True
    at Newton's last rigid-body unknowns (``[d]`` under load control; ``penetration``
    otherwise) where every tip's reach at that approach spans at most
    ``DEFER_SAFE_PATH_MAX_CELLS`` cells of side ``h`` (mm); None (never) under a free tilt,
    whose union CG sizes its box by the macro step's tilt and forces, and on a height map."""
    if tilt or any(a.shape == "map" for a in asperities):
        return None
    tips: list = []  # the tip arrays, made at the first call (only few-tip macro steps call)

    def defer(rigid: np.ndarray) -> bool:
        if not tips:
            tips.append((TipTable.of(asperities), np.array([a.shape != "paraboloid" for a in asperities])))
        t, sphere = tips[0]
        x, y, z, R = t.x, t.y, t.z, t.curvature
        depth = (float(rigid[0]) if len(rigid) else float(penetration)) - z
        # Asperity.reach for every tip at once: a paraboloid's sqrt(2 R depth), a sphere's cap
        cap = np.minimum(depth, R)
        r = np.sqrt(np.maximum(np.where(sphere, cap * (2.0 * R - cap), 2.0 * R * depth), 0.0))
        on = depth > 0.0
        if not np.any(on) or not np.all(np.isfinite(r[on])):
            return False
        nx = (np.max(x[on] + r[on]) - np.min(x[on] - r[on])) / h + 1.0
        ny = (np.max(y[on] + r[on]) - np.min(y[on] - r[on])) / h + 1.0
        return bool(nx * ny <= DEFER_SAFE_PATH_MAX_CELLS)

    return defer


@dataclass(frozen=True)
class Choice:
    """What the policy chose.

    Attributes
    ----------
    iteration : {"union-cg", "block-gs", "two-level"}
    far_tol : float or None
        Far-field coupling tolerance; None = every pair of patches exact.
    reason : str
        One sentence a user can read.
    estimates : dict
        Scene figures and cost estimates (grid-product work units) behind the choice.
    by_caller : bool
        The caller fixed the iteration (the policy did not choose).
    """

    iteration: str
    far_tol: float | None
    reason: str
    estimates: dict
    by_caller: bool = False


def fft_work(cells: float) -> float:
    """Work of one zero-padded FFT product on a grid of ``cells`` cells (4x padding)."""
    n = 4.0 * max(cells, 1.0)
    return n * math.log2(n)


def scene_figures(patches: Sequence[Patch], box_cells: int) -> dict:
    """Patch count, carried cells and their share of the box."""
    cells = [int(np.count_nonzero(pt.owned)) for pt in patches]
    carried = int(sum(cells))
    return {
        "patches": len(patches),
        "carried_cells": carried,
        "box_cells": int(box_cells),
        "coverage": carried / max(box_cells, 1),
        "largest_patch": max(cells, default=0),
    }


def near_neighbours(patches: Sequence[Patch], far_tol: float) -> float:
    """Mean number of patches a patch is coupled to exactly under far-field coupling with
    ``far_tol`` (the rule of :class:`~.farfield.FarFieldCoupling`:
    :func:`~.farfield.near_lists`)."""
    from scipy.spatial import cKDTree

    from .farfield import patch_frames

    if len(patches) < 2:
        return 0.0
    # the pairs counted at once (near_lists' loop over 6,933 patches: 0.12 s of CPU)
    centres, radii = patch_frames(patches)
    reach = 2.0 * float(radii.max()) / math.sqrt(far_tol)
    i, j = cKDTree(centres).query_pairs(reach, output_type="ndarray").T
    near = np.hypot(*(centres[j] - centres[i]).T) * math.sqrt(far_tol) < radii[j] + radii[i]
    return 2.0 * float(np.count_nonzero(near)) / len(patches)


def estimate_costs(patches: Sequence[Patch], box_cells: int, model: CostModel = FITTED) -> dict:
    """Estimated work (grid-product units) of each iteration on these patches.

    A pair of patches coupled exactly costs ``model.pair_products`` patch-sized products per
    sweep. Calibrated on seeded dense scenes under load control (quiet machine): 200 tips,
    union CG 13.5 s, two-level with far field 6.35 s, with exact coupling 38.6 s, block
    Gauss-Seidel 65.8 s (full-grid reference 23.4 s); 50 tips 2.11, 1.76, 1.49, 2.46 s
    (reference 5.2 s). One work unit is then 1.6-1.9 ns for every iteration."""
    cells = np.array([max(int(np.count_nonzero(pt.owned)), 1) for pt in patches], dtype=float)
    if len(cells) == 0:
        return {"union-cg": 0.0, "block-gs": 0.0, "two-level": 0.0}
    return work_of(cells, near_neighbours(patches, AUTO_FAR_TOL), box_cells, model)


def work_of(cells: np.ndarray, near: float, box_cells: float, model: CostModel = FITTED) -> dict:
    """:func:`estimate_costs` from the patches' owned ``cells`` (array, at least one), the
    mean number ``near`` each is coupled to exactly under the far field
    (:func:`near_neighbours`) and the box's cells: what the memory estimate predicts the
    policy's choice from before the patches exist."""
    n = len(cells)
    # a local solve's and a CG iteration's product also has a fixed cost (Python and
    # transform set-up), which decides on small patches; pairs share their transforms
    padded = 4.0 * np.maximum(cells, 1.0)  # fft_work of every patch at once
    local = float(np.sum(padded * np.log2(padded))) + n * model.product_overhead
    pair = fft_work(float(np.mean(cells)))
    union = model.union_products * (fft_work(box_cells) + model.product_overhead)
    exact = model.gs_sweeps * (model.local_products * local + model.pair_products * n * (n - 1) * pair)
    # far field: the near pairs exact, the rest through one point-operator product of 9 n sources
    near_pairs = model.near_pairs * near / model.near_pairs_calibration
    far = model.gs_sweeps * (
        model.local_products * local + model.pair_products * near_pairs * n * pair + 10.0 * fft_work(9.0 * n)
    )
    return {"union-cg": union, "block-gs": exact, "two-level": far}


def union_limit(block_seconds: dict, model: CostModel = FITTED) -> float:
    """Predicted seconds up to which the union CG is taken against the block iterations'
    predictions ``block_seconds``: ``model.union_margin`` times the exact block iterations'
    (measured on scenes of under 100 patches, where their few large patches run faster as
    one CG than the work estimate says), and ``model.far_union_margin`` times the far-field
    two-level iteration's. A margin of 1.7 on both had sent 814 spheres under load (predicted
    1.35x) to a union CG of over 110 s of CPU against 40 s."""
    limits = [model.union_margin * block_seconds["block-gs"]] if "block-gs" in block_seconds else []
    limits += [model.far_union_margin * block_seconds["two-level"]] if "two-level" in block_seconds else []
    return min(limits, default=math.inf)


def choose(
    patches: Sequence[Patch],
    box_cells: int,
    *,
    merged_contacts: bool = False,
    load_control: bool = False,
    tilt: bool = False,
    height_map: bool = False,
    model: CostModel = FITTED,
    union: bool = True,
) -> Choice:
    """The iteration and coupling for these patches (see the module docstring).

    ``merged_contacts``: the macro step met contacts so close that they merge (its safe
    path). The block iterations solve merged patches as one block, so this rules nothing
    out (the union CG over the whole box was the answer once, and ran 300 light spheres on
    a box of 70 M cells, 88 % empty); under load control it keeps the paper's block
    Gauss-Seidel where exact coupling is cheapest, its prediction times
    ``model.sensitivity_factor``, and the union CG is weighed against it even on a mostly
    empty box where the far field is not a candidate. The far field is not used below
    ``FAR_FIELD_MIN_PATCHES`` patches (from ``model.sparse_far_field_min_patches`` on a
    box they cover less than ``UNION_MIN_COVERAGE`` of, or less than
    ``model.far_field_coverage`` of without merged contacts or on a box of at least
    ``model.far_field_box_cells`` cells; from ``model.sparse_tilt_far_field_min_patches``
    there with the ``tilt``), nor the union CG below ``UNION_MIN_COVERAGE`` (under penetration
    control below ``model.union_coverage``). ``load_control``: where exact block iterations are
    cheapest, their two-level variant runs first (its coarse step corrects the approach
    and tilt instead of sensitivity sweeps: S1-S3 2.7-3x faster), block Gauss-Seidel if it
    stalls; the choice names the two-level iteration with exact coupling. The work of each
    candidate becomes predicted CPU seconds by ``model`` (its block iterations' work costs
    more under load control and with the ``tilt``); the cheapest prediction is chosen, the
    union CG up to :func:`union_limit`. ``height_map``: the patches are a height map's
    stones (:func:`decide`). ``union=False``: the union CG is no candidate (its box does not
    fit in the memory available: :func:`twoscale.micro.driver.run_micro`)."""
    return decide(
        {**scene_figures(patches, box_cells), "height_map": bool(height_map)},
        estimate_costs(patches, box_cells, model),
        merged_contacts=merged_contacts,
        load_control=load_control,
        tilt=tilt,
        model=model,
        union=union,
    )


def _against(rest: dict, margins: bool, model: CostModel) -> str:
    """The union CG's reason, its comparison: the best block iteration's prediction and,
    where the margins hold, how far the union CG is taken past it."""
    if not rest:
        return ""
    text = f", the block iterations {min(rest.values()):.2g} s"
    if margins:
        text += f"; it is taken up to {model.union_margin:g}x the exact ones'"
        if "two-level" in rest:
            text += f" and {model.far_union_margin:g}x the far-field two-level iteration's"
    return text


def decide(
    figures: dict,
    work: dict,
    *,
    merged_contacts: bool = False,
    load_control: bool = False,
    tilt: bool = False,
    model: CostModel = FITTED,
    union: bool = True,
) -> Choice:
    """:func:`choose` from the patches' figures (:func:`scene_figures`) and each
    candidate's work (:func:`estimate_costs`), what a solve's details keep: a choice can be
    made again under another cost model without the patches. On a height map
    (``figures["height_map"]``) the union CG stays a candidate below
    ``model.union_min_coverage``: its box is at most the map's own grid, and on the sweep's
    maps at 8-9 % of their box it ran 0.68-0.73 of the exact two-level iteration's CPU time
    (where scattered tips at 10-14 % ran it 1.9-2.0x slower than the far field). So it does
    on a box of at most ``model.union_small_box_cells`` cells (``figures["box_cells"]``),
    with the margins under load control with the ``tilt`` on at most ``RIGID_UNKNOWNS`` patches.
    ``union=False``: the block iterations alone (one patch: its local solve)."""
    costs = model.seconds(
        work, load_control=load_control, tilt=tilt, coverage=figures["coverage"], patches=figures["patches"]
    )
    # merged contacts under load control: the exact block iterations are block Gauss-Seidel
    # with sensitivity sweeps (below), dearer than the two-level variant the fit saw most
    sensitivity = load_control and merged_contacts
    if sensitivity:
        costs["block-gs"] *= model.sensitivity_factor
    if figures.get("height_map", False) and "two-level" in costs:
        costs["two-level"] *= model.map_far_field_factor
    est = {
        **figures,
        "merged_contacts": bool(merged_contacts),
        "work": {k: float(f"{v:.3g}") for k, v in work.items()},
        "seconds": {k: float(f"{v:.3g}") for k, v in costs.items()},
    }
    n = figures["patches"]
    if n <= 1 and (tilt or not union):
        return Choice("block-gs", None, "one patch: a single local solve", est)
    if n <= 1:
        # the constrained CG on the patch itself, without the eq. 7 start the block
        # iterations make first: one sphere 5.9 ms against 15.8 ms (the full-grid
        # reference 7.4 ms), the same forces
        return Choice("union-cg", None, "one patch: one constrained CG on it", est)
    candidates = dict(costs) if union else {k: v for k, v in costs.items() if k != "union-cg"}
    if n > model.exact_max_patches:
        candidates.pop("block-gs")
    sparse = figures["coverage"] < model.union_min_coverage
    # the far field from few patches where they are scattered: on a mostly empty box, up to its own
    # bound where no contacts merge (it stalls where they crowd), or on a box of many cells
    large = 0 < model.far_field_box_cells <= figures.get("box_cells", 0)
    scattered = sparse or large or (figures["coverage"] < model.far_field_coverage and not merged_contacts)
    few = model.sparse_tilt_far_field_min_patches if tilt else model.sparse_far_field_min_patches
    if n < (few if scattered else model.far_field_min_patches):
        candidates.pop("two-level")
    small = 0 < figures.get("box_cells", 0) <= model.union_small_box_cells
    kept = figures.get("height_map", False) or small or (sensitivity and "two-level" not in candidates)
    if figures["coverage"] < model.union_coverage(load_control, n) and len(candidates) > 1 and not kept:
        # a mostly empty box (under penetration control a lower bound); but on a small one, or
        # against block Gauss-Seidel with sensitivity sweeps alone (few merged patches under
        # load), the prediction decides: 15 paraboloids on 12 % of a 0.5 M-cell box, union CG
        # 1.1-1.2 s of CPU against 2.0-2.6 s
        candidates.pop("union-cg", None)
    rest = {k: v for k, v in candidates.items() if k != "union-cg"}
    # on a small box under load with the tilt, as many patches as rigid-body unknowns
    # (approach, two angles: their forces are the statics' alone) keep the margins: 3
    # paraboloids on 56 K cells, the two-level trial stopped slow after 11 sweeps, block
    # Gauss-Seidel ran 1.8x its prediction, the union CG 0.17 s of CPU against 0.49 s;
    # 5 tilted spheres (42 K cells, 1.14x predicted) ran it 1.23x slower than the two-level one
    tilted = small and tilt and load_control and n <= RIGID_UNKNOWNS
    margins = (
        figures["coverage"] >= model.union_margin_min_coverage
        or figures.get("height_map", False)
        or sensitivity
        or tilted
    )
    limit = (union_limit(rest, model) if margins else min(rest.values())) if rest else math.inf
    if "union-cg" in candidates and candidates["union-cg"] <= limit:
        best = "union-cg"
    else:
        best = min(rest, key=rest.get)
    cov = figures["coverage"]
    if best == "union-cg":
        against = _against(rest, margins, model)
        reason = (
            f"{n} patches carry {100 * cov:.0f} % of their bounding box's "
            f"{figures['box_cells']} cells: one constrained CG over the box (predicted "
            f"{candidates['union-cg']:.2g} s{against})"
        )
        return Choice("union-cg", None, reason, est)
    if best == "block-gs" and load_control and not merged_contacts:
        reason = (
            f"{n} patches, {100 * cov:.0f} % of their box: block iterations with exact coupling "
            "are cheapest; under load control the two-level one corrects the approach (block "
            "Gauss-Seidel follows if it stalls)"
        )
        return Choice("two-level", None, reason, est)
    # under penetration control block Gauss-Seidel stays: on the sweep's 29 scenes of seeds 0-3
    # where it was picked, the exact two-level iteration ran 1.24x its CPU (median; slower on
    # 24, 2.8x on 6 patches of seed 1's #98, 13 sweeps against 6), faster only on seed 3's #7,
    # 0.63x, where block Gauss-Seidel folded six patches (three without contact) into one
    # block of 159 K cells, and without that merge ran as fast as the two-level iteration
    if best == "block-gs":
        reason = f"{n} patches, {100 * cov:.0f} % of their box: block Gauss-Seidel with exact coupling is cheapest"
        return Choice("block-gs", None, reason, est)
    reason = (
        f"{n} scattered patches ({100 * cov:.0f} % of their box): two-level iteration with "
        f"far-field coupling (far_tol {AUTO_FAR_TOL}) is cheapest"
    )
    return Choice("two-level", AUTO_FAR_TOL, reason, est)
