"""The two-scale solver (Cesbron et al. 2009; docs/method.md sections 2-3).

1. Macro step: tip forces ``P_k`` of the interacting asperities (:func:`twoscale.macro.solve_macro`).
2. Micro step: pressure on one patch per asperity, from eq. 7 and block Gauss-Seidel
   with the approach and tilt corrected so that the pressure carries the load and the
   moments. The micro step's iteration is chosen by a policy from the patches
   (:mod:`twoscale.micro.driver`, :mod:`twoscale.micro.policy`): block Gauss-Seidel over
   the patches, its two-level variant, or one constrained CG over their bounding box.

Only the cells where contact can be are modelled, which is where the speed comes from.
"""

from __future__ import annotations

import difflib
import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numpy as np

from .bulge_rounds import rises, settle, with_macro_lift
from .control import Loading, check_control
from .indenters import Asperity, tip_positions
from .influence.base import InfluenceProvider
from .influence.cached import with_caches
from .laws import law_for
from .macro.result import continued
from .macro.solve import MacroHandover, macro_step, solve_macro
from .macro.start import MacroStart
from .influence.separated import check_rtol
from .micro.driver import fixed_choice, run_micro
from .micro.policy import safe_path_deferral
from .micro.problem import SIZING_RESIDUAL, MicroProblem
from .options import KEYWORDS, MacroOptions, SolverOptions
from .results import ContactResult
from .twoscale_result import twoscale_result as _result
from .warm_start import WarmStart, warm_start


def _check(asperities, h, loading: Loading) -> None:
    if len(asperities) == 0:
        raise ValueError("asperities must not be empty")
    if not all(isinstance(a, Asperity) for a in asperities):
        raise ValueError("asperities must be Asperity objects")
    if isinstance(h, bool) or not isinstance(h, (int, float)) or not math.isfinite(h) or h <= 0:
        raise ValueError(f"cell size h must be a finite number > 0 (mm), got {h!r}")
    check_control(loading.penetration, loading.total_load)
    if loading.tilt and loading.total_load is None:
        raise ValueError("tilt=True needs total_load (ball-and-socket joint under load control)")


#: Keywords of :func:`solve_twoscale` beside the loading and the flat option names of the
#: macro and micro groups (:data:`twoscale.options.KEYWORDS`).
EXTRAS = ("options", "laws", "anchor", "coarse", "progress", "start")


def check_keywords(keywords) -> None:
    """Refuse an unknown or misspelt keyword of :func:`solve_twoscale`, naming it and the
    closest known ones (the values are checked by the option objects and the solver)."""
    known = {k for k, (group, _) in KEYWORDS.items() if group in ("macro", "micro")}
    unknown = [k for k in keywords if k not in known and k not in EXTRAS]
    if unknown:
        key = unknown[0]
        # a group's prefix on a flat keyword ("micro_tol"): the micro step's options go without it
        stem = key.split("_", 1)[1] if key.startswith(("micro_", "micro.")) else ""
        close = [stem] if stem in known else difflib.get_close_matches(key, sorted(known | set(EXTRAS)), n=3)
        hint = (
            f" (did you mean {', '.join(repr(c) for c in close)}?)"
            if close
            else " (twoscale.list_options() lists the options)"
        )
        raise ValueError(f"unknown option {key!r} for the two-scale solver{hint}")


