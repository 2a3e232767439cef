"""Newton's method globalised by a backtracking line search on the residual norm."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

_ARMIJO = 1e-4  # sufficient decrease: ||r(x + t s)|| <= (1 - ARMIJO t) ||r(x)||
#: The line search gives up below this step. No step under 2^-21 was accepted on the sweeps'
#: 245 tip scenes of up to 300 tips (seeds 0 and 1; 10 under 2^-12), while each of their 24
#: failures evaluated the residual 40 times from 2^-40 (49 merged spheres: 40 of the macro
#: step's 87 residuals, each one law inversion per tip).
_MIN_STEP = 2.0**-24
#: A stagnation check (``stall``) applies only once the relative residual is below this:
#: farther out, Newton's global phase may take several slow steps before it converges.
STALL_RESIDUAL = 1e-2
#: The stall (``stall``) stops sooner, after a single step, when that step, from at most
#: ``STALL_RESIDUAL``, took off under this fraction of the residual: Newton has met what it
#: cannot remove (662 spheres, a merged pair whose force sat on the wrong tip: 9.70e-3 then
#: 9.69e-3, and three more steps to 8.70e-3 before the four-step stall). Over the no-stop
#: histories of 786 tip scenes of 20-2,000 tips (seeds 0-8) it stops 19 stalls 1-3 steps
#: sooner, and none that Newton goes on to solve (a step of 1 % stopped three of them).
STALL_STEP_DROP = 1e-3
#: A plateau (``plateau``): the relative residual, at most ``PLATEAU_RESIDUAL`` at the
#: window's start, fell by less than ``PLATEAU_DROP`` of itself over the window (8 spheres
#: with merged contacts: 18 steps within 1e-4 of 1.14e-2). Above that level the residual
#: of a cold start under penetration control sits at its cap of 1 for several steps
#: before Newton converges (39 spheres: 1.0, 0.9997, 1.0, 0.96, 1.0, 0.60, ..., 13 steps).
PLATEAU_RESIDUAL = 0.1
PLATEAU_DROP = 1e-2
#: The unprojected search (``Stops.unprojected``) stops Newton once this many steps in a
#: row took it without halving the relative residual. 8,897 light tips took it once at a
#: time, the next projected step then fell 6.5x and 31x; 1,494 tips on a block took it on
#: every step from the 6th (about 90 forces below zero, 14 steps from 0.997 to 0.56). Three
#: tips took it three times in a row (norm 1.15 to 1.02), then converged in five steps.
UNPROJECTED_STEPS = 4


@dataclass(frozen=True)
class Stops:
    """When Newton stops short of the tolerance (:func:`newton`'s ``stops``).

    Attributes
    ----------
    stall : int or None
        Stop when the relative residual, already below ``STALL_RESIDUAL`` ``stall`` steps
        ago, has not halved since, or one step from below it took off under
        ``STALL_STEP_DROP`` of it: near a solution Newton converges fast or not at all (a
        kink of the semismooth residual, an indefinite Jacobian where contacts merge).
    plateau : int or None
        Stop when the relative residual, at most ``PLATEAU_RESIDUAL`` ``plateau`` steps
        ago, has not fallen by ``PLATEAU_DROP`` of itself since (above ``STALL_RESIDUAL``
        too): Newton sits at a stationary point of the residual's norm that is no solution
        (merged contacts), where each further step costs a line search.
    None: no such stop.
    drop : float, default ``PLATEAU_DROP``
        The plateau's fall (a fraction of the residual at the window's start).
    unprojected : bool, default False
        Where the projected path has no decrease, search the unprojected one too instead
        of stopping with a failed line search; stop after ``UNPROJECTED_STEPS`` such steps
        in a row that did not halve the relative residual.
    """

    stall: int | None = None
    plateau: int | None = None
    drop: float = PLATEAU_DROP
    unprojected: bool = False


@dataclass(frozen=True)
class NewtonOutcome:
    """Where the iteration stopped: unknowns, residual, and how it got there."""

    x: np.ndarray
    r: np.ndarray
    converged: bool
    message: str
    iterations: int
    residuals: tuple


def newton(
    residual: Callable[[np.ndarray], np.ndarray],
    step: Callable[[np.ndarray, np.ndarray], np.ndarray],
    x0: np.ndarray,
    *,
    scale: Callable[[np.ndarray], float],
    tol: float,
    max_iter: int,
    project: Callable[[np.ndarray], np.ndarray] = lambda x: x,
    stops: Stops = Stops(),
) -> NewtonOutcome:
    """Solve ``residual(x) = 0`` by Newton with backtracking.

    Parameters
    ----------
    residual : callable, x -> r
    step : callable, (x, r) -> Newton direction s solving ``J(x) s = -r``
    x0 : array, initial unknowns
    scale : callable, x -> positive float
        Converged when ``||r||_2 <= tol * scale(x)`` (or ``r == 0``).
    tol : float
        Relative residual tolerance.
    max_iter : int
        Maximum number of Newton steps.
    project : callable, x -> x, default identity
        Projection onto the admissible set, applied along the search path
        ``project(x + t s)`` (here: forces >= 0).
    stops : Stops, default none
        Stops short of ``tol`` where Newton stagnates (:class:`Stops`).

    Notes
    -----
    Each step is halved until the residual norm decreases by the Armijo factor along the
    projected path ``project(x + t s)``. Where the projection blocks every decrease (forces
    at zero that the direction takes below zero: 8,897 light tips under load stopped at a
    relative residual of 0.15 this way), ``stops.unprojected`` searches the unprojected path
    too; a converged answer is projected (kept only within the tolerance). If no step down to ``2^-24``
    decreases the residual, the iteration stops with ``converged=False``.
    """
    x = np.array(x0, dtype=float)
    r = residual(x)
    norm = float(np.linalg.norm(r))
    history = [_relative(norm, scale(x))]
    streak = 0  # steps in a row along the unprojected path
    for it in range(max_iter + 1):
        if norm <= tol * scale(x) or norm == 0.0:
            admissible = _admissible(residual, project, x, r, norm, tol * scale(x))
            if admissible is not None:
                x, r = admissible
                return NewtonOutcome(x, r, True, f"converged in {it} Newton steps", it, tuple(history))
        if not np.isfinite(norm):
            return NewtonOutcome(x, r, False, f"residual not finite at step {it}", it, tuple(history))
        if it == max_iter:
            break
        s = step(x, r)
        found = _line_search(residual, x, s, norm, project)
        streak = 0 if found is not None else streak + 1
        if found is None and stops.unprojected:
            found = _line_search(residual, x, s, norm, lambda y: y)
        if found is None:
            msg = (
                f"line search failed at Newton step {it + 1}: no decrease of the "
                f"residual {norm:.3e} along the Newton direction"
            )
            return NewtonOutcome(x, r, False, msg, it, tuple(history))
        x_new, r_new, norm_new = found
        x, r, norm = x_new, r_new, norm_new
        history.append(_relative(norm, scale(x)))
        stall, plateau = stops.stall, stops.plateau
        stalled = _stagnates(history, stall) if stall is not None else None
        if stalled and not norm <= tol * scale(x):
            msg = f"Newton stagnated at step {it + 1}: relative residual {history[-1]:.3e}, {stalled}"
            return NewtonOutcome(x, r, False, msg, it + 1, tuple(history))
        if plateau is not None and _flat(history, plateau, stops.drop) and not norm <= tol * scale(x):
            msg = f"Newton stagnated at step {it + 1}: relative residual {history[-1]:.3e}, down by under {stops.drop:.0%} in {plateau} steps"
            return NewtonOutcome(x, r, False, msg, it + 1, tuple(history))
        if (
            streak >= UNPROJECTED_STEPS
            and history[-1] > 0.5 * history[-1 - UNPROJECTED_STEPS]
            and not norm <= tol * scale(x)
        ):
            msg = f"Newton stagnated at step {it + 1}: relative residual {history[-1]:.3e}, not halved in {UNPROJECTED_STEPS} unprojected steps"
            return NewtonOutcome(x, r, False, msg, it + 1, tuple(history))
    msg = f"not converged after max_iter={max_iter} Newton steps: relative residual {history[-1]:.3e} > tol={tol:.1e}"
    return NewtonOutcome(x, r, False, msg, max_iter, tuple(history))


def _admissible(residual, project, x, r, norm, bound):
    """``(x, r)`` projected, if the projection keeps the residual within ``bound`` (after
    an unprojected step, forces may sit below zero by up to the residual), else None."""
    xp = project(x)
    if xp is x or np.array_equal(xp, x):
        return x, r
    rp = residual(xp)
    return (xp, rp) if float(np.linalg.norm(rp)) <= bound else None


def _line_search(residual, x, s, norm, project):
    """``(x_new, r_new, norm_new)`` at the longest step ``t = 2^-j`` with an Armijo decrease
    along ``project(x + t s)``, or None below ``_MIN_STEP``."""
    t = 1.0
    while t >= _MIN_STEP:
        x_new = project(x + t * s)
        r_new = residual(x_new)
        norm_new = float(np.linalg.norm(r_new))
        if norm_new <= (1.0 - _ARMIJO * t) * norm:
            return x_new, r_new, norm_new
        t *= 0.5
    return None


def _stagnates(history: list, window: int) -> str | None:
    """How the stall shows (for the message), or None."""
    if len(history) >= 2 and history[-2] <= STALL_RESIDUAL and history[-1] > (1.0 - STALL_STEP_DROP) * history[-2]:
        return f"down by under {STALL_STEP_DROP:.1%} in one step"
    if len(history) > window and history[-1 - window] <= STALL_RESIDUAL and history[-1] > 0.5 * history[-1 - window]:
        return f"not halved in {window} steps"
    return None


def _flat(history: list, window: int, drop: float) -> bool:
    if len(history) <= window:
        return False
    before = history[-1 - window]
    return before <= PLATEAU_RESIDUAL and history[-1] > (1.0 - drop) * before


def _relative(norm: float, scale: float) -> float:
    # ||r|| / max(scale, ||r||): 1 at a start with no force (P = 0, r = -f), ~||r||/||P|| near the end
    return norm / max(scale, norm) if norm > 0 else 0.0
