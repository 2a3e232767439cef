"""The safe path of the macro step, for scenes where plain Newton stalls.

Newton on the residual stalls where neighbouring contacts are so close that the
compliance ``diag(1/f_k') + T`` loses definiteness (merged contacts): the residual norm
then has stationary points that are not solutions. The macro equations are, for a
symmetric ``T``, the optimality conditions of a potential that is bounded below on
``P >= 0`` (``T >= 0`` entrywise), so:

* penetration control: minimise the potential over ``P >= 0`` (L-BFGS-B), then polish
  with Newton;
* load control and tilt: the rigid-body unknowns ``g = (d[, alpha, beta])`` are the
  multipliers of the equilibrium rows; maximise the concave dual
  ``Q(g) = min_{P >= 0} potential(P; g) + g.e`` by Newton with backtracking, each
  evaluation being a penetration-controlled solve.

Each dual evaluation minimises first and polishes after: Newton alone can land on a
saddle of the (then non-convex) potential, whose value overstates the dual and made
the ascent stall. After the first, up to ``NEAR_MAX_TIPS`` tips, a dual point tries
Newton first from the last minimum moved along its force sensitivity, and keeps its
answer only where it is a minimum below that start (stable, forces >= 0). Limit: the minimiser can still switch branch as ``g`` moves; the dual
then has a kink, the ascent may stall, and the result says so (``converged=False``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog, minimize

from .newton import PLATEAU_DROP, NewtonOutcome, Stops, newton
from .system import MacroSystem

_ARMIJO = 1e-4
#: Newton steps allowed before the safe path takes over (Newton needs 2-8 on sound scenes).
FAST_STEPS = 20
#: The dual ascent stops at this relative imbalance; the coupled Newton polish, which
#: converges quadratically from there, brings it to the user's tolerance.
_DUAL_TOL = 1e-7
_MIN_DUAL_STEP = 2.0**-12


@dataclass(frozen=True)
class SafeOutcome:
    """Unknowns ``x = [P, g]`` found by the safe path, and its effort."""

    x: np.ndarray
    converged: bool
    message: str
    newton_steps: int
    minimiser_steps: int


def project(x: np.ndarray, n: int) -> np.ndarray:
    """Forces clipped at zero; the rigid-body unknowns untouched."""
    return np.concatenate([np.maximum(x[:n], 0.0), x[n:]])


def run_newton(
    system: MacroSystem,
    x0: np.ndarray,
    *,
    tol: float,
    max_iter: int,
    scale_floor: float = 0.0,
    stall: int | None = None,
    plateau: int | None = None,
    drop: float = PLATEAU_DROP,
) -> NewtonOutcome:
    """Projected, backtracking Newton on ``system`` from ``x0`` (``stall``: stop when it
    stagnates near a solution, ``plateau``: anywhere, by under ``drop`` of its residual,
    :func:`.newton.newton`)."""
    n = system.n
    return newton(
        system.residual,
        system.newton_step,
        x0,
        scale=lambda x: float(np.linalg.norm(x[:n])) or scale_floor,
        tol=tol,
        max_iter=max_iter,
        project=lambda x: project(x, n),
        # not with tilt: 3,869 clustered tilted spheres (seed 1's #121) converged past the
        # clipping to a start that cost the two-level micro step 1.5x the CPU of the stall's
        stops=Stops(stall, plateau, drop, unprojected=system.G.shape[1] <= 1),
    )


def minimise_then_polish(system: MacroSystem, starts, *, tol: float, max_iter: int) -> SafeOutcome:
    """Minimise the potential over ``P >= 0`` (L-BFGS-B) from the best of ``starts``,
    then polish with Newton."""
    start = min((np.maximum(P, 0.0) for P in starts), key=system.energy)
    res = minimize(
        system.energy,
        start,
        jac=system.energy_gradient,
        method="L-BFGS-B",
        bounds=[(0.0, None)] * system.n,
        options={
            "maxiter": 20 * max_iter + 200,
            "maxcor": 20,
            "ftol": 1e-15,
            "gtol": 1e-12 * max(1.0, float(np.max(np.abs(system.offset)))),
        },
    )
    polish = run_newton(system, res.x, tol=tol, max_iter=max_iter)
    msg = f"{polish.message} (safe path: potential minimised in {res.nit} L-BFGS-B steps, then polished)"
    return SafeOutcome(polish.x, polish.converged, msg, polish.iterations, int(res.nit))


def solve_dual(system: MacroSystem, x0: np.ndarray, *, tol: float, max_iter: int) -> SafeOutcome:
    """Load control (with or without tilt): Newton ascent on the concave dual in ``g``,
    then a Newton polish of the coupled system."""
    n = system.n
    G, e = system.G, system.e
    P, g = np.maximum(x0[:n], 0.0), np.array(x0[n:], dtype=float)
    total_newton = total_min = 0
    state = _dual_point(system, g, P, tol, max_iter)
    total_newton += state.newton_steps
    total_min += state.minimiser_steps
    converged = stalled = untouched = False
    for it in range(max_iter):
        grad = e - G.T @ state.P
        if _balanced(system, state.P, max(tol, _DUAL_TOL)):
            converged = True
            break
        S = system.at(g).force_sensitivity(state.P, G)  # dP/dg on the contact set
        H = G.T @ S  # -Hessian of Q, PSD
        step = _ascent_step(H, grad)
        if not np.all(np.isfinite(step)):  # no tip in contact at g: the dual is linear there
            stalled = untouched = True
            break
        slope = float(grad @ step)
        t = 1.0
        while True:
            predicted = np.maximum(state.P + S @ (t * step), 0.0) if n <= NEAR_MAX_TIPS else None
            trial = _dual_point(system, g + t * step, state.P, tol, max_iter, predicted=predicted)
            total_newton += trial.newton_steps
            total_min += trial.minimiser_steps
            # Armijo, with room for rounding in Q (~1e-16 |Q|) once the ascent is done
            if trial.Q >= state.Q + _ARMIJO * t * slope - 1e-13 * abs(state.Q):
                break
            t *= 0.5
            if t < _MIN_DUAL_STEP:
                stalled = True
                break
        if stalled:
            break
        g, state = g + t * step, trial
    x = np.concatenate([state.P, g])
    polish = run_newton(system, x, tol=tol, max_iter=max_iter, scale_floor=float(e[0]))
    total_newton += polish.iterations
    if polish.converged:
        msg = f"{polish.message} (safe path: dual ascent in {it} steps, then polished)"
        return SafeOutcome(polish.x, True, msg, total_newton, total_min)
    if converged:
        msg = (
            f"safe path: dual ascent balanced the load to {_DUAL_TOL:.0e} in {it} steps but the "
            f"polish failed ({polish.message})"
        )
    elif untouched:
        msg = f"safe path: no tip touches at the dual ascent's step {it + 1}, so it has no finite step"
    elif stalled:
        msg = (
            f"safe path: dual ascent stalled at step {it + 1} with the load and moments "
            f"unbalanced by {float(np.linalg.norm(system.E @ state.P - e)):.3e} N (the inner "
            f"minimum switches between branches: contacts merged beyond what the point-force "
            f"interaction can represent, or no tilt can balance the load)"
        )
    else:
        msg = f"safe path not converged after max_iter={max_iter} dual steps"
    return SafeOutcome(x, False, msg, total_newton, total_min)


@dataclass(frozen=True)
class _DualPoint:
    P: np.ndarray
    Q: float
    newton_steps: int
    minimiser_steps: int


#: Newton steps a dual point tries from the predicted minimum before the minimiser runs
#: (:func:`_newton_near`; it stops sooner on a plateau of its residual, as the macro step's).
_NEAR_STEPS = 6
_NEAR_PLATEAU = 2
#: Up to this many tips: above, each Newton step's LU (``n^3``) costs what the minimiser's
#: steps cost, and its Newton attempts that end on a saddle more (814-859 tips, the macro
#: step alone: 3.23 s with them against 3.24 s without, on five scenes).
NEAR_MAX_TIPS = 500


def _dual_point(
    system: MacroSystem, g: np.ndarray, P_start: np.ndarray, tol: float, max_iter: int, *, predicted=None
) -> _DualPoint:
    """The inner minimum at ``g``: by Newton from ``predicted`` (the last point's minimum
    moved along its force sensitivity) where that ends at a minimum (:func:`_newton_near`),
    else minimised from ``P_start``."""
    inner = system.at(g)
    if predicted is not None:
        near = _newton_near(inner, predicted, tol)
        if near is not None:
            return _DualPoint(near.x, inner.energy(near.x) + float(g @ system.e), near.iterations, 0)
    # minimise first: Newton alone may land on a saddle of the potential (merged
    # contacts), whose value would overstate the dual
    out = minimise_then_polish(inner, (P_start,), tol=tol, max_iter=max_iter)
    P = np.maximum(out.x, 0.0)
    Q = inner.energy(P) + float(g @ system.e)
    return _DualPoint(P, Q, out.newton_steps, out.minimiser_steps)


def _newton_near(inner: MacroSystem, P_start: np.ndarray, tol: float) -> NewtonOutcome | None:
    """Newton from ``P_start`` (the last dual point's minimum moved along its force
    sensitivity), kept where it ends at a minimum of the potential not above the start's
    value: converged, forces ``>= 0`` (its zero residual then holds the bound's
    conditions), stable (a strict local minimum on the contact set,
    :meth:`~.system.MacroSystem.stable`, not a saddle). Else None, and the minimiser runs
    (from the last minimum, as before). Eight merged spheres under load: the three ascent
    steps' minimisations (15 L-BFGS-B steps each) replaced by 5, 2 and 1 Newton steps on
    the same path to the same forces, the macro step 0.091 -> 0.043 s."""
    out = run_newton(inner, P_start, tol=tol, max_iter=_NEAR_STEPS, plateau=_NEAR_PLATEAU)
    if not out.converged or np.any(out.x < 0.0) or not inner.stable(out.x):
        return None
    start = inner.energy(P_start)
    # rounding: the start can be the minimum itself (Newton converged in 0-1 steps)
    if inner.energy(out.x) > start + 1e-13 * abs(start):
        return None
    return out


def _balanced(system: MacroSystem, P: np.ndarray, tol: float) -> bool:
    r = system.E @ P - system.e
    return float(np.linalg.norm(r)) <= tol * max(float(np.linalg.norm(P)), 1e-300)


def _ascent_step(H: np.ndarray, grad: np.ndarray) -> np.ndarray:
    # H is PSD but singular when too few asperities touch to fix every rigid-body
    # unknown: regularise slightly (Levenberg) so the step stays an ascent direction.
    mu = 1e-10 * max(float(np.trace(H)), 1e-300)
    return np.linalg.solve(H + mu * np.eye(len(grad)), grad)


def levelled_retry(system: MacroSystem, x1: np.ndarray | None, **newton_options) -> NewtonOutcome | None:
    """Newton again from ``x1``, the cold start with the face turned along the tips' plane
    (:func:`.start.levelling_tilt`; None: their heights lie on no plane): its outcome when it
    converges to a stable root, else None. From no tilt a face set askew reaches only the
    tips on one side of the pivot and Newton stalls. The caller tries the plain start first,
    so a converging scene's path is unchanged, and only where some forces balance the
    moments (a pivot outside the tips' hull, where no start converges, is not retried)."""
    if x1 is None:
        return None
    again = run_newton(system, x1, **newton_options)
    return again if again.converged and system.stable(again.x) else None


def balance_feasible(system: MacroSystem) -> bool:
    """Whether some forces ``P >= 0`` at the tips satisfy the equilibrium rows ``E P = e``
    (under tilt: whether the pivot lies in the tips' convex hull), by a linear program."""
    if system.E.shape[0] < 2:
        return True
    out = linprog(np.zeros(system.n), A_eq=system.E, b_eq=system.e, bounds=(0.0, None), method="highs")
    return out.status != 2  # 2: infeasible; anything else is no proof that it is
