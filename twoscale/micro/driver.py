"""The micro step's driver: one entry that composes an iteration with a coupling.

``run_micro`` builds the patches from the macro forces, asks the policy
(:mod:`.policy`) which iteration and coupling to use unless the caller fixed them (a
union CG whose box does not fit in the memory available then gives way to a block
iteration: :func:`_plan`), runs the chosen strategy, and, when it does not converge, the
next one in a fixed order. Every attempt is recorded (:class:`Attempt`: what ran, its
sweeps or CG iterations, its time, its outcome), so nothing is restarted behind the
user's back.

The strategies are objects of :mod:`.strategies`: an iteration (:class:`~.strategies.UnionCG`,
:class:`~.strategies.BlockGaussSeidel`, :class:`~.strategies.TwoLevel`) run with a coupling
it accepts (:class:`~.couplings.Exact` or :class:`~.couplings.FarField`; none for the union
CG). :func:`solve_micro` runs one iteration with one coupling, without the policy.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..errors import MemoryWarning, SceneError, user_stacklevel
from ..indenters import Asperity
from ..memory_now import UNION_BOX_SPREAD, available_memory, box_check, union_box_bytes, union_box_fits
from ..influence.base import InfluenceProvider
from ..options import MicroOptions
from .couplings import Exact, coupling_for
from .patches import TipTable
from .policy import ITERATIONS, MODEL, UNION_MIN_COVERAGE, Choice, choose
from .problem import BlockSettings, MicroContext, MicroProblem
from .release import release_freed_memory
from .result import MicroResult
from .sampling import detached
from .setup import one_asperity_patches, reach_approaches
from .strategies import STRATEGIES, BlockGaussSeidel, TwoLevel, UnionCG
from .union import box_of

#: Sweeps a two-level attempt chosen by the policy gets (it needs 5-10 where it works)
#: before the next strategy is tried unless it is converging fast then (its trial:
#: :attr:`~.twolevel.SweepLimits.trial`; a field of the cost model, :mod:`.costmodel`).
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
    """What the micro step ran: the policy's choice and every attempt, in order, and the
    macro step it started from (``macro``: the one given, or its refinement, ``run_micro``'s
    ``refine``)."""

    choice: Choice
    attempts: tuple
    macro: object = None


def _plan(patches, grid, choice_fixed: Choice | None, asperities, problem: MicroProblem, merged: bool) -> Choice:
    """The caller's choice, else the policy's; a union CG the policy picks whose box does not
    fit in the memory available now gives way to the block iteration it picks without it
    (:func:`_without_union`). ``grid``: the patches' box."""
    if choice_fixed is not None:
        return choice_fixed

    def pick(union: bool) -> Choice:
        return choose(
            patches,
            grid.size,
            merged_contacts=merged,
            load_control=problem.total_load is not None,
            tilt=bool(problem.free_tilt),
            height_map=all(a.shape == "map" for a in asperities.asperities),
            union=union,
        )

    picked = pick(True)
    if picked.iteration != "union-cg":
        return picked
    # on patches at each tip's reach (a stalled macro step) overlapping beyond their box, the
    # block iterations would hold more than the box: no fallback there
    blocks = len(patches) > 1 and problem.size_from_forces
    return _without_union(picked, grid, pick if blocks else None)


def _without_union(picked: Choice, grid, pick: Callable | None) -> Choice:
    """``picked`` (the union CG on the box ``grid``) where its box fits in the memory
    available now (:func:`twoscale.memory_now.box_check`; the estimate made before the solve
    counts it only where the policy surely takes it), else the block iteration
    ``pick(False)`` chooses without it, said in its reason and a :class:`MemoryWarning` (its
    memory was counted before the solve); without ``pick`` (one patch, or patches at each
    tip's reach), a one-line :class:`SceneError` naming a cell size at which the box fits."""
    check = box_check(grid.nx, grid.ny, grid.h)
    if check.fits:
        return picked
    if pick is None:
        raise SceneError(f"{check.text}, and no block iteration replaces it on these patches; {check.advice}")
    other = pick(False)
    note = f"{check.text}: {other.iteration}" + (f" with far_tol {other.far_tol:g}" if other.far_tol else "")
    warnings.warn(MemoryWarning(f"{note} instead"), stacklevel=user_stacklevel())
    return dataclasses.replace(other, reason=f"{other.reason} ({check.text})")


def _box_share(merged: bool) -> float:
    """The patches' share of their box from which it is sampled once for them
    (:func:`~.sampling.build_patches`' ``box_share``): where the policy can choose the union
    CG, which runs on that box, before the far field could take them (scattered patches
    without merged contacts, up to ``MODEL.far_field_coverage``). There the union CG samples
    its box itself, after patches that cost a fraction of it: 10 paraboloids on 14 % of a
    155 K-cell box, 0.020-0.024 s for the box, 0.002-0.003 s for the patches one by one."""
    return UNION_MIN_COVERAGE if merged else max(UNION_MIN_COVERAGE, MODEL.far_field_coverage)