def solve_twoscale(
    provider: InfluenceProvider,
    asperities: Sequence[Asperity],
    *,
    h: float,
    penetration: float | None = None,
    total_load: float | None = None,
    tilt: bool = False,
    pivot: tuple[float, float] = (0.0, 0.0),
    **options,
) -> ContactResult:
    """Multi-asperity contact by the two-scale iterative method.

    Parameters
    ----------
    provider : InfluenceProvider
        The elastic body.
    asperities : sequence of Asperity
        The rigid indenters.
    h : float
        Cell side of the micro step, mm.
    penetration : float, optional
        Rigid approach d, mm (penetration control).
    total_load : float, optional
        Total load W, N (load control); exactly one of the two.
    tilt : bool, default False
        Ball-and-socket joint (with ``total_load``): solve the tilt angles alpha (about x)
        and beta (about y) so that the moments about ``pivot`` vanish.
    pivot : (float, float), default (0, 0)
        Pivot of the joint, mm.
    **options
        ``options``: a :class:`~twoscale.options.SolverOptions` (its macro and micro
        groups; default the documented defaults), changed by the flat option keywords of
        those groups (docs/options.md): ``tol`` (1e-6, eq. 9 relative change),
        ``max_sweeps`` (100), ``iteration``, ``far_tol``, ``margin``, ``dense_max_cells``,
        ``separated_rtol``, ``merge``, ``p0``, ``macro_tol``, ``macro_max_iter``,
        ``macro_dense_max``, ``macro_operator_rtol``; and ``laws``, ``anchor``, ``coarse``,
        ``progress``, ``start`` below. An unknown or misspelt keyword is an error naming
        the closest known ones.
    iteration : {"auto", "union-cg", "block-gs", "two-level"}, default "auto"
        The micro step's iteration (:mod:`twoscale.micro.driver`). ``"auto"``: the policy
        (:mod:`twoscale.micro.policy`) picks from the patches the macro forces give (how
        many, how much of their bounding box they cover) by a cost estimate, and records
        why. ``"union-cg"``: one constrained CG over the box of the patches, warm-started
        from the macro forces (or eq. 7 with ``p0``). ``"block-gs"``: the paper's block
        Gauss-Seidel (eq. 8) over the (merged) patches, with sensitivity sweeps for the
        load and tilt. ``"two-level"``: block Gauss-Seidel with a coarse correction by the
        linearised macro equations (:mod:`twoscale.micro.twolevel`). If the chosen one
        does not converge, the next is tried; every attempt is in ``details.micro.attempts``.
    far_tol : float or None, default None
        Cross-patch coupling of the block iterations: None = exact; a number in (0, 1)
        approximates patches farther apart than ``(r_k + r_l) / sqrt(far_tol)`` by their
        resultant force (:mod:`twoscale.micro.farfield`). Given with ``iteration="auto"``
        it selects the two-level iteration. Patches are then sized from the macro local
        penetrations (bulk deflection included).
    merge : bool, default True
        Micro step without ``far_tol``: close patches (close or merged contacts) are solved
        as one block when their common grid has at most twice the cells they have apart
        (:func:`twoscale.micro.patches.merge_overlapping`,
        :data:`twoscale.micro.problem.MERGE_GROWTH`); eq. 7 still gives each asperity its own
        ``p0``. False: one block per asperity, the paper's iteration (more sweeps for close
        asperities: 13-19 against 4 in the paper's closest cases).
    laws : sequence of AsperityLaw, optional
        Load-penetration law per asperity; default ``law_for(asperity, provider.material)``.
    anchor : (float, float), default (0, 0)
        A cell centre of the lattice, mm (use the reference grid's to compare cell by cell).
    coarse : bool or None, default None
        Older spelling of ``iteration``: True = ``"two-level"``, False = ``"block-gs"``.
    progress : callable or None, default None
        Called with a short stage description (``progress(text)``) as the solve goes on.
    start : ContactResult, MacroStart or WarmStart, optional
        Warm start, e.g. the solve of the neighbouring position on a track: a previous
        result with the same tips in the same order (its macro forces, approach and
        tilt), or a :class:`~twoscale.macro.start.MacroStart` (forces in this solve's tip
        order, built with ``MacroStart.from_result(result, index)`` when the tips
        differ): the macro Newton iteration starts there, the micro step as without it.
        A :class:`~twoscale.warm_start.WarmStart` (:func:`~twoscale.warm_start.warm_start`)
        also starts the micro step from the previous pressure moved with the tips. The
        answer is the same to the tolerances; the work shrinks when the start is close.

    Returns
    -------
    ContactResult
        ``method="twoscale"``; one field per block (a merged block's patches give one).
        ``details`` is a :class:`~twoscale.details.TwoScaleDetails`: ``details.macro``
        (tip forces N, local approaches mm, how the interaction was held) and
        ``details.micro`` (the policy's choice and reason, every attempt, the coupling
        routes, ``merged_patches`` as 0-based asperity indices, eq. 7's ``p0`` and
        ``p0_change_percent = 100 ||p0 - p|| / ||p||`` or None, see ``p0``).
    """
    check_keywords(options)
    extras = {k: options.pop(k) for k in EXTRAS if k in options}
    base = extras.get("options")
    if base is not None and not isinstance(base, SolverOptions):
        raise ValueError(f"options must be a twoscale.SolverOptions, got {type(base).__name__}")
    run = TwoScaleRun(
        options=SolverOptions.from_keywords(base, **options),
        laws=extras.get("laws"),
        anchor=extras.get("anchor", (0.0, 0.0)),
        coarse=extras.get("coarse"),
        progress=extras.get("progress"),
        start=extras.get("start"),
    )
    return run_twoscale(provider, asperities, h, Loading(penetration, total_load, tilt, pivot), run)


