"""The road's stones at one position as the solvers' indenters: the basins of a height map
shifted and seen through the body's face (:class:`ShiftedBasins`, :class:`RolledStone`),
spheres and paraboloids likewise (:class:`ShiftedTip`), a position's choice of them
(:class:`Selection`: made by :meth:`~twoscale.rolling.road.Road.stones_at`), their reaches
at once and their union sampled on a grid."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..grid import Grid
from ..indenters import Asperity, Surface, surface_on
from ..surface.indenter import MapAsperity

if TYPE_CHECKING:
    from .road import Face


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
    face's window), ``dist`` their distances from its summit there.

    Made by :meth:`~.road.Road.stones_at`, ``dist`` and ``extent`` are found when first asked for
    (:meth:`lazy`): a position's window solve asks for neither (its cover is checked on the
    stones' boxes, :func:`~twoscale.rolling.reach.covers_extents`), and their passes over
    the ~250,000 samples of a tyre's ~500 stones cost ~1.5 of the ~5 ms of
    :meth:`~.road.Road.stones_at`."""

    def __post_init__(self) -> None:
        pass  # made by :meth:`~.road.Road.map_stones` from a checked basin: finite by construction

    @classmethod
    def of(cls, *values) -> "RolledStone":
        """The stone of the fields' ``values`` in their order, as the constructor makes it,
        its fields written at once (the frozen ``__init__`` sets its 10 one by one through
        ``object.__setattr__``: ~4 us a stone against ~1, ~560 stones a tyre's position)."""
        stone = object.__new__(cls)
        stone.__dict__.update(zip(_ROLLED_FIELDS, values))
        return stone

    @classmethod
    def lazy(cls, values: tuple, samples: tuple) -> "RolledStone":
        """:meth:`of` without ``extent`` and ``dist`` (``values``: the fields before them,
        then ``fall``), found from ``samples`` when first asked for: the stone's samples' x,
        y (the road's frame, mm) and recess + face, and its summit's x, y there."""
        stone = object.__new__(cls)
        stone.__dict__.update(zip(_LAZY_FIELDS, values))
        stone.__dict__["_samples"] = samples
        return stone

    @property
    def extent(self) -> float:
        """The farthest of its samples inside the face's window from its summit, mm."""
        if "extent" in self.__dict__:
            return self.__dict__["extent"]
        rec = self.__dict__["_samples"][2]
        found = self.__dict__["extent"] = float(np.max(np.where(np.isfinite(rec), self.dist, -np.inf)))
        return found

    @extent.setter
    def extent(self, value: float) -> None:  # (the dataclass's ``__init__``)
        self.__dict__["extent"] = value

    @property
    def dist(self) -> np.ndarray:
        """Its samples' distances from its summit, mm (``fall``'s order)."""
        if "dist" in self.__dict__:
            return self.__dict__["dist"]
        x, y, _, xt, yt = self.__dict__["_samples"]
        found = np.subtract(x, xt)  # (the passes the slab's took at once: per sample the same)
        dy = np.subtract(y, yt)
        found *= found
        dy *= dy
        found += dy
        np.sqrt(found, out=found)
        self.__dict__["dist"] = found
        return found

    @dist.setter
    def dist(self, value: np.ndarray) -> None:
        self.__dict__["dist"] = value


_ROLLED_FIELDS = tuple(f.name for f in dataclasses.fields(RolledStone))
_LAZY_FIELDS = tuple(f for f in _ROLLED_FIELDS if f not in ("extent", "dist"))


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
    road (0-based: the segmentation's labels, or the scene's tip order); their summits
    ``(x, y, z)`` laid out once (mm, a row each: the per-stone loops of a position read
    them); ``group``: the :class:`ShiftedBasins` all of them are basins of, if so."""

    stones: tuple
    numbers: np.ndarray
    shift: float
    summits: np.ndarray | None = field(default=None, repr=False)
    group: object = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.summits is None:
            xyz = np.array([(s.x, s.y, s.z) for s in self.stones], dtype=float).reshape(-1, 3)
            object.__setattr__(self, "summits", xyz)

    @property
    def low(self) -> float:
        """The lowest summit's recess, mm (``inf`` without stones)."""
        return float(np.min(self.summits[:, 2], initial=np.inf))


def stones_surface(grid: Grid, stones, group=None) -> Surface:
    """:func:`~twoscale.indenters.surface_on` of ``stones`` on ``grid``: when they are all
    basins of one shifted height map on its lattice (``group``, when known: a
    :class:`Selection`'s), the map's windows themselves (the union of a single group is its
    own sampling: the same arrays without the grid-sized fill, comparison and two masked
    copies, ~2 of ~4 ms on the tyre's window)."""
    if group is None:
        group = getattr(stones[0], "group", None) if stones else None
        if group is not None and not all(type(s) is RolledStone and s.group is group for s in stones):
            group = None
    if group is not None:
        found = group.union_on_grid(grid, {s.label: k for k, s in enumerate(stones)})
        if found is not None:
            return Surface(grid, found[0], found[1], len(stones))
    return surface_on(grid, stones)
