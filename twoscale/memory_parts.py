"""The parts of a solve's peak memory, counted from the scene (no grid array is built):
a full grid and its FFT work, and the two-scale solve's patches, block operators and union
box (:func:`twoscale.resources.estimate_memory` adds them up). Bytes, mm."""

from __future__ import annotations

import math

import numpy as np

from .grid import Grid
from .memory_costs import BLOCK_ATTEMPT_HELD, COUPLING_CACHE_BYTES, DENSE_CELLS, DENSE_GRID_CELLS, DENSE_PAIR_ENTRIES
from .memory_costs import FAR_OPERATOR_BYTES_PER_PATCH, FFT_WORK_BYTES_PER_CELL, GRID_BYTES_PER_CELL, MACRO_DENSE_MAX
from .memory_costs import MARGIN, MERGE_GROWTH, PAIR_HELD, PATCH_BYTES_EACH, PATCH_BYTES_PER_CELL
from .memory_costs import PATCH_WINDOW_BYTES_EACH
from .memory_costs import COARSE_BYTES_PER_LOADED_CELL_AND_FILL, COARSE_BYTES_PER_SQUARE_PAIR, COARSE_FILL_MARGIN
from .micro.policy import AUTO_FAR_TOL, FAR_FIELD_MIN_PATCHES, UNION_MIN_COVERAGE
from .micro.sources import KEPT_BYTES_PER_OWNED_CELL, SEPARABLE_BYTES_PER_ROW_OR_COLUMN, SEPARABLE_CELLS
from .pk.coarse import MAX_FILL as COARSE_MAX_FILL, MAX_SQUARES as COARSE_MAX_SQUARES
from .pk.coarse import MIN_CELLS as COARSE_MIN_CELLS, SIDE as COARSE_SIDE
from .memory_choice import Routes, possible_routes
from .mean_field import alone_approaches, mean_field, pushed_approaches, pushed_contact_radii, reaches, tip_arrays
from .resolution import _contact_radii
from .memory_stall import patch_box, stall_possible, stalled_patches
from .scene import Scene


def patch_half_widths(scene: Scene, h: float, *, margin: float = MARGIN, pushed: bool = True) -> np.ndarray:
    """Estimated half-width (mm) of each asperity's patch, 0 for one that cannot touch:
    ``min(margin a_k + 2 h, reach_k + h)`` as :func:`twoscale.micro.patches.patch_radius`,
    with ``a_k`` the contact radius at the expected approach: with the neighbours' mean push
    under penetration control (:func:`twoscale.mean_field.pushed_approaches`), or, with
    ``pushed=False``, of the asperity alone (an upper estimate)."""
    delta = pushed_approaches(scene) if pushed else alone_approaches(scene)
    a = pushed_contact_radii(scene, pushed)
    return np.where(delta > 0, np.minimum(reaches(scene, delta) + h, margin * a + 2.0 * h), 0.0)


def _lifted_half_widths(scene: Scene, h: float) -> np.ndarray:
    """Under load control, the patches' half-widths (mm) as the macro step's forces size
    them, an upper estimate: at the level the neighbours' mean push raises
    (:func:`twoscale.mean_field.mean_field`), a tip still in contact ``margin a + 2 h``
    from its pushed approach, one lifted out of it the reach of its geometric approach
    (:func:`twoscale.micro.patches.patch_radius`), both within that reach plus a cell. Seed
    7's #156 (839 spheres, load): 0.25 of their box, the policy's patches 0.21, the
    contacts alone 0.12 (the union CG ran on the box, uncounted)."""
    field = mean_field(scene)
    local = np.maximum(field.local, 0.0)
    a = _contact_radii(scene.asperities, local)
    reach = reaches(scene, field.geometric) + h
    out = np.where(field.local > 0, np.minimum(reach, MARGIN * a + 2.0 * h), reach)
    return np.where(field.geometric > 0, out, 0.0)


def _held_half_widths(scene: Scene, h: float, r: np.ndarray) -> np.ndarray:
    """The patches' half-widths (mm) as held, from those of the pushed contacts ``r``: under
    penetration control (where the macro step cannot stall) a tip the neighbours' push lifts
    out of contact but below the level still gets a patch, at the reach of its geometric
    approach plus a cell (:func:`twoscale.micro.patches.patch_radius`). Seed 8's #168 (639
    paraboloids on a block): 463 such patches of 702 K cells, the solve's 463 of 660 K; the
    pushed contacts' 229 of 318 K (its peak 1.57x the estimate so counted). The policy's
    choice stays made on ``r`` (:func:`twoscale.memory_choice.possible_routes`)."""
    if scene.penetration is None or stall_possible(scene):
        return r
    geometric = mean_field(scene).geometric
    lifted = (r <= 0) & (geometric > 0)
    if not np.any(lifted):
        return r
    return np.where(lifted, reaches(scene, np.where(lifted, geometric, 0.0)) + h, r)


