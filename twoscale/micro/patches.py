"""Patches: one aligned sub-grid of cells per asperity (docs/method.md section 3).

Every patch lies on the lattice ``anchor + h Z^2`` so patches (and the reference solver's
full grid, built with the same anchor) exchange cells exactly. Where patches overlap, a cell
belongs to the asperity nearest the body (lowest height,
:func:`twoscale.indenters.surface_on`); a patch's *block* is the set of its cells its own
asperity owns, so no cell is ever counted twice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np

from ..grid import Grid
from ..indenters import SAMPLE_BATCH, Asperity, TipArrays, sample_tips, sampled_in_batches, surface_on


@dataclass(frozen=True)
class Patch:
    """Cells where asperity ``asperity`` may touch.

    Attributes
    ----------
    asperity : int
        Index of the asperity in the scene (the first of ``members`` for a merged patch).
    grid : Grid
        The patch, aligned on the common lattice.
    height : (ny, nx) array, mm
        Untilted height of the union of all indenters (``inf`` where none has material).
    owner : (ny, nx) int array
        Owning asperity of each cell (-1 where none has material).
    members : tuple of int, default ``(asperity,)``
        The asperities whose owned cells form the block: more than one for a patch merged
        from overlapping ones (:func:`merge_overlapping`).
    owned : (ny, nx) bool array
        The block: cells the members own (derived).
    """

    asperity: int
    grid: Grid
    height: np.ndarray
    owner: np.ndarray
    members: tuple = ()
    owned: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        members = tuple(map(int, self.members)) if self.members else (int(self.asperity),)
        if members[0] != self.asperity:
            raise ValueError(f"a patch's asperity {self.asperity} must be the first of its members {members}")
        object.__setattr__(self, "members", members)
        # the block: boolean (ny, nx) mask of the cells the members own
        owned = self.owner == self.asperity if len(members) == 1 else np.isin(self.owner, members)
        owned.setflags(write=False)
        object.__setattr__(self, "owned", owned)


#: Bounded asperities above which :meth:`TipTable.reaching` looks them up in a k-d tree.
TREE_MIN = 64


class TipTable(Sequence):
    """The asperities of a scene with their tip arrays computed once (a solve wraps its
    scene in one, so that building thousands of patches does not rebuild the arrays from
    the asperity objects each time). Behaves as the sequence of asperities."""

    def __init__(self, asperities: Sequence[Asperity]):
        self.asperities = tuple(asperities)
        self.x = np.array([a.x for a in self.asperities], dtype=float)
        self.y = np.array([a.y for a in self.asperities], dtype=float)
        # material radius: spheres R, paraboloids inf, height-map basins their extent
        self.R = np.array([a.material_radius for a in self.asperities], dtype=float)
        self.unbounded = ~np.isfinite(self.R)
        # paraboloids: tip recess and curvature radius, for the lower bound of their height
        self.parabolic = np.array([type(a) is Asperity and a.shape == "paraboloid" for a in self.asperities])
        self.spherical = np.array([type(a) is Asperity and a.shape == "sphere" for a in self.asperities])
        self.z = np.array([a.z for a in self.asperities], dtype=float)
        self.curvature = np.array([a.R for a in self.asperities], dtype=float)
        self._tree = None
        self._reach = None

    @classmethod
    def of(cls, asperities: Sequence[Asperity]) -> "TipTable":
        return asperities if isinstance(asperities, cls) else cls(asperities)

    def reaching(
        self, bounds: tuple[float, float, float, float], *, index: bool = True, below: float = math.inf
    ) -> np.ndarray:
        """Sorted indices of the asperities whose material (``r < R``) can reach the box
        ``(xmin, xmax, ymin, ymax)`` (mm), unbounded ones included; with a finite ``below``
        (mm: a height the surface is known not to exceed over the box) not the spheres and
        paraboloids whose lowest point over the box is not below it (they own no cell of
        it). With ``index`` the candidates come from a k-d tree of the tips (built on first
        use): a sphere or paraboloid of curvature radius ``R`` is at least ``r^2 / (2 R)``
        above its tip at distance ``r``, so none farther than ``sqrt(2 R_max (below -
        z_min))`` from the box can count, and a solve that builds thousands of patches
        pays ``O(log N)`` per patch instead of ``O(N)`` (6,933 near-touching spheres of R
        1.2 mm with contacts of 0.02 mm: 300 spheres reached each patch by their radius,
        and sampling them was 95 of the solve's 100 s)."""
        xmin, xmax, ymin, ymax = bounds
        n = len(self.x)
        radius = self._candidate_radius(below) + 0.5 * math.hypot(xmax - xmin, ymax - ymin)
        if index and n > TREE_MIN and math.isfinite(radius):
            if self._tree is None:
                from scipy.spatial import cKDTree

                self._tree = cKDTree(np.column_stack([self.x, self.y]))
            cand = np.sort(
                np.asarray(
                    self._tree.query_ball_point([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)], radius), dtype=np.int64
                )
            )
        else:
            cand = np.arange(n)
        x, y, R = self.x[cand], self.y[cand], self.R[cand]
        dx = np.maximum(np.maximum(xmin - x, x - xmax), 0.0)
        dy = np.maximum(np.maximum(ymin - y, y - ymax), 0.0)
        r2 = dx * dx + dy * dy
        keep = self.unbounded[cand] | (r2 < R * R)
        if math.isfinite(below):
            curv = self.curvature[cand]
            low = np.full(len(cand), -np.inf)
            par, sph = self.parabolic[cand], self.spherical[cand] & keep
            low[par] = r2[par] / (2.0 * curv[par])
            low[sph] = r2[sph] / (curv[sph] + np.sqrt(np.maximum(curv[sph] ** 2 - r2[sph], 0.0)))
            keep &= ~((par | sph) & (self.z[cand] + low >= below))
        return cand[keep]

    def _candidate_radius(self, below: float) -> float:
        """Largest distance (mm) from a box at which an asperity can still own a cell of it."""
        if self._reach is None:
            simple = self.parabolic | self.spherical
            other = ~simple
            self._reach = (
                float(np.max(self.R[other], initial=0.0)),  # inf with an unbounded other
                float(np.max(self.R[self.spherical], initial=0.0)),
                bool(np.any(self.parabolic)),
                float(np.max(self.curvature[simple], initial=0.0)),
                float(np.min(self.z[simple], initial=np.inf)),
            )
        other, sphere, parabolic, curv, zmin = self._reach
        rho = math.sqrt(2.0 * curv * max(below - zmin, 0.0)) if math.isfinite(below) else math.inf
        return max(other, min(sphere, rho), rho if parabolic else 0.0)

    @property
    def plain(self) -> bool:
        """Every asperity is a plain sphere or paraboloid (:meth:`sample` takes them all)."""
        return bool(np.all(self.parabolic | self.spherical))

    def sample(self, grid: Grid, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Heights (mm, ``inf`` without material) and owners (scene indices, -1 for none)
        of the plain asperities ``keep`` (sorted indices) on ``grid``: what
        :func:`make_patch` gives for them, from the table's arrays (building them from the
        asperity objects for each of the 600 tiles of a box of 6,933 spheres cost more
        than their sampling)."""
        height = np.full(grid.shape, np.inf)
        owner = np.full(grid.shape, -1, dtype=np.int64)
        keep = np.asarray(keep, dtype=np.int64)
        step = max(SAMPLE_BATCH // grid.size, 1)
        for b in range(0, len(keep), step):
            k = keep[b : b + step]
            tips = TipArrays(k, self.x[k], self.y[k], self.z[k], self.curvature[k], self.spherical[k])
            sample_tips(grid.x, grid.y, tips, height, owner)
        return height, owner

    def __len__(self) -> int:
        return len(self.asperities)

    def __getitem__(self, k):
        return self.asperities[k]


def highest_over(grid: Grid, owners: Sequence[Asperity]) -> float:
    """The highest the rigid surface can be on ``grid`` (mm): the largest, over its cells,
    of the lowest of ``owners`` (an asperity owning no cell of its own patch gives inf).
    One plain sphere or paraboloid is highest at the cell centre farthest from its tip:
    that cell alone is sampled, by the arithmetic :func:`surface_on` uses on such a grid
    (sampling the whole grid was half of building a patch)."""
    if len(owners) == 1 and type(owners[0]) is Asperity and sampled_in_batches(grid):
        a = owners[0]
        xs, ys = grid.x[[0, -1]], grid.y[[0, -1]]
        dx2, dy2 = (xs - a.x) ** 2, (ys - a.y) ** 2
        far_x, far_y = xs[[int(np.argmax(dx2))]], ys[[int(np.argmax(dy2))]]
        height, owner = np.full((1, 1), np.inf), np.full((1, 1), -1, dtype=np.int64)
        x, y, z, R = (np.array([v], dtype=float) for v in (a.x, a.y, a.z, a.R))
        tip = TipArrays(np.zeros(1, dtype=np.int64), x, y, z, R, np.array([a.shape == "sphere"]))
        sample_tips(far_x, far_y, tip, height, owner)
        return float(height[0, 0])
    return float(np.max(surface_on(grid, owners).height))


def patch_candidates(grid: Grid, asperities: Sequence[Asperity], members: tuple) -> list:
    """Sorted indices of the asperities that can own a cell of ``grid``: those whose
    material reaches it and that can be lower there than the highest of the ``members``'
    surface over it (:meth:`TipTable.reaching`)."""
    # a table made here is used once: its tree would cost more than the direct test
    table = TipTable.of(asperities)
    return table.reaching(
        grid.bounds, index=isinstance(asperities, TipTable), below=highest_over(grid, [asperities[m] for m in members])
    ).tolist()


def make_patch(
    k: int, grid: Grid, asperities: Sequence[Asperity], members: tuple = (), keep: list | None = None
) -> Patch:
    """Patch ``k`` (of ``members``, default ``(k,)``) on ``grid``, with heights and owners
    from every asperity.

    Spheres whose material (``r < R``) cannot reach the grid are skipped (their height is
    ``inf`` there), so building a patch costs its cells times the nearby asperities only;
    ``keep``: those asperities (:func:`patch_candidates`) when known.
    """
    if keep is None:
        keep = patch_candidates(grid, asperities, members or (k,))
    if isinstance(asperities, TipTable) and sampled_in_batches(grid) and asperities.plain:
        # the batches surface_on samples, from the table's arrays: no asperity objects and
        # no cell-centre meshes (1,572 patches of 1,485 clustered spheres: half their CPU)
        height, owner = asperities.sample(grid, np.asarray(keep, dtype=np.int64))
        return Patch(k, grid, height, owner, members)
    surf = surface_on(grid, [asperities[l] for l in keep])
    index = np.append(np.asarray(keep, dtype=np.int64), -1)
    return Patch(k, grid, surf.height, index[surf.owner], members)


def crop_patch(patch: Patch, grid: Grid) -> Patch | None:
    """``patch`` (one asperity's) cut down to ``grid``, an aligned grid inside its own, or
    None where ``grid`` is not inside. A cell's height and owner are the lowest asperity
    there (those :func:`make_patch` leaves out cannot be lower), so they do not depend on
    the grid they are sampled on: the cut windows (read-only views) are the patch
    :func:`make_patch` would build on ``grid``, the cells' heights as sampled at the
    larger grid's centres."""
    if len(patch.members) != 1 or not math.isclose(grid.h, patch.grid.h, rel_tol=1e-12):
        return None
    di, dj = grid.offset_in(patch.grid)
    if di < 0 or dj < 0 or di + grid.nx > patch.grid.nx or dj + grid.ny > patch.grid.ny:
        return None
    window = (slice(dj, dj + grid.ny), slice(di, di + grid.nx))
    height, owner = patch.height[window], patch.owner[window]
    height.setflags(write=False)
    owner.setflags(write=False)
    return Patch(patch.asperity, grid, height, owner)


def patch_radius(asperity: Asperity, *, force: float, approach: float, E_star: float, h: float, margin: float) -> float:
    """Half-width (mm) of the patch of one asperity.

    The Hertz-like contact radius ``a = (3 P R / (4 E*))^(1/3)`` from the macro force ``P``
    (N), times ``margin`` plus two cells, but never beyond the reach of the indenter at the
    geometric approach ``approach`` (mm; no cell farther out can touch when displacements
    are into the body) plus one cell. An asperity the macro step leaves out of contact
    (``force <= 0``) or a non-finite ``force`` (no usable macro force) gets that reach:
    a neighbour's displacement can move its contact away from its tip. ``E*`` (MPa) is only used for this estimate.
    """
    reach = asperity.reach(approach) + h
    if not math.isfinite(force) or force <= 0.0:
        return reach
    a = (3.0 * max(force, 0.0) * asperity.R / (4.0 * E_star)) ** (1.0 / 3.0)
    return min(reach, margin * a + 2.0 * h)


def edges_loaded(patch: Patch, pressure: np.ndarray) -> tuple[bool, bool, bool, bool]:
    """Whether pressure (ny, nx) reaches the (left, right, bottom, top) edge of the patch."""
    p = np.where(patch.owned, pressure, 0.0) > 0.0
    return (bool(p[:, 0].any()), bool(p[:, -1].any()), bool(p[0, :].any()), bool(p[-1, :].any()))


def grow_patch(
    patch: Patch, sides: tuple[bool, bool, bool, bool], asperities: Sequence[Asperity], *, fraction: float = 0.25
) -> Patch:
    """The patch extended on the flagged (left, right, bottom, top) sides by ``fraction``
    of its size (at least two cells)."""
    g = patch.grid
    gx, gy = max(2, math.ceil(fraction * g.nx)), max(2, math.ceil(fraction * g.ny))
    left, right, bottom, top = sides
    i0, j0 = -gx if left else 0, -gy if bottom else 0
    nx = g.nx + (gx if left else 0) + (gx if right else 0)
    ny = g.ny + (gy if bottom else 0) + (gy if top else 0)
    return make_patch(patch.asperity, g.subgrid(i0, j0, nx, ny), asperities, patch.members)


def extend_patch(patch: Patch, points: np.ndarray, asperities: Sequence[Asperity], *, pad: int = 2) -> Patch:
    """The patch enlarged to cover ``points`` (M, 2) mm plus ``pad`` cells."""
    g = patch.grid
    xmin, xmax, ymin, ymax = g.bounds
    m = pad * g.h
    xmin, xmax = min(xmin, points[:, 0].min() - m), max(xmax, points[:, 0].max() + m)
    ymin, ymax = min(ymin, points[:, 1].min() - m), max(ymax, points[:, 1].max() + m)
    i0 = math.floor((xmin - g.x0) / g.h + 0.5)
    j0 = math.floor((ymin - g.y0) / g.h + 0.5)
    i1 = math.ceil((xmax - g.x0) / g.h - 0.5)
    j1 = math.ceil((ymax - g.y0) / g.h - 0.5)
    return make_patch(patch.asperity, g.subgrid(i0, j0, i1 - i0 + 1, j1 - j0 + 1), asperities, patch.members)


def transfer(old: Patch, new: Patch, pressure: np.ndarray) -> np.ndarray:
    """Copy a patch array (ny, nx) onto an aligned larger patch (zero on new cells)."""
    di, dj = old.grid.offset_in(new.grid)
    out = np.zeros(new.grid.shape)
    out[dj : dj + old.grid.ny, di : di + old.grid.nx] = pressure
    return out


def merge_overlapping(
    patches: Sequence[Patch], asperities: Sequence[Asperity], *, growth: float = 1.0, carries=None
) -> tuple[list[Patch], list[tuple]]:
    """Patches merged where one block over them costs few more cells than they do apart.

    Patches become one when the smallest aligned grid covering them has at most ``growth``
    times as many cells as their own grids together (``growth`` = 1: they overlap or abut
    along most of a side, i.e. close or merged contacts). A pair is tested together with
    every patch its covering grid meets (a ring of patches around a centre merges as a
    whole, though the centre and no single neighbour would). The merged patch's block is
    the union of the members' owned cells (each cell still owned by the asperity nearest
    the body), so block Gauss-Seidel solves strongly coupled asperities together instead of
    passing their interaction back and forth over many sweeps; far patches stay one per
    asperity, and so do those ``carries`` (a bool per patch) marks False (no start pressure
    or no owned cell: a block over them only adds empty cells).

    Returns the patches (merged ones with several ``members``, ordered by their first
    member) and, for each, the indices of the input patches it covers.
    """
    if not (math.isfinite(growth) and growth >= 1.0):
        raise ValueError(f"merge growth must be >= 1, got {growth!r}")
    if len(patches) < 2:
        return list(patches), [(k,) for k in range(len(patches))]
    # integer lattice boxes [i0, i1) x [j0, j1) of each group, and the cells of its members' grids
    offsets = [pt.grid.offset_in(patches[0].grid) for pt in patches]
    box = np.array(
        [(di, di + pt.grid.nx, dj, dj + pt.grid.ny) for (di, dj), pt in zip(offsets, patches)], dtype=np.int64
    )
    own = (box[:, 1] - box[:, 0]) * (box[:, 3] - box[:, 2])
    groups = [[k] for k in range(len(patches))]
    alive = np.ones(len(patches), dtype=bool) if carries is None else np.asarray(carries, dtype=bool).copy()
    keep = ~alive  # left out: one group each

    def closure(sel):
        # every group whose box meets the union box joins, until none is added
        while True:
            u = np.array([box[sel, 0].min(), box[sel, 1].max(), box[sel, 2].min(), box[sel, 3].max()])
            meet = alive & (box[:, 0] < u[1]) & (box[:, 1] > u[0]) & (box[:, 2] < u[3]) & (box[:, 3] > u[2])
            meet[sel] = True
            if meet.sum() == sel.sum():
                return sel, u
            sel = meet

    changed = True
    while changed:  # until no group qualifies (a grown group may now pair with an earlier one)
        changed = False
        for k in np.flatnonzero(alive):
            if not alive[k]:
                continue
            b = box[k]
            union = (np.maximum(box[:, 1], b[1]) - np.minimum(box[:, 0], b[0])) * (
                np.maximum(box[:, 3], b[3]) - np.minimum(box[:, 2], b[2])
            )
            ratio = union / (own + own[k])
            meets = (box[:, 0] < b[1]) & (box[:, 1] > b[0]) & (box[:, 2] < b[3]) & (box[:, 3] > b[2])
            near = alive & (meets | (ratio <= growth))
            near[k] = False
            # partners in order of the least empty grid they add
            for l in np.flatnonzero(near)[np.argsort(ratio[near], kind="stable")]:
                sel = np.zeros(len(patches), dtype=bool)
                sel[[k, l]] = True
                sel, u = closure(sel)
                if (u[1] - u[0]) * (u[3] - u[2]) <= growth * own[sel].sum():
                    for i in np.flatnonzero(sel):
                        if i != k:
                            groups[k] += groups[i]
                            alive[i] = False
                    box[k], own[k] = u, own[sel].sum()
                    changed = True
                    break
    return merge_groups(patches, asperities, [groups[k] for k in np.flatnonzero(alive | keep)])


def merge_groups(
    patches: Sequence[Patch], asperities: Sequence[Asperity], groups: Sequence[Sequence[int]]
) -> tuple[list[Patch], list[tuple]]:
    """One patch per group of ``patches`` (indices; every patch in exactly one group): the
    patch itself for a group of one, else a merged patch on the smallest aligned grid
    covering the group's grids, whose members are the group's patches' members. Returns the
    patches ordered by their first member and, for each, the indices it covers."""
    out, covers = [], []
    for group in groups:
        members = tuple(sorted(m for i in group for m in patches[i].members))
        if len(group) == 1:
            out.append(patches[group[0]])
        else:
            g0 = patches[group[0]].grid
            b = np.array([(*patches[i].grid.offset_in(g0), patches[i].grid.nx, patches[i].grid.ny) for i in group])
            i0, j0 = int(b[:, 0].min()), int(b[:, 1].min())
            grid = g0.subgrid(i0, j0, int((b[:, 0] + b[:, 2]).max()) - i0, int((b[:, 1] + b[:, 3]).max()) - j0)
            out.append(make_patch(members[0], grid, asperities, members))
        covers.append(tuple(sorted(group, key=lambda i: patches[i].asperity)))
    order = np.argsort([pt.asperity for pt in out], kind="stable")
    return [out[i] for i in order], [covers[i] for i in order]
