"""Aligned boxes of a window's cells (sub-grids on its lattice) and fields moved between
them: the rolling window's bookkeeping (:mod:`.window`)."""

from __future__ import annotations

import numpy as np

from ..grid import Grid


def grown(g: Grid, cells: int) -> Grid:
    """``g`` with ``cells`` more on every side."""
    return Grid(g.x0 - cells * g.h, g.y0 - cells * g.h, g.h, g.nx + 2 * cells, g.ny + 2 * cells)


def loaded_box(grid: Grid, p: np.ndarray) -> Grid | None:
    """The box of the cells of ``grid`` where ``p`` is positive, None where there are none."""
    on = p > 0.0
    rows, cols = np.flatnonzero(on.any(axis=1)), np.flatnonzero(on.any(axis=0))
    if not rows.size:
        return None
    return grid.subgrid(int(cols[0]), int(rows[0]), int(cols[-1] - cols[0] + 1), int(rows[-1] - rows[0] + 1))


def covers(outer: Grid, inner: Grid) -> bool:
    """``outer`` covers ``inner`` (to rounding)."""
    a, b, eps = outer.bounds, inner.bounds, 1e-9 * inner.h
    return a[0] <= b[0] + eps and a[1] >= b[1] - eps and a[2] <= b[2] + eps and a[3] >= b[3] - eps


def union(a: Grid, b: Grid) -> Grid:
    """The aligned box covering both grids."""
    i, j = b.offset_in(a)
    i0, j0 = min(i, 0), min(j, 0)
    return a.subgrid(i0, j0, max(a.nx, i + b.nx) - i0, max(a.ny, j + b.ny) - j0)


def moved(grid: Grid, pressure: np.ndarray, shift: float, target: Grid, to: float) -> np.ndarray:
    """``pressure`` on ``grid`` at ``shift`` moved with the road to shift ``to`` (to the
    nearest cell: exact when the step is a multiple of the cell) and cut to ``target``."""
    h = target.h
    i0 = int(round((grid.x0 + (to - shift) - target.x0) / h))
    j0 = int(round((grid.y0 - target.y0) / h))
    out = np.zeros(target.shape)
    ys, yd = _overlap(j0, grid.ny, target.ny)
    xs, xd = _overlap(i0, grid.nx, target.nx)
    if ys is not None and xs is not None:
        out[yd, xd] = pressure[ys, xs]
    return out


def _overlap(offset: int, n_src: int, n_dst: int):
    lo, hi = max(0, -offset), min(n_src, n_dst - offset)
    if hi <= lo:
        return None, None
    return slice(lo, hi), slice(lo + offset, hi + offset)
