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

import math
import time
from typing import Sequence

import numpy as np

from .control import check_control
from .details import Coupling, MacroDetails, MicroDetails, TwoScaleDetails
from .indenters import Asperity
from .influence.base import InfluenceProvider
from .influence.cached import with_caches
from .laws import law_for
from .macro import solve_macro
from .macro.solve import DENSE_MAX
from .macro.start import MacroStart
from .influence.separated import check_rtol
from .micro.driver import fixed_choice, run_micro
from .results import ContactResult, PressureField, summarise
from .warm_start import WarmStart


def _check(asperities, h, penetration, total_load, tilt, tol, max_sweeps) -> None:
    if len(asperities) == 0:
        raise ValueError("asperities must not be empty")
    if not all(isinstance(a, Asperity) for a in asperities):
        raise ValueError("asperities must be Asperity objects")
    if isinstance(h, bool) or not isinstance(h, (int, float)) or not math.isfinite(h) or h <= 0:
        raise ValueError(f"cell size h must be a finite number > 0 (mm), got {h!r}")
    check_control(penetration, total_load)
    if tilt and total_load is None:
        raise ValueError("tilt=True needs total_load (ball-and-socket joint under load control)")
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a finite number > 0, got {tol!r}")
    if isinstance(max_sweeps, bool) or not isinstance(max_sweeps, int) or max_sweeps < 1:
        raise ValueError(f"max_sweeps must be an integer >= 1, got {max_sweeps!r}")


