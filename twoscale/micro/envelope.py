"""The lower envelope of thousands of plain spheres and paraboloids on a large box, sampled
in small tiles all at once.

A cell belongs to the asperity lowest over it. A tile of ``ENVELOPE_TILE`` cells a side
needs only the asperities that can be lower than a height the surface is known not to
exceed over it: the highest, over its cells, of the lowest of the ``NEAR_TIPS`` tips
nearest its centre. An asperity of curvature radius ``R`` is at least ``r^2 / (2 R)``
above its tip at distance ``r`` (and a sphere has no material beyond ``R``), so the
candidates of every tile come from one k-d tree query and one test, as
:meth:`~.patches.TipTable.reaching` makes them for one box. Every tile's candidates are
then evaluated on its cells by :func:`~twoscale.indenters.sample_tips`' arithmetic, tiles
of equal candidate counts together: no Python work a tile, so the tiles can be small and
their candidates few. The box's own cell centres are used, as :func:`surface_on` samples
a grid whole: the same heights and owners as every asperity on every cell (on a tie the
earlier index).

CPU s on the union boxes of sweep scenes (the tiles of 64 cells split while their cells
times candidates exceeded 150,000, one Python pass each, against this): 9,110 clustered
spheres, 552 K cells, 0.66-0.72 / 0.16-0.21; 8,492 spheres, 1.04 M cells, 0.67 /
0.25-0.28; 7,881 spheres, 2.9 M cells, 1.1-1.3 / 0.39-0.43; 3,869 clustered spheres,
32 M cells, 3.7-3.9 / 2.9-3.3 (peak 647 against 601 MB, 512 MB of them the surface).
Owners equal, heights within 8e-13 mm (the tiles took their own cell centres,
``x0 + i0 h + i h``).
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from ..indenters import Surface, tip_heights

#: Side of the tiles, cells (8 / 16 / 32 on the three boxes above: 0.16 / 0.21 / 0.41,
#: 0.22-0.28 / 0.25-0.26 / 0.62, 0.47-0.61 / 0.39-0.43 / 0.65 s).
ENVELOPE_TILE = 16
#: Tips nearest a tile's centre that bound the surface's height over it.
NEAR_TIPS = 4
#: Entries (cells times asperities) evaluated at once: about 17 bytes each in flight.
ENVELOPE_CHUNK = 1 << 20
#: Tiles whose candidates are found at once (4,096 tiles of 16 cells: 1 M cells). On the
#: 32 M cells above, all at once: peak 710 MB; by 16,384: 706; by 4,096: 647.
ENVELOPE_GROUP = 4096


def _heights(xs: np.ndarray, ys: np.ndarray, tx, ty, tz, tR, sphere) -> np.ndarray:
    """Heights (t, K, T, T), mm, of the tips (t, K) (``sphere`` (t, K) bool) over the
    tiles' cell centres ``xs``, ``ys`` (t, T) by :func:`~twoscale.indenters.tip_heights`
    (squared distances as the y square plus the x square, as ``sample_tips``)."""
    r2 = ((ys[:, None, :] - ty[:, :, None]) ** 2)[:, :, :, None] + ((xs[:, None, :] - tx[:, :, None]) ** 2)[
        :, :, None, :
    ]
    return tip_heights(r2, tz[:, :, None, None], tR[:, :, None, None], sphere[:, :, None, None])


def _tiles(grid: Grid, T: int, ids: np.ndarray):
    """Tiles ``ids`` of ``T`` x ``T`` cells, numbered row-major: the columns and rows of
    their cells (t, T) (cells past the grid's edge repeat its last cell), their cell centres
    ``xs``, ``ys`` (t, T), mm, and their cells' outer edges ``(xmin, xmax, ymin, ymax)``."""
    nbx = -(-grid.nx // T)
    ix = np.minimum((ids % nbx)[:, None] * T + np.arange(T), grid.nx - 1)
    iy = np.minimum((ids // nbx)[:, None] * T + np.arange(T), grid.ny - 1)
    xs, ys = grid.x[ix], grid.y[iy]
    hh = 0.5 * grid.h
    edges = (xs[:, 0] - hh, xs[:, -1] + hh, ys[:, 0] - hh, ys[:, -1] + hh)
    return ix, iy, xs, ys, edges


def _bounds(table, xs, ys, near: np.ndarray) -> np.ndarray:
    """Per tile, the highest over its cells of the lowest of its ``near`` tips (t, k), mm."""
    out = np.empty(len(near))
    step = max(1, ENVELOPE_CHUNK // (near.shape[1] * xs.shape[1] * ys.shape[1]))
    for a in range(0, len(near), step):
        k = near[a : a + step]
        hk = _heights(xs[a : a + step], ys[a : a + step], *_arrays(table, k))
        out[a : a + step] = hk.min(axis=1).reshape(len(k), -1).max(axis=1)
    return out


def _arrays(table, k: np.ndarray) -> tuple:
    return table.x[k], table.y[k], table.z[k], table.curvature[k], table.spherical[k]


def _candidates(table, tree, edges, below: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(tile, asperity)`` pairs, sorted, of the asperities that can own a cell of each
    tile: :meth:`~.patches.TipTable.reaching` with ``below`` for every tile at once."""
    xmin, xmax, ymin, ymax = edges
    sphere_R = float(np.max(table.R[table.spherical], initial=0.0))
    curv, zmin = float(np.max(table.curvature)), float(np.min(table.z))
    with np.errstate(invalid="ignore"):
        rho = np.where(np.isfinite(below), np.sqrt(2.0 * curv * np.maximum(below - zmin, 0.0)), np.inf)
    reach = np.maximum(np.minimum(sphere_R, rho), rho if np.any(table.parabolic) else 0.0)
    centres = np.column_stack([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)])
    lists = tree.query_ball_point(centres, reach + 0.5 * np.hypot(xmax - xmin, ymax - ymin))
    counts = np.fromiter((len(c) for c in lists), dtype=np.int64, count=len(lists))
    k = np.fromiter((i for c in lists for i in c), dtype=np.int64, count=int(counts.sum()))
    t = np.repeat(np.arange(len(lists)), counts)
    x, y, R, c = table.x[k], table.y[k], table.R[k], table.curvature[k]
    dx = np.maximum(np.maximum(xmin[t] - x, x - xmax[t]), 0.0)
    dy = np.maximum(np.maximum(ymin[t] - y, y - ymax[t]), 0.0)
    r2 = dx * dx + dy * dy
    keep = r2 < R * R  # inf for a paraboloid
    low = np.where(table.parabolic[k], r2 / (2.0 * c), r2 / (c + np.sqrt(np.maximum(c * c - r2, 0.0))))
    keep &= ~(table.z[k] + low >= below[t])
    order = np.lexsort((k[keep], t[keep]))
    return t[keep][order], k[keep][order]


def _evaluate(table, xs, ys, cells, t, k, flat_h, flat_o) -> None:
    """Each tile's candidates (``(t, k)`` pairs, sorted) on its cells (``cells`` (t, T, T),
    flat indices), the lowest into ``flat_h`` and its index into ``flat_o``; tiles of like
    counts together, padded with no tip (height inf)."""
    tile = xs.shape[1]
    count = np.bincount(t, minlength=len(xs))
    first = np.cumsum(count) - count
    tiles = np.argsort(count, kind="stable")
    tiles = tiles[count[tiles] > 0]
    a = 0
    while a < len(tiles):
        ts = tiles[a : a + max(1, ENVELOPE_CHUNK // (tile * tile * int(count[tiles[a]])))]
        ts = ts[: max(1, ENVELOPE_CHUNK // (tile * tile * int(count[ts[-1]])))]
        a += len(ts)
        slot = np.arange(int(count[ts[-1]]))
        valid = slot[None, :] < count[ts][:, None]
        idx = k[np.minimum(first[ts][:, None] + slot, len(k) - 1)]
        x, y, z, R, sphere = _arrays(table, idx)
        hk = _heights(xs[ts], ys[ts], x, y, np.where(valid, z, np.inf), R, sphere)
        best = np.argmin(hk, axis=1)  # the first of equals: the earlier index
        low = np.take_along_axis(hk, best[:, None], axis=1)[:, 0]
        own = np.take_along_axis(idx, best.reshape(len(ts), -1), axis=1).reshape(best.shape)
        own[~(low < np.inf)] = -1
        at = cells[ts].ravel()
        flat_h[at], flat_o[at] = low.ravel(), own.ravel()  # a repeated edge cell: equal values


def envelope_on(grid: Grid, table, *, tile: int = ENVELOPE_TILE) -> Surface:
    """The surface of a :class:`~.patches.TipTable` of plain spheres and paraboloids on
    ``grid`` (mm), by small tiles evaluated all at once (module docstring)."""
    from scipy.spatial import cKDTree

    n = len(table)
    tree = cKDTree(np.column_stack([table.x, table.y]))
    height = np.full(grid.shape, np.inf)  # owning their memory: patches are windows of them
    owner = np.full(grid.shape, -1, dtype=np.int64)
    flat_h, flat_o = height.reshape(-1), owner.reshape(-1)
    tiles = -(-grid.nx // tile) * -(-grid.ny // tile)
    for g in range(0, tiles, ENVELOPE_GROUP):  # memory bounded by a group's tiles and pairs
        ix, iy, xs, ys, edges = _tiles(grid, tile, np.arange(g, min(g + ENVELOPE_GROUP, tiles)))
        centres = np.column_stack([0.5 * (edges[0] + edges[1]), 0.5 * (edges[2] + edges[3])])
        near = np.sort(tree.query(centres, k=min(NEAR_TIPS, n))[1].reshape(len(centres), -1), axis=1)
        t, k = _candidates(table, tree, edges, _bounds(table, xs, ys, near))
        _evaluate(table, xs, ys, iy[:, :, None] * grid.nx + ix[:, None, :], t, k, flat_h, flat_o)
    return Surface(grid, height, owner, n)