@dataclass(frozen=True)
class TwoScaleRun:
    """How one two-scale solve runs, beside the body, the tips and the loading: the options
    (macro and micro groups), the tips' laws, the lattice anchor, the older ``coarse``
    spelling, a progress callback and a warm start (:func:`solve_twoscale`'s keywords)."""

    options: SolverOptions = field(default_factory=SolverOptions)
    laws: Sequence | None = None
    anchor: tuple = (0.0, 0.0)
    coarse: bool | None = None
    progress: Callable | None = None
    start: object = None


def run_twoscale(
    provider: InfluenceProvider, asperities: Sequence[Asperity], h: float, loading: Loading, run: TwoScaleRun
) -> ContactResult:
    """:func:`solve_twoscale` with its arguments as typed objects."""
    _check(asperities, h, loading)
    macro_options, micro_options = run.options.macro, run.options.micro
    check_rtol(micro_options.separated_rtol, "separated_rtol", allow_none=True)
    provider = with_caches(provider)  # a solver object's caches, or this solve's own
    progress, start = run.progress, run.start
    t0 = time.perf_counter()
    laws = [law_for(a, provider.material) for a in asperities] if run.laws is None else run.laws
    tips = tip_positions(asperities)
    z = np.array([a.z for a in asperities], dtype=float)
    if progress is not None:
        progress(f"macro step, {len(asperities)} asperities")
    first = _first_stage(macro_options, len(asperities))
    choice = _caller_choice(micro_options.iteration, micro_options.far_tol, run.coarse)
    begin = _macro_start(start, len(asperities))
    defer = None if choice is not None else safe_path_deferral(asperities, h, loading.penetration, loading.tilt)
    macro = macro_step(provider, tips, z, laws, loading, first, MacroHandover(start=begin, defer_safe_path=defer))
    t1 = time.perf_counter()
    micro_start = start.micro if isinstance(start, WarmStart) else None

    def micro_problem(macro, start):  # a tip the macro step's rise lifts into contact gets a patch
        return with_macro_lift(provider, asperities, _micro_problem(macro, h, loading, run.anchor, start))

    problem = micro_problem(macro, micro_start)
    refine = None
    # the staged first stage is taken to the macro tolerance, but not after the safe path's skip
    # (an unstable equilibrium of merged contacts, or a stall), where Newton stalled again (1,013
    # spheres: five more LU steps, 1.9e-3 to 5.7e-4; 1,485: one, a failed line search); the micro
    # step resolves the merged contacts either way. A deferred safe path: the macro step again.
    if (first is not macro_options and not macro.safe_path) or macro.safe_path_deferred:

        def refine():
            again = begin if macro.safe_path_deferred else MacroStart(macro.forces, macro.penetration, macro.tilt)
            full = continued(macro, solve_macro(provider, tips, z, laws, loading, macro_options, start=again))
            return full, micro_problem(full, micro_start)

    micro, plan = run_micro(
        provider, asperities, macro, problem, micro_options, choice=choice, progress=progress, refine=refine
    )
    t2 = time.perf_counter()
    if plan.macro is not macro:  # refined inside the micro step: its time counts as the macro step's
        t1 += float(plan.macro.timings_s["total"]) - float(macro.timings_s["total"])
        macro = plan.macro
    elif refine is not None:
        macro = _first_stage_kept(macro)
    result = _result(asperities, macro, micro, plan, h, {"macro": t1 - t0, "micro": t2 - t1, "total": t2 - t0})
    if not rises(provider) or loading.tilt:  # a free tilt moves every apex's approach: not checked
        return result

    def again(lift, previous):  # the micro step with the lifted tips' patches, from the answer's pressure
        t = time.perf_counter()
        warm = warm_start(previous, tips, len(asperities), h).micro
        retry = replace(_micro_problem(macro, h, loading, run.anchor, warm), lift=lift)
        micro, again_plan = run_micro(
            provider, asperities, macro, retry, micro_options, choice=choice, progress=progress
        )
        spent = time.perf_counter() - t
        took = {k: previous.timings_s[k] + (spent if k != "macro" else 0.0) for k in ("macro", "micro", "total")}
        return _result(asperities, macro, micro, again_plan, h, took)

    return settle(result, asperities, provider, micro_problem(macro, micro_start).lift, again)


