"""Contacts that reach the edge of a height map.

Beyond its edge a map has no surface, so a stone cut by the edge ends there in a vertical
wall: where its contact reaches that wall the pressure is a punch corner's (a new user's
road showed 20.8 MPa on such a stone against 5-7 MPa on whole ones). The solver cannot
know what lies beyond the scan; it says which asperities are concerned, in a warning and
in the result's :class:`~twoscale.details.SurfaceDetails` (:func:`surface_details`).
"""

from __future__ import annotations

import warnings

import numpy as np

from ..details import SurfaceDetails
from ..errors import user_stacklevel
from ..grid import Grid
from .conditioning import SurfaceWarning


def edge_contacts(result, grid: Grid) -> list[int]:
    """0-based indices of the asperities with pressure on the outermost samples of ``grid``
    (the height map's), in increasing order."""
    x_lo, y_lo = grid.x0, grid.y0
    x_hi, y_hi = grid.x0 + (grid.nx - 1) * grid.h, grid.y0 + (grid.ny - 1) * grid.h
    tol = 0.5 * grid.h
    found: set[int] = set()
    for f in result.fields:
        X, Y = f.grid.centres()
        edge = (X < x_lo + tol) | (X > x_hi - tol) | (Y < y_lo + tol) | (Y > y_hi - tol)
        hit = edge & (f.pressure > 0) & (f.owner >= 0)
        found.update(int(k) for k in np.unique(f.owner[hit]))
    return sorted(found)


def surface_details(surface, result) -> SurfaceDetails:
    """The report of a height-map solve: the conditioned map of ``surface`` (a
    :class:`~twoscale.surface.MeasuredSurface`) and the asperities of ``result`` whose
    contact reaches its edge."""
    hm = surface.hmap
    return SurfaceDetails(
        source=hm.source,
        samples=hm.shape,
        spacing=hm.h,
        measured_spacing=hm.measured_spacing,
        units=hm.units,
        units_from=hm.units_from,
        missing=hm.filled,
        fill=surface.options.fill,
        edge_contacts=tuple(edge_contacts(result, hm.grid)),
    )


def warn_edge_contacts(ks, *, show: int = 5) -> None:
    """A :class:`SurfaceWarning` naming (from 1) the asperities ``ks`` (0-based) whose
    contact reaches the map's edge, where the scan ends in a wall and the pressure is a
    punch corner's; nothing when ``ks`` is empty."""
    if ks:
        names = ", ".join(str(k + 1) for k in ks[:show]) + (f" and {len(ks) - show} more" if len(ks) > show else "")
        warnings.warn(
            SurfaceWarning(
                f"the contact of asperit{'y' if len(ks) == 1 else 'ies'} {names} reaches the edge of the height "
                f"map, where the scan ends in a wall: the pressure there is a punch corner's; crop the "
                f"map inward or scan a wider area if those stones matter"
            ),
            stacklevel=user_stacklevel(),
        )