def _cells_across(r: np.ndarray, h: float) -> np.ndarray:
    return np.floor(2.0 * r / h) + 1.0


def grid_parts(scene: Scene, grid: Grid, name: str, dense: bool = True) -> dict:
    """A full grid's parts: its arrays and FFT work, and on a ``"reference grid"`` the dense
    solver's matrices where it has few cells with material (``dense``: where the solve may
    take that solver)."""
    n = float(grid.size)
    parts = {
        f"the {name} ({grid.ny} x {grid.nx} cells) and its FFT work": (GRID_BYTES_PER_CELL + FFT_WORK_BYTES_PER_CELL)
        * n
    }
    if name == "reference grid" and dense:
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


def twoscale_parts(scene: Scene, h: float, *, iteration: str = "auto") -> tuple[int, dict, dict]:
    """Cells carried, the parts of a two-scale solve's peak (the patches and the macro
    matrix, the block iterations' operators and, where the union CG surely runs, its box),
    and the parts if the policy takes the union CG where it may take a block iteration too
    (empty where that is not more). Under ``"auto"`` what the policy may run
    (:func:`twoscale.memory_choice.possible_routes`, its choice made on the patches counted
    here, on half their cells and on the upper estimate below): where both may, the block
    iteration is counted, and the union CG (run first, or after a block attempt that did
    not converge, whose memory is then given back (:mod:`twoscale.micro.release`) but for
    ``BLOCK_ATTEMPT_HELD`` of it) is checked against the memory available when the policy
    takes it (:func:`twoscale.micro.driver._plan`); where the exact pairs' operators under
    the far field would hold more than the box, the union CG alone (the policy's work
    estimates, products on the same grids, then make it the cheaper: on the sweep's seed 7
    it ran on all 16 such scenes). The box is counted beyond the patches' cells (its bytes
    a cell were measured with them). An ``iteration`` asked for runs alone
    (:func:`twoscale.micro.driver.run_micro`): only its own parts.

    The patches are sized by the contacts with the neighbours' push
    (:func:`patch_half_widths`); the upper estimate of the macro step's patches is the
    contacts alone (interaction only lowers an approach; under load control, at most 1,000
    tips, at the level the mean push raises): where the policy took the union CG on the
    sweep's scenes its patches covered up to 4x what the pushed contacts do."""
    r = patch_half_widths(scene, h)
    on = r > 0
    held = _held_half_widths(scene, h, r)
    across = _cells_across(held[held > 0], h)
    cells = int((across**2).sum())
    n = len(scene.asperities)
    count = int((held > 0).sum())
    parts = {f"{count} patches": PATCH_BYTES_PER_CELL * cells + PATCH_BYTES_EACH * count}
    if n <= MACRO_DENSE_MAX:
        parts["macro interaction matrix"] = 3.0 * 8.0 * n * n  # matrix, its LU, a work copy
    else:
        parts["macro interaction matrix"] = 2000.0 * n  # matrix-free point operator
    # under load control the level rises: tips lifted out of contact get their reach (#156); beyond
    # the macro step's safe path the contacts alone (the lifted count put seed 7's #49 at 0.92 of
    # its box against the policy's 0.33; the union CG runs there stayed within 1.09 of the estimate)
    lifted = scene.penetration is None and not stall_possible(scene)
    alone = _lifted_half_widths(scene, h) if lifted else patch_half_widths(scene, h, pushed=False)
    tips = tip_arrays(scene).tips
    box = patch_box(tips, r, h)  # one patch: the union CG on it
    upper = float((_cells_across(alone[alone > 0], h) ** 2).sum())
    # a height map's stones may take the union CG at any coverage (policy.decide)
    on_map = all(a.shape == "map" for a in scene.asperities)
    routes = Routes(iteration == "union-cg", iteration != "union-cg")
    if iteration == "auto" and box is not None:
        load = scene.penetration is None
        routes = possible_routes(
            tips, r, alone, h, box.size, load_control=load, tilt=bool(scene.tilt), height_map=on_map
        )
    blocks = _block_parts(tips[on], r[on], h, box, upper) if routes.blocks else {}
    union = {}
    if box is not None and (routes.union or (on_map and iteration == "auto")):
        union = grid_parts(scene, box, "union box")
    near = blocks.get("cached cross-patch operators", 0.0) if "far field's point operator" in blocks else 0.0
    if union and near > sum(union.values()):
        blocks = {}  # the near pairs cost more than the box: the policy takes the union CG
    # where the macro step may stall (over 1,000 tips), its safe path's and the sampled
    # patches' memory is not counted otherwise: the patches' cells stay (seed 6's #20 and #69,
    # seed 7's #92 and #163: stalled, the union CG alone, peaks 1.9-2.7x the box and windows)
    windows = not stall_possible(scene)
    if_union = _routes_parts(scene, box, parts, blocks, union, count, windows) if union else {}
    # on a height map the union box stays counted (the larger of it and a block attempt): its
    # stones' block parts are not fitted to their peaks (seed 6's #21 and #156, roads the
    # two-level iteration solved, peaked 1.6x the block parts alone)
    if union and (not blocks or on_map):  # the union CG surely taken, or a map: counted
        parts, if_union, cells = if_union, {}, max(cells, int(box.size))
    else:  # a block iteration may run: counted; the union CG checked where the policy takes it
        parts = parts | blocks
    if iteration in ("auto", "two-level") and stall_possible(scene):
        auto = iteration == "auto"
        stalled_cells, stalled, stalled_union = _stalled_route(scene, h, tips, parts["macro interaction matrix"], auto)
        # the policy takes the union CG there, checked when it does (counted up front, it put
        # seed 9's #98 and seed 6's #150 at 0.31-0.38 of their peaks: no stall, two-level)
        if auto and sum(stalled_union.values()) > sum(if_union.values()):
            if_union = stalled_union
        if sum(stalled.values()) > sum(parts.values()):
            cells, parts = max(cells, stalled_cells), stalled
    return cells, parts, (if_union if sum(if_union.values()) > sum(parts.values()) else {})


