"""A lower bound of the displacement a pressure makes on a half-space, away from it: the
window's a posteriori check of a solve on a cut (:func:`touching_outside`) keeps the cells
outside the cut off by it, without the window's product, when it suffices.

Love's displacement of a uniformly loaded cell is the mean over the cell of Boussinesq's
``1 / (pi E* r)`` times its force, so a tile of cells (any set of them, in a box) pushes a
point by at least its force over ``pi E*`` times the distance to the box's farthest
point. Summed over the tiles of the pressure's grid, that is a lower bound of the
displacement at every point; a cell whose height minus the approach, plus the bound, is
positive cannot touch (the exact gap is larger). On the tyre's footprint the ~1,000 cells
outside the cut below the approach (by up to 0.9 mm) were kept off by 0.08-0.36 mm with
tiles of 32 cells, the exact gap 0.18-0.48 mm.
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from ..influence import HalfSpace
from ..influence.cached import CachedBody
from .boxes import loaded_box

#: Tile sides (cells) tried in turn: the coarse tiles' bound for every cell, the finer
#: ones' for the cells it left (the cost is the cells times the tiles).
TILE_CELLS = (64, 16)
#: The cut's check screens the cells around it with a float32 product: a cell whose gap is
#: above this fraction of the largest displacement stays off whatever the product's
#: rounding (measured ~1e-7 of it); the others are checked on an exact product.
SCREEN_GAP = 1e-5


def half_space_modulus(provider) -> float | None:
    """``E*`` (MPa) of ``provider`` when it is a half-space (or a solver's caching wrapper of
    one, :class:`~twoscale.influence.cached.CachedBody`), else None (no bound)."""
    body = provider.body if isinstance(provider, CachedBody) else provider
    return float(body.E_star) if isinstance(body, HalfSpace) else None


def lower_displacement(pressure: np.ndarray, grid: Grid, x: np.ndarray, y: np.ndarray, e_star: float, tile: int):
    """At the points ``(x, y)`` (mm), a lower bound of the half-space displacement (mm) made
    by ``pressure`` (MPa, on ``grid``, non-negative), from its tiles of ``tile`` cells."""
    ny, nx = pressure.shape
    gy, gx = -(-ny // tile), -(-nx // tile)
    padded = np.zeros((gy * tile, gx * tile))
    padded[:ny, :nx] = pressure
    force = padded.reshape(gy, tile, gx, tile).sum(axis=(1, 3)) * grid.h**2
    jy, ix = np.nonzero(force > 0.0)
    x0 = grid.x0 + (ix * tile - 0.5) * grid.h  # the tiles' boxes (the cells' edges)
    y0 = grid.y0 + (jy * tile - 0.5) * grid.h
    side = tile * grid.h
    dx = np.maximum(np.abs(x[:, None] - x0), np.abs(x[:, None] - (x0 + side)))
    dy = np.maximum(np.abs(y[:, None] - y0), np.abs(y[:, None] - (y0 + side)))
    return (force[jy, ix] / np.hypot(dx, dy)).sum(axis=1) / (np.pi * e_star)


def kept_off(pressure: np.ndarray, grid: Grid, x: np.ndarray, y: np.ndarray, level: np.ndarray, e_star: float) -> bool:
    """Whether every point ``(x, y)`` whose height less the approach is ``level`` (mm) stays
    off the body under ``pressure`` by the bound (:data:`TILE_CELLS` in turn)."""
    left = np.arange(len(x))
    for tile in TILE_CELLS:
        bound = lower_displacement(pressure, grid, x[left], y[left], e_star, tile)
        left = left[level[left] + bound <= 0.0]
        if not left.size:
            return True
    return False


def touching_outside(body, surface, result, tol: float) -> Grid | None:
    """The a posteriori check of a solve on a cut (``body`` the window's
    :class:`~twoscale.rolling.window.KeptBody`): the displacement its pressure makes on
    the whole window (``surface.grid``), and the box of the cells outside the cut whose
    gap is below ``-tol`` times the cut's largest displacement (the stopping rule's
    interpenetration test), None when there are none. Tried first on a lower bound of the
    lift (:func:`kept_off`), then screened by a float32 product (:data:`SCREEN_GAP`); only a
    window with a cell near contact takes the exact one."""
    f = result.fields[0]
    window = surface.grid
    low = surface.height < result.penetration  # (the cells outside below the approach: inf is not)
    low[f.grid.window_in(window)] = False
    if not np.any(low):
        return None  # no cell outside lies below the approach (the pressure only lifts them)
    e_star = half_space_modulus(body.provider)
    if e_star is not None:  # kept off by a lower bound of the lift?
        rows, cols = np.divmod(np.flatnonzero(low), window.nx)  # (np.nonzero on two axes: ~8x the time)
        x, y = window.x0 + cols * window.h, window.y0 + rows * window.h
        if kept_off(f.pressure, f.grid, x, y, surface.height[rows, cols] - result.penetration, e_star):
            return None
    outside = np.isfinite(surface.height)
    outside[f.grid.window_in(window)] = False
    level = surface.height - result.penetration
    op, p = body.grid_operator(window), f.grid.embed_in(f.pressure, window)
    u = op.single_precision().apply(p)
    scale = max(float(np.abs(u[f.grid.window_in(window)]).max()), np.finfo(float).tiny)
    gap = np.where(outside, u + level, np.inf)
    if float(gap.min()) > SCREEN_GAP * scale:
        return None
    gap = np.where(outside, op.apply(p) + level, np.inf)
    return loaded_box(window, gap < -tol * scale)
