"""The micro step's driver: one entry that composes an iteration with a coupling.

``run_micro`` builds the patches from the macro forces, asks the policy
(:mod:`.policy`) which iteration and coupling to use unless the caller fixed them, runs
the chosen strategy, and, when it does not converge, the next one in a fixed order. Every
attempt is recorded (:class:`Attempt`: what ran, its sweeps or CG iterations, its time, its
outcome), so nothing is restarted behind the user's back.

The strategies are objects of :mod:`.strategies`: an iteration (:class:`~.strategies.UnionCG`,
:class:`~.strategies.BlockGaussSeidel`, :class:`~.strategies.TwoLevel`) run with a coupling
(:class:`~.strategies.Exact` or :class:`~.strategies.FarField`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..indenters import Asperity
from ..influence.base import InfluenceProvider
from .patches import TipTable, build_patches
from .policy import ITERATIONS, MODEL, UNION_MIN_COVERAGE, Choice, choose
from .start import MicroStart
from .result import MicroResult
from .solve import EXACT_FAR_TOL, solve_micro
from .strategies import BlockGaussSeidel, Exact, FarField, MicroContext, TwoLevel, UnionCG
from .union import box_of
from .workset import tip_approaches

#: Sweeps a two-level attempt chosen by the policy gets (it needs 5-10 where it works)
#: before the next strategy is tried (a field of the cost model, :mod:`.costmodel`).
TWO_LEVEL_SWEEPS = MODEL.two_level_sweeps


@dataclass(frozen=True)
class Attempt:
    """One strategy run by the driver.

    Attributes
    ----------
    iteration : str
        ``"union-cg"``, ``"block-gs"`` or ``"two-level"``.
    far_tol : float or None
        Far-field coupling tolerance (None: exact).
    converged : bool
    sweeps : int
        Block sweeps (block iterations) or CG iterations (union).
    seconds : float
        Wall-clock time of the attempt.
    message : str
        Its stopping reason ("" when it converged).
    """

    iteration: str
    far_tol: float | None
    converged: bool
    sweeps: int
    seconds: float
    message: str


@dataclass(frozen=True)
class MicroPlan:
    """What the micro step ran: the policy's choice and every attempt, in order."""

    choice: Choice
    attempts: tuple


def _plan(patches, box, choice_fixed: Choice | None, merged_contacts: bool, load_control: bool,
          tilt: bool = False) -> Choice:
    if choice_fixed is not None:
        return choice_fixed
    return choose(patches, box, merged_contacts=merged_contacts, load_control=load_control, tilt=tilt)


def fixed_choice(iteration: str, far_tol: float | None, why: str) -> Choice:
    """A choice made by the caller, not the policy."""
    if iteration not in ITERATIONS:
        raise ValueError(f"iteration must be one of {('auto',) + ITERATIONS}, got {iteration!r}")
    if iteration == "union-cg" and far_tol is not None:
        raise ValueError("far_tol applies to the block iterations, not to iteration='union-cg'")
    return Choice(iteration, far_tol, why, {}, by_caller=True)


