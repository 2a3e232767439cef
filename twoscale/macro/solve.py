"""``solve_macro``: tip forces with interaction, penetration or load control, tilt."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from ..control import Loading
from ..influence.base import InfluenceProvider
from ..options import MacroOptions
from .checks import check_load as _check_load, check_scene as _check_scene
from .interaction import MatrixFreeInteraction, sampled_operator_error
from .result import MacroResult
from .reach import among, reaching, widened
from .start import MacroStart, cold_start, levelled_start, rigid_start
from .newton import PLATEAU_DROP
from .robust import FAST_STEPS, balance_feasible, levelled_retry, minimise_then_polish, run_newton, solve_dual
from .system import MacroSystem

#: Default largest N solved with a dense interaction matrix (32 MB at 2,000).
DENSE_MAX = MacroOptions.dense_max


#: Above this many asperities a stalled Newton is not followed by the safe path
#: (:mod:`.robust`): its dual ascent costs tens of seconds there (2,000 tips with merged
#: contacts: 21 s of a 27 s macro step, dense), more than the micro step that follows;
#: the macro forces only size the patches and start the micro step.
SAFE_PATH_MAX_TIPS = 1000

#: Newton stops when its residual, near a solution, has not halved in this many steps
#: (:func:`.newton.newton`'s ``stall``), and each step factorises the active block. Above
#: ``SAFE_PATH_MAX_TIPS`` no safe path follows (2,596 spheres, a few close pairs: 20 steps,
#: 11 s of CPU, stagnating at 3.3e-4 from step 11 on; the micro step needs only its forces
#: near a solution to size the patches); below, the safe path follows sooner than the
#: plateau's 1 % would send it (662 spheres, a merged pair whose force Newton moved from one
#: tip to the other: 11 steps from 9.7e-3 to 7.7e-3, the macro step 0.33 -> 0.21 s; of 499
#: tip scenes of 20-1,000 tips, seeds 0-6, 28 reach the safe path 1-16 steps sooner, and
#: none converged by Newton is handed over).
STALL_STEPS = 4

#: Up to ``SAFE_PATH_MAX_TIPS`` Newton hands over to the safe path when its residual has
#: not fallen by 1 % in this many steps (:func:`.newton.newton`'s ``plateau``): 8 merged
#: spheres sat at 1.14e-2 from step 2 to 20 (0.33 s of 0.41). Two steps, not four: of 133
#: tip scenes up to 1,000 tips the same 13 take the safe path, 2-6 steps sooner (761
#: paraboloids: 0.156 -> 0.108 s); none converged by Newton is handed over.
PLATEAU_STEPS = 2

#: Where the caller would defer the safe path at the cold start's approach (``defer_safe_path``),
#: the plateau is a fall of under this fraction in those steps: the stalled iterate only starts
#: the union CG there (49 merged spheres: 8 Newton steps at 6.8e-2 instead of 11 at 6.3e-2, the
#: CG's iterations 26 against 27).
DEFERRED_PLATEAU_DROP = 0.1


def solve_macro(
    provider: InfluenceProvider,
    tips,
    z,
    laws,
    loading: Loading,
    options: MacroOptions | None = None,
    *,
    self_compliance: bool = True,
    start: MacroStart | None = None,
) -> MacroResult:
    """Tip forces of N interacting asperities (docs/method.md section 2; paper eqs. 4-5, 11-12).

    Solves ``P_k = f_k(delta_k) H(delta_k)`` with ``delta_k = d - z_k - [beta (x_k - px)
    + alpha (y_k - py)] - sum_{l != k} T_kl P_l - c_k P_k`` by Newton-Raphson on the
    forces, globalised by a backtracking line search on the residual norm with the
    forces kept >= 0 along the search path. Where that stalls (contacts so close that
    they merge: the compliance ``diag(1/f_k') + T`` is then indefinite), a safe path
    takes over (:mod:`twoscale.macro.robust`): the equations are the optimality
    conditions of a potential bounded below on ``P >= 0``; it is minimised by L-BFGS-B,
    with the rigid-body unknowns found by Newton ascent on the concave dual, and the
    result is polished by Newton. The safe path assumes a symmetric ``T``.

    Parameters
    ----------
    provider : InfluenceProvider
        The body. ``T_kl = provider.point_compliance(tips, tips)`` off the diagonal
        (mm/N); ``c_k = provider.smooth_self_compliance(tips)`` on it.
    tips : (N, 2) array, mm
        Tip positions (distinct).
    z : (N,) array, mm
        Tip recesses: asperity k touches when ``d > z_k``.
    laws : AsperityLaw or sequence of N AsperityLaw
        Each asperity's own law on the half-space (one law is used for all).
    loading : Loading
        Exactly one of ``penetration`` (rigid approach d, mm) and ``total_load`` (W > 0,
        N); ``tilt`` (only with ``total_load``): a ball-and-socket joint, adding the angles
        alpha (about x) and beta (about y), radians, with zero moment about ``pivot`` (mm).
    options : MacroOptions, optional
        The Newton iteration's ``tol``, ``max_iter``, ``dense_max`` and
        ``operator_rtol`` (below; default :class:`~twoscale.options.MacroOptions`).
    self_compliance : bool, default True
        Add ``c_k`` (zero on the half-space). Set False when the laws already contain
        the body's own compliance (e.g. tabulated from single-asperity solves on it).
    options.tol : float, default 1e-10
        Relative residual: ``||r||_2 <= tol * ||P||_2``, with ``r`` the force residuals ``P_k -
        f_k(delta_k)`` and the equilibrium rows (moments over the RMS tip distance from the pivot), N.
    options.max_iter : int, default 100
        Maximum Newton steps; reaching it gives ``converged=False``.
    options.dense_max : int, default 2000
        Largest N solved with the dense ``N x N`` interaction matrix (LU per Newton step). Above
        it the interaction is matrix-free (:mod:`twoscale.macro.interaction`): products by
        ``provider.point_operator(tips, tips, rtol=operator_rtol)``, Newton steps by conjugate
        gradients, memory ``O(N)``; the operator's error at the solution, measured on a sample
        of tips, is reported (``operator_error``).
    options.operator_rtol : float, default 1e-6
        Accuracy asked of the matrix-free point operator (relative to ``max |u|``); the forces
        then solve the macro equations with ``T`` perturbed by about that much.
    start : MacroStart, optional
        Warm start (:mod:`twoscale.macro.start`): initial forces (N, this solve's tip
        order), approach (mm) and tilt (rad), e.g. a neighbouring position's solution.
        Default: the cold start (no force; under load control the approach at which the
        asperities, ignoring interaction, carry the load). The answer is the same to
        ``tol``; only the number of Newton steps changes.

    Returns
    -------
    MacroResult
    """
    return macro_step(provider, tips, z, laws, loading, options, MacroHandover(self_compliance, start))


@dataclass(frozen=True)
class MacroHandover:
    """How :func:`macro_step` starts and hands over (:func:`solve_macro`'s keywords, and
    ``defer_safe_path``: asked with Newton's last rigid-body unknowns, ``[d]`` under load
    control, else empty, when it stalls; True hands that iterate on without the safe path,
    ``safe_path_deferred`` in the result)."""

    self_compliance: bool = True
    start: MacroStart | None = None
    defer_safe_path: Callable[[np.ndarray], bool] | None = None


def macro_step(provider, tips, z, laws, loading: Loading, options, how: MacroHandover) -> MacroResult:
    """:func:`solve_macro` with its keywords as a :class:`MacroHandover`; under penetration
    control on a body whose surface only sinks, among the tips that reach it (:mod:`.reach`)."""
    keep = reaching(provider, tips, z, laws, loading)
    if keep is None:
        return _macro_step(provider, tips, z, laws, loading, options, how)
    start = None if how.start is None else replace(how.start, forces=np.asarray(how.start.forces)[keep])
    sub = (np.asarray(tips, dtype=float)[keep], np.asarray(z, dtype=float)[keep], among(laws, keep))
    result = _macro_step(provider, *sub, loading, options, replace(how, start=start))
    return widened(result, keep, provider, tips, z, loading.penetration)


def _macro_step(provider, tips, z, laws, loading: Loading, options, how: MacroHandover) -> MacroResult:
    """The macro step on every tip given: the interaction (dense up to ``dense_max`` tips,
    else matrix-free), the cold or warm start, Newton and the safe path."""
    self_compliance, start = how.self_compliance, how.start
    t0 = time.perf_counter()
    options = MacroOptions() if options is None else options
    tol, max_iter, dense_max, operator_rtol = options.tol, options.max_iter, options.dense_max, options.operator_rtol
    penetration, total_load, tilt, pivot = loading.penetration, loading.total_load, loading.tilt, loading.pivot
    tips, z, stack = _check_scene(tips, z, laws)
    mode = _check_load(penetration, total_load, tilt, pivot, tol, max_iter)
    if isinstance(dense_max, bool) or not isinstance(dense_max, (int, np.integer)) or dense_max < 1:
        raise ValueError(f"dense_max must be an integer >= 1, got {dense_max!r}")
    if not (np.isfinite(operator_rtol) and 0.0 < operator_rtol < 1.0):
        raise ValueError(f"operator_rtol must be in (0, 1), got {operator_rtol!r}")
    if len(tips) <= dense_max:
        T = _interaction(provider, tips, self_compliance)
    else:
        T = _matrix_free_interaction(provider, tips, self_compliance, operator_rtol)
    t1 = time.perf_counter()
    system = _build_system(T, tips, z, stack, penetration, total_load, tilt, pivot)
    cold = lambda: cold_start(system, z, stack, penetration, total_load, tilt)  # noqa: E731
    levelled = (lambda: levelled_start(system, z, stack, total_load)) if tilt else None
    if start is None:
        first = cold()
        x, converged, message, steps, residuals, path = _newton_then_safe(
            system, first.x, tol, max_iter, how.defer_safe_path, levelled, merging=first.merging
        )
    else:  # the cold start's forces are not needed, nor its approach when the start has one
        x0 = start.unknowns(len(z), rigid_start(z, stack, total_load, tilt, start))
        x, converged, message, steps, residuals, path = _warm_then_cold(system, x0, cold, levelled, tol, max_iter, how)
    t2 = time.perf_counter()
    P, g = system.split(x)
    delta = system.delta(x)
    d = float(penetration) if mode == "penetration" else float(g[0])
    angles = (float(g[1]), float(g[2])) if tilt else None
    timings = {"compliance": t1 - t0, "newton": t2 - t1}
    extra = {}
    if isinstance(T, MatrixFreeInteraction):
        error = sampled_operator_error(provider, tips, T, P)
        timings["error_check"] = time.perf_counter() - t2
        if T.cg_failures:
            message += f" ({T.cg_failures} Newton steps with an inexact CG solve)"
        extra = {
            "interaction": "matrix-free",
            "operator_rtol": float(operator_rtol),
            "operator_error": error,
            "krylov_iterations": int(T.cg_iterations),
        }
    timings["total"] = time.perf_counter() - t0
    return MacroResult(
        forces=P,
        penetration=d,
        tilt=angles,
        pivot=(float(pivot[0]), float(pivot[1])),
        local_penetrations=delta,
        in_contact=delta > 0,
        converged=converged,
        message=message,
        iterations=steps,
        residuals=residuals,
        timings_s=timings,
        safe_path=bool(path),
        safe_path_deferred=path == "deferred",
        **extra,
    )


def _warm_then_cold(system: MacroSystem, x0: np.ndarray, cold, levelled, tol: float, max_iter: int, how):
    """Newton from the warm start ``x0``, or the cold solve (``cold()``, with the levelled
    retry) where ``x0`` leaves every tip off the body: Newton's Jacobian then has no contact
    rows and the safe path's dual ascent no finite step (a load history askew by 0.2 rad
    warm-started at the micro step's approach, 0.1 mm below the tips' one). Returns what
    :func:`_newton_then_safe` returns."""
    if system.n == 0 or np.any(system.delta(x0) > 0):
        return _newton_then_safe(system, x0, tol, max_iter, how.defer_safe_path)
    x, converged, message, steps, residuals, path = _newton_then_safe(
        system, cold().x, tol, max_iter, how.defer_safe_path, levelled
    )
    return x, converged, f"{message} (from the cold start: the warm one touched no tip)", steps, residuals, path


def _newton_then_safe(
    system: MacroSystem, x0: np.ndarray, tol: float, max_iter: int, defer=None, levelled=None, *, merging=False
):
    """Projected Newton with backtracking from the cold start; if it fails, again from
    ``levelled()`` (a tilted cold start, :func:`.robust.levelled_retry`); if that fails too, the
    safe path (:mod:`.robust`). Returns (x, converged, message, Newton steps, residual
    history, the safe path: "" not needed, "taken", "skipped" or "deferred" by ``defer``).

    ``merging`` (the secant start's problem not definite, penetration control): the safe path
    at once where it would be taken, without Newton first. On 12 such sweep scenes of 75-849
    tips Newton had stalled on 8 before the safe path (#46: 9 steps); the macro step took
    0.29-0.60 of the CPU there and 0.97-1.32 on the four where Newton converged (ms), the
    forces within 2e-10 of the largest but on seed 7's #196, where a merged pair shares
    its load otherwise (total within 8e-6, the potential lower by 9e-6 of it)."""
    if merging and system.G.shape[1] == 0 and system.n <= SAFE_PATH_MAX_TIPS and not (defer and defer(x0[system.n :])):
        return _safe_path(system, x0, (x0,), tol, max_iter, None, "the secant start's problem is not definite")
    W = float(system.e[0]) if system.e.size else 0.0
    plateau = PLATEAU_STEPS if system.n <= SAFE_PATH_MAX_TIPS else None
    steps = min(max_iter, FAST_STEPS)
    drop = DEFERRED_PLATEAU_DROP if plateau and defer is not None and defer(x0[system.n :]) else PLATEAU_DROP
    fast = run_newton(system, x0, tol=tol, max_iter=steps, scale_floor=W, stall=STALL_STEPS, plateau=plateau, drop=drop)
    if fast.converged and system.stable(fast.x):
        return fast.x, True, fast.message, fast.iterations, fast.residuals, ""
    again = None
    if levelled is not None and system.n <= SAFE_PATH_MAX_TIPS and balance_feasible(system):
        again = levelled_retry(system, levelled(), tol=tol, max_iter=steps, scale_floor=W, plateau=PLATEAU_STEPS)
    if again is not None:
        message = f"{again.message} from the face turned along the tips' plane"
        return again.x, True, message, fast.iterations + again.iterations, fast.residuals + again.residuals, ""
    if not fast.converged and fast.iterations >= max_iter:
        return fast.x, False, fast.message, fast.iterations, fast.residuals, ""
    skip, path = None, "skipped"
    if system.n > SAFE_PATH_MAX_TIPS:
        # merged contacts among thousands of tips: the micro step resolves them on the real contact
        # (its patches reach as far as the indenters can touch; under load control it corrects the
        # approach); the safe path would cost more than the solve
        skip = f"with {system.n} asperities"
    elif not balance_feasible(system):
        # the safe path's dual ascent cannot end (four tilted spheres: 15 inner minimisations,
        # 2.2 s of a 3.3 s solve, then Newton's iterate handed on all the same); the real
        # contacts, spread over the spheres, can balance what the tips cannot
        skip = "no forces at the tips balance the moments about the pivot (outside their convex hull):"
    elif defer is not None and not fast.converged and defer(fast.x[system.n :]):
        # a stall only: an unstable equilibrium's forces size the box short (16 merged
        # paraboloids: the union CG's box grew once, 44 iterations against 22 after the safe path)
        skip, path = "the safe path deferred (the union CG on a small box needs none):", "deferred"
    if skip is not None:
        why = (
            "Newton converged to an unstable equilibrium (merged contacts)"
            if fast.converged
            else f"Newton stalled ({fast.message})"
        )
        message = f"{why}; {skip} the micro step starts from Newton's last iterate"
        return fast.x, False, message, fast.iterations, fast.residuals, path
    why = (
        "Newton converged to an unstable equilibrium (active compliance indefinite: merged contacts)"
        if fast.converged
        else f"Newton stalled ({fast.message})"
    )
    # a saddle is a stationary point of the potential: the minimiser must not start there
    return _safe_path(system, x0, (x0,) if fast.converged else (x0, fast.x), tol, max_iter, fast, why)


def _safe_path(system: MacroSystem, x0: np.ndarray, starts, tol: float, max_iter: int, fast, why: str):
    """The safe path (:mod:`.robust`) after Newton's attempt ``fast`` (None: none made), as
    :func:`_newton_then_safe` returns it."""
    if system.G.shape[1] == 0:
        safe = minimise_then_polish(system, starts, tol=tol, max_iter=max_iter)
    else:
        safe = solve_dual(system, x0, tol=tol, max_iter=max_iter)
    x = safe.x
    if fast is not None and not safe.converged and _residual_norm(system, fast.x) < _residual_norm(system, x):
        # a failed safe path can end far from any solution (a dual ascent that cannot balance
        # the moments with point forces sent the approach to 1e7 mm and the micro step sized
        # a patch as the whole sphere): the micro step starts from the better iterate
        x = fast.x
    r = system.residual(x)
    P = x[: system.n]
    norm = float(np.linalg.norm(r))
    W = float(system.e[0]) if system.e.size else 0.0
    final = norm / max(float(np.linalg.norm(P)) or W, norm) if norm > 0 else 0.0
    before = (fast.iterations, fast.residuals) if fast is not None else (0, ())
    message = f"{why}; {safe.message}"
    return x, safe.converged, message, before[0] + safe.newton_steps, before[1] + (final,), "taken"


def _residual_norm(system: MacroSystem, x: np.ndarray) -> float:
    r = system.residual(x)
    return float(np.linalg.norm(r)) if np.all(np.isfinite(r)) else np.inf


def _interaction(provider: InfluenceProvider, tips: np.ndarray, self_compliance: bool) -> np.ndarray:
    """``T`` (mm/N): point compliance off the diagonal, smooth self-compliance on it."""
    T = np.asarray(provider.point_compliance(tips, tips), dtype=float)  # (a new array: the caller's)
    n = len(tips)
    if T.shape != (n, n):
        raise ValueError(f"provider.point_compliance returned shape {T.shape}, expected {(n, n)}")
    diag = np.arange(n)
    T[diag, diag] = 0.0
    if not np.all(np.isfinite(T)):
        k, l = np.argwhere(~np.isfinite(T))[0]
        raise ValueError(f"tips {k} and {l} coincide or the compliance is not finite: {tips[k]!r}, {tips[l]!r}")
    if self_compliance:
        T[diag, diag] = np.asarray(provider.smooth_self_compliance(tips), dtype=float)
    return T


def _matrix_free_interaction(
    provider: InfluenceProvider, tips: np.ndarray, self_compliance: bool, rtol: float
) -> MatrixFreeInteraction:
    """``T`` as the provider's point operator plus the smooth self-compliance."""
    close = cKDTree(tips).query_pairs(1e-12 * (1.0 + float(np.max(np.abs(tips)))), output_type="ndarray")
    if len(close):
        k, l = close[0]
        raise ValueError(f"tips {k} and {l} coincide: {tips[k]!r}, {tips[l]!r}")
    n = len(tips)
    diag = np.asarray(provider.smooth_self_compliance(tips), dtype=float) if self_compliance else np.zeros(n)
    if diag.shape != (n,) or not np.all(np.isfinite(diag)):
        raise ValueError(f"provider.smooth_self_compliance returned {diag.shape}, expected finite {(n,)}")
    return MatrixFreeInteraction(provider.point_operator(tips, tips, rtol=rtol), diag)


def _build_system(T, tips, z, stack, penetration, total_load, tilt, pivot) -> MacroSystem:
    n = len(z)
    if total_load is None:
        return MacroSystem(T, float(penetration) - z, np.zeros((n, 0)), np.zeros((0, n)), np.zeros(0), stack)
    if not tilt:
        return MacroSystem(T, -z, np.ones((n, 1)), np.ones((1, n)), np.array([float(total_load)]), stack)
    X = tips[:, 0] - pivot[0]
    Y = tips[:, 1] - pivot[1]
    L = float(np.sqrt(np.mean(X * X + Y * Y))) or 1.0
    G = np.column_stack([np.ones(n), -Y, -X])  # unknowns (d, alpha, beta)
    E = np.vstack([np.ones(n), X / L, Y / L])
    return MacroSystem(T, -z, G, E, np.array([float(total_load), 0.0, 0.0]), stack)
