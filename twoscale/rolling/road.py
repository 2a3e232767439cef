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

import math
from dataclasses import dataclass, field

import numpy as np

from ..indenters import Asperity
from ..scene import Scene
from .spec import RollingSpec
from .stones import RolledStone, Selection, ShiftedBasins, ShiftedTip


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
        if self.surface is None:
            out, numbers = [], []
            for k in self.candidates(shift, bound):
                stone = self._tip(self.tips[k], shift, face)
                if stone is not None and stone.z < bound:
                    out.append(stone)
                    numbers.append(int(k))
            return Selection(tuple(out), np.array(numbers, dtype=np.int64), float(shift))
        group = ShiftedBasins(self.basins, shift, face)
        rank = self.rank[self.candidates(shift, bound)]
        if not rank.size:
            return Selection((), np.zeros(0, dtype=np.int64), float(shift), group=group)
        lo, hi = int(rank.min()), int(rank.max()) + 1  # the slab of stones from the first candidate to the last
        ks = self.by_x[lo:hi]
        a, b = self.sample_start[lo], self.sample_start[hi]
        counts = np.diff(self.sample_start[lo : hi + 1])
        slab, summits = self._mapped(ks, [v[a:b] for v in self.samples], counts, shift, group, bound)
        order = np.argsort(ks, kind="stable")  # the road's order
        order = order[~np.isnan(summits[order, 2])]
        stones = tuple(slab[i] for i in order.tolist())
        return Selection(stones, ks[order].astype(np.int64), float(shift), summits[order], group)

    def farthest(self, selection: Selection) -> np.ndarray:
        """A bound of each basin's extent in ``selection`` (mm): its samples' box's farthest
        corner from its summit (on the tyre's window the bound decides its cover, without
        the extents' passes over the stones' samples); a little more for the rounding of
        the summit moved back to the road."""
        box = self.box[selection.numbers]
        x, y = selection.summits[:, 0] - selection.shift, selection.summits[:, 1]
        dx = np.maximum(np.abs(box[:, 0] - x), np.abs(box[:, 1] - x))
        dy = np.maximum(np.abs(box[:, 2] - y), np.abs(box[:, 3] - y))
        return np.hypot(dx, dy) * (1.0 + 1e-9) + 1e-9

    def map_stones(self, ks, shift: float, group: ShiftedBasins) -> list:
        """Basins ``ks`` at ``shift`` (:meth:`_mapped`)."""
        ks = np.asarray(ks, dtype=np.int64)
        r = self.rank[ks]
        parts = [np.arange(self.sample_start[i], self.sample_start[i + 1]) for i in r.tolist()]
        flat = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        counts = self.sample_start[r + 1] - self.sample_start[r]
        return self._mapped(ks, [v[flat] for v in self.samples], counts, shift, group, np.inf)[0]

    def _mapped(self, ks, samples: list, counts: np.ndarray, shift: float, group: ShiftedBasins, bound: float):
        """Basins ``ks`` (their ``samples`` x, y, recess one after the other, ``counts`` each)
        at ``shift`` (:class:`RolledStone`: summit, recess and the samples of recess + face
        for the reach), None for one with no sample in the face's window or whose summit
        is not below ``bound``, and their summits' ``(x, y, z)`` (body frame, mm; a row
        each, nan for the Nones). All the basins' samples in one pass (a loop over the ~500
        stones within reach of a tyre cost ~20 ms a position)."""
        summits = np.full((len(ks), 3), np.nan)
        if not len(ks):
            return [], summits
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        x, y = samples[0], samples[1]  # (on the road: the distances below do not depend on the shift)
        rec = samples[2] + self._face_at(shift)[samples[3]]
        low = np.minimum.reduceat(rec, starts)
        keep = (low < bound) & np.isfinite(low)
        if not keep.any():
            return [None] * len(keep), summits
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
        ks, low, counts, starts = np.asarray(ks)[keep], low[keep], counts[keep], starts[keep]
        xt, yt = xt[keep], yt[keep]
        summits[keep] = np.column_stack([xt + shift, yt, low])
        ends = (starts + counts).tolist()
        made = []
        # (their distances from the summit and extent when first asked for: RolledStone.lazy)
        columns = zip(ks.tolist(), xt.tolist(), yt.tolist(), low.tolist(), summits[keep, 0].tolist())
        for (k, x0, y0, z, xb), a, b in zip(columns, starts.tolist(), ends):
            base = self.tips[k]
            made.append(
                RolledStone.lazy(
                    (xb, y0, z, base.R, "map", group, base.label, fall[a:b]), (x[a:b], y[a:b], rec[a:b], x0, y0)
                )
            )
        out: list = [None] * len(keep)
        for i, stone in zip(np.flatnonzero(keep).tolist(), made):
            out[i] = stone
        return out, summits

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