def _low_share(merged: bool, load_control: bool, asperities, problem: MicroProblem) -> float | None:
    """The lower share of their box from which the patches' box is sampled once where it has
    few cells a patch (:func:`~.sampling.sampled_patches`' ``low_share``): the policy's
    ``MODEL.union_coverage``, under penetration control on enough patches below
    ``UNION_MIN_COVERAGE`` (the union CG stays a candidate there); None elsewhere and with
    merged contacts. Only there are the tips the approach reaches counted."""
    if merged or load_control or len(asperities) < MODEL.union_penetration_min_patches:
        return None
    reaching = int(np.count_nonzero(~(reach_approaches(asperities, problem) <= 0.0)))
    lower = MODEL.union_coverage(load_control, reaching)
    return lower if lower < UNION_MIN_COVERAGE else None


def fixed_choice(iteration: str, far_tol: float | None, why: str) -> Choice:
    """A choice made by the caller, not the policy."""
    if iteration not in ITERATIONS:
        raise ValueError(f"iteration must be one of {('auto',) + ITERATIONS}, got {iteration!r}")
    if iteration == "union-cg" and far_tol is not None:
        raise ValueError("far_tol applies to the block iterations, not to iteration='union-cg'")
    return Choice(iteration, far_tol, why, {}, by_caller=True)


def run_micro(
    provider: InfluenceProvider,
    asperities: Sequence[Asperity],
    macro,
    problem: MicroProblem,
    options: MicroOptions,
    *,
    choice: Choice | None = None,
    progress: Callable | None = None,
    refine: Callable | None = None,
) -> tuple[MicroResult, MicroPlan]:
    """Run the micro step after ``macro`` (a :class:`~twoscale.macro.result.MacroResult`).

    Parameters
    ----------
    problem : MicroProblem
        What the macro step leaves (:meth:`~.problem.MicroProblem.from_macro`).
    options : MicroOptions
        Tolerance, sweeps, patches, coupling settings; ``p0`` also computes the paper's
        eq. 7 pressures for the report (the block iterations always do: they start from
        them; the union CG then starts from them too).
    choice : Choice or None
        Fixed by the caller (:func:`fixed_choice`), or None to let the policy choose.
    progress : callable or None
        Called as ``progress(stage: str)`` when an attempt starts.
    refine : callable or None
        For a ``macro`` stopped short of its tolerance at a residual that sizes the patches
        (the driver's staged macro step): ``refine() -> (macro, problem)`` solves it to its
        tolerance. Called when the iteration chosen is not the union CG, which solves every
        contact on the box and takes the macro forces only as its patches and start; the
        block iterations start patch by patch from them. The patches stay (building them
        again cost 5,096 scattered spheres more than the macro step) unless they were sized
        by each tip's reach (a deferred safe path's stall far from a solution); the choice is
        made again.
    """
    asperities = TipTable.of(asperities)  # tip arrays once for every patch built
    share = _box_share(bool(macro.safe_path)) if choice is None else UNION_MIN_COVERAGE
    low = (
        None
        if choice is not None
        else _low_share(bool(macro.safe_path), problem.total_load is not None, asperities, problem)
    )
    patches = tuple(one_asperity_patches(provider, asperities, problem, options.margin, share, low))
    if not patches:
        context = MicroContext(provider, asperities, problem, options, BlockSettings(), patches)
        return BlockGaussSeidel().run(context, Exact(), max_sweeps=options.max_sweeps), MicroPlan(
            Choice("block-gs", None, "no asperity reaches the body", {}), (), macro
        )
    grid = box_of([pt.grid for pt in patches], problem.h, problem.anchor)
    picked = _plan(patches, grid, choice, asperities, problem, bool(macro.safe_path))
    if refine is not None and picked.iteration != "union-cg":
        macro, refined = refine()
        if refined.size_from_forces != problem.size_from_forces:  # a deferred safe path's forces size them
            patches = tuple(one_asperity_patches(provider, asperities, refined, options.margin, share))
            grid = box_of([pt.grid for pt in patches], refined.h, refined.anchor)
        problem = refined
        picked = _plan(patches, grid, choice, asperities, problem, bool(macro.safe_path))
    order = _order(picked)
    if not any(isinstance(iteration, UnionCG) for iteration, _ in order):
        patches = tuple(detached(patches))  # no union CG: the sampled box they were cut from is let go
    context = MicroContext(provider, asperities, problem, options, BlockSettings(), patches)
    attempts: list = []
    result = None
    for iteration, coupling in order:
        if attempts and isinstance(iteration, UnionCG):
            iteration, coupling = _union_or_blocks(grid.size, order[0][1])
        stage = f"micro step, {iteration.name}" + (
            f" ({coupling.name} {coupling.far_tol:g})" if coupling is not None and coupling.far_tol is not None else ""
        )
        monitor = None
        if progress is not None:
            progress(stage)
            unit = "CG iteration" if isinstance(iteration, UnionCG) else "sweep"
            monitor = lambda k, r, _s=stage, _u=unit: progress(f"{_s}: {_u} {k}, residual {r:.1e}")
        t = time.perf_counter()
        result = iteration.run(context, coupling, max_sweeps=options.max_sweeps, monitor=monitor)
        attempts.append(
            Attempt(
                iteration.name,
                None if coupling is None else coupling.far_tol,
                bool(result.converged),
                int(result.sweeps),
                time.perf_counter() - t,
                result.message,
            )
        )
        if result.converged:
            break
        release_freed_memory()  # what the failed attempt freed, before the next one allocates
    return result, MicroPlan(picked, tuple(attempts), macro)


