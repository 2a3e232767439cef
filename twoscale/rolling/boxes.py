"""Aligned boxes of a window's cells (sub-grids on its lattice) and fields moved between
them: the rolling window's bookkeeping (:mod:`.window`)."""

from __future__ import annotations

import math

import numpy as np

from ..grid import Grid

#: Cells added before and behind the previous contact's box (along x, the rolling
#: direction: stones enter and leave there) when the cut window is built.
CUT_MARGIN_CELLS = 8
#: Cells added at least beside it (along y: the footprint's sides stay where the face's
#: width puts them; the tyre's 601 loaded rows never moved over 40 mm). The cut's side
#: along y is then the largest with the same zero-padded transform length
#: (:func:`cut_grid`): 608 rows, a transform of 1215, where 8 cells took 625 rows and 1250.
CUT_SIDE_MARGIN_CELLS = 2


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


def fast_grid(grid: Grid) -> Grid:
    """``grid`` grown (about its centre) to sides of 5-smooth lengths: the preconditioner
    transforms the grid itself, and a prime side (Bluestein's FFT) costs as much as the
    zero-padded product."""
    from scipy.fft import next_fast_len

    nx, ny = next_fast_len(grid.nx, real=True), next_fast_len(grid.ny, real=True)
    return Grid(grid.x0 - ((nx - grid.nx) // 2) * grid.h, grid.y0 - ((ny - grid.ny) // 2) * grid.h, grid.h, nx, ny)


def cut_grid(need: Grid) -> Grid:
    """The cut around ``need`` (a contact's box): :data:`CUT_MARGIN_CELLS` more before and
    behind it, the side along x 5-smooth (:func:`fast_grid`); :data:`CUT_SIDE_MARGIN_CELLS`
    at least beside it, the side along y the largest whose zero-padded transform (``2 n - 1``
    to the next fast length, :class:`~twoscale.influence.convolution.ConvolutionOperator`)
    is that of the side needed: the margin the transform's length leaves costs nothing,
    and a 5-smooth side ``n`` pads to ``2 n``, up to twice the rows' step of a fast length
    (the tyre's 605 rows needed: 625 and 1250, against 608 and 1215, a float32 product
    8 % cheaper). The side itself need not be 5-smooth then (608 = 2^5 19): the CG's
    products are the padded ones, and only the circulant inverse the stones' blocks fall
    back on transforms the cut itself."""
    from scipy.fft import next_fast_len

    nx = next_fast_len(need.nx + 2 * CUT_MARGIN_CELLS, real=True)
    ny = (next_fast_len(2 * (need.ny + 2 * CUT_SIDE_MARGIN_CELLS) - 1, real=True) + 1) // 2
    h = need.h
    return Grid(need.x0 - ((nx - need.nx) // 2) * h, need.y0 - ((ny - need.ny) // 2) * h, h, nx, ny)


def clipped(grid: Grid, domain: tuple | None) -> Grid:
    """The cells of ``grid`` whose centres lie in ``domain`` (x0, x1, y0, y1), mm: a block
    answers only there (the stones' cells lie inside it by the face window's margin);
    ``grid`` itself for no domain (the half-space)."""
    if domain is None:
        return grid
    x0, x1, y0, y1 = domain
    e = 1e-9 * grid.h
    i0, j0 = max(math.ceil((x0 - grid.x0) / grid.h - e), 0), max(math.ceil((y0 - grid.y0) / grid.h - e), 0)
    i1 = min(math.floor((x1 - grid.x0) / grid.h + e) + 1, grid.nx)
    j1 = min(math.floor((y1 - grid.y0) / grid.h + e) + 1, grid.ny)
    if (i0, j0, i1, j1) == (0, 0, grid.nx, grid.ny):
        return grid
    return Grid(grid.x0 + i0 * grid.h, grid.y0 + j0 * grid.h, grid.h, i1 - i0, j1 - j0)
