"""The measured surface as indenters: one asperity per watershed basin, whose rigid
surface is the height map itself on the basin's samples.

:class:`MapAsperity` keeps the contract of :class:`twoscale.indenters.Asperity` that the
solvers use: a tip ``(x, y)`` at the summit, its recess ``z`` below the highest summit,
a curvature radius ``R`` (the equivalent sphere: patch-size and eq. 7 estimates only),
``height(X, Y)`` (the map's recess on the basin's samples, ``inf`` elsewhere: no
material), ``reach(depth)`` (farthest basin sample less than ``depth`` below the summit)
and ``material_radius`` (farthest basin sample). The union of all asperities
(:func:`twoscale.indenters.surface_on`) is then the height map with each sample owned
by its basin, so patches, the policy, the block iterations and the reference solver run
on the true heights unchanged.

Heights are looked up at the nearest sample: on a grid whose cell centres are the map's
samples (the scene's lattice, :mod:`.conditioning`) that is exact.
"""

from __future__ import annotations

import functools

import math
from dataclasses import dataclass, field

import numpy as np

from ..grid import Grid
from ..indenters import Asperity
from .heightmap import HeightMap
from .segmentation import Segmentation
from .sphere_fit import CAP_DEPTH, basin_order, fit_spheres


@dataclass(frozen=True, eq=False)
class BasinMap:
    """The lattice, the recess below the highest summit (mm; ``inf`` where masked) and
    the basin of every sample, shared by the asperities of one surface."""

    grid: Grid
    recess: np.ndarray
    labels: np.ndarray
    book: object = None

    def _nearest(self, X, Y):
        """Index of the nearest sample of each point, and whether it is on the map."""
        g = self.grid
        i = np.rint((np.asarray(X, dtype=float) - g.x0) / g.h).astype(np.int64)
        j = np.rint((np.asarray(Y, dtype=float) - g.y0) / g.h).astype(np.int64)
        inside = (i >= 0) & (i < g.nx) & (j >= 0) & (j < g.ny)
        return np.clip(j, 0, g.ny - 1), np.clip(i, 0, g.nx - 1), inside

    def lookup(self, X, Y, label: int) -> np.ndarray:
        """Recess at the nearest samples of points (X, Y) that lie in basin ``label``,
        ``inf`` elsewhere (outside the basin or the map), mm."""
        jc, ic, inside = self._nearest(X, Y)
        mine = inside & (self.labels[jc, ic] == label)
        return np.where(mine, self.recess[jc, ic], np.inf)

    @functools.cached_property
    def n_labels(self) -> int:
        """Basins on the map (labels run from 0), found once, not on every look-up."""
        return int(self.labels.max()) + 1

    def _owners(self, index: dict) -> np.ndarray:
        table = np.full(self.n_labels, -1, dtype=np.int64)
        table[np.fromiter(index.keys(), dtype=np.int64)] = np.fromiter(index.values(), dtype=np.int64)
        return table

    def union_on(self, X, Y, index: dict):
        """Recess (mm; ``inf`` off the map or in basins not in ``index``) and owner (the
        value ``index[label]`` of the sample's basin, -1 there) at points (X, Y)."""
        jc, ic, inside = self._nearest(X, Y)
        owner = np.where(inside, self._owners(index)[self.labels[jc, ic]], -1)
        return np.where(owner >= 0, self.recess[jc, ic], np.inf), owner

    def union_on_grid(self, grid: Grid, index: dict):
        """:meth:`union_on` at the cell centres of ``grid`` when they are samples of the
        map's lattice (its spacing, a whole number of cells away): windows of the map
        instead of a look-up per point (a union box of 10^6 cells: 0.2 s of CPU).
        None for any other grid."""
        g = self.grid
        if not math.isclose(grid.h, g.h, rel_tol=1e-12):
            return None
        di, dj = (grid.x0 - g.x0) / g.h, (grid.y0 - g.y0) / g.h
        i0, j0 = round(di), round(dj)
        if abs(di - i0) > 1e-9 or abs(dj - j0) > 1e-9:
            return None
        a0, a1 = max(j0, 0), min(j0 + grid.ny, g.ny)
        b0, b1 = max(i0, 0), min(i0 + grid.nx, g.nx)
        if (a1 - a0, b1 - b0) == grid.shape:  # the grid within the map: its window alone
            owner = self._owners(index)[self.labels[a0:a1, b0:b1]]
            return np.where(owner >= 0, self.recess[a0:a1, b0:b1], np.inf), owner
        height = np.full(grid.shape, np.inf)
        owner = np.full(grid.shape, -1, dtype=np.int64)
        if a1 > a0 and b1 > b0:
            window = (slice(a0 - j0, a1 - j0), slice(b0 - i0, b1 - i0))
            mine = self._owners(index)[self.labels[a0:a1, b0:b1]]
            owner[window] = mine
            height[window] = np.where(mine >= 0, self.recess[a0:a1, b0:b1], np.inf)
        return height, owner


