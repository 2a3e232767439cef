"""The road at one position: its stones shifted by the position's shift and seen through
the body's face (a tyre's cylinder, a footprint window).

The strip is segmented once (:class:`Road`); at each position :meth:`Road.stones_at` picks
the stones within reach of the footprint and returns them as indenters in the body frame:
a road point at x appears at body x + shift, and the face's height at body x
(:meth:`~twoscale.rolling.spec.RollingSpec.face`; ``inf`` outside the window) is added to
the gap. For the basins of a height map the shifted stones look the map up through
:class:`ShiftedBasins` (no copy of the map); their summit, recess and reach are those of
the basin plus the face, found on the basin's own samples.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..grid import Grid
from ..indenters import Asperity, Surface, surface_on
from ..scene import Scene
from ..surface.indenter import MapAsperity
from .spec import RollingSpec


#: Points this close to the face window's edge (mm) are inside it (rounding of cell centres).
EDGE_TOL = 1e-9


@dataclass(frozen=True)
class Face:
    """The body's face: the tyre's profile along x and the window outside which the road
    never touches (body frame, mm; ``inf`` bounds: no window that way)."""

    spec: RollingSpec
    window: tuple  # (x0, x1, y0, y1)
    _kept: dict = field(default_factory=dict, compare=False, repr=False)  # the last grid's heights

    def on_grid(self, grid) -> np.ndarray:
        """:meth:`height` at the cell centres of ``grid``, kept for the last grid asked for
        (the window path samples the same window, fixed in the body, at every position)."""
        found = self._kept.get(grid)
        if found is None:
            self._kept.clear()
            found = self._kept[grid] = self.height(*grid.centres())
            found.setflags(write=False)
        return found

    def height(self, X, Y) -> np.ndarray:
        X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
        x0, x1, y0, y1 = self.window
        e = EDGE_TOL  # a cell centre on the window's edge is inside, however its grid was built
        inside = (X >= x0 - e) & (X <= x1 + e) & (Y >= y0 - e) & (Y <= y1 + e)
        return np.where(inside, self.spec.face(X), np.inf)

    def slope(self, x: float) -> float:
        """d(face)/dx at body x (the tyre's tilt under a stone)."""
        R = self.spec.tyre_radius
        if R is None:
            return 0.0
        if self.spec.tyre_shape == "parabola":
            return x / R
        return x / math.sqrt(max(R * R - x * x, 1e-300))


@dataclass(frozen=True, eq=False)
class ShiftedBasins:
    """The basins of a height map shifted along x and seen through a face: the ``group``
    the solvers sample (:func:`twoscale.indenters.surface_on`), as a
    :class:`~twoscale.surface.indenter.BasinMap` is."""

    base: object  # BasinMap of the whole strip
    shift: float
    face: Face

    @property
    def grid(self):
        return self.base.grid

    @property
    def book(self):
        return self.base.book

    @property
    def labels(self):
        return self.base.labels

    @property
    def n_labels(self) -> int:
        return self.base.n_labels

    def lookup(self, X, Y, label: int) -> np.ndarray:
        return self.base.lookup(np.asarray(X) - self.shift, Y, label) + self.face.height(X, Y)

    def union_on(self, X, Y, index: dict):
        hk, owner = self.base.union_on(np.asarray(X) - self.shift, Y, index)
        hk = hk + self.face.height(X, Y)
        return hk, np.where(np.isfinite(hk), owner, -1)

    def union_on_grid(self, grid, index: dict):
        """:meth:`union_on` at the cell centres of ``grid`` when, shifted back by the shift,
        they are samples of the map's lattice: windows of the map (a window of 200,000
        cells: ~10 -> 2 ms), else None."""
        moved = dataclasses.replace(grid, x0=grid.x0 - self.shift)
        found = self.base.union_on_grid(moved, index)
        if found is None:
            return None
        np.add(found[0], self.face.on_grid(grid), out=found[0])  # (new arrays: in place, two passes less)
        found[1][~np.isfinite(found[0])] = -1
        return found


@dataclass(frozen=True)
class ShiftedTip(Asperity):
    """A sphere or paraboloid of the road shifted by ``shift`` and seen through ``face``;
    its tip and recess are the first-order ones of the tip on the tilted face."""

    base: Asperity | None = field(default=None, repr=False)
    shift: float = 0.0
    face: Face | None = field(default=None, repr=False)

    def height(self, X, Y):
        return self.base.height(np.asarray(X) - self.shift, Y) + self.face.height(X, Y)

    @property
    def material_radius(self) -> float:
        return self.base.material_radius + abs(self.x - self.base.x - self.shift)

    def reach(self, depth: float) -> float:
        return self.base.reach(depth) + abs(self.x - self.base.x - self.shift)


@dataclass(frozen=True, eq=False)
class RolledStone(MapAsperity):
    """A basin of the road at one position: a :class:`~twoscale.surface.indenter.MapAsperity`
    whose samples' depths below the summit ``fall`` are recess + face (``inf`` outside the
    face's window), ``dist`` their distances from its summit there."""

    def __post_init__(self) -> None:
        pass  # made by :meth:`Road.map_stones` from a checked basin: finite by construction

    @classmethod
    def of(cls, *values) -> "RolledStone":
        """The stone of the fields' ``values`` in their order, as the constructor makes it,
        its fields written at once (the frozen ``__init__`` sets its 10 one by one through
        ``object.__setattr__``: ~4 us a stone against ~1, ~560 stones a tyre's position)."""
        stone = object.__new__(cls)
        stone.__dict__.update(zip(_ROLLED_FIELDS, values))
        return stone


_ROLLED_FIELDS = tuple(f.name for f in dataclasses.fields(RolledStone))


def reaches(stones, depths: np.ndarray) -> np.ndarray:
    """Each stone's ``reach(depth)`` (mm) for its ``depths`` (mm): the basins' (:class:`RolledStone`)
    on all their samples at once (one loop over ~500 stones a position cost ~4 ms), the
    others' one by one."""
    depths = np.asarray(depths, dtype=float)
    if not stones or not all(type(s) is RolledStone for s in stones):
        return np.array([s.reach(float(d)) for s, d in zip(stones, depths.tolist())], dtype=float)
    counts = np.array([s.fall.size for s in stones])
    fall = np.concatenate([s.fall for s in stones])
    dist = np.concatenate([s.dist for s in stones])
    within = fall < np.repeat(depths, counts)  # (a fall is >= 0: a depth <= 0 takes no sample)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    out = np.zeros(len(stones))
    some = counts > 0
    out[some] = np.maximum.reduceat(np.where(within, dist, 0.0), starts[some])
    return out


@dataclass(frozen=True)
class Selection:
    """The stones of one position: the indenters (body frame) and their numbers in the
    road (0-based: the segmentation's labels, or the scene's tip order)."""

    stones: tuple
    numbers: np.ndarray
    shift: float


class Road:
    """The road of a rolling scene, prepared once: the stones' boxes, and for a height map
    the basins' samples and the x-slope of the strip (for the drag)."""

    def __init__(self, scene: Scene, face_window: tuple):
        self.scene = scene
        self.tips = tuple(scene.asperities)
        self.spec: RollingSpec = scene.rolling
        self.window = face_window
        self.face = Face(self.spec, face_window)
        self.surface = scene.surface
        z = np.array([a.z for a in self.tips], dtype=float)
        self.z = z
        if self.surface is not None:
            self._prepare_map()
        else:
            xy = np.array([[a.x, a.y] for a in self.tips], dtype=float)
            r = np.array([min(a.material_radius, 1e6) for a in self.tips], dtype=float)
            self.box = np.column_stack([xy[:, 0] - r, xy[:, 0] + r, xy[:, 1] - r, xy[:, 1] + r])

    def _prepare_map(self) -> None:
        from ..surface.sphere_fit import basin_cells

        hmap = self.surface.hmap
        self.basins = self.tips[0].basins
        self.cells = basin_cells(self.surface.segmentation)
        X, Y = (c.ravel() for c in hmap.grid.centres())
        self.box = np.array([[X[c].min(), X[c].max(), Y[c].min(), Y[c].max()] for c in self.cells])
        recess = self.basins.recess
        self.slope_x = _x_slope(recess, hmap.h)
        # the basins' samples (x, y, recess) stone after stone in the order of their boxes'
        # left edges: the stones within reach of a position are then one slab of them
        self.by_x = np.argsort(self.box[:, 0], kind="stable")
        self.rank = np.empty_like(self.by_x)
        self.rank[self.by_x] = np.arange(len(self.by_x))
        flat = np.concatenate([self.cells[k] for k in self.by_x.tolist()])
        self.sample_start = np.concatenate([[0], np.cumsum([len(self.cells[k]) for k in self.by_x.tolist()])])
        x0, x1, y0, y1 = self.window
        x, y = X[flat], Y[flat]
        # (the face's height at a sample, ``inf`` outside its window, at every position: of
        # the strip's few columns (``columns[column]`` is x), and only inside across y)
        self.columns, column = np.unique(x, return_inverse=True)
        across = (y >= y0 - EDGE_TOL) & (y <= y1 + EDGE_TOL)
        self.samples = (x, y, recess.ravel()[flat], np.where(across, column, len(self.columns)))

    @property
    def extent_x(self) -> tuple:
        """The road's x range (its own frame), mm."""
        return float(self.box[:, 0].min()), float(self.box[:, 1].max())

    def candidates(self, shift: float, bound: float) -> np.ndarray:
        """Stones whose box meets the window at ``shift`` and whose lowest possible point
        lies below ``bound`` (:meth:`lowest`)."""
        return np.flatnonzero(self.lowest(shift) < bound)

    def lowest(self, shift: float) -> np.ndarray:
        """A lower bound of each stone's recess + face at ``shift`` (``inf`` outside the
        window): the summit recess plus the face's lowest height over the stone's box."""
        x0, x1, y0, y1 = self.window
        bx0, bx1 = self.box[:, 0] + shift, self.box[:, 1] + shift
        meets = (bx1 >= x0) & (bx0 <= x1) & (self.box[:, 3] >= y0) & (self.box[:, 2] <= y1)
        closest = np.clip(0.0, np.maximum(bx0, x0), np.minimum(bx1, x1))
        return np.where(meets, self.z + self.spec.face(closest), np.inf)

    def stones_at(self, shift: float, bound: float) -> Selection:
        """The stones that can touch at ``shift`` when the approach is at most ``bound``
        (mm, below the strip's highest point): none left out can touch, since the body's
        surface only moves away from the road under pressure."""
        face = self.face
        out, numbers = [], []
        if self.surface is not None:
            group = ShiftedBasins(self.basins, shift, face)
            rank = self.rank[self.candidates(shift, bound)]
            if rank.size:  # the slab of stones from the first candidate to the last
                lo, hi = int(rank.min()), int(rank.max()) + 1
                ks = self.by_x[lo:hi]
                a, b = self.sample_start[lo], self.sample_start[hi]
                counts = np.diff(self.sample_start[lo : hi + 1])
                slab = self._mapped(ks, [v[a:b] for v in self.samples], counts, shift, group, bound)
                for i in np.argsort(ks, kind="stable").tolist():  # the road's order
                    if slab[i] is not None:
                        out.append(slab[i])
                        numbers.append(int(ks[i]))
        else:
            for k in self.candidates(shift, bound):
                stone = self._tip(self.tips[k], shift, face)
                if stone is not None and stone.z < bound:
                    out.append(stone)
                    numbers.append(int(k))
        return Selection(tuple(out), np.array(numbers, dtype=np.int64), float(shift))

    def map_stones(self, ks, shift: float, group: ShiftedBasins) -> list:
        """Basins ``ks`` at ``shift`` (:meth:`_mapped`)."""
        ks = np.asarray(ks, dtype=np.int64)
        r = self.rank[ks]
        parts = [np.arange(self.sample_start[i], self.sample_start[i + 1]) for i in r.tolist()]
        flat = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        counts = self.sample_start[r + 1] - self.sample_start[r]
        return self._mapped(ks, [v[flat] for v in self.samples], counts, shift, group, np.inf)

    def _mapped(self, ks, samples: list, counts: np.ndarray, shift: float, group: ShiftedBasins, bound: float) -> list:
        """Basins ``ks`` (their ``samples`` x, y, recess one after the other, ``counts`` each)
        at ``shift`` (:class:`RolledStone`: summit, recess and the samples of recess + face
        for the reach), None for one with no sample in the face's window or whose summit
        is not below ``bound``. All the basins' samples in one pass (a loop over the ~500
        stones within reach of a tyre cost ~20 ms a position)."""
        if not len(ks):
            return []
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        x, y = samples[0], samples[1]  # (on the road: the distances below do not depend on the shift)
        rec = samples[2] + self._face_at(shift)[samples[3]]
        low = np.minimum.reduceat(rec, starts)
        keep = (low < bound) & np.isfinite(low)
        if not keep.any():
            return [None] * len(keep)
        # the passes over every stone of the slab, the few that cannot touch with no summit
        # (their fall nan): cheaper than taking the others' samples out (~1.8 ms); in place
        # (~250,000 samples a tyre's position: fresh temporaries cost ~1 of ~5 ms)
        fall = np.repeat(np.where(keep, low, np.nan), counts)
        np.subtract(rec, fall, out=fall)
        # each basin's first sample at its lowest recess (np.argmin's choice on the basin)
        first = np.flatnonzero(fall == 0.0)
        top = first[np.unique(np.searchsorted(starts, first, side="right"), return_index=True)[1]]
        xt, yt = np.zeros((2, len(keep)))
        xt[keep], yt[keep] = x[top], y[top]
        r, dy = np.subtract(x, np.repeat(xt, counts)), np.subtract(y, np.repeat(yt, counts))
        r *= r
        dy *= dy
        r += dy
        np.sqrt(r, out=r)  # (np.hypot: ~40 ns a sample, 10 of the pass's 25 ms)
        extent = np.maximum.reduceat(np.where(np.isfinite(rec), r, -np.inf), starts)
        xt[keep] += shift
        ks, low, counts, starts = np.asarray(ks)[keep], low[keep], counts[keep], starts[keep]
        xt, yt, extent = xt[keep], yt[keep], extent[keep]
        ends = (starts + counts).tolist()
        made = []
        columns = zip(np.asarray(ks).tolist(), xt.tolist(), yt.tolist(), low.tolist(), extent.tolist())
        for (k, x0, y0, z, reach), a, b in zip(columns, starts.tolist(), ends):
            base = self.tips[k]
            fields = (x0, y0, z, base.R, "map", group, base.label, reach)
            made.append(RolledStone.of(*fields, fall[a:b], r[a:b]))
        out: list = [None] * len(keep)
        for i, stone in zip(np.flatnonzero(keep).tolist(), made):
            out[i] = stone
        return out

    def _face_at(self, shift: float) -> np.ndarray:
        """:meth:`Face.height` of the strip's sample columns at ``shift`` and ``inf`` last
        (samples outside the window across y): a look-up, not ten passes over the samples."""
        out = np.full(len(self.columns) + 1, np.inf)
        out[:-1] = self.face.height(self.columns + shift, self.window[2])
        return out

    def _tip(self, a: Asperity, shift: float, face: Face) -> ShiftedTip | None:
        """A sphere or paraboloid at ``shift``: on the face's tilt g its lowest point moves
        by -g R along x and sinks by g^2 R / 2 (first order in g). None when its centre is
        outside the face's window: such a tip does not touch (as a static study's tips
        outside the footprint), though its box may overlap the window."""
        xb = a.x + shift
        g = face.slope(xb)
        dx = -g * a.R if abs(g) < 0.5 else 0.0
        z = a.z + float(face.height(np.array(xb), np.array(a.y))) - 0.5 * g * g * a.R * (abs(g) < 0.5)
        if not math.isfinite(z):
            return None
        return ShiftedTip(xb + dx, a.y, z, a.R, a.shape, base=a, shift=shift, face=face)

    def road_slope(self, selection: Selection, X, Y, owner) -> np.ndarray:
        """x-slope of the road's recess (mm/mm) at body points (X, Y) owned by the
        selection's stones (``owner``: 0-based index into ``selection.stones``, -1 none)."""
        X, Y, owner = np.asarray(X, dtype=float), np.asarray(Y, dtype=float), np.asarray(owner)
        out = np.zeros(X.shape)
        if self.surface is not None:
            g = self.surface.hmap.grid
            i = np.rint((X - selection.shift - g.x0) / g.h).astype(np.int64)
            j = np.rint((Y - g.y0) / g.h).astype(np.int64)
            inside = (owner >= 0) & (i >= 0) & (i < g.nx) & (j >= 0) & (j < g.ny)
            out[inside] = self.slope_x[j[inside], i[inside]]
            return out
        h = 1e-3 * max(min(a.R for a in self.tips), 1e-9)
        for n, stone in enumerate(selection.stones):
            mine = owner == n
            if np.any(mine):
                xb, yb = X[mine] - selection.shift, Y[mine]
                up, down = stone.base.height(xb + h, yb), stone.base.height(xb - h, yb)
                s = (up - down) / (2.0 * h)
                out[mine] = np.where(np.isfinite(s), s, 0.0)
        return out


def _x_slope(recess: np.ndarray, h: float) -> np.ndarray:
    """Central x-differences of the recess (one-sided next to a masked sample or the
    map's end; 0 where a sample has no neighbour)."""
    r = np.asarray(recess, dtype=float)
    left = np.full(r.shape, np.nan)
    right = np.full(r.shape, np.nan)
    left[:, 1:], right[:, :-1] = r[:, :-1], r[:, 1:]
    with np.errstate(invalid="ignore"):
        central = (right - left) / (2.0 * h)
        fwd, back = (right - r) / h, (r - left) / h
    out = np.where(
        np.isfinite(central), central, np.where(np.isfinite(fwd), fwd, np.where(np.isfinite(back), back, 0.0))
    )
    return np.where(np.isfinite(r), out, 0.0)


def stones_surface(grid: Grid, stones) -> Surface:
    """:func:`~twoscale.indenters.surface_on` of ``stones`` on ``grid``: when they are all
    basins of one shifted height map on its lattice, the map's windows themselves (the
    union of a single group is its own sampling: the same arrays without the grid-sized
    fill, comparison and two masked copies, ~2 of ~4 ms on the tyre's window)."""
    group = getattr(stones[0], "group", None) if stones else None
    if group is not None and all(type(s) is RolledStone and s.group is group for s in stones):
        found = group.union_on_grid(grid, {s.label: k for k, s in enumerate(stones)})
        if found is not None:
            return Surface(grid, found[0], found[1], len(stones))
    return surface_on(grid, stones)