def _routes_parts(scene: Scene, box: Grid, parts: dict, blocks: dict, union: dict, count: int, windows: bool) -> dict:
    """``parts`` (the patches and the macro step's) with the union box's ``union`` and, where
    a block iteration may run too, its ``blocks``. The union CG alone holds its ``count``
    patches as windows of the box it samples once (:mod:`twoscale.micro.sampling`): their
    cells are the box's, ``PATCH_WINDOW_BYTES_EACH`` a patch beside (where ``windows``).
    Else the box's bytes count beyond the patches' (its cost per cell was measured with
    them) and beyond what a block attempt before it gave back."""
    name = next(iter(parts))  # the patches'
    if windows and not blocks:
        windows = {f"{count} patches, windows of the union box": PATCH_WINDOW_BYTES_EACH * count}
        rest = {k: v for k, v in parts.items() if k != name}
        return windows | rest | union | coarse_parts(scene, box)
    given_back = parts[name] - PATCH_BYTES_EACH * count + (1.0 - BLOCK_ATTEMPT_HELD) * sum(blocks.values())
    beyond = {f"{k} beyond the patches'": max(0.0, size - given_back) for k, size in union.items()}
    return parts | blocks | beyond | coarse_parts(scene, box)


def _stalled_route(scene: Scene, h: float, tips: np.ndarray, macro: float, auto: bool) -> tuple[int, dict, dict]:
    """Cells and parts of the micro step after a macro step stalled far from a solution
    (:mod:`twoscale.memory_stall`): the far field's block iterations on the patches at the
    indenters' reach, the policy's larger ones kept beside them (or, where more, those
    patches while they are sampled); and the parts where those overlap so much that they
    hold more cells than their box, where the policy takes the union CG on it (its work
    then the least: the blocks' is at least their cells'), else empty; where the policy
    chooses (``auto``) and takes it, no block iteration's parts."""
    st = stalled_patches(scene, h, tips)
    union = {}
    if st.policy_cells >= st.policy_box.size:
        union = _or_sampled(grid_parts(scene, st.policy_box, "union box") | coarse_parts(scene, st.policy_box), st)
        union["macro interaction matrix"] = macro
        if auto:
            return int(st.policy_box.size), {}, union
    on = st.work > 0
    across = _cells_across(st.work[on], h)
    cells = int((across**2).sum())
    parts = {
        f"{int(on.sum())} patches at the indenters' reach (a stalled macro step)": PATCH_BYTES_PER_CELL * cells
        + PATCH_BYTES_EACH * int(on.sum()),
        "the policy's patches at the geometric reach, kept": st.held_bytes,
    }
    box = patch_box(tips, st.work, h)
    parts.update(_block_parts(tips[on], st.work[on], h, box, float(cells)))
    parts = _or_sampled(parts, st)
    parts["macro interaction matrix"] = macro
    return cells, parts, union


