"""Where a position's stones can touch: the grid covering their reach at an approach bound
(:func:`reference_grid`, also the full-grid reference's), the box of their cells below it
(:func:`contact_box`), and whether a grid covers their reach at any bound
(:func:`covers_extents`: the rolling window's test before it samples the stones)."""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from ..indenters import surface_on
from .boxes import covers, loaded_box
from .stones import Selection, reaches
from .track import Track


def reference_grid(track: Track, selection: Selection, bound: float) -> Grid:
    """Cells of ``track.h`` (lattice h Z^2) covering where ``selection``'s stones can touch
    at approaches up to ``bound``, within the face window."""
    z = selection.summits[:, 2]
    return reach_grid(track, selection, reaches(selection.stones, np.maximum(bound - z, 0.0)))


def reach_grid(track: Track, selection: Selection, reach: np.ndarray) -> Grid:
    """:func:`reference_grid` for the stones' ``reach`` (mm) instead of their reach at the bound."""
    h = track.h
    x, y = selection.summits[:, 0], selection.summits[:, 1]
    r = reach * 1.05 + 3.0 * h
    x0, x1, y0, y1 = track.road.window
    lo_x, hi_x = max((x - r).min(), x0 - h), min((x + r).max(), x1 + h)
    lo_y, hi_y = max((y - r).min(), y0 - h), min((y + r).max(), y1 + h)
    return Grid.covering(lo_x, hi_x, lo_y, hi_y, h)


def contact_box(track, selection, bound: float) -> Grid | None:
    """The box of the cells of ``selection``'s stones that lie below ``bound`` (the only
    ones that can touch when the approach is at most ``bound``), on the run's lattice;
    None when no cell is that low."""
    reach = reference_grid(track, selection, bound)
    return low_box(surface_on(reach, selection.stones), bound)


def low_box(surface, bound: float) -> Grid | None:
    low = np.isfinite(surface.height) & (surface.height < bound)
    return loaded_box(surface.grid, low)


def covers_extents(grid: Grid, track: Track, selection: Selection) -> bool:
    """Whether ``grid`` covers :func:`reference_grid` at any bound: its box with each basin's
    extent (its farthest sample from the summit, never less than its reach) for the reach,
    tried first on a bound of the extents (:meth:`~.road.Road.farthest`; on the tyre's
    window it decides: an extent is found when first asked for, and this way none is,
    :class:`~.stones.RolledStone`); False for stones other than basins."""
    if not selection.stones or selection.group is None:
        return False
    if covers(grid, reach_grid(track, selection, track.road.farthest(selection))):
        return True
    return covers(grid, reach_grid(track, selection, np.array([s.extent for s in selection.stones])))
