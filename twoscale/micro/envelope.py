"""The lower envelope of thousands of plain spheres and paraboloids on a large box, sampled
in small tiles all at once.

A cell belongs to the asperity lowest over it. A tile of ``ENVELOPE_TILE`` cells a side
needs only the asperities that can be lower than a height the surface is known not to
exceed over it: the highest, over its cells, of the lowest of the ``NEAR_TIPS`` tips
nearest its centre. An asperity of curvature radius ``R`` is at least ``r^2 / (2 R)``
above its tip at distance ``r`` (and a sphere has no material beyond ``R``), so the
candidates of every tile come from one k-d tree query and one test, as
:meth:`~.patches.TipTable.reaching` makes them for one box. The same test on each
sub-tile of ``ENVELOPE_SUBTILE`` cells a side, against the highest there of the lowest
near tip, keeps fewer: tips a micron apart in clusters left 16.6 candidates a cell on
tiles of 16 cells, 2.9 on sub-tiles of 4. Every sub-tile's candidates are then evaluated
on its cells by :func:`~twoscale.indenters.sample_tips`' arithmetic, sub-tiles of like
candidate counts together, one candidate slot at a time over a block of cells small
enough to stay in a core's cache: no Python work a tile, so the tiles can be small and
their candidates few. The box's own cell centres are used, as :func:`surface_on` samples
a grid whole: the same heights and owners as every asperity on every cell (on a tie the
earlier index).

CPU s on the union boxes of sweep scenes (the tiles of 64 cells split while their cells
times candidates exceeded 150,000, one Python pass each, against this): 9,110 clustered
spheres, 552 K cells, 0.66-0.72 / 0.16-0.21; 8,492 spheres, 1.04 M cells, 0.67 /
0.25-0.28; 7,881 spheres, 2.9 M cells, 1.1-1.3 / 0.39-0.43; 3,869 clustered spheres,
32 M cells, 3.7-3.9 / 2.9-3.3 (peak 647 against 601 MB, 512 MB of them the surface).
Owners equal, heights within 8e-13 mm (the tiles took their own cell centres,
``x0 + i0 h + i h``). Tiles evaluated whole (their candidates' heights (t, K, T, T) at
once, 1 M entries a pass, the lowest by ``argmin`` over K) against sub-tiles: 4,437
clustered spheres, 375 K cells, 0.12-0.14 / 0.065-0.076; 8,807 spheres, 973 K cells,
0.20 / 0.14; 1,652 lattice paraboloids, 179 K cells, 0.031-0.034 / 0.019-0.027 (the same
heights and owners to the bit).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..grid import Grid
from ..indenters import Surface, tip_heights

#: Side of the tiles, cells (8 / 16 / 32 on the three boxes above: 0.16 / 0.21 / 0.41,
#: 0.22-0.28 / 0.25-0.26 / 0.62, 0.47-0.61 / 0.39-0.43 / 0.65 s).
ENVELOPE_TILE = 16
#: Tips nearest a tile's centre that bound the surface's height over it.
NEAR_TIPS = 4
#: Side of the sub-tiles each tile's candidates are tested on again, cells (a divisor of
#: the tile's). CPU s, tiles of 16 and sub-tiles of 4 / 8 against 8 / 4, 24 / 8, 32 / 8:
#: the 375 K cells above 0.070 / 0.065 against 0.076, 0.073, 0.085; 1,652 paraboloids
#: 0.021 / 0.019 against 0.026, 0.019, 0.024.
ENVELOPE_SUBTILE = 8
#: Cells evaluated at once (one candidate slot a pass): 32 K / 64 K / 128 K cells, 0.065 /
#: 0.068 / 0.070 s on the 375 K cells above; at 1 M entries a pass the tiles' passes left
#: the cache (0.12 against 0.08 s at 64 K).
ENVELOPE_CELLS = 1 << 16
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


def _upper(table, xs, ys, near: np.ndarray) -> np.ndarray:
    """Per cell of each tile, the lowest of the tile's ``near`` tips (t, k) over it (t, T,
    T), mm: a height the surface does not exceed there."""
    T = xs.shape[1]
    out = np.empty((len(near), T, T))
    step = max(1, ENVELOPE_CELLS // (near.shape[1] * T * T))
    for a in range(0, len(near), step):
        k = near[a : a + step]
        out[a : a + step] = _heights(xs[a : a + step], ys[a : a + step], *_arrays(table, k)).min(axis=1)
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
    lists = tree.query_ball_point(centres, reach + 0.5 * np.hypot(xmax - xmin, ymax - ymin), return_sorted=True)
    counts = np.fromiter((len(c) for c in lists), dtype=np.int64, count=len(lists))
    k = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=int(counts.sum()))
    t = np.repeat(np.arange(len(lists)), counts)
    x, y, R, c = table.x[k], table.y[k], table.R[k], table.curvature[k]
    dx = np.maximum(np.maximum(xmin[t] - x, x - xmax[t]), 0.0)
    dy = np.maximum(np.maximum(ymin[t] - y, y - ymax[t]), 0.0)
    r2 = dx * dx + dy * dy
    keep = r2 < R * R  # inf for a paraboloid
    low = np.where(table.parabolic[k], r2 / (2.0 * c), r2 / (c + np.sqrt(np.maximum(c * c - r2, 0.0))))
    keep &= ~(table.z[k] + low >= below[t])
    return t[keep], k[keep]  # each tile's in increasing order, as the tree lists them


def _refined(table, xs, ys, upper, t, k, sub: int, hh: float) -> tuple[np.ndarray, np.ndarray]:
    """The tiles' candidates ``(t, k)`` (sorted) kept on each sub-tile of ``sub`` cells a
    side where they can be lower than the highest of ``upper`` over it: a sphere or
    paraboloid of curvature radius ``R`` is at least ``r^2 / (2 R)`` above its tip at
    distance ``r`` (the sub-tile's cells' outer edges: ``hh`` half a cell, mm), and a
    sphere has no material from ``R``. Returns ``(idx (S, K), count (S,))``, sub-tile ``s
    = t m^2 + qy m + qx`` (``m = T / sub``) with its candidates, in increasing order,
    ``idx[s, :count[s]]``."""
    nt, T = xs.shape
    m = T // sub
    sx, sy = xs.reshape(nt, m, sub), ys.reshape(nt, m, sub)
    x, y = table.x[k][:, None], table.y[k][:, None]
    dx = np.maximum(np.maximum(sx[t, :, 0] - hh - x, x - sx[t, :, -1] - hh), 0.0)  # (P, qx)
    dy = np.maximum(np.maximum(sy[t, :, 0] - hh - y, y - sy[t, :, -1] - hh), 0.0)
    r2 = (dy * dy).T[:, None, :] + (dx * dx).T[None, :, :]  # (qy, qx, P)
    keep = r2 < table.R[k] ** 2  # inf for a paraboloid
    r2 *= 0.5 / table.curvature[k]
    r2 += table.z[k]
    keep &= r2 < _block_max(upper, sub).transpose(1, 2, 0)[:, :, t]
    keep = keep.reshape(m * m, len(k))
    # a kept pair's slot: its rank among its tile's pairs kept on the same sub-tile
    rank = np.zeros((m * m, len(k) + 1), dtype=np.int64)
    np.cumsum(keep, axis=1, out=rank[:, 1:])
    ends = np.cumsum(np.bincount(t, minlength=nt))
    before = rank[:, ends - np.bincount(t, minlength=nt)]  # (m^2, t): kept before the tile's pairs
    count = (rank[:, ends] - before).T.reshape(-1)
    q, p = np.nonzero(keep)
    idx = np.zeros((nt * m * m, max(int(count.max(initial=0)), 1)), dtype=np.int64)
    idx[t[p] * m * m + q, rank[q, p + 1] - before[q, t[p]] - 1] = k[p]
    return idx, count


def _block_max(a: np.ndarray, sub: int) -> np.ndarray:
    """The highest of ``a`` (t, T, T) over each block of ``sub`` x ``sub`` cells (t, T /
    sub, T / sub)."""
    cols = a[:, :, 0::sub].copy()
    for i in range(1, sub):
        np.maximum(cols, a[:, :, i::sub], out=cols)
    out = cols[:, 0::sub, :].copy()
    for i in range(1, sub):
        np.maximum(out, cols[:, i::sub, :], out=out)
    return out


def _evaluate(table, xs, ys, cells, idx, count, flat_h, flat_o) -> None:
    """Each sub-tile's candidates (``idx``, ``count`` of :func:`_refined`) on its cells
    (``xs``, ``ys`` (S, s) their centres, mm; ``cells`` (S, s, s) their flat indices), the
    lowest into ``flat_h`` and its index into ``flat_o``: sub-tiles of like counts together,
    ``ENVELOPE_CELLS`` cells at a time, one candidate slot at a time over those that have
    it (strictly lower replaces: on a tie the earlier index)."""
    order = np.argsort(count, kind="stable")
    order = order[count[order] > 0]
    sub = xs.shape[1]
    for a in range(0, len(order), max(1, ENVELOPE_CELLS // (sub * sub))):
        ss = order[a : a + max(1, ENVELOPE_CELLS // (sub * sub))]
        c = count[ss]
        kk = idx[ss, : int(c[-1])]
        x, y, z, R, sphere = _arrays(table, kk)
        sx, sy = xs[ss], ys[ss]
        low = np.full((len(ss), sub, sub), np.inf)
        slot = np.zeros((len(ss), sub, sub), dtype=np.int64)
        for j, s in enumerate(np.searchsorted(c, np.arange(kk.shape[1]), side="right").tolist()):
            one = slice(j, j + 1)  # the sub-tiles from s have a slot j
            hj = _heights(sx[s:], sy[s:], x[s:, one], y[s:, one], z[s:, one], R[s:, one], sphere[s:, one])[:, 0]
            better = hj < low[s:]
            np.copyto(low[s:], hj, where=better)
            np.copyto(slot[s:], j, where=better)
        own = np.take_along_axis(kk, slot.reshape(len(ss), -1), axis=1).reshape(slot.shape)
        own[~(low < np.inf)] = -1
        at = cells[ss].ravel()
        flat_h[at], flat_o[at] = low.ravel(), own.ravel()  # a repeated edge cell: equal values


def envelope_on(grid: Grid, table, *, tile: int = ENVELOPE_TILE, sub: int = ENVELOPE_SUBTILE) -> Surface:
    """The surface of a :class:`~.patches.TipTable` of plain spheres and paraboloids on
    ``grid`` (mm), by tiles of ``tile`` cells a side and their sub-tiles of ``sub`` (a
    divisor of ``tile``) evaluated all at once (module docstring)."""
    from scipy.spatial import cKDTree

    if tile < 1 or sub < 1 or tile % sub:
        raise ValueError(f"the sub-tile side must divide the tile's, got {sub} and {tile}")
    n, m = len(table), tile // sub
    tree = cKDTree(np.column_stack([table.x, table.y]))
    height = np.full(grid.shape, np.inf)  # owning their memory: patches are windows of them
    owner = np.full(grid.shape, -1, dtype=np.int64)
    flat_h, flat_o = height.reshape(-1), owner.reshape(-1)
    tiles = -(-grid.nx // tile) * -(-grid.ny // tile)
    for g in range(0, tiles, ENVELOPE_GROUP):  # memory bounded by a group's tiles and pairs
        ix, iy, xs, ys, edges = _tiles(grid, tile, np.arange(g, min(g + ENVELOPE_GROUP, tiles)))
        centres = np.column_stack([0.5 * (edges[0] + edges[1]), 0.5 * (edges[2] + edges[3])])
        near = np.sort(tree.query(centres, k=min(NEAR_TIPS, n))[1].reshape(len(centres), -1), axis=1)
        upper = _upper(table, xs, ys, near)
        t, k = _candidates(table, tree, edges, upper.reshape(len(near), -1).max(axis=1))
        idx, count = _refined(table, xs, ys, upper, t, k, sub, 0.5 * grid.h)
        nt = len(near)
        cells = (iy[:, :, None] * grid.nx + ix[:, None, :]).reshape(nt, m, sub, m, sub).transpose(0, 1, 3, 2, 4)
        sx = np.broadcast_to(xs.reshape(nt, 1, m, sub), (nt, m, m, sub)).reshape(-1, sub)
        sy = np.broadcast_to(ys.reshape(nt, m, 1, sub), (nt, m, m, sub)).reshape(-1, sub)
        _evaluate(table, sx, sy, cells.reshape(-1, sub, sub), idx, count, flat_h, flat_o)
    return Surface(grid, height, owner, n)
