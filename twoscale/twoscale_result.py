"""The two-scale solve's answer: the :class:`~twoscale.results.ContactResult` assembled
from its macro and micro steps (:func:`twoscale_result`), with their report
(:class:`~twoscale.details.TwoScaleDetails`)."""

from __future__ import annotations

import numpy as np

from .details import Coupling, MacroDetails, MicroDetails, TwoScaleDetails
from .results import ContactResult, PressureField, summarise


def twoscale_result(asperities, macro, micro, plan, h, timings: dict) -> ContactResult:
    """The answer of the macro step ``macro`` and the micro step ``micro`` run as ``plan``
    (:class:`~twoscale.micro.driver.MicroPlan`) at cell size ``h`` (mm); ``timings`` in s."""
    fields = tuple(
        PressureField(pt.grid, p, pt.owner, g) for pt, p, g in zip(micro.patches, micro.pressures, micro.gaps)
    )
    p = np.concatenate([v.ravel() for v in micro.pressures]) if fields else np.zeros(0)
    change = None
    if micro.initial:
        p0 = np.concatenate([v.ravel() for v in micro.initial])
        norm = float(np.linalg.norm(p))
        change = 100.0 * float(np.linalg.norm(p0 - p)) / norm if norm > 0 else 0.0
    messages = [m for m in (("macro step: " + macro.message) if not macro.converged else "", micro.message) if m]
    details = TwoScaleDetails(
        macro=MacroDetails(
            forces=macro.forces,
            local_penetrations=macro.local_penetrations,
            converged=bool(macro.converged),
            interaction=macro.interaction,
            operator_error=macro.operator_error,
            seconds=timings["macro"],
            penetration=float(macro.penetration),
            tilt=None if macro.tilt is None else tuple(float(t) for t in macro.tilt),
        ),
        micro=MicroDetails(
            iteration=_iteration_text(plan),
            strategy=plan.attempts[-1].iteration if plan.attempts else plan.choice.iteration,
            choice=plan.choice,
            attempts=plan.attempts,
            coupling=Coupling.of(micro.coupling),
            merged_patches=micro.merged,
            growths=int(micro.growths),
            p0=tuple(micro.initial) if micro.initial else None,
            p0_change_percent=change,
            seconds=timings["micro"],
        ),
    )
    return ContactResult(
        method="twoscale",
        fields=fields,
        penetration=micro.penetration,
        tilt=micro.tilt,
        total_load=float(h * h * p.sum()),
        asperities=summarise(fields, len(asperities)),
        converged=bool(micro.converged),
        message="; ".join(messages),
        iterations={
            "macro": int(macro.iterations),
            "macro_krylov": int(macro.krylov_iterations),
            "micro": int(micro.sweeps),
            "corrections": int(micro.corrections),
            "sensitivity_sweeps": int(micro.linear_sweeps),
        },
        residuals={"macro": tuple(macro.residuals), "micro": tuple(micro.history)},
        timings_s=timings,
        details=details,
    )


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
        text += (
            " ("
            + "; ".join(f"{names[a.iteration]} did not converge in {a.sweeps} sweeps" for a in plan.attempts[:-1])
            + ")"
        )
    return text


__all__ = ["twoscale_result"]
