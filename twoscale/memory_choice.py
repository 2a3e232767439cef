"""Which micro iterations a default two-scale solve may run, predicted before the macro step.

The micro step's policy chooses after the macro step, from the patches it sized
(:func:`twoscale.micro.policy.decide`): the union CG over their box, or a block iteration;
a far-field two-level attempt on patches that cover at least ``UNION_MIN_COVERAGE`` of
their box is followed by the union CG where it does not converge
(:func:`twoscale.micro.driver._order`) where its box fits in the memory available then
(:func:`twoscale.memory_now.union_box_fits`; else block Gauss-Seidel with the same
coupling). The memory estimate makes the same choice on the patches it counts
(:func:`twoscale.memory_parts.patch_half_widths`), over a band of their size
(:data:`LOW_FACTOR`) and with and without merged contacts (which only the macro step
finds): an iteration chosen anywhere in the band may run; one chosen nowhere is not
counted. Where the band holds both, the block iteration is counted and the union CG is
checked against the memory available when the policy takes it
(:func:`twoscale.memory_now.box_check`). The union CG that only follows a far-field
attempt is not counted: it runs only where it fits when the attempt has failed (in the
sweep records, 88 far-field attempts at that coverage on 75 scenes of seeds 1 and 5-9,
none failed). Cells, mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .micro.policy import AUTO_FAR_TOL, UNION_MIN_COVERAGE, decide, work_of

#: Below the patches the estimate counts, the band's lower end: their cells times this
#: (the policy's coverage of the box was 0.46 of the count at the least on seed 8's scenes
#: of tips, sweep records).
LOW_FACTOR = 0.5


@dataclass(frozen=True)
class Routes:
    """Which micro iterations may run.

    Attributes
    ----------
    union : bool
        The union CG over the patches' box, chosen.
    blocks : bool
        A block iteration (two-level or block Gauss-Seidel).
    fallback : bool
        The union CG after a far-field two-level attempt that does not converge (run only
        where its box fits then: :func:`twoscale.memory_now.union_box_fits`).
    """

    union: bool
    blocks: bool
    fallback: bool = False


def possible_routes(
    tips: np.ndarray,
    r: np.ndarray,
    upper: np.ndarray,
    h: float,
    box_cells: float,
    *,
    load_control: bool,
    tilt: bool,
    height_map: bool = False,
) -> Routes:
    """The iterations the policy may choose for the patches of half-widths ``r`` (mm, 0:
    none) about ``tips`` ((N, 2) mm) on a box of ``box_cells`` cells at cell size ``h``
    (mm): at those, at :data:`LOW_FACTOR` of their cells, and at the half-widths ``upper``
    (mm, an upper estimate of what the macro step's forces size), each with and without
    merged contacts."""
    on = (r > 0) | (upper > 0)
    if not np.any(on):
        return Routes(False, True)
    tips, r, upper = tips[on], r[on], upper[on]
    pairs: list = []  # found at the first band that needs them
    union = blocks = fallback = False
    for widths in (r, upper, math.sqrt(LOW_FACTOR) * r):
        has = widths > 0
        if (union and blocks) or not np.any(has):
            continue
        cells = (np.floor(2.0 * widths[has] / h) + 1.0) ** 2
        carried = min(float(cells.sum()), float(box_cells))  # owned cells: overlaps once
        figures = {
            "patches": len(cells),
            "carried_cells": int(carried),
            "box_cells": int(box_cells),
            "coverage": carried / max(float(box_cells), 1.0),
            "largest_patch": int(cells.max()),
            "height_map": height_map,
        }
        # the block iterations' work grows with the near pairs: where the union CG is chosen
        # against none, it is chosen against any, and they need not be counted
        near = 0.0
        if not _union_everywhere(figures, work_of(cells, 0.0, box_cells), load_control, tilt):
            if not pairs:
                reach = 2.0 * math.sqrt(2.0) * float(np.max(np.maximum(r, upper))) / math.sqrt(AUTO_FAR_TOL)
                pairs.extend(_pairs(tips, reach))
            scaled, i, j = pairs
            # a patch's half-diagonal (policy.near_neighbours' radii); none: never near
            diag = np.where(has, math.sqrt(2.0) * widths, -np.inf)
            near = 2.0 * np.count_nonzero(scaled < diag[i] + diag[j])
        work = work_of(cells, near / len(cells), box_cells)
        for merged in (False, True):
            choice = decide(figures, work, merged_contacts=merged, load_control=load_control, tilt=tilt)
            if choice.iteration == "union-cg":
                union = True
                continue
            blocks = True
            far = choice.iteration == "two-level" and choice.far_tol is not None
            fallback |= far and figures["coverage"] >= UNION_MIN_COVERAGE
    return Routes(union, blocks, fallback and not union)


def _union_everywhere(figures: dict, work: dict, load_control: bool, tilt: bool) -> bool:
    """Whether the policy takes the union CG with and without merged contacts."""
    return all(
        decide(figures, work, merged_contacts=m, load_control=load_control, tilt=tilt).iteration == "union-cg"
        for m in (False, True)
    )


def _pairs(tips: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs of ``tips`` closer than ``reach`` (mm): their distances times
    ``sqrt(AUTO_FAR_TOL)`` (mm) and indices."""
    from scipy.spatial import cKDTree

    found = cKDTree(tips).query_pairs(reach, output_type="ndarray").reshape(-1, 2)
    i, j = np.ascontiguousarray(found[:, 0]), np.ascontiguousarray(found[:, 1])
    x, y = np.ascontiguousarray(tips[:, 0]), np.ascontiguousarray(tips[:, 1])
    dx, dy = x[i] - x[j], y[i] - y[j]
    return np.sqrt((dx * dx + dy * dy) * AUTO_FAR_TOL), i, j
