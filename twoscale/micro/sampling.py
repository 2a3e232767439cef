"""The one-asperity patches of a solve and the rigid surface sampled for them: each patch
sized from the macro forces (:func:`build_patches`), a large union box sampled tile by
tile, and crowded patches cut from the box that covers them.

A patch's heights and owners are the union of every indenter on its cells
(:func:`.patches.make_patch` only skips indenters that cannot own a cell), so patches that
overlap sample the same cells again and again. Where the patches' cells together
outnumber their bounding box's (touching contacts; or a macro step that did not converge,
whose patches reach as far as each indenter can touch), the box is sampled once and each
patch is a read-only window of it: 1,277 touching spheres had patches of 34 M cells in all
over a box of 0.73 M, and sampling them took 67 of the solve's 83 s of CPU. A height
map's patches are cut from their box whatever their number (:func:`one_map`): the box is
a window of the map, which the union CG then takes as sampled.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..grid import Grid, covering_grids, offsets_in
from ..indenters import Asperity, Surface, surface_by_windows, surface_on, window_cells
from .candidates import candidates_of
from .costmodel import FITTED
from .envelope import envelope_on
from .patches import Patch, TipTable, crop_patch, make_patch, patch_candidates, patch_radius

#: Side (cells) of the tiles a large union box is sampled by (:func:`box_surface`): a
#: tile's candidates are the asperities that can be lower than the highest of its four
#: nearest tips' surface over it, so smaller tiles have fewer. CPU s of the union box,
#: tiles of 128 / 64 / 32 cells: 1,485 clustered spheres (1161 x 1162 cells, 79
#: candidates a tile at 128) 1.32-1.72 / 0.57-0.63 / 0.64-0.77; 281 paraboloids (860 x
#: 861) 0.28-0.51 / 0.19 / 0.29; 174 touching spheres (544 x 583) 0.12-0.34 / 0.07-0.08 /
#: 0.12 (owners equal, heights within 2e-15 mm: the tiles' own cell centres).
SAMPLE_TILE = 64
#: Boxes of at most this many cells are sampled whole, where their cells times their
#: asperities are at most ``SAMPLE_WHOLE_ENTRIES`` (a height costs ~12 ns): 5,220 touching
#: spheres on 55,696 cells took 3.4 s whole against 0.09 s by tiles (the same heights and
#: owners to the bit); 79 spheres on 12,769 cells 0.015 against 0.008 s.
SAMPLE_WHOLE_CELLS = 65_536
SAMPLE_WHOLE_ENTRIES = 1 << 21
#: A tile is split in four while its cells times its candidate asperities exceed this
#: (a height costs ~25 ns, a tile's set-up ~0.3 ms), down to ``SAMPLE_MIN_TILE`` cells a
#: side. CPU s of the union box, never split / split from 50,000 / 150,000 / 400,000: 761
#: dense paraboloids (361 x 355 cells) 0.31-0.44 / 0.14 / 0.12-0.14 / 0.15-0.16; 281
#: paraboloids 0.23 / 0.26 / 0.21-0.22 / 0.21-0.22; 39 clustered spheres, 174 touching
#: spheres and 272 paraboloids within 0.01 s either way.
SAMPLE_SPLIT_ENTRIES = 150_000
SAMPLE_MIN_TILE = 16
#: A box of spheres is sampled sphere by sphere on the window of its radius
#: (:func:`~twoscale.indenters.surface_by_windows`) instead of by tiles where ``WINDOW_SETUP
#: n + WINDOW_SHARE W`` is below its cells (``n`` spheres, ``W`` cells in their windows): a
#: window costs about 25 us to set up and 0.01-0.03 us a cell, a box cell 0.2-0.7 us by
#: tiles. CPU s by tiles / by windows on the reference grids of sweep scenes (owners equal,
#: heights within 2.3e-11 mm, the tiles' own cell centres): 8,772 spheres (1.8 M cells,
#: W 0.6x) 1.25 / 0.27; 2,847 (1.5 M, 3.6x) 0.40 / 0.16; 1,013 (0.79 M, 2.3x) 0.15 / 0.05;
#: 102 (0.35 M, 11x) 0.056 / 0.037; 5,162 large spheres (5.5 M, 83x) 1.6 / 4.6 (by tiles).
WINDOW_SETUP = 125
WINDOW_SHARE = 0.06
#: Patches are cut from their box sampled once also where the box has at most this many
#: cells a patch (as where they crowd it, :func:`crowded`): building a patch costs about
#: 0.2 ms whatever its size, sampling a box cell 1-2 us, and the union CG then takes the box
#: as sampled (7,028 lattice paraboloids, patches of 59 cells a tip covering 86 % of a
#: 477 K-cell box: 1.46 s for the patches, then the box again for the union CG).
BOX_CELLS_PER_PATCH = 250
#: Patches are cut from their box sampled once also where their cells together are at least
#: this share of the box: the policy may then choose the union CG
#: (:attr:`~.costmodel.CostModel.union_min_coverage`, the owned cells' share, at most the
#: patches'), which runs on that box, and the memory estimate counts the box from that
#: share (:func:`twoscale.resources.estimate_memory`). Sampled once, the box is not
#: sampled again after 6,823 spheres' patches were built one by one (1.3 s, then 1.2 s for
#: the box of 3.4 M cells; 2,875 spheres 0.59 s, then 0.58 s).
BOX_MIN_PATCH_SHARE = FITTED.union_min_coverage
#: Under penetration control on many patches the policy keeps the union CG a candidate down to
#: a lower share of their box (:meth:`~.costmodel.CostModel.union_coverage`, 8 %): from that
#: share the box is sampled once where it has at most this many cells a patch
#: (:func:`sampled_patches`' ``low_share``). Paired CPU of the whole solve, box sampled once
#: against patches one by one: 8,834, 9,580, 3,904 and 2,642 paraboloids at 500, 399, 455 and
#: 1,125 box cells a patch took the union CG on that box (0.92, 0.88, 0.95, 0.92); 2,103
#: spheres at 3,085 cells a patch took the far field, 1.27x slower from their box sampled
#: once (6.5 M cells for 0.75 M in patches).
LOW_SHARE_CELLS_PER_PATCH = 1500


def box_of(grids: Sequence[Grid], h: float, anchor: tuple[float, float], *, grow: float = 1.0) -> Grid:
    """The grid covering every grid of ``grids`` (the patches' grids), its half-sizes
    scaled by ``grow`` about its centre."""
    x0, y0, gh, nx, ny = (np.array([getattr(g, f) for g in grids]) for f in ("x0", "y0", "h", "nx", "ny"))
    hh = 0.5 * gh  # Grid.bounds of each, as arrays
    xmin, xmax = (x0 - hh).min(), (x0 + (nx - 1) * gh + hh).max()
    ymin, ymax = (y0 - hh).min(), (y0 + (ny - 1) * gh + hh).max()
    cx, cy, rx, ry = (xmin + xmax) / 2, (ymin + ymax) / 2, (xmax - xmin) / 2, (ymax - ymin) / 2
    return Grid.covering(cx - grow * rx, cx + grow * rx, cy - grow * ry, cy + grow * ry, h, anchor=anchor)


def box_surface(grid: Grid, asperities: Sequence[Asperity], *, whole_cells: int = SAMPLE_WHOLE_CELLS) -> Surface:
    """``surface_on(grid, asperities)``, sampled tile by tile with only the asperities that
    can own a cell of the tile: paraboloids have no material radius, and 843 of them sampled
    on every cell of a union box took about 45 s of CPU before the CG's first iteration.
    Plain spheres and paraboloids by small tiles all at once (:func:`.envelope.envelope_on`);
    other indenters by tiles of ``SAMPLE_TILE`` cells a side, split while
    ``SAMPLE_SPLIT_ENTRIES`` says so, each built as a patch (:func:`.patches.make_patch`,
    bounded by the tile's four nearest tips). Grids up to ``whole_cells`` cells are sampled
    whole, every asperity on every cell, where that is at most ``SAMPLE_WHOLE_ENTRIES``
    heights; spheres whose windows are small against the grid
    one by one on their windows (``WINDOW_SETUP``)."""
    whole = grid.size <= whole_cells and grid.size * len(asperities) <= SAMPLE_WHOLE_ENTRIES
    if whole or any(getattr(a, "group", None) is not None for a in asperities):
        return surface_on(grid, asperities)
    if WINDOW_SETUP * len(asperities) + WINDOW_SHARE * window_cells(grid, asperities) < grid.size:
        return surface_by_windows(grid, asperities)
    table = TipTable.of(asperities)
    if table.plain:  # small tiles all at once (8,492 spheres, 1.04 M cells: 0.25 against 0.67 s)
        return envelope_on(grid, table)
    from scipy.spatial import cKDTree

    tree = cKDTree(np.column_stack([table.x, table.y]))
    height = np.full(grid.shape, np.inf)
    owner = np.full(grid.shape, -1, dtype=np.int64)
    tiles = [
        (i0, j0, min(SAMPLE_TILE, grid.nx - i0), min(SAMPLE_TILE, grid.ny - j0))
        for j0 in range(0, grid.ny, SAMPLE_TILE)
        for i0 in range(0, grid.nx, SAMPLE_TILE)
    ]
    while tiles:
        i0, j0, nx, ny = tiles.pop()
        tile = grid.subgrid(i0, j0, nx, ny)
        b = tile.bounds
        near = np.atleast_1d(tree.query([0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3])], k=min(4, len(table)))[1])
        members = tuple(int(k) for k in near)
        keep = patch_candidates(tile, table, members)
        if len(keep) * tile.size > SAMPLE_SPLIT_ENTRIES and min(nx, ny) >= 2 * SAMPLE_MIN_TILE:
            hx, hy = nx // 2, ny // 2
            tiles += [(i0, j0, hx, hy), (i0 + hx, j0, nx - hx, hy), (i0, j0 + hy, hx, ny - hy)]
            tiles.append((i0 + hx, j0 + hy, nx - hx, ny - hy))
            continue
        window = (slice(j0, j0 + ny), slice(i0, i0 + nx))
        part = make_patch(members[0], tile, table, members=members, keep=keep)
        height[window], owner[window] = part.height, part.owner
    return Surface(grid, height, owner, len(asperities))


def one_map(asperities: Sequence[Asperity]) -> bool:
    """Whether every asperity is a basin of one height map (one ``group``): its box is then
    a window of the map, as cheap as one patch, and each patch a window of the box, the
    same cells and owners as :func:`.patches.make_patch` gives (every basin with a sample
    on a grid reaches it). A 70 mm road's 174 patches cost 0.03 s of CPU one by one, and
    the union CG sampled their box again."""
    group = getattr(asperities[0], "group", None) if len(asperities) else None
    return group is not None and all(getattr(a, "group", None) is group for a in asperities)


def crowded(grids: Sequence[Grid], box: Grid, share: float = 1.0) -> bool:
    """Whether the ``grids`` together have at least ``share`` times as many cells as their
    covering ``box`` (at 1, sampling the box once costs less than sampling each grid)."""
    return len(grids) > 1 and sum(g.size for g in grids) >= share * box.size


def patches_cut_from_box(wanted: Sequence[tuple[int, Grid]], box: Grid, asperities: Sequence[Asperity]) -> list:
    """One-asperity patches ``(k, grid)`` of ``wanted`` as read-only windows of the surface
    sampled once on ``box`` (which covers every grid, on the same lattice)."""
    surface = box_surface(box, asperities)
    height, owner = surface.height, surface.owner
    height.setflags(write=False)
    owner.setflags(write=False)
    out = []
    offsets = zip(*(d.tolist() for d in offsets_in([grid for _, grid in wanted], box)))
    for (k, grid), (di, dj) in zip(wanted, offsets):
        if di < 0 or dj < 0 or di + grid.nx > box.nx or dj + grid.ny > box.ny:  # not covered: its own
            out.append(make_patch(k, grid, asperities))
            continue
        window = (slice(dj, dj + grid.ny), slice(di, di + grid.nx))
        out.append(Patch(k, grid, height[window], owner[window]))
    return out


def detached(patches: Sequence[Patch]) -> list[Patch]:
    """The ``patches`` with each window of a sampled box (:func:`patches_cut_from_box`)
    copied into arrays of its own, so that the box is freed once no union CG is to run on
    it: 9,792 clustered paraboloids held a 11.3 M-cell box (181 MB of heights and owners)
    for 1.1 M patch cells through the whole solve."""
    out = []
    for pt in patches:
        if not (_in_larger(pt.height) or _in_larger(pt.owner)):
            out.append(pt)
            continue
        height, owner = pt.height.copy(), pt.owner.copy()
        height.setflags(write=False)
        owner.setflags(write=False)
        out.append(Patch(pt.asperity, pt.grid, height, owner, pt.members))
    return out


def _in_larger(a: np.ndarray) -> bool:
    """Whether ``a`` is a window of a larger array (whose memory it keeps alive)."""
    return isinstance(a.base, np.ndarray) and a.base.nbytes > a.nbytes


def shared_box(patches: Sequence[Patch], n_asperities: int, anchor: tuple[float, float]) -> Surface | None:
    """The box surface the ``patches`` were cut from (:func:`patches_cut_from_box`), when
    every one is a window of the same sampled box at its place on the lattice (``anchor``,
    mm, a cell centre of it); else None.
    The union CG runs on that box and need not sample it again."""
    if not patches:
        return None
    base_h, base_o = patches[0].height.base, patches[0].owner.base
    if not isinstance(base_h, np.ndarray) or not isinstance(base_o, np.ndarray) or base_h.ndim != 2:
        return None
    grids = [pt.grid for pt in patches]
    box = box_of(grids, grids[0].h, anchor)
    if box.shape != base_h.shape or base_o.shape != base_h.shape:
        return None
    if not all(pt.height.base is base_h and pt.owner.base is base_o for pt in patches):
        return None
    # each window's place, shape and strides as arrays; its data pointer checked against the
    # box's at that place (one look-up an array: 8,772 windows by slicing the box again and
    # comparing four addresses each took 0.07 s)
    di, dj = offsets_in(grids, box)
    nx, ny = np.array([g.nx for g in grids]), np.array([g.ny for g in grids])
    if np.any(di < 0) or np.any(dj < 0) or np.any(di + nx > box.nx) or np.any(dj + ny > box.ny):
        return None
    for name, base in (("height", base_h), ("owner", base_o)):
        arrays = [getattr(pt, name) for pt in patches]
        if not all(
            a.shape == (y, x) and a.strides == base.strides for a, y, x in zip(arrays, ny.tolist(), nx.tolist())
        ):
            return None
        address = np.array([a.ctypes.data for a in arrays], dtype=np.int64)
        if np.any(address != base.ctypes.data + dj * base.strides[0] + di * base.strides[1]):
            return None
    return Surface(box, base_h, base_o, n_asperities)


def build_patches(
    asperities: Sequence[Asperity],
    *,
    h: float,
    forces: np.ndarray,
    approaches: np.ndarray,
    E_star: float,
    margin: float = 1.3,
    anchor: tuple[float, float] = (0.0, 0.0),
    reuse: Sequence[Patch] = (),
) -> list[Patch]:
    """One patch per asperity that can touch (``approaches[k] > 0``): their grids
    (:func:`patch_grids`) sampled (:func:`sampled_patches`).

    Parameters
    ----------
    asperities : sequence of Asperity
    h : float
        Cell side, mm.
    forces : (N,) array
        Macro forces, N.
    approaches : (N,) array
        Geometric approach of each tip ``d - z_k - tilt(x_k, y_k)``, mm.
    E_star : float
        Plane-strain modulus, MPa (patch sizing only).
    margin : float, default 1.3
        Patch half-width over the Hertz-like contact radius.
    anchor : (float, float), default (0, 0)
        A cell centre of the common lattice, mm.
    reuse : sequence of Patch, default ()
        Patches built before for the same scene (e.g. for the policy): one with the same
        asperity and grid is taken as it is (a patch depends on nothing else), one of the
        same asperity on a grid holding the wanted one is cut down to it
        (:func:`~.patches.crop_patch`: the far field's patches, sized from smaller
        approaches than the policy's, were sampled a second time, 0.3-0.5 s on 1,000-1,500
        spheres).
    """
    wanted = patch_grids(
        asperities, h=h, forces=forces, approaches=approaches, E_star=E_star, margin=margin, anchor=anchor
    )
    return sampled_patches(asperities, wanted, h=h, anchor=anchor, reuse=reuse)


def patch_grids(
    asperities: Sequence[Asperity],
    *,
    h: float,
    forces: np.ndarray,
    approaches: np.ndarray,
    E_star: float,
    margin: float = 1.3,
    anchor: tuple[float, float] = (0.0, 0.0),
) -> list[tuple[int, Grid]]:
    """``(k, grid)`` of the patch of each asperity that can touch (:func:`build_patches`'
    parameters)."""
    if not (math.isfinite(margin) and margin >= 1.0):
        raise ValueError(f"patch margin must be >= 1, got {margin!r}")
    forces, approaches = np.asarray(forces, dtype=float), np.asarray(approaches, dtype=float)
    touch = np.flatnonzero(~(approaches <= 0.0)).tolist()
    tips = [asperities[k] for k in touch]
    if not all(type(a) is Asperity for a in tips):  # other indenters: their own reach
        radii = [
            patch_radius(a, force=float(forces[k]), approach=float(approaches[k]), E_star=E_star, h=h, margin=margin)
            for k, a in zip(touch, tips)
        ]
    else:
        radii = _plain_radii(tips, forces[touch], approaches[touch], E_star=E_star, h=h, margin=margin)
    x, y, r = np.array([a.x for a in tips], dtype=float), np.array([a.y for a in tips], dtype=float), np.array(radii)
    return list(zip(touch, covering_grids(x - r, x + r, y - r, y + r, h, anchor=anchor)))


def _plain_radii(tips, forces, approaches, *, E_star: float, h: float, margin: float) -> np.ndarray:
    """:func:`.patches.patch_radius` of plain spheres and paraboloids, as arrays (the same
    arithmetic: ``Asperity.reach`` then the Hertz-like radius, each power by Python's)."""
    d, f = np.asarray(approaches, dtype=float), np.asarray(forces, dtype=float)
    R = np.array([a.R for a in tips], dtype=float)
    paraboloid = np.array([a.shape == "paraboloid" for a in tips], dtype=bool)
    with np.errstate(invalid="ignore"):
        reach = np.where(paraboloid, np.sqrt(2.0 * R * d), np.where(d >= R, R, np.sqrt(d * (2.0 * R - d)))) + h
    loaded = np.isfinite(f) & (f > 0.0)
    a = np.array(
        [(3.0 * p * q / (4.0 * E_star)) ** (1.0 / 3.0) for p, q in zip(f[loaded].tolist(), R[loaded].tolist())]
    )
    out = reach.copy()
    out[loaded] = np.minimum(reach[loaded], margin * a + 2.0 * h)
    return out


def sampled_patches(
    asperities: Sequence[Asperity],
    wanted: Sequence[tuple[int, Grid]],
    *,
    h: float,
    anchor: tuple[float, float] = (0.0, 0.0),
    reuse: Sequence[Patch] = (),
    box_share: float = BOX_MIN_PATCH_SHARE,
    low_share: float | None = None,
) -> list[Patch]:
    """The patches on the ``wanted`` grids (:func:`patch_grids`), ``reuse`` as in
    :func:`build_patches`. ``box_share``: the patches' share of their box from which the box
    is sampled once and they are cut from it (:func:`crowded`), the share from which the
    policy can choose the union CG, which runs on that box; ``low_share``: a lower share
    from which it is, on a box of at most ``LOW_SHARE_CELLS_PER_PATCH`` cells a patch."""
    built = _reused(wanted, reuse)  # aligned with wanted: a patch, or None to build
    new = [i for i, pt in enumerate(built) if pt is None]
    if new:
        grids = [wanted[i][1] for i in new]
        box = box_of(grids, h, anchor)
        once = crowded(grids, box, box_share) or box.size <= BOX_CELLS_PER_PATCH * len(new) or one_map(asperities)
        few = low_share is not None and box.size <= LOW_SHARE_CELLS_PER_PATCH * len(new)
        if once or (few and crowded(grids, box, low_share)):  # sampled once
            for i, pt in zip(new, patches_cut_from_box([wanted[i] for i in new], box, asperities)):
                built[i] = pt
    rest = [i for i, pt in enumerate(built) if pt is None]
    keeps = candidates_of(asperities, [wanted[i] for i in rest]) if rest and isinstance(asperities, TipTable) else None
    if keeps is not None:  # the candidates of all at once, each patch's as it finds them
        for i, c in zip(rest, keeps):
            built[i] = make_patch(*wanted[i], asperities, keep=c)
    return [pt if pt is not None else make_patch(k, grid, asperities) for pt, (k, grid) in zip(built, wanted)]


def _reused(wanted: Sequence[tuple[int, Grid]], reuse: Sequence[Patch]) -> list:
    """For each ``(k, grid)`` of ``wanted``, the one-asperity patch of ``reuse`` on that
    grid, else one of ``reuse`` on a grid holding it cut down to it, else None."""
    if not reuse:
        return [None] * len(wanted)
    same = {(pt.asperity, pt.grid): pt for pt in reuse if len(pt.members) == 1}
    larger = {pt.asperity: pt for pt in reuse if len(pt.members) == 1}
    out = []
    for k, grid in wanted:
        pt = same.get((k, grid))
        out.append(pt if pt is not None or k not in larger else crop_patch(larger[k], grid))
    return out