def _or_sampled(parts: dict, st) -> dict:
    """``parts``, or the policy's patches at the geometric reach while they are sampled
    where that holds more (:func:`twoscale.memory_stall.stalled_patches`' ``sampling_bytes``)."""
    if st.sampling_bytes > sum(parts.values()):
        return {"the policy's patches at the geometric reach, sampled (a stalled macro step)": st.sampling_bytes}
    return parts


def coarse_parts(scene: Scene, box: Grid) -> dict:
    """The union CG's coarse correction on ``box`` (:mod:`twoscale.pk.coarse`, from its
    ``MIN_CELLS``): the near pairs of its precorrected product among the loaded cells and
    the squares' matrix, where it may be built (:func:`loaded_squares`: the contacts with
    the neighbours' push, :func:`pushed_contact_radii`, at most ``MAX_SQUARES`` squares
    loaded and at most ``COARSE_FILL_MARGIN`` times ``MAX_FILL`` full, their fill counted at
    most ``MAX_FILL``). Seeds 6-8's union CG runs measured: built on 17 of 22, not where
    the fill was 0.27-0.78 (seed 8's #2, #28 and #169, seed 7's #19, seed 6's #26)."""
    if box.size < COARSE_MIN_CELLS:
        return {}
    a = pushed_contact_radii(scene)
    on = a > 0
    loaded = loaded_squares(tip_arrays(scene).tips[on], a[on], box)
    if loaded is None or not len(loaded) or len(loaded) > COARSE_MAX_SQUARES:
        return {}
    fill = float(loaded @ loaded) / (COARSE_SIDE**2 * float(loaded.sum()))
    if fill > COARSE_FILL_MARGIN * COARSE_MAX_FILL:
        return {}
    fill = min(fill, COARSE_MAX_FILL)
    pairs = COARSE_BYTES_PER_LOADED_CELL_AND_FILL * fill * float(loaded.sum())
    return {"the union CG's coarse correction": pairs + COARSE_BYTES_PER_SQUARE_PAIR * float(len(loaded)) ** 2}


def loaded_squares(tips: np.ndarray, a: np.ndarray, box: Grid) -> np.ndarray | None:
    """Loaded cells (K,) of each of the coarse correction's squares of ``SIDE`` cells on
    ``box`` that contacts of radii ``a`` (mm) about ``tips`` ((N, 2) mm) load, each
    contact's cells spread evenly over the squares its bounding box meets and a square at
    most full; None where they meet far more squares than ``MAX_SQUARES`` (too many to
    list). Contacts crowding a square fill it together (seed 8's #28: 3,340 contacts, fill
    0.35 measured; counted contact by contact, 0.06)."""
    side = box.h * COARSE_SIDE
    lo = np.floor((tips - a[:, None] - (box.x0, box.y0)) / side).astype(np.int64)
    hi = np.floor((tips + a[:, None] - (box.x0, box.y0)) / side).astype(np.int64)
    span = hi - lo + 1
    squares = np.prod(span, axis=1)
    if int(squares.sum()) > 50 * COARSE_MAX_SQUARES:
        return None
    columns = int(hi[:, 0].max(initial=0)) + 2
    # every contact's squares listed at once: the k-th square of contact c at row k // span_x
    owner = np.repeat(np.arange(len(squares)), squares)
    k = np.arange(int(squares.sum())) - np.repeat(np.cumsum(squares) - squares, squares)
    rows, cols = np.divmod(k, span[owner, 0])
    keys = (lo[owner, 1] + rows) * columns + lo[owner, 0] + cols
    _, which = np.unique(keys, return_inverse=True)
    cells = np.pi * a**2 / box.h**2
    return np.minimum(np.bincount(which, weights=(cells / squares)[owner]), float(COARSE_SIDE**2))


