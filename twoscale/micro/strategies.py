"""The micro step's iterations, each a small frozen object composed with a coupling.

Two orthogonal choices (in the spirit of a Krylov method composed with a preconditioner):

* a **coupling** (:mod:`.couplings`) says how patches act on each other and builds the
  engine of the cross-patch products: :class:`~.couplings.Exact` or
  :class:`~.couplings.FarField`;
* an **iteration** solves the micro step with any coupling it accepts (``accepts``, a tuple
  of coupling types): :class:`BlockGaussSeidel` (the paper's eq. 8-9 with sensitivity
  corrections of the load and tilt) and :class:`TwoLevel` (block Gauss-Seidel with a
  coarse correction by the linearised macro equations) take either coupling;
  :class:`UnionCG` (one constrained CG over the box of the patches) accepts none.

Every iteration has ``name``, ``accepts`` and ``run(context, coupling, *, max_sweeps,
monitor)`` returning a :class:`~.result.MicroResult`; the block iterations set up their
blocks (:func:`.setup.block_setup`) and run their loop (:mod:`.block_iterations`) directly.
:mod:`.driver` composes them in the order the policy gives.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np

from ..stopping import StopReason
from .block_iterations import finish, run_block_gauss_seidel, run_two_level
from .couplings import Exact, FarField
from .problem import MicroContext
from .result import MicroResult
from .setup import block_setup, initial_on_patches
from .union import UnionSettings, box_of, carried, solve_union, tilted_box_grids

#: The union CG's KKT residual over the block iterations' tolerance (a relative change of the
#: pressure between sweeps): at the default 1e-6 the CG stops at the reference solver's 1e-8.
UNION_TOL_FACTOR = 1e-2
#: Boxes up to this many cells are solved to ``UNION_SMALL_TOL_FACTOR`` instead (a product
#: costs well under a millisecond there): the answer then no longer depends on the start at
#: the 1e-7 level (a study resumed mid-way, whose macro steps start from other neighbours,
#: gives the same tables to 1e-9, as the block iterations' direct local solves do).
UNION_SMALL_CELLS = 40_000
UNION_SMALL_TOL_FACTOR = 1e-4
#: The union CG's tolerance is never asked below this: its double-precision products' rounding
#: holds the KKT residual at about 1e-12 of the largest displacement (a 12,320-cell box of 12
#: crowded tips stalled at 1.06-1.26e-12 for 1,000 iterations with numpy 2.4 and scipy 1.17
#: when asked for 1e-12, that is ``tol=1e-8`` on a small box).
UNION_MIN_TOL = 1e-11


def _check(iteration, coupling) -> None:
    """Refuse a coupling the iteration does not accept (None where it accepts none)."""
    if iteration.accepts and isinstance(coupling, iteration.accepts):
        return
    if not iteration.accepts and coupling is None:
        return
    wanted = " or ".join(c.__name__ for c in iteration.accepts) or "no coupling"
    raise ValueError(f"the {iteration.name} iteration takes {wanted}, got {coupling!r}")


def _no_patch(setup) -> MicroResult:
    """The result when no asperity reaches the body: the answer under penetration control
    (no contact, no load), a failure under load control (the load asked is not carried)."""
    target = setup.control.target
    load = float(target[0]) if setup.control.n_unknowns and target is not None else 0.0
    reason, message = StopReason.CONVERGED, "no asperity reaches the body"
    if load > 0.0:
        reason = StopReason.FAILED
        message += f" at the approach it started from: the load of {load:.6g} N asked is not carried"
    counts = {"sweeps": 0, "corrections": 0, "growths": 0, "linear_sweeps": 0}
    return finish(setup, [], setup.theta, setup.tilt, reason, message, counts, ())


@dataclass(frozen=True)
class BlockGaussSeidel:
    """The paper's block Gauss-Seidel (eq. 8-9) from eq. 7 over the patches, merged where
    close with exact coupling (``options.merge``)."""

    name: str = "block-gs"
    accepts: ClassVar[tuple] = (Exact, FarField)

    def run(self, ctx: MicroContext, coupling, *, max_sweeps: int, monitor: Callable | None = None) -> MicroResult:
        _check(self, coupling)
        setup = block_setup(
            ctx,
            coupling,
            held=False,
            merge=ctx.options.merge and isinstance(coupling, Exact),
            sizing_approaches=_sizing(ctx, coupling),
        )
        if not setup.state.patches:
            return _no_patch(setup)
        pb = ctx.problem
        return run_block_gauss_seidel(
            setup,
            free_tilt=pb.free_tilt,
            tol=ctx.options.tol,
            max_sweeps=max_sweeps,
            max_growths=ctx.settings.max_growths,
            max_corrections=ctx.settings.max_corrections,
            monitor=monitor,
        )


@dataclass(frozen=True)
class TwoLevel:
    """Block Gauss-Seidel with a coarse correction (:mod:`.twolevel`), which also moves the
    approach and tilt under load control; one block per asperity (the coarse space's
    unknowns are the blocks' resultants), but with far-field coupling one block over the
    asperities whose contacts touch (:mod:`.touching`). ``trial_sweeps``: after that many sweeps it goes on
    only while converging fast (:attr:`~.twolevel.SweepLimits.trial`); None: up to
    ``max_sweeps`` whatever its rate."""

    name: str = "two-level"
    trial_sweeps: int | None = None
    accepts: ClassVar[tuple] = (Exact, FarField)

    def run(self, ctx: MicroContext, coupling, *, max_sweeps: int, monitor: Callable | None = None) -> MicroResult:
        _check(self, coupling)
        setup = block_setup(
            ctx,
            coupling,
            held=True,
            merge=False,
            sizing_approaches=_sizing(ctx, coupling),
            merge_touching=isinstance(coupling, FarField),
        )
        if not setup.state.patches:
            return _no_patch(setup)
        pb = ctx.problem
        if pb.tilt is not None or pb.free_tilt:
            setup = dataclasses.replace(setup, tilt=pb.tilt if pb.tilt is not None else (0.0, 0.0))
        return run_two_level(
            setup,
            tol=ctx.options.tol,
            max_sweeps=max_sweeps,
            max_growths=ctx.settings.max_growths,
            monitor=monitor,
            trial=self.trial_sweeps,
        )


@dataclass(frozen=True)
class UnionCG:
    """One constrained CG over the box of the patches (:func:`.union.solve_union`); it
    couples the patches through the box itself, so it accepts no coupling."""

    name: str = "union-cg"
    precision: str = "auto"
    accepts: ClassVar[tuple] = ()

    def run(self, ctx: MicroContext, coupling=None, *, max_sweeps: int, monitor: Callable | None = None) -> MicroResult:
        """One constrained CG over the patches' box (wider under a free tilt), from a
        previous solve's pressure or eq. 7's when asked; the box grows where pressure
        reaches its edge."""
        _check(self, coupling)
        pb = ctx.problem
        grids = tuple(pt.grid for pt in ctx.patches)
        start = start_grid = None
        if pb.start is not None:  # a previous solve's pressure, moved with the tips
            start_grid = box_of(grids, pb.h, pb.anchor)
            start = pb.start.on_grid(start_grid, ctx.asperities, pb.forces)
            start_grid = start_grid if start is not None else None
        if start is None and ctx.options.p0:
            start_grid, start = initial_on_patches(ctx)
        small = box_of(grids, pb.h, pb.anchor).size <= UNION_SMALL_CELLS
        factor = UNION_SMALL_TOL_FACTOR if small else UNION_TOL_FACTOR
        # under a free tilt the macro step's tilt and forces size the patches short: a wider box
        wide = None
        if pb.free_tilt:
            wide = box_of(
                tilted_box_grids(ctx.patches, ctx.asperities, pb, ctx.provider.material.E_star), pb.h, pb.anchor
            )
        tol = max(factor * ctx.options.tol, UNION_MIN_TOL)
        settings = UnionSettings(tol=tol, precision=self.precision, first_box=wide)
        out = solve_union(
            ctx.provider,
            ctx.asperities,
            ctx.patches,
            pb,
            settings,
            start=None if start is None else (start_grid, start),
            approaches=pb.local_penetrations,
            monitor=monitor,
        )
        r, field = out.result, out.result.fields[0]
        converged = bool(r.converged) and not out.on_edge
        message = (
            r.message
            if not r.converged
            else (f"pressure still reaches the box's edge after {out.enlargements} enlargements" if out.on_edge else "")
        )
        # the CG's own outcome is in its message; an edge still loaded used up the enlargements
        reason = StopReason.CONVERGED if converged else (StopReason.MAX_ITER if r.converged else StopReason.FAILED)
        # eq. 7 pressures only where computed (p0=True): none to report otherwise
        initial = (carried(start, start_grid, out.patch.grid),) if start is not None else ()
        tilt = r.tilt if pb.free_tilt else None
        return MicroResult(
            (out.patch,),
            (field.pressure,),
            initial,
            (field.gap,),
            float(r.penetration),
            tilt,
            converged,
            message,
            int(out.iterations),
            0,
            int(out.enlargements),
            0,
            tuple(r.residuals.get("gap", ())),
            {
                "box": int(out.patch.grid.size),
                "products": int(out.products),
                **{k: int(v) for k, v in r.iterations.items() if k == "precorrected"},
            },
            (tuple(out.patch.members),) if len(out.patch.members) > 1 else (),
            reason,
        )


#: The iteration objects by the names the policy and the caller use.
STRATEGIES = {"union-cg": UnionCG, "block-gs": BlockGaussSeidel, "two-level": TwoLevel}


def _sizing(ctx: MicroContext, coupling):
    """Approaches sizing the patches: the problem's, else with far-field coupling the macro
    local penetrations plus a fifth of the largest (with thousands of asperities the bulk
    deflection makes d - z_k > 0 for all), also those of a macro step stalled far from a
    solution (3,869 clustered spheres: contacts of 6.8 cells from the tip against a reach
    of 22.7 at the geometric approach, 11.5 by this rule), else None (the geometric
    approaches)."""
    pb = ctx.problem
    if pb.sizing_approaches is not None:
        return pb.sizing_approaches
    local = pb.local_penetrations if pb.local_penetrations is not None else pb.sizing_penetrations
    if not isinstance(coupling, FarField) or local is None:
        return None
    delta = np.asarray(local, dtype=float)
    return delta + 0.2 * max(float(delta.max()), 0.0)
