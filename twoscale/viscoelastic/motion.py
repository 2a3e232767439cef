"""What a run of a moving indenter under a viscoelastic body is given: its motion (the
shifts, the speed, the memory grid and the held control: :class:`Motion`) and how it is
solved (:class:`MovingOptions`), and the memory grid swept by tips (:func:`sweep_grid`)."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..control import check_control
from ..grid import Grid
from ..material import Material

MOVING_METHODS = ("twoscale", "reference", "dense", "cg")
STARTS = ("ramp", "relaxed")


@dataclass(frozen=True)
class MovingOptions:
    """How a moving run is solved.

    Parameters
    ----------
    method : {"reference", "twoscale", "dense", "cg"}, default "reference"
        The step solver: the full-grid reference on the memory grid ("reference": dense up
        to 2,000 cells with material, else CG warm-started from the previous pressure moved
        with the indenter), or the two-scale method (tips only; macro step warm-started
        from the previous forces).
    start : {"ramp", "relaxed"}, default "ramp"
        The state before the first position: "ramp", unloaded, pressed to the first position
        over one step's time (so a material far slower than the run answers glassy from the
        first position on, a far faster one relaxed); "relaxed", held at the first position
        long enough to relax (no memory but the relaxed pressure).
    keep_results : bool, default False
        Keep every position's :class:`~twoscale.results.ContactResult` (memory: three grid
        fields per position); otherwise only the figures.
    solver : mapping, default {}
        Options of the step solver (``tol``, ``max_iter`` of the reference; those of
        :func:`twoscale.driver.solve_twoscale`).
    open_edges : bool, default False
        The memory grid is the body's footprint (a tread block's face, a window of the
        half-space under a road): contact may reach its edge. Otherwise pressure on the
        grid's edge means the grid is too small: the position is reported not converged.
    near_gap : float, optional
        With ``method="cg"``: a step's CG runs on the cells within this gap (mm) of the
        indenter at the last position, moved with it, and those loaded at the start
        (``solve_cg(reach=...)``: the other cells checked on the answer, the whole grid
        solved from it if one would touch). None: the whole grid.
    """

    method: str = "reference"
    start: str = "ramp"
    keep_results: bool = False
    solver: Mapping = field(default_factory=dict)
    open_edges: bool = False
    near_gap: float | None = None

    def __post_init__(self) -> None:
        if self.method not in MOVING_METHODS:
            raise ValueError(f"method must be one of {MOVING_METHODS}, got {self.method!r}")
        if self.start not in STARTS:
            raise ValueError(f"start must be one of {STARTS}, got {self.start!r}")


def sweep_grid(
    material: Material, asperities, shifts, h: float, *, penetration=None, total_load=None, grow: float = 1.2
) -> Grid:
    """The memory grid of tips moved over ``shifts`` (mm): the reference grid of the scene at
    its relaxed modulus (every place contact can reach, plus a margin, scaled by ``grow``:
    :func:`twoscale.reference.on_scene.reference_grid`), swept along x from the smallest to
    the largest shift, on the lattice of cell ``h`` through the tips' frame origin."""
    from ..reference.on_scene import reference_grid
    from ..scene import Scene

    scene = Scene(material.relaxed(), tuple(asperities), penetration=penetration, total_load=total_load, h=h)
    g = reference_grid(scene, h, grow=grow)
    x0, x1, y0, y1 = g.bounds
    s = np.asarray(shifts, dtype=float)
    return Grid.covering(x0 + float(s.min()), x1 + float(s.max()), y0, y1, h, anchor=(g.x0, g.y0))


@dataclass(frozen=True)
class Motion:
    """Where the indenter goes, how fast, on which memory grid and under which control.

    Parameters
    ----------
    shifts : sequence of float
        Positions, mm, increasing (any spacing).
    speed : float
        mm/s (1 km/h = 277.8 mm/s): position n is at ``t = (shift_n - shift_0) / speed``.
    grid : Grid
        The memory grid, fixed in the body: it must cover every cell the contact reaches
        (:func:`sweep_grid` for tips; a footprint window for a road under a tyre). The
        reference solves on it; the two-scale patches lie on its lattice.
    penetration, total_load : float
        The control, held over the run: rigid approach (mm) or total load (N); one of them.
    """

    shifts: tuple
    speed: float
    grid: Grid
    penetration: float | None = None
    total_load: float | None = None

    def __post_init__(self) -> None:
        speed = self.speed
        if isinstance(speed, bool) or not isinstance(speed, numbers.Real) or not math.isfinite(speed) or speed <= 0:
            raise ValueError(f"speed must be a finite number > 0 (mm/s), got {speed!r}")
        if not isinstance(self.grid, Grid):
            raise ValueError(f"grid must be a twoscale.grid.Grid (the memory grid), got {type(self.grid).__name__}")
        check_control(self.penetration, self.total_load)
        try:
            s = np.asarray(self.shifts, dtype=float)
        except (TypeError, ValueError):
            s = np.array([np.nan])
        if s.ndim != 1 or s.size < 1 or not np.all(np.isfinite(s)):
            raise ValueError(f"shifts must be a non-empty list of finite numbers (mm), got {self.shifts!r}")
        if np.any(np.diff(s) <= 0):
            k = int(np.argmax(np.diff(s) <= 0)) + 1
            raise ValueError(
                f"shifts must increase (the indenter moves along +x), got shifts[{k}] = {s[k]!r} after {s[k - 1]!r}"
            )
        object.__setattr__(self, "shifts", tuple(s.tolist()))

    @property
    def control(self) -> tuple[str, float]:
        """``("penetration", mm)`` or ``("total", N)``."""
        if self.penetration is not None:
            return "penetration", float(self.penetration)
        return "total", float(self.total_load)


#: The keywords of :class:`Motion` that :func:`solve_moving` still takes with the shifts
#: as its fourth argument.
MOTION_KEYWORDS = ("speed", "grid", "penetration", "total_load")


def motion_of(motion, legacy: dict) -> Motion:
    """``motion`` if it is a :class:`Motion` (and nothing else given), else the Motion the
    shifts ``motion`` and the keywords ``legacy`` describe; refuses a mix or an unknown keyword."""
    if isinstance(motion, Motion):
        if legacy:
            raise ValueError(
                f"give the run as a Motion or as shifts with {', '.join(MOTION_KEYWORDS)}, "
                f"not both (got {sorted(legacy)!r} with a Motion)"
            )
        return motion
    unknown = sorted(set(legacy) - set(MOTION_KEYWORDS))
    if unknown:
        raise TypeError(f"solve_moving() got unexpected keyword arguments {unknown!r}")
    if "speed" not in legacy or "grid" not in legacy:
        raise ValueError("give the run as a Motion(shifts, speed, grid, penetration=... or total_load=...)")
    return Motion(motion, **legacy)
