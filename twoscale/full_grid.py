"""The default route's full-grid solve: the scenes the two-scale method cannot beat on its
own terms, solved as one constrained CG over the reference solver's grid.

Three kinds of scene take that route (:func:`twoscale.resources.full_grid_route`): the
smallest grids (a few tips), untilted tips crowding their grid (a few cells a tip), and a
tilt about a pivot outside the tips. The grid and the iteration are the reference's
(:func:`twoscale.reference.on_scene.solve_reference_scene`, the same tolerance), run with
the settings the union CG uses where they pay (:func:`full_grid_settings`): the reference
itself keeps the plain double-precision CG, the yardstick.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

from .influence.base import InfluenceProvider
from .micro.full_grid_rule import FULL_GRID_CELLS_PER_TIP
from .micro.union import union_precision
from .results import ContactResult
from .scene import Scene

#: Grids of at most this many cells keep the reference's own choice (its dense solver on
#: the cells with material, or its CG): the dense solver's few active-set passes are
#: cheaper there. CPU ms, reference's choice against the preconditioned CG, one process,
#: median of 5 (the sweep's one- to three-tip scenes): 506-576 cells 1.4-2.4 / 3.4-6.5,
#: 806 2.9 / 3.7, 1,221 3.9 / 4.8; 1,406 8.2 / 5.0, 1,444-1,521 13.6-17.0 / 4.2-5.1,
#: 2,304 23.6 / 5.0.
FULL_GRID_DENSE_CELLS = 1_300

#: The prefix of the result's message on this route (the command line's summary reads it).
DEFAULT_ROUTE = "default route: "

#: How the result's message names the reference's own choice.
_SOLVERS = {"dense": "dense active-set solve", "cg": "CG"}


@dataclass(frozen=True)
class FullGridSettings:
    """How the full grid's CG runs: ``solver`` ("auto": the reference's own choice, or
    "cg"), ``precondition`` and ``precision`` (:func:`twoscale.reference.solve_cg`'s)."""

    solver: str
    precondition: bool
    precision: str

    def options(self) -> dict:
        """Keyword arguments of :func:`~twoscale.reference.on_scene.solve_reference_scene`."""
        if self.solver != "cg":
            return {"solver": self.solver}
        return {"solver": "cg", "precondition": self.precondition, "precision": self.precision}

    def describe(self, ran: str | None = None) -> str:
        """One line for the result's message; ``ran``: the solver the reference chose
        ("dense" or "cg"), named after the solve."""
        if self.solver != "cg":
            return "the reference's own solver" + (f" ({_SOLVERS.get(ran, ran)})" if ran else "")
        kind = "preconditioned CG" if self.precondition else "CG"
        return kind + ("" if self.precision == "double" else f" ({self.precision} precision)")


def full_grid_settings(cells: int, tips: int) -> FullGridSettings:
    """The CG's settings on a full grid of ``cells`` cells carrying ``tips`` tips.

    * at most :data:`FULL_GRID_DENSE_CELLS` cells: the reference's own choice;
    * preconditioned (the kernel's inverse on the grid's torus) unless the tips crowd the
      grid (at most ``FULL_GRID_CELLS_PER_TIP`` cells a tip), where contacts of a few cells
      each gain nothing from it. CPU s against the plain CG, one process: one or two tips
      on 2,300-4,500 cells 0.58-0.95 (median 0.70; 11-16 iterations instead of 27-44); 37
      tips on 4,278 cells 0.94; 79 spheres on 12,769 cells 0.55 (28 against 55
      iterations); 4 tilted tips about a pivot outside them on 738,783 cells 0.36 (24
      against 68); 5,220 spheres on 55,696 cells and 7,610 paraboloids on 154,449 (10.7
      and 20.3 cells a tip) 1.13-1.17 with it, 0.65-0.70 without (single-directions);
    * the union CG's precision (:func:`twoscale.micro.union.union_precision`): float32
      search directions from 10,000 cells.
    """
    if cells <= FULL_GRID_DENSE_CELLS:
        return FullGridSettings("auto", False, "double")
    crowded = tips > 0 and cells <= FULL_GRID_CELLS_PER_TIP * tips
    return FullGridSettings("cg", not crowded, union_precision("auto", cells))


def solve_full_grid(
    scene: Scene, provider: InfluenceProvider, h: float, route: str, *, progress: Callable[[str], None] | None = None
) -> ContactResult:
    """``scene`` at cell size ``h`` (mm) solved on the reference's full grid with
    :func:`full_grid_settings`; the result's message names the route and the settings.
    ``progress`` (a status line's callable, as the two-scale driver's) is told the grid
    and the solver before the solve starts."""
    from .reference.on_scene import reference_grid, solve_reference_scene

    cells = int(reference_grid(scene, h).size)
    settings = full_grid_settings(cells, len(scene.asperities))
    if progress is not None:
        progress(f"full grid, {cells:,} cells: {settings.describe()}")
    result = solve_reference_scene(scene, provider, h, **settings.options())
    message = f"{DEFAULT_ROUTE}{route}; {settings.describe(result.solver)}; {result.message}"
    return dataclasses.replace(result, message=message.rstrip("; "))


__all__ = ["DEFAULT_ROUTE", "FULL_GRID_DENSE_CELLS", "FullGridSettings", "full_grid_settings", "solve_full_grid"]