def run_micro(provider: InfluenceProvider, asperities: Sequence[Asperity], *, macro, h: float,
              total_load: float | None, free_tilt: bool, pivot, tol: float, max_sweeps: int,
              choice: Choice | None = None, p0: bool = False, progress: Callable | None = None,
              start: MicroStart | None = None, **block_options) -> tuple[MicroResult, MicroPlan]:
    """Run the micro step after ``macro`` (a :class:`~twoscale.macro.result.MacroResult`).

    Parameters
    ----------
    choice : Choice or None
        Fixed by the caller (:func:`fixed_choice`), or None to let the policy choose.
    p0 : bool, default False
        Also compute the paper's eq. 7 pressures for the report (the block iterations always
        do: they start from them; the union CG then starts from them too).
    progress : callable or None
        Called as ``progress(stage: str)`` when an attempt starts.
    start : MicroStart or None
        A previous solve's pressure (:mod:`.start`), the first pressure of every iteration
        where it has one (eq. 7 or the union CG's own start elsewhere).
    block_options
        Passed to :func:`.solve.solve_micro` (margin, anchor, dense_max_cells, merge, ...).
    """
    asperities = TipTable.of(asperities)  # tip arrays once for every patch built
    forces = np.asarray(macro.forces, dtype=float)
    anchor = block_options.get("anchor", (0.0, 0.0))
    penetration, tilt = macro.penetration, macro.tilt
    if start is not None and total_load is not None:
        penetration, tilt = start.theta(penetration, tilt)
    common = dict(h=h, forces=forces, penetration=penetration, tilt=tilt, pivot=pivot,
                  total_load=total_load, free_tilt=free_tilt, tol=tol, size_from_forces=bool(macro.converged),
                  start=start, **block_options)
    # the patches solve_micro would build from the same arguments, built once here
    theta = (penetration, *(tilt if tilt is not None else (0.0, 0.0)))
    patches = build_patches(asperities, h=h, forces=forces if macro.converged else np.full(len(forces), np.inf),
                            approaches=tip_approaches(asperities, theta, pivot), E_star=provider.material.E_star,
                            margin=block_options.get("margin", 1.3), anchor=anchor)
    if not patches:
        return solve_micro(provider, asperities, max_sweeps=max_sweeps, **common), \
            MicroPlan(Choice("block-gs", None, "no asperity reaches the body", {}), ())
    picked = _plan(patches, box_of([pt.grid for pt in patches], h, anchor).size, choice,
                   merged_contacts=bool(macro.safe_path), load_control=total_load is not None,
                   tilt=bool(free_tilt))
    context = MicroContext(provider, asperities, macro, tuple(patches), common, p0)
    attempts: list = []
    result = None
    for iteration, coupling, sweeps_cap in _order(picked):
        stage = f"micro step, {iteration.name}" + (f" ({coupling.name} {coupling.far_tol:g})"
                                                   if coupling.far_tol is not None else "")
        monitor = None
        if progress is not None:
            progress(stage)
            unit = "CG iteration" if isinstance(iteration, UnionCG) else "sweep"
            monitor = (lambda k, r, _s=stage, _u=unit: progress(f"{_s}: {_u} {k}, residual {r:.1e}"))
        t = time.perf_counter()
        cap = min(max_sweeps, sweeps_cap) if sweeps_cap else max_sweeps
        result = iteration.run(context, coupling, max_sweeps=cap, monitor=monitor)
        attempts.append(Attempt(iteration.name, coupling.far_tol, bool(result.converged), int(result.sweeps),
                                time.perf_counter() - t, result.message))
        if result.converged:
            break
    return result, MicroPlan(picked, tuple(attempts))


def _order(choice: Choice) -> list:
    """Attempts to make, in order: ``(iteration, coupling, sweep cap or None)``. The caller's
    choice runs alone; the policy's is followed by a fallback where it can stall."""
    coupling = Exact() if choice.far_tol is None or choice.far_tol <= EXACT_FAR_TOL else FarField(choice.far_tol)
    if choice.iteration == "union-cg":
        return [(UnionCG(), Exact(), None)]
    if choice.iteration == "block-gs":
        return [(BlockGaussSeidel(), coupling, None)]
    if choice.by_caller:
        return [(TwoLevel(), coupling, None)]
    if isinstance(coupling, Exact):
        # the two-level iteration can stall where contacts merge: the paper's iteration decides
        return [(TwoLevel(), Exact(), TWO_LEVEL_SWEEPS), (BlockGaussSeidel(), Exact(), None)]
    # far-field coupling can fail to converge where contacts merge: the union CG decides
    # where the patches crowd their box; elsewhere its box is mostly empty (and may not fit
    # in memory), and block Gauss-Seidel with the same coupling decides
    if choice.estimates.get("coverage", 1.0) >= UNION_MIN_COVERAGE:
        return [(TwoLevel(), coupling, TWO_LEVEL_SWEEPS), (UnionCG(), Exact(), None)]
    return [(TwoLevel(), coupling, TWO_LEVEL_SWEEPS), (BlockGaussSeidel(), coupling, None)]