def solve_twoscale(provider: InfluenceProvider, asperities: Sequence[Asperity], *, h: float,
                   penetration: float | None = None, total_load: float | None = None,
                   tilt: bool = False, pivot: tuple[float, float] = (0.0, 0.0), tol: float = 1e-6,
                   max_sweeps: int = 100, laws=None, margin: float = 1.3,
                   anchor: tuple[float, float] = (0.0, 0.0), dense_max_cells: int = 400,
                   macro_tol: float = 1e-10, macro_max_iter: int = 100,
                   macro_dense_max: int = DENSE_MAX, macro_operator_rtol: float = 1e-6,
                   iteration: str = "auto", far_tol: float | None = None, coarse: bool | None = None,
                   separated_rtol: float | None = 1e-8, merge: bool = True, p0: bool = False,
                   progress=None, start=None) -> ContactResult:
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
    tol : float, default 1e-6
        Eq. 9 tolerance on the relative change of the pressure between sweeps.
    max_sweeps : int, default 100
        Block Gauss-Seidel sweeps allowed (all rounds together).
    laws : sequence of AsperityLaw, optional
        Load-penetration law per asperity; default ``law_for(asperity, provider.material)``.
    margin : float, default 1.3
        Patch half-width over the Hertz-like contact radius of the macro force.
    anchor : (float, float), default (0, 0)
        A cell centre of the lattice, mm (use the reference grid's to compare cell by cell).
    dense_max_cells : int, default 400
        Blocks up to this many cells are solved densely, larger ones by FFT + CG.
    macro_tol : float, default 1e-10
        Relative residual of the macro Newton iteration.
    macro_max_iter : int, default 100
    macro_dense_max : int, default 3000
        Up to this many asperities the macro step factorises the dense interaction;
        above, it is matrix-free (fast point operator + conjugate gradients), its
        operator error reported in ``details.macro.operator_error``.
    macro_operator_rtol : float, default 1e-6
        Accuracy of that point operator (relative to ``max |u|``).
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
    coarse : bool or None, default None
        Older spelling of ``iteration``: True = ``"two-level"``, False = ``"block-gs"``.
    separated_rtol : float or None, default 1e-8
        Micro step: patches far apart for their size are coupled through the provider's
        low-rank separated operator (half-space: Chebyshev interpolation of Love's kernel),
        accurate to this fraction of the pair's displacement; None: FFT products only.
    merge : bool, default True
        Micro step without ``far_tol``: close patches (close or merged contacts) are solved
        as one block when their common grid has at most twice the cells they have apart
        (:func:`twoscale.micro.patches.merge_overlapping`,
        :data:`twoscale.micro.solve.MERGE_GROWTH`); eq. 7 still gives each asperity its own
        ``p0``. False: one block per asperity, the paper's iteration (more sweeps for close
        asperities: 13-19 against 4 in the paper's closest cases).
    p0 : bool, default False
        Compute the paper's eq. 7 pressures even where the chosen iteration does not start
        from them (``union-cg``), for the report (``details.micro.p0``, Fig. 6).
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
    _check(asperities, h, penetration, total_load, tilt, tol, max_sweeps)
    check_rtol(separated_rtol, "separated_rtol", allow_none=True)
    provider = with_caches(provider)  # a solver object's caches, or this solve's own
    t0 = time.perf_counter()
    laws = [law_for(a, provider.material) for a in asperities] if laws is None else laws
    tips = np.array([[a.x, a.y] for a in asperities], dtype=float)
    z = np.array([a.z for a in asperities], dtype=float)
    if progress is not None:
        progress(f"macro step, {len(asperities)} asperities")
    macro = solve_macro(provider, tips, z, laws, penetration=penetration, total_load=total_load,
                        tilt=tilt, pivot=pivot, tol=macro_tol, max_iter=macro_max_iter,
                        dense_max=macro_dense_max, operator_rtol=macro_operator_rtol,
                        start=_macro_start(start, len(asperities)))
    t1 = time.perf_counter()
    choice = _caller_choice(iteration, far_tol, coarse)
    micro, plan = run_micro(provider, asperities, macro=macro, h=h, total_load=total_load, free_tilt=tilt,
                            pivot=pivot, tol=tol, max_sweeps=max_sweeps, choice=choice, p0=p0, progress=progress,
                            margin=margin, anchor=anchor, dense_max_cells=dense_max_cells,
                            separated_rtol=separated_rtol, merge=bool(merge),
                            start=start.micro if isinstance(start, WarmStart) else None)
    t2 = time.perf_counter()
    return _result(asperities, macro, micro, plan, h, {"macro": t1 - t0, "micro": t2 - t1, "total": t2 - t0})


def _macro_start(start, n: int):
    """``start`` as a :class:`MacroStart` (None: cold start)."""
    if start is None or isinstance(start, MacroStart):
        return start
    if isinstance(start, WarmStart):
        return start.macro
    if isinstance(start, ContactResult):
        if len(start.asperities.forces) != n:
            raise ValueError(f"start has {len(start.asperities.forces)} asperities, this solve {n}: "
                             f"give MacroStart.from_result(result, index) to map them")
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


def _result(asperities, macro, micro, plan, h, timings) -> ContactResult:
    fields = tuple(PressureField(pt.grid, p, pt.owner, g)
                   for pt, p, g in zip(micro.patches, micro.pressures, micro.gaps))
    p = np.concatenate([v.ravel() for v in micro.pressures]) if fields else np.zeros(0)
    change = None
    if micro.initial:
        p0 = np.concatenate([v.ravel() for v in micro.initial])
        norm = float(np.linalg.norm(p))
        change = 100.0 * float(np.linalg.norm(p0 - p)) / norm if norm > 0 else 0.0
    messages = [m for m in (("macro step: " + macro.message) if not macro.converged else "", micro.message) if m]
    details = TwoScaleDetails(
        macro=MacroDetails(forces=macro.forces, local_penetrations=macro.local_penetrations,
                           converged=bool(macro.converged), interaction=macro.interaction,
                           operator_error=macro.operator_error, seconds=timings["macro"],
                           penetration=float(macro.penetration),
                           tilt=None if macro.tilt is None else tuple(float(t) for t in macro.tilt)),
        micro=MicroDetails(iteration=_iteration_text(plan),
                           strategy=plan.attempts[-1].iteration if plan.attempts else plan.choice.iteration,
                           choice=plan.choice,
                           attempts=plan.attempts, coupling=Coupling.of(micro.coupling),
                           merged_patches=micro.merged, growths=int(micro.growths),
                           p0=tuple(micro.initial) if micro.initial else None, p0_change_percent=change,
                           seconds=timings["micro"]))
    return ContactResult(
        method="twoscale", fields=fields, penetration=micro.penetration, tilt=micro.tilt,
        total_load=float(h * h * p.sum()), asperities=summarise(fields, len(asperities)),
        converged=bool(micro.converged), message="; ".join(messages),
        iterations={"macro": int(macro.iterations), "macro_krylov": int(macro.krylov_iterations),
                    "micro": int(micro.sweeps),
                    "corrections": int(micro.corrections), "sensitivity_sweeps": int(micro.linear_sweeps)},
        residuals={"macro": tuple(macro.residuals), "micro": tuple(micro.history)},
        timings_s=timings, details=details)


def _iteration_text(plan) -> str:
    """What produced the answer, with the attempts before it (result.json ``micro_iteration``)."""
    names = {"union-cg": "union CG", "block-gs": "block Gauss-Seidel", "two-level": "two-level"}
    if not plan.attempts:
        return names[plan.choice.iteration]
    last = plan.attempts[-1]
    text = names[last.iteration]
    if last.iteration == "two-level":
        text += " (far-field coupling)" if last.far_tol is not None else " (exact coupling)"
    if len(plan.attempts) > 1:
        text += " (" + "; ".join(f"{names[a.iteration]} did not converge in {a.sweeps} sweeps"
                                 for a in plan.attempts[:-1]) + ")"
    return text