def _union_or_blocks(box_cells: int, coupling) -> tuple:
    """The union CG after a far-field attempt where its box of ``box_cells`` cells fits in the
    memory available now (:func:`twoscale.memory_now.union_box_fits`: the estimate made before
    the solve does not count it), else block Gauss-Seidel with the attempt's ``coupling`` (the
    fallback where patches cover less of their box), with a :class:`MemoryWarning`."""
    if union_box_fits(box_cells):
        return UnionCG(), None
    warnings.warn(
        MemoryWarning(
            f"the union CG on the patches' box ({box_cells:,} cells, up to "
            f"{UNION_BOX_SPREAD * union_box_bytes(box_cells) / 1e9:.2g} GB) does not fit in 80 % of the memory available now "
            f"({available_memory() / 1e9:.2g} GB): block Gauss-Seidel with the same far field instead"
        ),
        stacklevel=user_stacklevel(),
    )
    return BlockGaussSeidel(), coupling


def solve_micro(
    provider: InfluenceProvider,
    asperities: Sequence[Asperity],
    problem: MicroProblem,
    options: MicroOptions | None = None,
    *,
    iteration: str = "block-gs",
    settings: BlockSettings | None = None,
    monitor: Callable | None = None,
) -> MicroResult:
    """The micro step by one iteration without the policy or fallbacks (docs/method.md
    section 3): ``iteration`` (``"block-gs"``, ``"two-level"`` or ``"union-cg"``) with the
    coupling ``options.far_tol`` names (None exact; the union CG takes none), for at most
    ``options.max_sweeps`` sweeps; ``settings`` the block iterations' internal limits
    (:class:`~.problem.BlockSettings`). :func:`run_micro` is the driver's entry."""
    options = MicroOptions() if options is None else options
    if iteration not in ITERATIONS:
        raise ValueError(f"iteration must be one of {ITERATIONS}, got {iteration!r}")
    if iteration == "union-cg" and options.far_tol is not None:
        raise ValueError("far_tol applies to the block iterations, not to iteration='union-cg'")
    asperities = TipTable.of(asperities)
    patches = one_asperity_patches(provider, asperities, problem, options.margin)
    context = MicroContext(provider, asperities, problem, options, settings or BlockSettings(), tuple(patches))
    strategy = STRATEGIES[iteration]()
    coupling = None if iteration == "union-cg" else coupling_for(options.far_tol)
    return strategy.run(context, coupling, max_sweeps=options.max_sweeps, monitor=monitor)


def _order(choice: Choice) -> list:
    """Attempts to make, in order: ``(iteration, coupling)``. The caller's choice runs alone;
    the policy's is followed by a fallback where it can stall (its two-level attempt on a
    trial of ``TWO_LEVEL_SWEEPS``)."""
    coupling = coupling_for(choice.far_tol)
    if choice.iteration == "union-cg":
        return [(UnionCG(), None)]
    if choice.iteration == "block-gs":
        return [(BlockGaussSeidel(), coupling)]
    if choice.by_caller:
        return [(TwoLevel(), coupling)]
    if isinstance(coupling, Exact):
        # the two-level iteration can stall where contacts merge: the paper's iteration decides
        return [(TwoLevel(trial_sweeps=TWO_LEVEL_SWEEPS), Exact()), (BlockGaussSeidel(), Exact())]
    # far-field coupling can fail to converge where contacts merge: the union CG decides
    # where the patches crowd their box; elsewhere its box is mostly empty (and may not fit
    # in memory), and block Gauss-Seidel with the same coupling decides
    if choice.estimates.get("coverage", 1.0) >= UNION_MIN_COVERAGE:
        return [(TwoLevel(trial_sweeps=TWO_LEVEL_SWEEPS), coupling), (UnionCG(), None)]
    return [(TwoLevel(trial_sweeps=TWO_LEVEL_SWEEPS), coupling), (BlockGaussSeidel(), coupling)]
