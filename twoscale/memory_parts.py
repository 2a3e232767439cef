"""The parts of a solve's peak memory, counted from the scene (no grid array is built):
a full grid and its FFT work, and the two-scale solve's patches, block operators and union
box (:func:`twoscale.resources.estimate_memory` adds them up). Bytes, mm."""

from __future__ import annotations

import math

import numpy as np

from .grid import Grid
from .memory_costs import GRID_BYTES_PER_CELL, PATCH_BYTES_PER_CELL, FFT_WORK_BYTES_PER_CELL
from .memory_costs import COUPLING_CACHE_BYTES, MARGIN, MERGE_GROWTH, MACRO_DENSE_MAX, DENSE_CELLS
from .memory_costs import FAR_OPERATOR_BYTES_PER_PATCH, DENSE_GRID_CELLS
from .micro.policy import FAR_FIELD_MIN_PATCHES, MODEL, UNION_MIN_COVERAGE
from .micro.sources import KEPT_BYTES_PER_OWNED_CELL
from .scene import Scene, expected_approaches, expected_contact_radii


def patch_half_widths(scene: Scene, h: float, *, margin: float = MARGIN) -> np.ndarray:
    """Estimated half-width (mm) of each asperity's patch, 0 for one that cannot touch:
    ``min(margin a_k + 2 h, reach_k + h)`` as :func:`twoscale.micro.patches.patch_radius`,
    with ``a_k`` the contact radius alone at the expected approach."""
    delta = expected_approaches(scene)
    a = expected_contact_radii(scene)
    out = np.zeros(len(scene.asperities))
    for k, asp in enumerate(scene.asperities):
        if delta[k] > 0:
            out[k] = min(asp.reach(float(delta[k])) + h, margin * float(a[k]) + 2.0 * h)
    return out


def _cells_across(r: np.ndarray, h: float) -> np.ndarray:
    return np.floor(2.0 * r / h) + 1.0


def grid_parts(scene: Scene, grid: Grid, name: str) -> dict:
    n = float(grid.size)
    parts = {
        f"the {name} ({grid.ny} x {grid.nx} cells) and its FFT work": (GRID_BYTES_PER_CELL + FFT_WORK_BYTES_PER_CELL)
        * n
    }
    if name == "reference grid":
        material = _material_cells(scene, grid)
        if material <= DENSE_CELLS:  # the dense solver: its matrix, a sub-matrix, a factor
            whole = n if n <= DENSE_GRID_CELLS else 0.0
            parts["dense influence matrix"] = 8.0 * (whole**2 + 2.0 * material**2)
    return parts


def _material_cells(scene: Scene, grid: Grid) -> float:
    """Cells of ``grid`` under indenter material (an upper estimate): the whole grid for
    paraboloids, the discs ``r < R`` of the spheres otherwise."""
    if any(a.shape != "sphere" for a in scene.asperities):
        return float(grid.size)
    discs = sum(math.pi * (a.R + grid.h) ** 2 for a in scene.asperities) / grid.h**2
    return float(min(grid.size, discs))


def twoscale_parts(scene: Scene, h: float, *, iteration: str = "auto") -> tuple[int, dict]:
    """Cells carried and the parts of a two-scale solve's peak: the patches and the macro
    matrix, the block iterations' operators and, where the union CG may run, its box. Under
    ``"auto"`` both: the union CG may follow a block attempt that did not converge, and the
    memory that attempt took is not given back to the system before the union CG allocates
    (1,000 paraboloids at h = 0.051 mm, two-level trial stopped after one sweep: 1.12 GB
    resident before the union CG, 0.41 GB of it in live arrays; peak 2.27 GB, against 1.30 GB
    for the two-level iteration alone and 1.38 GB for the union CG alone). An ``iteration``
    asked for runs alone (:func:`twoscale.micro.driver.run_micro`): only its own parts."""
    r = patch_half_widths(scene, h)
    on = r > 0
    across = _cells_across(r[on], h)
    patch_cells = across**2
    cells = int(patch_cells.sum())
    n = len(scene.asperities)
    parts = {f"{int(on.sum())} patches": PATCH_BYTES_PER_CELL * cells}
    if n <= MACRO_DENSE_MAX:
        parts["macro interaction matrix"] = 3.0 * 8.0 * n * n  # matrix, its LU, a work copy
    else:
        parts["macro interaction matrix"] = 2000.0 * n  # matrix-free point operator
    box = _patch_box(scene, r, h) if int(on.sum()) else None  # one patch: the union CG on it
    blocks = {} if iteration == "union-cg" else _block_parts(across, box, cells)
    # a height map's stones may take the union CG at any coverage, penetration from a lower share (policy.decide)
    on_map = all(a.shape == "map" for a in scene.asperities)
    crowded = box is not None and cells >= MODEL.union_coverage(scene.penetration is None, n) * box.size
    union = {}
    if box is not None and iteration in ("auto", "union-cg") and (iteration == "union-cg" or on_map or crowded):
        union = grid_parts(scene, box, "union box")
        cells = max(cells, int(box.size))
    parts.update(blocks)
    parts.update(union)
    return cells, parts


def _block_parts(across: np.ndarray, box: Grid | None, cells: int) -> dict:
    """What the block iterations hold beyond the patches: the largest block's FFT work, the
    cached cross-patch operators and, where the policy may take the far field, its weights
    and point operator (``across``: cells across each patch that can touch)."""
    patch_cells = across**2
    count = len(across)
    # a merged block (overlapping patches solved together) may have up to MERGE_GROWTH
    # times its members' cells: its FFT work, not the patches' arrays, grows with it
    growth = MERGE_GROWTH if count > 1 else 1.0
    parts = {"FFT work on the largest patch": FFT_WORK_BYTES_PER_CELL * growth * float(patch_cells.max(initial=0))}
    if count > 1:
        parts["cached cross-patch operators"] = min(COUPLING_CACHE_BYTES, _pair_bytes(across))
    crowded = box is not None and cells >= UNION_MIN_COVERAGE * box.size
    if count > 1 and (not crowded or count >= FAR_FIELD_MIN_PATCHES):
        # where the policy may take the far field (micro.policy.decide): its per-patch
        # weights, every patch cell counted as owned (4,548 paraboloids: 4.5 M owned cells,
        # 326 MB of source weights and 326 MB of interpolation rows measured)
        parts["far field's kept weights"] = KEPT_BYTES_PER_OWNED_CELL * cells
        # and its point operator among the patches (8,376 patches of paraboloids: 260 MB)
        parts["far field's point operator"] = FAR_OPERATOR_BYTES_PER_PATCH * float(count)
    return parts


def _pair_bytes(across: np.ndarray) -> float:
    """Bytes of every cross-patch FFT operator, ``sum_{k != l} 8 (n_k + n_l)^2`` with
    ``n`` cells across (``Coupling.full_operator``'s size of a half-spectrum)."""
    s = float(across.sum())
    sq = float((across**2).sum())
    return 8.0 * (2.0 * (len(across) - 1) * sq + 2.0 * (s * s - sq))


def _patch_box(scene: Scene, r: np.ndarray, h: float) -> Grid | None:
    on = r > 0
    if not np.any(on):
        return None
    tips = scene.tips[on]
    rr = r[on]
    return Grid.covering(
        float((tips[:, 0] - rr).min()),
        float((tips[:, 0] + rr).max()),
        float((tips[:, 1] - rr).min()),
        float((tips[:, 1] + rr).max()),
        h,
    )