@dataclass(frozen=True, eq=False)
class MapAsperity(Asperity):
    """One basin of a height map as an indenter; see the module docstring.

    Extra attributes: ``basins`` (the shared :class:`BasinMap`), ``label`` (its basin),
    ``extent`` (farthest basin sample from the tip, mm), and for the reach the basin's
    measured samples' depths below the summit ``fall`` and distances from it ``dist`` (mm,
    raster order, unsorted: a reach is one pass over them, where a sorted table cost a
    sort of every basin, ~25 ms on 700 x 700 samples, for one or two reaches a solve).
    """

    shape: str = "map"
    basins: BasinMap | None = field(default=None, repr=False)
    label: int = -1
    extent: float = 0.0
    fall: np.ndarray | None = field(default=None, repr=False)
    dist: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        for name in ("x", "y", "z", "R", "extent"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ValueError(f"map asperity {self.label}: {name} must be finite, got {v!r}")
        if self.R <= 0:
            raise ValueError(f"map asperity {self.label}: R must be > 0 (mm), got {self.R!r}")

    @property
    def group(self) -> BasinMap:
        """Sampled together with the other basins of its map (:func:`twoscale.indenters.surface_on`)."""
        return self.basins

    def height(self, X, Y) -> np.ndarray:
        return self.basins.lookup(X, Y, self.label)

    def reach(self, depth: float) -> float:
        if depth <= 0:
            return 0.0
        within = self.fall < depth
        return float(self.dist[within].max()) if within.any() else 0.0

    def law(self, material):
        """This asperity's load-penetration law on a body of ``material`` (from the
        surface's law book: tabulated from single-asperity solves, or its sphere's)."""
        if self.basins.book is None:
            raise ValueError(f"map asperity {self.label} has no law book (build it with load_surface)")
        return self.basins.book.law(self.label, material)

    @property
    def material_radius(self) -> float:
        return self.extent + self.basins.grid.h


def map_asperities(hmap: HeightMap, seg: Segmentation, *, cap_depth: float = CAP_DEPTH, book=None) -> tuple:
    """One :class:`MapAsperity` per basin of ``seg`` (asperity order), with the equivalent
    sphere of its cap (:func:`twoscale.surface.sphere_fit.fit_spheres`); ``book`` gives
    their laws (:class:`twoscale.surface.measured.LawBook`). Returns
    ``(asperities, sphere_fit)``."""
    top = float(seg.heights.max())
    recess = top - hmap.heights
    recess[np.isnan(recess)] = np.inf
    recess.setflags(write=False)
    basins = BasinMap(hmap.grid, recess, seg.labels, book)
    fit = fit_spheres(hmap, seg, depth=cap_depth)
    X, Y = hmap.grid.centres()
    order, bounds = basin_order(seg)
    # every basin's samples at once: depth below the summit and distance from it (each
    # basin's run of the gathered arrays moved by its summit in place: no repeated copies)
    (j, i), zk = seg.summits.T, top - seg.heights
    x, y = X[j, i], Y[j, i]
    fall, dx, dy = recess.ravel()[order], X.ravel()[order], Y.ravel()[order]
    for k, (a, b) in enumerate(zip(bounds[:-1].tolist(), bounds[1:].tolist())):
        fall[a:b] -= zk[k]
        dx[a:b] -= x[k]
        dy[a:b] -= y[k]
    dist = np.hypot(dx, dy, out=dx)
    extent = np.maximum.reduceat(dist, bounds[:-1]) if len(order) else np.zeros(0)
    ok = np.isfinite(fall)
    if not ok.all():  # (masked samples: not in the reach)
        bounds = np.r_[0, np.cumsum(ok)[bounds[1:] - 1]]
        fall, dist = fall[ok], dist[ok]
    fall.setflags(write=False)
    dist.setflags(write=False)
    out = []
    for k, (a, b) in enumerate(zip(bounds[:-1].tolist(), bounds[1:].tolist())):
        out.append(
            MapAsperity(
                float(x[k]),
                float(y[k]),
                float(zk[k]),
                float(fit.R[k]),
                basins=basins,
                label=k,
                extent=float(extent[k]),
                fall=fall[a:b],
                dist=dist[a:b],
            )
        )
    return tuple(out), fit