def _block_parts(tips: np.ndarray, r: np.ndarray, h: float, box: Grid | None, upper: float) -> dict:
    """What the block iterations hold beyond the patches: the largest block's FFT work, the
    cached operators of the pairs coupled exactly and, where the policy may take the far
    field, its weights and point operator (``tips`` (N, 2) mm and ``r`` the half-widths of
    the patches that can touch; ``upper`` their cells alone, for the crowding test)."""
    patch_cells = _cells_across(r, h) ** 2
    cells = float(patch_cells.sum())
    count = len(r)
    # a merged block (overlapping patches solved together) may have up to MERGE_GROWTH
    # times its members' cells: its FFT work, not the patches' arrays, grows with it
    growth = MERGE_GROWTH if count > 1 else 1.0
    parts = {"FFT work on the largest patch": FFT_WORK_BYTES_PER_CELL * growth * float(patch_cells.max(initial=0))}
    crowded = box is not None and upper >= UNION_MIN_COVERAGE * box.size
    far = count > 1 and (not crowded or count >= FAR_FIELD_MIN_PATCHES)
    # overlapping patches share their cells: the share of a patch's cells it owns
    share = 1.0 if box is None else min(1.0, box.size / cells)
    if count > 1:
        # the near pairs where the policy may take the far field, else every pair (exact)
        pairs = pair_bytes(tips, r, h, AUTO_FAR_TOL if far else None, owned=share)
        parts["cached cross-patch operators"] = min(COUPLING_CACHE_BYTES, pairs)
    if far:
        # where the policy may take the far field (micro.policy.decide): the weights it keeps
        across = _cells_across(r, h)
        parts["far field's kept weights"] = far_weight_bytes(share * across**2, 2.0 * across)
        # and its point operator among the patches (8,376 patches of paraboloids: 260 MB)
        parts["far field's point operator"] = FAR_OPERATOR_BYTES_PER_PATCH * float(count)
    return parts


def far_weight_bytes(owned: np.ndarray, sides: np.ndarray) -> float:
    """Bytes the far field holds for its weights on patches of ``owned`` owned cells and
    ``sides`` rows plus columns each: ``KEPT_BYTES_PER_OWNED_CELL`` an owned cell on a patch
    that owns fewer than ``SEPARABLE_CELLS``, the tensor-product form's weights of its rows
    and columns on a larger one (:mod:`twoscale.micro.level_far`). Held at the most in
    two-level solves: seed 8's #150, 892 patches of 241 K owned cells, 154 bytes an owned
    cell (the whole patches' weights of their few shapes 2.4 of them); #138, 108 patches of
    1,024 owned cells or more, none (4,548 paraboloids of
    ~1,000 cells, before the larger patches kept none: 326 MB of source weights and 326 MB
    of interpolation rows)."""
    owned = np.asarray(owned, dtype=float)
    small = owned < SEPARABLE_CELLS
    rows_and_columns = float(np.asarray(sides, dtype=float)[~small].sum())
    return KEPT_BYTES_PER_OWNED_CELL * float(owned[small].sum()) + SEPARABLE_BYTES_PER_ROW_OR_COLUMN * rows_and_columns


def pair_bytes(tips: np.ndarray, r: np.ndarray, h: float, far_tol: float | None, owned: float = 1.0) -> float:
    """Bytes of the operators of the pairs of patches coupled exactly
    (:class:`twoscale.micro.blocks.Coupling`): every pair (``far_tol`` None), or those whose
    centres are closer than ``(r_k + r_l) / sqrt(far_tol)``, ``r`` the half-diagonals
    (:func:`twoscale.micro.farfield.near_lists`). A pair of ``c_k c_l`` cells at most
    ``DENSE_PAIR_ENTRIES`` owned cells (``owned`` of a patch's cells: where patches overlap,
    the share of the box each one owns) holds its dense block (``8 c_k c_l`` bytes; the reverse pair is
    its view), a larger one an FFT operator of ``8 (n_k + n_l)^2`` bytes (``n`` cells
    across: a half-spectrum; the reverse shares it), both times ``PAIR_HELD`` (what the
    coupling keeps beside them). ``tips`` (N, 2) mm; ``r`` half-widths, mm."""
    n = _cells_across(r, h)
    if len(n) < 2:
        return 0.0
    if far_tol is None:
        i, j = np.triu_indices(len(n), 1)
    else:
        from scipy.spatial import cKDTree

        diag = math.sqrt(2.0) * r
        found = cKDTree(tips).query_pairs(2.0 * float(diag.max()) / math.sqrt(far_tol), output_type="ndarray")
        i, j = found.reshape(-1, 2).T
        near = np.hypot(*(tips[i] - tips[j]).T) * math.sqrt(far_tol) < diag[i] + diag[j]
        i, j = i[near], j[near]
    c = owned * n**2
    dense = c[i] * c[j] <= DENSE_PAIR_ENTRIES
    return PAIR_HELD * float(np.sum(np.where(dense, 8.0 * c[i] * c[j], 8.0 * (n[i] + n[j]) ** 2)))
