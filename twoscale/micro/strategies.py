"""The micro step's strategies: an iteration composed with a coupling.

Two orthogonal choices, each a small frozen object (in the spirit of a Krylov method
composed with a preconditioner):

* a **coupling** says how patches act on each other: :class:`Exact` (every pair through
  the provider's operators, :class:`.blocks.Coupling`) or :class:`FarField` (pairs farther
  apart than ``(r_k + r_l) / sqrt(tol)`` through their resultant forces,
  :mod:`.farfield`);
* an **iteration** solves the micro step with a coupling: :class:`BlockGaussSeidel` (the
  paper's eq. 8-9 with sensitivity corrections of the load and tilt), :class:`TwoLevel`
  (block Gauss-Seidel with a coarse correction by the linearised macro equations), or
  :class:`UnionCG` (one constrained CG over the box of the patches; it needs no
  coupling).

Every iteration has ``name`` and ``run(context, coupling, *, max_sweeps, monitor)`` returning
a :class:`~.solve.MicroResult`; :mod:`.driver` composes them in the order the policy gives.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .result import MicroResult
from .solve import EXACT_FAR_TOL, solve_micro
from .union import box_of, solve_union

#: The union CG's KKT residual over the block iterations' tolerance (a relative change of the
#: pressure between sweeps): at the default 1e-6 the CG stops at the reference solver's 1e-8.
UNION_TOL_FACTOR = 1e-2
#: Boxes up to this many cells are solved to ``UNION_SMALL_TOL_FACTOR`` instead (a product
#: costs well under a millisecond there): the answer then no longer depends on the start at
#: the 1e-7 level (a study resumed mid-way, whose macro steps start from other neighbours,
#: gives the same tables to 1e-9, as the block iterations' direct local solves do).
UNION_SMALL_CELLS = 40_000
UNION_SMALL_TOL_FACTOR = 1e-4


@dataclass(frozen=True)
class Exact:
    """Every pair of patches coupled exactly."""

    name: str = "exact"

    @property
    def far_tol(self) -> float | None:
        return None


@dataclass(frozen=True)
class FarField:
    """Patches farther apart than ``(r_k + r_l) / sqrt(tol)`` act through their resultants
    (relative error per far pair about ``tol``, 0 < tol < 1)."""

    tol: float
    name: str = "far field"

    def __post_init__(self) -> None:
        if not (isinstance(self.tol, (int, float)) and 0.0 < self.tol < 1.0):
            raise ValueError(f"far-field tol must be a number in (0, 1), got {self.tol!r}")

    @property
    def far_tol(self) -> float | None:
        return float(self.tol)


@dataclass(frozen=True)
class MicroContext:
    """What every iteration needs: the body, the indenters, the macro result, the patches
    the policy saw (built once: the block iterations start from them, the union CG uses
    their extent), and the options of the micro step (``common``: h, forces, penetration,
    tilt, pivot, total_load, free_tilt, tol and the block options)."""

    provider: object
    asperities: object
    macro: object
    patches: tuple
    common: dict
    p0: bool = False

    @property
    def grids(self) -> tuple:
        return tuple(pt.grid for pt in self.patches)


@dataclass(frozen=True)
class BlockGaussSeidel:
    """The paper's block Gauss-Seidel (eq. 8-9) from eq. 7 over the (merged) patches."""

    name: str = "block-gs"

    def run(self, ctx: MicroContext, coupling, *, max_sweeps: int, monitor: Callable | None = None) -> MicroResult:
        return solve_micro(ctx.provider, ctx.asperities, max_sweeps=max_sweeps, far_tol=coupling.far_tol,
                           coarse=False, sizing_approaches=_sizing(ctx.macro, coupling.far_tol), monitor=monitor,
                           patches=list(ctx.patches), **ctx.common)


@dataclass(frozen=True)
class TwoLevel:
    """Block Gauss-Seidel with a coarse correction (:mod:`.twolevel`), which also moves the
    approach and tilt under load control."""

    name: str = "two-level"

    def run(self, ctx: MicroContext, coupling, *, max_sweeps: int, monitor: Callable | None = None) -> MicroResult:
        far_tol = coupling.far_tol if coupling.far_tol is not None else EXACT_FAR_TOL
        return solve_micro(ctx.provider, ctx.asperities, max_sweeps=max_sweeps, far_tol=far_tol, coarse=True,
                           sizing_approaches=_sizing(ctx.macro, coupling.far_tol), monitor=monitor,
                           patches=list(ctx.patches), **ctx.common)


@dataclass(frozen=True)
class UnionCG:
    """One constrained CG over the box of the patches (:func:`.union.solve_union`)."""

    name: str = "union-cg"
    precision: str = "auto"

    def run(self, ctx: MicroContext, coupling, *, max_sweeps: int, monitor: Callable | None = None) -> MicroResult:
        common = ctx.common
        start = start_grid = None
        if common.get("start") is not None:  # a previous solve's pressure, moved with the tips
            start_grid = box_of(ctx.grids, common["h"], common.get("anchor", (0.0, 0.0)))
            start = common["start"].on_grid(start_grid, ctx.asperities, common["forces"])
            start_grid = start_grid if start is not None else None
        if start is None and ctx.p0:
            from .solve import initial_on_patches

            start_grid, start = initial_on_patches(ctx.provider, ctx.asperities, ctx.patches, common)
        load = common["total_load"]
        anchor = common.get("anchor", (0.0, 0.0))
        small = box_of(ctx.grids, common["h"], anchor).size <= UNION_SMALL_CELLS
        factor = UNION_SMALL_TOL_FACTOR if small else UNION_TOL_FACTOR
        out = solve_union(ctx.provider, ctx.asperities, ctx.grids, h=common["h"],
                          anchor=anchor, penetration=None if load is not None
                          else common["penetration"], total_load=load, free_tilt=common["free_tilt"],
                          pivot=common["pivot"], tol=factor * common["tol"], start=start,
                          start_grid=start_grid, approaches=_approaches(ctx.macro), precision=self.precision,
                          monitor=monitor)
        r, field = out.result, out.result.fields[0]
        converged = bool(r.converged) and not out.on_edge
        message = r.message if not r.converged else (
            f"pressure still reaches the box's edge after {out.enlargements} enlargements" if out.on_edge else "")
        # eq. 7 pressures only where computed (p0=True): none to report otherwise
        initial = (start_grid.embed_in(start, out.patch.grid),) if start is not None else ()
        tilt = r.tilt if common["free_tilt"] else None
        return MicroResult((out.patch,), (field.pressure,), initial, (field.gap,), float(r.penetration), tilt,
                           converged, message, int(out.iterations), 0, int(out.enlargements), 0,
                           tuple(r.residuals.get("gap", ())), {"box": int(out.patch.grid.size),
                                                              "products": int(out.products)},
                           (tuple(out.patch.members),) if len(out.patch.members) > 1 else ())


ITERATIONS = {"union-cg": UnionCG, "block-gs": BlockGaussSeidel, "two-level": TwoLevel}


def _approaches(macro):
    # the macro local approaches place the union CG's start, where the macro step converged
    return np.asarray(macro.local_penetrations, dtype=float) if macro.converged else None


def _sizing(macro, far_tol):
    # patch sizing from the macro local penetrations (far-field coupling only): with
    # thousands of asperities the bulk deflection makes d - z_k > 0 for all
    if far_tol is None or not macro.converged:
        return None
    delta = np.asarray(macro.local_penetrations, dtype=float)
    return delta + 0.2 * max(float(delta.max()), 0.0)