#: Above this many asperities the macro step is staged: Newton stops first at the relative
#: residual ``SIZING_RESIDUAL`` (the micro step's "near a solution"), and goes on to the
#: macro tolerance only when the iteration chosen is not the union CG (``run_micro``'s
#: ``refine``). The union CG solves every contact on the box and takes the macro forces as
#: its patches and start only: 6,933 crowded spheres (merged contacts), Newton stopped at
#: 9.6e-3 after 5 steps instead of stalling at 8.1e-3 after 9, gave it 39 iterations
#: against 41, and the macro step 0.7-0.9 s of CPU against 1.35 s.
STAGED_MIN_TIPS = 1000


#: The first stage's matrix-free interaction is held to this relative error (it only sizes the
#: patches and starts the micro step; a second stage builds its own): 9,110 tips' Ewald
#: product 2.2 against 5.6 ms at 1e-6, their staged macro step 0.55 against 1.0 s of CPU.
FIRST_STAGE_OPERATOR_RTOL = 1e-3


def _first_stage(options: MacroOptions, n: int) -> MacroOptions:
    """The macro options of the first stage (``STAGED_MIN_TIPS``), or ``options`` itself."""
    if n <= STAGED_MIN_TIPS or options.tol >= SIZING_RESIDUAL:
        return options
    return replace(options, tol=SIZING_RESIDUAL, operator_rtol=max(options.operator_rtol, FIRST_STAGE_OPERATOR_RTOL))


def _first_stage_kept(macro):
    """The first stage's macro result as the answer's macro step: not converged to the
    macro tolerance, and saying so (a stall or an unstable equilibrium says so already)."""
    if not macro.converged:
        return macro
    last = macro.residuals[-1] if len(macro.residuals) else 0.0
    why = (
        f"stopped at relative residual {last:.1e} (at most {SIZING_RESIDUAL:g}) after {macro.iterations} "
        f"Newton steps: the union CG solves every contact on the box from it"
    )
    return replace(macro, converged=False, message=why)


def _micro_problem(macro, h: float, loading: Loading, anchor: tuple, start) -> MicroProblem:
    return MicroProblem.from_macro(
        macro,
        h=h,
        total_load=loading.total_load,
        free_tilt=loading.tilt,
        pivot=loading.pivot,
        anchor=anchor,
        start=start,
    )


def _macro_start(start, n: int):
    """``start`` as a :class:`MacroStart` (None: cold start)."""
    if start is None or isinstance(start, MacroStart):
        return start
    if isinstance(start, WarmStart):
        return start.macro
    if isinstance(start, ContactResult):
        if len(start.asperities.forces) != n:
            raise ValueError(
                f"start has {len(start.asperities.forces)} asperities, this solve {n}: "
                f"give MacroStart.from_result(result, index) to map them"
            )
        return MacroStart.from_result(start)
    raise ValueError(f"start must be a ContactResult, a MacroStart or a WarmStart, got {type(start).__name__}")


def _caller_choice(iteration, far_tol, coarse):
    """The caller's fixed choice, or None for the policy."""
    if far_tol is not None and not (isinstance(far_tol, (int, float)) and 0.0 < far_tol < 1.0):
        raise ValueError(f"far_tol must be a number in (0, 1), got {far_tol!r}")
    if coarse is not None:
        if iteration != "auto":
            raise ValueError(f"give iteration or coarse, not both (iteration={iteration!r}, coarse={coarse!r})")
        iteration = "two-level" if coarse else "block-gs"
    if iteration == "auto":
        if far_tol is None:
            return None
        return fixed_choice("two-level", far_tol, f"far_tol = {far_tol} given: two-level with far-field coupling")
    return fixed_choice(iteration, far_tol, f"iteration fixed by the caller: {iteration}")
