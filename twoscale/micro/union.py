"""Union iteration: one constrained conjugate-gradient solve over the box of the patches.

Where contacts crowd (hundreds of tips under real loads, merged contacts) the patches
cover much of their bounding box and the cross-patch products cost more than one FFT
product on the box itself. Then the micro step is best solved as one problem: the
Polonsky-Keer constrained conjugate gradient (:func:`twoscale.reference.cg.solve_cg`) on
the box of all patches (the macro forces say where contact is, so the box is much tighter
than the reference solver's a-priori reach), started from the paper's eq. 7 pressures when
they were computed, else from each tip's geometric interference at a fraction of its
macro local approach, scaled to the tip's macro force where the macro step came near a
solution (:mod:`.union_start`: the CG's active set shrinks onto the contact in a few large
steps, where it grows cell by cell; the macro forces spread as Hertz pressures were tried
as a start: twice the iterations, since the active set then has to grow into merged
contacts). The load, the approach and the tilt are solved by the same iteration (no
sensitivity sweeps). Under a free tilt the first box covers wider patches (``TILT_MARGIN``:
the macro step's tilt is least sure there). If pressure reaches the box's edge, the box
grows on the sides it reaches and resumes from its pressure, keeping the cells it had
(:func:`widened_surface`); the CG on a box that may still grow stops as soon as pressure has
settled on its edge (:class:`~.union_edge.EdgeWatch`), and the first box stopped so grows by
``GROW_EARLY``. A tip outside the box that the answer's approach and tilt reach widens it
too (:func:`~.union_edge.reached_outside`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..grid import Grid
from ..indenters import Asperity, Surface
from ..influence.base import InfluenceProvider
from ..results import ContactResult
from .patches import TREE_MIN, Patch, patch_radius
from .sampling import SAMPLE_WHOLE_CELLS, box_of, box_surface, shared_box
from .union_edge import GROW_EARLY, EdgeWatch, reached_outside
from .union_start import interference_start

#: Enlargements of the box when pressure reaches its edge (:func:`grown_box`).
MAX_ENLARGEMENTS = 3
#: Each enlargement moves a side the pressure reaches out by ``GROW - 1`` of the box's half-size.
GROW = 1.5
#: Under a free tilt the union CG's first box covers each tip's patch sized with this
#: margin over its Hertz-like contact radius (:func:`tilted_box_grids`), where the micro
#: step's patches take ``margin`` (1.3): the macro step's point forces balance the moments
#: at the tips, so its tilt and forces are off where contacts are large (seven tilted
#: spheres: tilt 0.146 against 0.089, a force 0.035 against 0.055 N; two contacts reached
#: 1.50-1.58 contact radii from their tips, past their patches, and the box grew once: 40
#: CG iterations on two boxes against 18 on one box of 1.12x the first's cells).
TILT_MARGIN = 1.6
#: Boxes from this many cells run the CG with float32 products (``"auto"``): below, one is
#: overhead-bound (1,600 cells: 0.13 ms float32, 0.06 float64; 10,000 cells on: 3-4x faster).
MIXED_MIN_CELLS = 10_000
#: The CG keeps its conjugate directions after a step where at most this fraction of the
#: loaded cells entered (``solve_cg``'s ``keep_conjugacy``): on boxes of thousands of
#: contacts a few hundred cells enter at the edges in nearly every step, and each restart
#: made the iteration a steepest descent again (6,215 tilted paraboloids on 2.9 M cells:
#: 47 iterations against 97).
KEEP_CONJUGACY = 0.005
#: The first box's CG runs on the cells below the level ``L + REACH_MARGIN (L - z_min)``
#: (:func:`contact_reach`), ``L`` the highest level a tip's macro approach reaches. The
#: macro approaches are poor stone by stone (stones it leaves out carry force), but their
#: highest level was above the largest height of the final contact's loaded cells on six of
#: the sweep's seven roads on the union CG and 0.035 mm (2.8 % of the heights' span) under
#: it on one; 0.1 kept every final contact inside the part there.
REACH_MARGIN = 0.1
#: A part of more than this fraction of the box's cells is not worth its gathers: the CG
#: runs on the whole box (a road's part of 39 % of its cells: 7 % less CPU for the solve,
#: one of 6 %: 22 % less).
REACH_MAX_FRACTION = 0.5
#: Under penetration control the union CG crops its box to the cells below the approach
#: only when that keeps fewer than this fraction of its cells (``solve_cg``'s
#: ``crop_below``): the crop costs a second operator and a float64 product for the
#: displacement on the whole box, about seven of its float32 products (39 clustered
#: spheres, a crop of one column of 385: 34 ms, the CG's 46 products 3 ms each), which
#: a crop of a tenth saves on a CG of 70 products.
CROP_BELOW = 0.9


@dataclass(frozen=True)
class UnionOutcome:
    """What the union iteration produced.

    Attributes
    ----------
    result : ContactResult (the CG's on the final box, one field)
    patch : Patch
        The box as one patch whose members are every asperity owning a cell of it.
    start : (ny, nx) array
        The warm start on the final box before the CG's rescaling: eq. 7 pressures (MPa),
        the interference start (mm, or MPa scaled to the macro forces), or zeros (the CG's own geometric start).
    enlargements : int
        How often the box grew because pressure reached its edge.
    on_edge : bool
        Pressure still reaches the final box's edge (the answer may be clipped).
    iterations : int
        CG iterations, all boxes together.
    products : int
        FFT products, all boxes together.
    """

    result: ContactResult
    patch: Patch
    start: np.ndarray
    enlargements: int
    on_edge: bool
    iterations: int
    products: int


def _on_edge(p: np.ndarray) -> bool:
    return bool(np.any(p[0, :] > 0) or np.any(p[-1, :] > 0) or np.any(p[:, 0] > 0) or np.any(p[:, -1] > 0))


def grown_box(box: Grid, pressure: np.ndarray, grow: float = GROW) -> Grid:
    """The union CG's next box when ``pressure`` (on ``box``) reached its edge: each side
    the pressure reaches moves out by ``grow - 1`` times the box's half-size across it,
    the others stay (seven tilted spheres whose contact passed one side by 4 cells: the
    box grown about its centre on all four sides had 2.25x the cells, as many as the
    reference's grid, and its CG cost twice the first box's)."""
    ny, nx = box.shape
    ex, ey = math.ceil(0.5 * (grow - 1.0) * nx), math.ceil(0.5 * (grow - 1.0) * ny)
    left, right = ex * bool(np.any(pressure[:, 0] > 0)), ex * bool(np.any(pressure[:, -1] > 0))
    low, high = ey * bool(np.any(pressure[0, :] > 0)), ey * bool(np.any(pressure[-1, :] > 0))
    return Grid(box.x0 - left * box.h, box.y0 - low * box.h, box.h, nx + left + right, ny + low + high)


@dataclass(frozen=True)
class UnionSettings:
    """How the union CG runs.

    Attributes
    ----------
    tol : float
        KKT residual of the CG relative to the largest displacement.
    max_iter : int, default 20000
        CG iterations per box.
    max_enlargements : int, default ``MAX_ENLARGEMENTS`` (3)
        Box enlargements when pressure reaches its edge.
    precision : {"auto", "single-directions", "mixed", "double"}, default "auto"
        Of the CG's products (:func:`twoscale.reference.cg.solve_cg`): ``"mixed"``
        single-precision iterations to 3e-6 first (``SINGLE_TOL``), then double precision
        to ``tol``; ``"single-directions"`` one stage, the search directions' products in
        single precision; ``"auto"``: single-directions from ``MIXED_MIN_CELLS`` cells
        (:func:`union_precision`), double below.
    precondition : bool, default True
        Precondition the CG by the operator's approximate inverse (``solve_cg``'s
        ``precondition``): half the iterations on merged contacts.
    coarse : bool, default True
        With ``precondition``: the torus inverse with a coarse correction over squares of
        the box once the contact has nearly settled (``solve_cg``'s ``coarse``,
        :class:`~twoscale.pk.coarse.SquaresCorrection`): thousands of separated tips share
        modes the torus does not reach (seed 1's #101 27 -> 16 iterations, seed 6's #147
        25 -> 13, #1 33 -> 19, seed 5's #20 20 -> 14).
    keep_conjugacy : float, default ``KEEP_CONJUGACY`` (0.005)
        ``solve_cg``'s ``keep_conjugacy``: the fraction of the loaded cells that may enter
        in a step without a restart of the conjugate directions (0: Polonsky & Keer's
        restart after any entry).
    first_box : Grid or None, default None
        The first box, when not the box of the patches' grids (it must contain it; a free
        tilt's, :func:`tilted_box_grids`); the patches' sampled box is reused inside it.
    """

    tol: float
    max_iter: int = 20_000
    max_enlargements: int = MAX_ENLARGEMENTS
    precision: str = "auto"
    precondition: bool = True
    coarse: bool = True
    keep_conjugacy: float = KEEP_CONJUGACY
    first_box: Grid | None = None


def solve_union(
    provider: InfluenceProvider,
    asperities: Sequence[Asperity],
    grids: Sequence[Grid] | Sequence[Patch],
    problem,
    settings: UnionSettings,
    *,
    start: tuple | None = None,
    approaches: np.ndarray | None = None,
    monitor=None,
) -> UnionOutcome:
    """Solve the micro step as one problem on the box of the patches' ``grids``.

    Parameters
    ----------
    provider, asperities
        The body and the indenters.
    grids : sequence of Grid, or the patches
        The grids of the macro step's patches (only their extent is used); patches cut from
        one sampled box (:func:`.sampling.patches_cut_from_box`) lend it to the first box.
    problem : MicroProblem
        Cell side ``h`` and ``anchor`` (mm), the control (``total_load`` N, else the
        ``penetration`` mm), ``free_tilt`` about ``pivot`` (mm).
    settings : UnionSettings
        Tolerance, iterations, enlargements, precision, preconditioner, first box.
    start : (Grid, (ny, nx) array) or None
        Warm start on its grid (e.g. eq. 7 pressures), MPa; default: from
        ``approaches``, else the CG's own.
    approaches : (N,) array or None
        The macro step's local approach of each asperity, mm (:func:`interference_start`).
    monitor : callable, optional
        ``monitor(iteration, residual)``, passed to the CG (progress display).
    """
    from ..reference.cg import solve_cg

    h, anchor, pivot = problem.h, problem.anchor, problem.pivot
    sampled = None
    if grids and all(isinstance(g, Patch) for g in grids):
        sampled = shared_box(grids, len(asperities), anchor)
        grids = [g.grid for g in grids]
    penetration = None if problem.total_load is not None else problem.penetration
    start_grid, start = (None, None) if start is None else start
    iterations, products = 0, 0
    previous = None
    box = box_of(grids, h, anchor) if settings.first_box is None else settings.first_box
    for enlargement in range(settings.max_enlargements + 1):
        sampled = widened_surface(sampled, box, asperities)  # the last box's cells kept
        surface = material_box(sampled)
        grid = surface.grid
        rough = previous is None and start is None and approaches is not None
        if previous is not None:
            warm = carried(previous.fields[0].pressure, previous.fields[0].grid, grid)
        elif start is not None:
            warm = carried(start, start_grid, grid)
        else:
            forces = problem.forces if problem.size_from_forces else None  # (near a solution: each cap to its force)
            warm = interference_start(surface, asperities, approaches, forces) if rough else None
        first = previous is None and approaches is not None and not problem.free_tilt
        reach = contact_reach(surface, asperities, approaches) if first else None
        # a box that may still grow stops once pressure has settled on its edge
        watch = EdgeWatch(grid, box) if enlargement < settings.max_enlargements else None
        result = solve_cg(
            provider,
            surface,
            penetration=penetration,
            total_load=problem.total_load,
            tilt=problem.free_tilt,
            pivot=pivot,
            tol=settings.tol,
            max_iter=settings.max_iter,
            start=warm,
            precision=union_precision(settings.precision, grid.size),
            precondition=settings.precondition,
            coarse=settings.coarse,
            keep_conjugacy=settings.keep_conjugacy,
            monitor=monitor,
            plane_sums=True,
            rough_start=rough,
            reach=reach,
            crop_below=CROP_BELOW,
            half_products=True,
            step_model=True,
            precorrected=True,
            stop=watch,
        )
        iterations += int(result.iterations.get("cg", 0))
        products += int(result.iterations.get("products", 0))
        on_box = grid.embed_in(result.fields[0].pressure, box)
        grow, done = watch is not None and watch.fired, enlargement == settings.max_enlargements or not result.converged
        wider = None if grow or done else reached_outside(box, asperities, result, provider, pivot)
        if not grow and wider is None and (not result.converged or not _on_edge(on_box)):
            break
        previous, box = result, wider or grown_box(box, on_box, GROW_EARLY if grow and not enlargement else GROW)
    # the owners present, counted (np.unique: 0.022 s on a 10^6-cell box)
    members = tuple(int(k) for k in np.flatnonzero(np.bincount(surface.owner[surface.owner >= 0])))
    first = members[0] if members else 0
    patch = Patch(first, grid, surface.height, surface.owner, members or (first,))
    warm = np.zeros(grid.shape) if warm is None else warm
    on_edge = _on_edge(grid.embed_in(result.fields[0].pressure, box))
    return UnionOutcome(result, patch, warm, enlargement, on_edge, iterations, products)


def tilted_box_grids(patches: Sequence[Patch], asperities: Sequence[Asperity], problem, E_star: float) -> list:
    """The grids whose box is the union CG's first box under a free tilt: each one-asperity
    patch widened about its tip to the half-width :func:`~.patches.patch_radius` gives with
    ``TILT_MARGIN`` (never beyond the tip's reach, as a patch), from the problem's macro
    forces and the geometric approaches at its approach and tilt (mm, N, MPa)."""
    h, anchor = problem.h, problem.anchor
    d, alpha, beta = (float(v) for v in problem.theta)
    px, py = problem.pivot
    sized = problem.size_from_forces
    out = []
    for pt in patches:
        k = pt.asperity
        a = asperities[k]
        approach = d - a.z - (beta * (a.x - px) + alpha * (a.y - py))
        if len(pt.members) > 1 or not approach > 0.0:
            out.append(pt.grid)
            continue
        force = float(problem.forces[k]) if sized else math.inf
        r = patch_radius(a, force=force, approach=approach, E_star=E_star, h=h, margin=TILT_MARGIN)
        g = pt.grid
        x1, y1 = g.x0 + (g.nx - 1) * h, g.y0 + (g.ny - 1) * h  # its cell centres' extent
        out.append(
            Grid.covering(min(a.x - r, g.x0), max(a.x + r, x1), min(a.y - r, g.y0), max(a.y + r, y1), h, anchor=anchor)
        )
    return out


def widened_surface(sampled: Surface | None, box: Grid, asperities: Sequence[Asperity]) -> Surface:
    """The surface on ``box``: ``sampled`` (a surface on an aligned grid inside it, or None)
    where it has cells, the rest sampled (:func:`.sampling.box_surface`) in up to four strips
    around it: a box grown or widened by a few rows keeps the cells it had (the union box of
    6,215 tilted paraboloids has 2.9 M cells)."""
    if sampled is not None and sampled.grid == box:
        return sampled
    inner = None if sampled is None else sampled.grid
    if inner is None or not _inside(inner, box):
        return box_surface(box, asperities)
    height = np.full(box.shape, np.inf)
    owner = np.full(box.shape, -1, dtype=np.int64)
    rows, cols = inner.window_in(box)
    height[rows, cols], owner[rows, cols] = sampled.height, sampled.owner
    strips = (  # (i0, j0, nx, ny): below, above, then left and right of the inner rows
        (0, 0, box.nx, rows.start),
        (0, rows.stop, box.nx, box.ny - rows.stop),
        (0, rows.start, cols.start, inner.ny),
        (cols.stop, rows.start, box.nx - cols.stop, inner.ny),
    )
    # a thin strip among many tips is sampled tile by tile (whole, each of 6,215 on each cell)
    whole = SAMPLE_WHOLE_CELLS if len(asperities) <= TREE_MIN else 0
    for i0, j0, nx, ny in strips:
        if nx > 0 and ny > 0:
            part = box_surface(box.subgrid(i0, j0, nx, ny), asperities, whole_cells=whole)
            height[j0 : j0 + ny, i0 : i0 + nx], owner[j0 : j0 + ny, i0 : i0 + nx] = part.height, part.owner
    return Surface(box, height, owner, len(asperities))


def _inside(inner: Grid, box: Grid) -> bool:
    di, dj = inner.offset_in(box)
    return di >= 0 and dj >= 0 and di + inner.nx <= box.nx and dj + inner.ny <= box.ny


def material_box(surface: Surface) -> Surface:
    """``surface`` cut to the bounding box of its cells with material (finite height):
    the others never carry pressure but pay for every FFT product (a height map's box
    reaches past the map where its edge stones' patches do: the 100 mm road's 1070 x 1074
    box is 1000 x 1000 cells of map). The surface itself when nothing can be cut."""
    finite = np.isfinite(surface.height)
    rows, cols = np.flatnonzero(finite.any(axis=1)), np.flatnonzero(finite.any(axis=0))
    if not rows.size:
        return surface
    j0, j1, i0, i1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    if (j1 - j0, i1 - i0) == surface.grid.shape:
        return surface
    sub = surface.grid.subgrid(i0, j0, i1 - i0, j1 - j0)
    return Surface(sub, surface.height[j0:j1, i0:i1], surface.owner[j0:j1, i0:i1], surface.n_asperities)


def carried(values: np.ndarray, source: Grid, target: Grid) -> np.ndarray:
    """``values`` on ``source`` placed on the aligned ``target`` where the two overlap,
    zero elsewhere (a start on the uncut box carried to the box cut to the material)."""
    out = np.zeros(target.shape)
    di, dj = source.offset_in(target)
    j0, j1 = max(dj, 0), min(dj + source.ny, target.ny)
    i0, i1 = max(di, 0), min(di + source.nx, target.nx)
    if j1 > j0 and i1 > i0:
        out[j0:j1, i0:i1] = values[j0 - dj : j1 - dj, i0 - di : i1 - di]
    return out


def contact_reach(surface, asperities: Sequence[Asperity], approaches: np.ndarray) -> np.ndarray | None:
    """The cells the union CG iterates on (``solve_cg``'s ``reach``): those with material
    whose height is below ``L + REACH_MARGIN (L - z_min)``, ``L`` the highest level
    ``z_k + delta_k`` a tip reaches at its macro local approach (mm) and ``z_min`` the
    lowest height of the box. The CG's array passes then run over these cells only (a
    road's contact loads 2-10 % of its box, its part holds 6-40 %); the answer is checked
    on the whole box and solved there from it when a cell off the part would touch. None
    when the part would hold more than ``REACH_MAX_FRACTION`` of the box's cells."""
    material = np.isfinite(surface.height)
    if not material.any() or not len(asperities):
        return None
    tips = np.array([a.z for a in asperities], dtype=float)
    level = float(np.max(tips + np.asarray(approaches, dtype=float)))
    lowest = float(surface.height[material].min())
    if not level > lowest:
        return None
    level += REACH_MARGIN * (level - lowest)
    reach = material & (surface.height < level)
    return reach if np.count_nonzero(reach) <= REACH_MAX_FRACTION * reach.size else None


def union_precision(asked: str, cells: int) -> str:
    """The CG's ``precision`` on a box of ``cells`` cells for the setting ``asked``.

    ``"auto"``: double below ``MIXED_MIN_CELLS``; above, ``"single-directions"`` (one
    stage: no restart at 1e-6, a few clipped cells corrected by the kernel's columns
    instead of a product; CPU s of the default solve against ``"mixed"``, same forces to
    3.2e-8 of the largest: 174 touching spheres 0.98-1.13 / 1.14-1.54, 281 paraboloids
    2.5 / 2.9-3.2, 114 paraboloids under load 2.44 / 3.96-4.2, 304 spheres under load
    1.08 / 1.21-1.46; with a free tilt, 4 spheres 0.91 / 2.12 (21 / 54 iterations), 1,913
    paraboloids 2.72 / 2.84)."""
    if asked == "auto":
        return "double" if cells < MIXED_MIN_CELLS else "single-directions"
    return asked
