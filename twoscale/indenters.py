"""Rigid indenters (asperities) and the rigid surface they form on a grid.

The rigid surface is the union of the indenters: at each point the indenter nearest
the body (lowest height) counts, and the cell belongs to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .grid import Grid

SHAPES = ("sphere", "paraboloid")


@dataclass(frozen=True)
class Asperity:
    """One rigid indenter.

    Parameters
    ----------
    x, y : float
        Tip position, mm.
    z : float
        Tip recess, mm: the local approach is ``d - z`` (a larger z touches later).
    R : float
        Radius of curvature at the tip, mm (> 0).
    shape : {"sphere", "paraboloid"}
        ``"sphere"``: exact spherical cap ``z + R - sqrt(R^2 - r^2)`` (no material
        beyond r = R); ``"paraboloid"``: ``z + r^2 / (2R)`` (Hertz's exact setting).
    """

    x: float
    y: float
    z: float
    R: float
    shape: str = "sphere"

    def __post_init__(self) -> None:
        for name in ("x", "y", "z", "R"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"asperity.{name} must be a finite number (mm), got {v!r}")
        if self.R <= 0:
            raise ValueError(f"asperity.R must be > 0 (mm), got {self.R!r}")
        if self.shape not in SHAPES:
            raise ValueError(f"asperity.shape must be one of {SHAPES}, got {self.shape!r}")

    def height(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """Indenter height above the lowest tip level at points (X, Y), mm.
        ``inf`` where the indenter has no material (sphere, r >= R)."""
        r2 = (np.asarray(X) - self.x) ** 2 + (np.asarray(Y) - self.y) ** 2
        if self.shape == "paraboloid":
            return self.z + r2 / (2.0 * self.R)
        R2 = self.R * self.R
        inside = r2 < R2
        # R - sqrt(R^2 - r^2) written as r^2 / (R + sqrt(R^2 - r^2)) to avoid cancellation
        with np.errstate(invalid="ignore"):
            cap = r2 / (self.R + np.sqrt(np.where(inside, R2 - r2, 0.0)))
        return np.where(inside, self.z + cap, np.inf)

    @property
    def material_radius(self) -> float:
        """Distance from the tip (mm) beyond which the indenter has no material: ``R`` for
        a sphere, ``inf`` for a paraboloid (indenters of other kinds override it)."""
        return self.R if self.shape == "sphere" else math.inf

    def reach(self, depth: float) -> float:
        """Radius (mm) within which the indenter is less than ``depth`` above its tip:
        the farthest a contact can extend when the local approach is ``depth``."""
        if depth <= 0:
            return 0.0
        if self.shape == "paraboloid":
            return math.sqrt(2.0 * self.R * depth)
        if depth >= self.R:
            return self.R
        return math.sqrt(depth * (2.0 * self.R - depth))


def tip_positions(asperities: Sequence) -> np.ndarray:
    """The tips' positions ``(x, y)``, (N, 2) mm: each column filled from the tips' numbers.
    (A list of N pairs made N small lists that the garbage collector tracks: on 9,545 tips,
    made eight times a solve, they counted towards its full collections, 50-70 ms each in a
    solver's process.)"""
    xy = np.empty((len(asperities), 2))
    xy[:, 0] = [a.x for a in asperities]
    xy[:, 1] = [a.y for a in asperities]
    return xy


@dataclass(frozen=True)
class Tilt:
    """Small rotation of the indenting surface about a pivot (ball-and-socket joint).

    The surface height becomes ``z(x, y) + beta (x - px) + alpha (y - py)`` (docs/method.md
    section 2): ``alpha`` about x, ``beta`` about y, radians; pivot ``(px, py)`` in mm.
    """

    alpha: float = 0.0
    beta: float = 0.0
    pivot: tuple[float, float] = (0.0, 0.0)

    def height(self, X, Y):
        return self.beta * (np.asarray(X) - self.pivot[0]) + self.alpha * (np.asarray(Y) - self.pivot[1])


@dataclass(frozen=True)
class Surface:
    """Rigid surface sampled at the cell centres of a grid.

    Attributes
    ----------
    grid : Grid
    height : (ny, nx) array, mm; ``inf`` where no indenter has material.
    owner : (ny, nx) int array; index of the indenter nearest the body, -1 if none.
    n_asperities : int
        Number of indenters in the scene (some may own no cell).
    """

    grid: Grid
    height: np.ndarray
    owner: np.ndarray
    n_asperities: int


def _window(grid: Grid, x: float, y: float, radius: float):
    """The slices of ``grid`` holding every cell centre within ``radius`` of (x, y) (the
    whole grid when the radius is infinite), or None when no cell is that close."""
    if not math.isfinite(radius):
        return (slice(None), slice(None))
    i0 = max(int(math.floor((x - radius - grid.x0) / grid.h)), 0)
    i1 = min(int(math.ceil((x + radius - grid.x0) / grid.h)) + 1, grid.nx)
    j0 = max(int(math.floor((y - radius - grid.y0) / grid.h)), 0)
    j1 = min(int(math.ceil((y + radius - grid.y0) / grid.h)) + 1, grid.ny)
    if i0 >= i1 or j0 >= j1:
        return None
    return (slice(j0, j1), slice(i0, i1))


#: Entries (cells times asperities, 8 MB of heights) that :func:`surface_on` samples at once.
SAMPLE_BATCH = 1 << 20
#: Fewest asperities per batch for which :func:`surface_on` samples them together: below,
#: the grid is large and each sphere's own window of cells is cheaper.
SAMPLE_MIN_BATCH = 8


def sampled_in_batches(grid: Grid) -> bool:
    """Whether :func:`surface_on` samples plain asperities on ``grid`` together, in batches
    of ``SAMPLE_BATCH // grid.size`` (at least :data:`SAMPLE_MIN_BATCH`), rather than each on
    its own window."""
    return SAMPLE_BATCH // grid.size >= SAMPLE_MIN_BATCH


def _sample_batch(X: np.ndarray, Y: np.ndarray, batch: list, height: np.ndarray, owner: np.ndarray) -> None:
    """Plain spheres and paraboloids ``batch`` (pairs (index, Asperity)) sampled on every
    cell at once (:func:`sample_tips`), into ``height`` and ``owner`` where lower (on a tie
    the earlier index keeps the cell, as one by one): a patch of a few hundred cells that
    300 spheres can reach cost 300 calls of ``Asperity.height`` each (1,277 touching
    spheres: 67 of the solve's 83 s of CPU)."""
    index = np.array([k for k, _ in batch], dtype=np.int64)
    x, y, z, R = (np.array([getattr(a, f) for _, a in batch], dtype=float) for f in "xyzR")
    sphere = np.array([a.shape == "sphere" for _, a in batch])
    sample_tips(X[0], Y[:, 0], TipArrays(index, x, y, z, R, sphere), height, owner)


@dataclass(frozen=True)
class TipArrays:
    """Plain spheres and paraboloids as arrays (N,): their ``index`` in the scene, tip
    ``x``, ``y``, ``z`` and curvature radius ``R`` (mm), and which are spheres."""

    index: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    R: np.ndarray
    sphere: np.ndarray


def tip_heights(r2: np.ndarray, z: np.ndarray, R: np.ndarray, sphere: np.ndarray) -> np.ndarray:
    """Heights (mm) of plain tips at squared distances ``r2`` from them (overwritten), by
    :meth:`Asperity.height`'s arithmetic: ``z`` plus a sphere's cap ``r^2 / (R + sqrt(R^2 -
    r^2))`` (inf outside it; no cancellation) or a paraboloid's ``r^2 / (2 R)``. ``z``,
    ``R`` and ``sphere`` (bool) broadcast against ``r2``; a batch of one shape skips the
    other's formula."""
    hk = None
    if sphere.any():
        R2 = R * R
        outside = r2 >= R2
        cut = bool(outside.any())  # (none: two masked passes fewer)
        hk = R2 - r2
        if cut:
            hk[outside] = 0.0
        np.sqrt(hk, out=hk)
        hk += R
        np.divide(r2, hk, out=hk)
        hk += z
        if cut:
            hk[outside] = np.inf
    if not sphere.all():
        par = np.divide(r2, 2.0 * R, out=r2)
        par += z
        hk = par if hk is None else np.where(sphere, hk, par)
    return hk


def sample_tips(xs: np.ndarray, ys: np.ndarray, tips: TipArrays, height: np.ndarray, owner: np.ndarray) -> None:
    """``tips`` sampled at once at the cell centres of a grid (axes ``xs`` (nx,) and ``ys``
    (ny,), mm), by the arithmetic of :meth:`Asperity.height`, into ``height`` (mm) and
    ``owner`` (the tips' ``index``), both (ny, nx), where lower; on a tie the earlier tip
    keeps the cell, and ``height`` keeps it from a tip before this call. The squared
    distances are sums of per-axis squares (a pass less over the tips times the cells),
    and a batch of one shape skips the other's formula (the 560 K cells of 6,933
    spheres' union box: 0.96 against 1.4 s)."""
    x, y, z, R = (v[:, None] for v in (tips.x, tips.y, tips.z, tips.R))
    n = len(tips.index)
    r2 = ((ys[None, :] - y) ** 2)[:, :, None] + ((xs[None, :] - x) ** 2)[:, None, :]
    hk = tip_heights(r2.reshape(n, -1), z, R, tips.sphere[:, None])
    first = np.argmin(hk, axis=0)
    low = hk[first, np.arange(hk.shape[1])]
    flat_h, flat_o = height.reshape(-1), owner.reshape(-1)
    better = low < flat_h
    flat_h[better] = low[better]
    flat_o[better] = tips.index[first[better]]


#: Mean window (cells) up to which :func:`_sample_windows` takes plain spheres all at once:
#: there Python's cost per sphere dominates (held-out #185: 8,772 windows of about 123 cells,
#: 0.20-0.26 s one by one, 0.09-0.11 s at once); larger windows cost more at once than one
#: by one (#35: 2,847 windows of about 1,900 cells, 0.15 against 1.3-1.6 s).
WINDOWS_AT_ONCE_CELLS = 256


def _sample_windows(grid: Grid, X, Y, asperities: Sequence, indices, height: np.ndarray, owner: np.ndarray) -> None:
    """The asperities ``indices`` one by one into ``height`` and ``owner`` where lower (the
    earlier keeps a tie), each on the window of its material radius (a sphere: R; the
    whole grid without one); ``X``, ``Y`` the grid's cell centres. Plain spheres with small
    windows all at once (:func:`_sphere_windows`, :data:`WINDOWS_AT_ONCE_CELLS`)."""
    indices = list(indices)
    if (
        len(indices) > 1
        and height.flags.c_contiguous
        and owner.flags.c_contiguous
        and all(type(asperities[k]) is Asperity and asperities[k].shape == "sphere" for k in indices)
    ):
        x, y, z, R = (np.array([getattr(asperities[k], f) for k in indices], dtype=float) for f in "xyzR")
        if float(np.mean((2.0 * R / grid.h + 2.0) ** 2)) <= WINDOWS_AT_ONCE_CELLS:
            index = np.array(indices, dtype=np.int64)
            _sphere_windows(grid, X, Y, TipArrays(index, x, y, z, R, np.ones(len(index), bool)), height, owner)
            return
    for k in indices:
        a = asperities[k]
        win = _window(grid, a.x, a.y, getattr(a, "material_radius", math.inf))
        if win is None:
            continue
        hk = a.height(X[win], Y[win])
        better = hk < height[win]
        height[win][better] = hk[better]
        owner[win][better] = k


def _sphere_windows(grid: Grid, X, Y, tips: TipArrays, height: np.ndarray, owner: np.ndarray) -> None:
    """:func:`_sample_windows` of spheres ``tips`` at once: every sphere's window of cells
    (:func:`_window`'s bounds, as arrays) as one flat list of (sphere, cell) entries, the
    heights by :meth:`Asperity.height`'s arithmetic, and per cell the lowest (on a tie the
    earlier sphere, and ``height``'s own value before either) by two ``ufunc.at`` passes.
    The same heights and owners to the bit; 8,772 spheres one by one cost 0.2-0.3 s of
    Python, most of a lattice's patches."""
    h, x, y, R = grid.h, tips.x, tips.y, tips.R
    i0 = np.maximum(np.floor((x - R - grid.x0) / h).astype(np.int64), 0)
    i1 = np.minimum(np.ceil((x + R - grid.x0) / h).astype(np.int64) + 1, grid.nx)
    j0 = np.maximum(np.floor((y - R - grid.y0) / h).astype(np.int64), 0)
    j1 = np.minimum(np.ceil((y + R - grid.y0) / h).astype(np.int64) + 1, grid.ny)
    cx, cy = np.maximum(i1 - i0, 0), np.maximum(j1 - j0, 0)
    n = cx * cy
    k = np.repeat(np.arange(len(n)), n)
    dj, di = np.divmod(np.arange(k.size) - np.repeat(np.cumsum(n) - n, n), cx[k])
    cell = (j0[k] + dj) * grid.nx + (i0[k] + di)
    r2 = (X.ravel()[cell] - x[k]) ** 2 + (Y.ravel()[cell] - y[k]) ** 2
    Rk = R[k]
    R2 = Rk * Rk
    inside = r2 < R2
    with np.errstate(invalid="ignore"):
        cap = r2 / (Rk + np.sqrt(np.where(inside, R2 - r2, 0.0)))
    hk = np.where(inside, tips.z[k] + cap, np.inf)
    flat_h, flat_o = height.reshape(-1), owner.reshape(-1)
    best = np.full(grid.size, np.inf)
    np.minimum.at(best, cell, hk)
    win = (hk == best[cell]) & (hk < flat_h[cell])
    first = np.full(grid.size, len(n), dtype=np.int64)
    np.minimum.at(first, cell[win], k[win])
    hit = np.flatnonzero(first < len(n))
    flat_h[hit] = best[hit]
    flat_o[hit] = tips.index[first[hit]]


def window_cells(grid: Grid, asperities: Sequence) -> float:
    """The cells :func:`surface_by_windows` evaluates: each asperity's window of its
    material radius (inf when one has none)."""
    r = np.array([getattr(a, "material_radius", math.inf) for a in asperities], dtype=float)
    side = np.minimum(2.0 * r / grid.h + 2.0, float(max(grid.nx, grid.ny)))
    return float(np.sum(side * side))


def surface_by_windows(grid: Grid, asperities: Sequence) -> Surface:
    """:func:`surface_on` of plain asperities sampled one by one, each on the window of its
    material radius only, whatever the grid's size (:func:`surface_on` samples them all on
    every cell of a small grid)."""
    X, Y = grid.centres()
    height = np.full(grid.shape, np.inf)
    owner = np.full(grid.shape, -1, dtype=np.int64)
    _sample_windows(grid, X, Y, asperities, range(len(asperities)), height, owner)
    return Surface(grid, height, owner, len(asperities))


def surface_on(grid: Grid, asperities: Sequence[Asperity], tilt: Tilt | None = None) -> Surface:
    """Sample the union of ``asperities`` (optionally tilted) at the cell centres.

    Asperities with a ``group`` attribute (e.g. the basins of one height map) are sampled
    together by ``group.union_on(X, Y, {label: index})``, which returns the height and the
    owning index of each point; ``label`` is the asperity's ``label`` attribute."""
    groups: dict = {}
    singles = []
    for k, a in enumerate(asperities):
        group = getattr(a, "group", None)
        if group is not None:  # sampled together (the basins of one height map: one look-up)
            groups.setdefault(id(group), (group, {}))[1][a.label] = k
        else:
            singles.append(k)
    if tilt is None and not singles and len(groups) == 1:
        alone = _one_group_on_grid(grid, *next(iter(groups.values())))
        if alone is not None:
            return Surface(grid, *alone, len(asperities))
    X, Y = grid.centres()
    height = np.full(grid.shape, np.inf)
    owner = np.full(grid.shape, -1, dtype=np.int64)
    batch = SAMPLE_BATCH // grid.size
    if sampled_in_batches(grid) and all(type(asperities[k]) is Asperity for k in singles):
        for b in range(0, len(singles), batch):
            _sample_batch(X, Y, [(k, asperities[k]) for k in singles[b : b + batch]], height, owner)
        singles = []
    _sample_windows(grid, X, Y, asperities, singles, height, owner)
    for group, index in groups.values():
        on_grid = getattr(group, "union_on_grid", None)
        sampled = None if on_grid is None else on_grid(grid, index)
        hk, ok = group.union_on(X, Y, index) if sampled is None else sampled
        better = hk < height  # (copied where better: masked assignments cost ~3x on 240,000 cells)
        np.copyto(height, hk, where=better, casting="unsafe")  # (as an assignment casts)
        np.copyto(owner, ok, where=better, casting="unsafe")
    if tilt is not None:
        height = height + tilt.height(X, Y)
    return Surface(grid, height, owner, len(asperities))


def _one_group_on_grid(grid: Grid, group, index: dict):
    """The height and owner :func:`surface_on` gives for one group alone, taken as they
    come from its ``union_on_grid`` (None where it has none, or for another grid): no
    grid-sized arrays to merge them into, nor the cell centres (a height map's union box
    of 700 x 700 cells: four such arrays, ~16 ms of fresh pages in a new process)."""
    on_grid = getattr(group, "union_on_grid", None)
    sampled = None if on_grid is None else on_grid(grid, index)
    if sampled is None:
        return None
    height, owner = sampled
    if height.dtype != np.float64 or owner.dtype != np.int64:
        return None
    outside = ~(height < np.inf)  # as merged into inf: no material, no owner
    height[outside] = np.inf
    owner[outside] = -1
    return height, owner
