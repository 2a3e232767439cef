"""The micro step's working set: patches, their blocks, the coupling, and patch growth.

:class:`WorkingSet` holds what the block iterations change as they go (patches grow when
pressure reaches an edge or an asperity penetrates outside its block; asperities the macro
step left out get a patch when the final approach reaches them). The functions here decide
and make those changes; :mod:`.block_iterations` runs the iterations.
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from ..indenters import Tilt
from .blocks import scatter
from .localblock import LocalBlock
from .constraints import member_forces
from .gauss_seidel import coupled_rhs
from .patches import extend_patch, grow_patch, make_patch, merge_groups, transfer
from .stop_cells import StopCells
from .touching import touching_groups


class WorkingSet:
    """Mutable working set of the micro step (patches, blocks, pressures); internal."""

    def __init__(self, provider, asperities, patches, coupling, *, dense_max_cells: int, blocks=None, rebuild=None):
        self.provider, self.asperities = provider, asperities
        # ``rebuild(patches)``: a new product engine, where patches may be merged as they go
        self.rebuild = rebuild
        self.dense_max_cells = dense_max_cells
        self._owned_cells: dict = {}  # id(patch) -> (patch, owned heights, X, Y): :meth:`heights`
        self.patches = list(patches)
        blocks = [None] * len(self.patches) if blocks is None else list(blocks)
        self.blocks = [
            blk if blk is not None else LocalBlock(provider, pt, dense_max_cells=dense_max_cells)
            for pt, blk in zip(self.patches, blocks)
        ]
        # the product engine a coupling object built for these patches (:mod:`.couplings`)
        self.coupling = coupling
        self.sensitivities = None
        # the last gaps (:meth:`gaps`) and the growth check's (:meth:`gaps_of`): dropped when
        # a patch or the engine changes (:meth:`_forget_gaps`)
        self._gaps: tuple | None = None
        self._gaps_of: tuple | None = None
        self.stop_cells = StopCells(len(asperities))  # the cells the stop tests read, per patch

    def tips(self) -> np.ndarray:
        """Tip of every asperity of the scene, (N, 2) mm."""
        return np.array([[a.x, a.y] for a in self.asperities], dtype=float).reshape(-1, 2)

    def heights(self, theta, pivot):
        """Indenter height with tilt on every block (list of (n_k,) arrays), mm: the
        module's :func:`heights` with each patch's owned heights and cell centres kept
        while the patch is the same object (asked at every sweep: 4,548 patches' centres
        made again each time were 0.3 s a call)."""
        tilt = Tilt(theta[1], theta[2], pivot)
        level = theta[1] == 0.0 and theta[2] == 0.0  # the kept heights themselves (read-only)
        kept = self._owned_cells
        out, now = [], {}
        for pt in self.patches:
            hit = kept.get(id(pt))
            if hit is None or hit[0] is not pt:
                X, Y = pt.grid.centres()
                hit = (pt, pt.height[pt.owned], X[pt.owned], Y[pt.owned])
                hit[1].setflags(write=False)
            now[id(pt)] = hit
            out.append(hit[1] if level else hit[1] + tilt.height(hit[2], hit[3]))
        self._owned_cells = now
        return out

    def patch_of(self) -> dict:
        """Index of the patch holding each asperity that has one."""
        return {m: k for k, pt in enumerate(self.patches) for m in pt.members}

    def grow(self, k: int, sides, vectors: list) -> None:
        """Enlarge patch ``k``; block vectors in ``vectors`` (lists) are carried over."""
        self._replace(k, grow_patch(self.patches[k], sides, self.asperities), vectors)

    def extend(self, asperity: int, points: np.ndarray, vectors: list) -> None:
        """Make the patch of ``asperity`` cover ``points`` (M, 2) mm, creating it if needed."""
        index = self.patch_of()
        if asperity not in index:
            h = self.patches[0].grid.h
            a = self.asperities[asperity]
            anchor = (self.patches[0].grid.x0, self.patches[0].grid.y0)
            grid = Grid.covering(a.x - h, a.x + h, a.y - h, a.y + h, h, anchor=anchor)
            self.patches.append(make_patch(asperity, grid, self.asperities))
            self.blocks.append(LocalBlock(self.provider, self.patches[-1], dense_max_cells=self.dense_max_cells))
            self.coupling.append(self.patches[-1])
            for vec in vectors:
                vec.append(np.zeros(self.blocks[-1].n))
            index[asperity] = len(self.patches) - 1
        k = index[asperity]
        self._replace(k, extend_patch(self.patches[k], points, self.asperities), vectors)

    def _replace(self, k: int, new, vectors: list) -> None:
        """Patch ``k`` becomes ``new``; its block, coupling and the block vectors follow."""
        old = self.patches[k]
        for vec in vectors:
            vec[k] = transfer(old, new, scatter(old, vec[k]))[new.owned]
        self.patches[k] = new
        blk = LocalBlock(self.provider, new, dense_max_cells=self.dense_max_cells)
        kept = self.blocks[k].coarse_shape
        if kept is not None:
            # the coarse step's shape A_SS^-1 1 depends on the active cells, not on the patch
            # around them: carried over, it is solved again only where the set moves
            active, shape = (transfer(old, new, scatter(old, v.astype(float)))[new.owned] for v in kept)
            blk.coarse_shape = (active > 0.0, shape)
        self.blocks[k] = blk
        self.coupling.replace(k, new)
        self._forget_gaps()

    def regroup(self, groups: list, vectors: list) -> None:
        """Each group of patch indices becomes one patch (:func:`~.patches.merge_groups`);
        the blocks, a new engine and the block vectors in ``vectors`` (lists, changed in
        place) follow."""
        merged, covers = merge_groups(self.patches, self.asperities, groups)
        for vec in vectors:
            old = list(vec)
            vec[:] = [
                old[c[0]]
                if len(c) == 1
                else sum(transfer(self.patches[i], pt, scatter(self.patches[i], old[i])) for i in c)[pt.owned]
                for pt, c in zip(merged, covers)
            ]
        self.blocks = [
            self.blocks[c[0]] if len(c) == 1 else LocalBlock(self.provider, pt, dense_max_cells=self.dense_max_cells)
            for pt, c in zip(merged, covers)
        ]
        old, self.patches = self.coupling, merged
        self.coupling = self.rebuild(merged)
        self.coupling.keep_pairs(old, {c[0]: k for k, c in enumerate(covers) if len(c) == 1})
        self.sensitivities = None
        self._forget_gaps()

    def _forget_gaps(self) -> None:
        """Drop the kept gaps: they no longer match the patches, and the growth check's
        hold the engine they were taken from, whose far field keeps per-patch weights
        (4,548 paraboloids: a replaced engine held 700 MB until the next round's check)."""
        self._gaps = self._gaps_of = None

    def full_displacement(self, pressures: list) -> list:
        """Displacement on every whole patch (list of (ny, nx) arrays), mm."""
        return [self._displacement(k, pressures) for k in range(len(self.patches))]

    def gaps(self, pressures: list, theta, pivot) -> list:
        """``z + tilt + u - d`` on every whole patch, mm (``inf`` where no indenter); the last
        answer again while the patches, the block vectors (replaced, never modified, when
        they change) and the approach and tilt are the same (the growth check at a round's
        end and the result ask for the same gaps), and the patches the check evaluated alone
        (:meth:`gaps_of`) taken from it (4,548 paraboloids: 1.2 of the result's 3.7 s)."""
        key = (tuple(float(v) for v in theta), tuple(pivot))
        last = self._gaps
        if last is not None and last[0] == key and _same(last[1], pressures) and _same(last[2], self.patches):
            return last[3]
        some = self._gaps_of  # the growth check's patches, at the same state
        if some is None or some[0] != key or not _same(some[1], pressures) or not _same(some[2], self._held()):
            some = (None, None, None, {})
        out = [
            some[3][k] if k in some[3] else self._gap(k, self._displacement(k, pressures), theta, pivot)
            for k in range(len(self.patches))
        ]
        self._gaps = (key, list(pressures), list(self.patches), out)
        return out

    def _held(self) -> list:
        """The patches and the coupling (whose held far field the gaps take)."""
        return self.patches + [self.coupling]

    def _displacement(self, k: int, pressures: list) -> np.ndarray:
        """Displacement on the whole patch ``k`` (ny, nx), mm."""
        u = self.coupling.patch_displacement(k, pressures)
        if np.any(pressures[k]):
            u += self.blocks[k].patch_product(pressures[k])
        return u

    def _gap(self, k: int, u: np.ndarray, theta, pivot) -> np.ndarray:
        pt = self.patches[k]
        X, Y = pt.grid.centres()
        with np.errstate(invalid="ignore"):
            return pt.height + Tilt(theta[1], theta[2], pivot).height(X, Y) + u - theta[0]

    def gaps_of(self, which, pressures: list, theta, pivot) -> dict:
        """:meth:`gaps` on the patches ``which`` only (``{k: (ny, nx) array}``; the kept
        answer's where :meth:`gaps` has one for these pressures): each patch's gap is the
        same whichever others are asked for."""
        key = (tuple(float(v) for v in theta), tuple(pivot))
        last = self._gaps
        if last is not None and last[0] == key and _same(last[1], pressures) and _same(last[2], self.patches):
            return {k: last[3][k] for k in which}
        out = {k: self._gap(k, self._displacement(k, pressures), theta, pivot) for k in which}
        self._gaps_of = (key, list(pressures), self._held(), out)
        return out

    def displacement(self, pressures: list) -> list:
        """``A p`` on every block (list of (n_k,) arrays), mm."""
        return [
            blk.matvec(pressures[k]) - coupled_rhs(self.coupling, k, pressures, np.zeros(blk.n))
            for k, blk in enumerate(self.blocks)
        ]


def _same(a: list, b: list) -> bool:
    """The same objects in the same order."""
    return len(a) == len(b) and all(x is y for x, y in zip(a, b))


def heights(patches, theta, pivot) -> list:
    """Indenter height with tilt on the blocks of ``patches`` (list of (n_k,) arrays), mm;
    without a tilt the owned heights themselves, as :meth:`WorkingSet.heights` gives them
    (the cells' centres for a tilt of zero: 0.1 s of CPU on 1,013 patches)."""
    tilt = Tilt(theta[1], theta[2], pivot)
    level = theta[1] == 0.0 and theta[2] == 0.0
    out = []
    for pt in patches:
        if level:
            out.append(pt.height[pt.owned])
            continue
        X, Y = pt.grid.centres()
        out.append(pt.height[pt.owned] + tilt.height(X[pt.owned], Y[pt.owned]))
    return out


def tip_approaches(asperities, theta, pivot) -> np.ndarray:
    """Geometric approach ``d - z_k - tilt(x_k, y_k)`` of every tip, mm."""
    tilt = Tilt(theta[1], theta[2], pivot)
    x, y, z = (np.array([getattr(a, f) for a in asperities], dtype=float) for f in "xyz")
    return theta[0] - z - tilt.height(x, y)


def _grow_loaded(state: WorkingSet, p: list, p0: list) -> int:
    grown = 0
    for k in state.stop_cells.loaded_edges(state.patches, p):  # no other patch's edge is loaded
        pt = state.patches[k]
        sides = state.stop_cells.sides(pt, p[k])
        if any(sides):
            state.grow(k, sides, [p, p0])
            grown += 1
    return grown


def _cover_penetration(state: WorkingSet, p: list, p0: list, theta, pivot, gap_tol: float) -> int:
    """Extend the patch of every asperity that penetrates on cells outside its own block
    (a neighbour can push its contact away from its tip); returns how many were extended."""
    wanted = _penetrations(state, p, theta, pivot, gap_tol)
    for k, pts in wanted.items():
        state.extend(k, pts, [p, p0])
    return len(wanted)


def _penetrations(state: WorkingSet, p: list, theta, pivot, gap_tol: float) -> dict:
    """The points (M, 2) mm outside its patch where each asperity penetrates on cells
    another owns, by asperity."""
    wanted: dict = {}
    # only cells owned by another asperity can be reported: the patches without any are
    # not evaluated (the whole gaps of 4,548 paraboloids' patches cost what a sweep does)
    foreign = {k: (pt.owner >= 0) & ~pt.owned for k, pt in enumerate(state.patches)}
    which = [k for k, f in foreign.items() if f.any()]
    for k, gap in state.gaps_of(which, p, theta, pivot).items():
        pt = state.patches[k]
        bad = (gap < -gap_tol) & foreign[k]
        if not bad.any():
            continue
        X, Y = pt.grid.centres()
        for k in np.unique(pt.owner[bad]):
            sel = bad & (pt.owner == k)
            wanted.setdefault(int(k), []).append(np.column_stack([X[sel], Y[sel]]))
    index = state.patch_of()
    out = {}
    for k, pts in wanted.items():
        pts = np.concatenate(pts)
        if k in index:
            xmin, xmax, ymin, ymax = state.patches[index[k]].grid.bounds
            inside = (pts[:, 0] > xmin) & (pts[:, 0] < xmax) & (pts[:, 1] > ymin) & (pts[:, 1] < ymax)
            pts = pts[~inside]
        if len(pts):
            out[k] = pts
    return out


def penetrates_outside(state: WorkingSet, p: list, theta, pivot, tol: float) -> bool:
    """Some asperity penetrates on cells outside its own block, which :func:`grow` would
    extend its patch over (the same test and gap tolerance), asked during a round: its gaps
    are not kept for the result (:meth:`WorkingSet.gaps`), as they were taken at the far field
    held through the last sweep, which the round's end refreshes."""
    found = bool(_penetrations(state, p, theta, pivot, _gap_tol(state, theta, pivot, tol)))
    state._gaps_of = None
    return found


def edges_loaded_any(state: WorkingSet, p: list) -> bool:
    """Pressure reaches an edge of some patch."""
    return state.stop_cells.any_edge(state.patches, p)


def grow(state: WorkingSet, p: list, p0: list, theta, pivot, tol: float) -> int:
    """Enlarge the patches whose pressure reaches an edge, and those of asperities that
    penetrate outside their blocks (found at once: 4,548 paraboloids and 102 spheres both
    extended the same patches after the first sweep as after the next round converged, a
    round saved), else give a patch to the asperities the approach now reaches; returns
    the number of patches changed."""
    grown = _grow_loaded(state, p, p0)
    if grown:
        return grown + _cover_penetration(state, p, p0, theta, pivot, _gap_tol(state, theta, pivot, tol))
    gap_tol = _gap_tol(state, theta, pivot, tol)
    return _cover_penetration(state, p, p0, theta, pivot, gap_tol) or _cover_unpatched(
        state, p, p0, theta, pivot, gap_tol
    )


def comes_to_touch(state: WorkingSet, p: list) -> bool:
    """Where the state may merge patches, whether the contacts of two of them touch at the
    pressures ``p`` (checked after each sweep: two tips 1.4 um apart among 2,117 light
    spheres, apart at the start, then passed their force back and forth at 0.8 a sweep)."""
    if state.rebuild is None or not state.stop_cells.may_touch(state.patches, p):
        return False  # no loaded cell within reach of another patch's: all apart
    only = state.stop_cells.loaded_touch(state.patches, p)
    return len(touching_groups(state.patches, p, only=only)) < len(state.patches)


def merge_touching(state: WorkingSet, p: list, p0: list) -> int:
    """Where the state may merge patches (``state.rebuild``), make one patch of each group
    whose contacts now touch (:func:`~.touching.touching_groups` on the pressures ``p``; a
    grown patch or one given to an asperity the macro step left out can meet a neighbour's
    contact: 845 paraboloids, a new patch and its neighbour's passed 0.02-0.09 N back and
    forth for five sweeps); returns how many patches were merged away."""
    if state.rebuild is None or len(state.patches) < 2:
        return 0
    groups = touching_groups(state.patches, p, only=state.stop_cells.loaded_touch(state.patches, p))
    if len(groups) == len(state.patches):
        return 0
    before = len(state.patches)
    state.regroup(groups, [p, p0])
    return before - len(state.patches)


def _cover_unpatched(state: WorkingSet, p: list, p0: list, theta, pivot, gap_tol: float) -> int:
    """Give a patch to every asperity without one that the indenter now reaches at its tip;
    returns how many were added. The macro step can leave an asperity out that the final
    approach or tilt brings in (e.g. a pivot on one tip: point forces balance any tilt that
    lifts the others, distributed pressure does not), and a finite block's surface can rise
    under a neighbour's load. The surface displacement at the tip is estimated from the
    patches' resultant forces (point forces)."""
    have = state.patch_of()
    missing = np.array([k for k in range(len(state.asperities)) if k not in have], dtype=int)
    if missing.size == 0 or not state.patches:
        return 0
    approach = tip_approaches([state.asperities[k] for k in missing], theta, pivot)
    tips = state.tips()
    h = state.patches[0].grid.h
    members, forces = member_forces(state.patches, p)
    u = state.provider.point_operator(tips[missing], tips[members]).apply(forces)
    local = approach - u
    reached = np.flatnonzero(local > -gap_tol)
    for i in reached:
        k = int(missing[i])
        # cover the sphere's reach at twice the estimated local approach (then grown as usual)
        r = state.asperities[k].reach(2.0 * max(float(local[i]), gap_tol)) + 2.0 * h
        state.extend(k, tips[k] + r * np.array([[-1.0, -1.0], [1.0, 1.0]]), [p, p0])
    return int(reached.size)


def _gap_tol(state: WorkingSet, theta, pivot, tol: float) -> float:
    # penetration (mm) accepted outside the blocks: the sweeps' tolerance times the largest approach
    z = state.heights(theta, pivot)
    depth = max((theta[0] - float(np.min(zk)) for zk in z if zk.size), default=0.0)
    return 10.0 * tol * max(depth, 0.0)
