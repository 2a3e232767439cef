"""Static solves of one position to measure a rolling run against: the full-grid reference
on every cell the stones can reach, and the default two-scale solve from cold.

Both take the same stones as the run (:meth:`~twoscale.rolling.road.Road.stones_at` at the
position's bound), so they answer the same contact problem: the road at that shift.
"""

from __future__ import annotations

import math

from ..indenters import surface_on
from ..results import ContactResult
from .run import Position, RollingOptions, drag_of, solve_position
from .reach import reference_grid
from .track import Track


def reference_position(track: Track, position: Position, *, tol: float = 1e-8) -> ContactResult:
    """The full-grid reference (:func:`twoscale.reference.solve_reference`, dense or CG by
    size) of the stones ``position`` was solved with; its bound is the run's approach
    (penetration control) or 1.5 times the solved local approach (load control)."""
    from ..reference import solve_reference

    sel, scene = position.selection, track.scene
    low = sel.low
    d = position.result.penetration
    bound = d if track.control == "penetration" else d + 0.5 * max(d - low, track.h)
    grid = reference_grid(track, sel, bound)
    return solve_reference(
        track.provider,
        surface_on(grid, sel.stones),
        penetration=scene.penetration,
        total_load=scene.total_load,
        tol=tol,
    )


def cold_position(track: Track, position: Position, options: RollingOptions | None = None) -> ContactResult:
    """The default two-scale solve of the same stones from cold (no start)."""
    return solve_position(track, position.selection, start=None, options=options or RollingOptions())


def drag_reference(track: Track, position: Position, result: ContactResult) -> float:
    """The drag (N) of another solve of ``position``'s stones (the same cells' slopes)."""
    return drag_of(track, position.selection, result)


def relative(a: float, b: float, scale: float | None = None) -> float:
    """``|a - b| / scale`` (default ``|b|``; 0 when both are 0)."""
    s = abs(b) if scale is None else scale
    return 0.0 if a == b else (abs(a - b) / s if s > 0 else math.inf)
