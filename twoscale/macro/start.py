"""A warm start of the macro step: tip forces and rigid-body unknowns from a neighbouring solve.

Consecutive positions of a texture sliding over a body (a study's track) solve nearly the
same macro equations: the tips keep their forces roughly, the approach and the tilt move a
little. :class:`MacroStart` carries such a start in this solve's tip order; tips that were
not in the previous solve (entering the footprint) start unloaded. The Newton iteration
then starts from it instead of the cold start (independent asperities carrying the load);
the answer is the same to the solver's tolerance (the equations do not change).

A cold start under a free tilt turns the face along the tips' plane where their heights lie
on one (:func:`levelling_tilt`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve
from scipy.optimize import brentq

from ..laws import LawStack
from .system import MacroSystem, cholesky_in_place, symmetric_part


@dataclass(frozen=True)
class MacroStart:
    """Initial unknowns of the macro Newton iteration.

    Attributes
    ----------
    forces : (N,) array, N
        Initial tip force of each asperity of the solve, in its order (negative values
        are clipped to 0).
    penetration : float or None, mm
        Initial rigid approach d (load control; ignored under penetration control, where d
        is given). None: the cold start's.
    tilt : (alpha, beta) or None, rad
        Initial tilt angles (load control with tilt). None: 0.
    """

    forces: np.ndarray
    penetration: float | None = None
    tilt: tuple | None = None

    def __post_init__(self) -> None:
        f = np.array(self.forces, dtype=float, copy=True)
        if f.ndim != 1 or not np.all(np.isfinite(f)):
            raise ValueError(f"start forces must be a finite 1-D array (N), got shape {f.shape}")
        f.setflags(write=False)
        object.__setattr__(self, "forces", f)
        if self.penetration is not None and not np.isfinite(self.penetration):
            raise ValueError(f"start penetration must be finite (mm), got {self.penetration!r}")
        if self.tilt is not None and (len(self.tilt) != 2 or not np.all(np.isfinite(self.tilt))):
            raise ValueError(f"start tilt must be two finite angles (rad), got {self.tilt!r}")

    @classmethod
    def from_result(cls, result, index=None) -> "MacroStart":
        """The start a previous :class:`~twoscale.results.ContactResult` gives.

        Parameters
        ----------
        result : ContactResult
            A previous solve: its macro forces (``details.macro.forces`` of a two-scale
            result, else its per-tip forces), its approach and tilt.
        index : (N,) int array, optional
            For each tip of the new solve, its position in ``result``'s tips, or -1 for
            a tip the previous solve did not have (it starts unloaded). Default: the
            same tips in the same order.
        """
        macro = getattr(getattr(result, "details", None), "macro", None)
        previous = np.asarray(macro.forces if macro is not None else result.asperities.forces, dtype=float)
        tilt = None if result.tilt is None else (float(result.tilt[0]), float(result.tilt[1]))
        return cls(mapped(previous, index), float(result.penetration), tilt)

    def unknowns(self, n: int, rigid: np.ndarray) -> np.ndarray:
        """``x0 = [P, g]`` for a system of ``n`` tips whose cold-start rigid-body unknowns
        are ``rigid`` (``[]``, ``[d]`` or ``[d, alpha, beta]``): the start's values where
        it has them, the cold ones elsewhere."""
        if self.forces.shape != (n,):
            raise ValueError(f"start forces must have one entry per asperity ({n}), got {self.forces.shape[0]}")
        g = np.array(rigid, dtype=float)
        if g.size >= 1 and self.penetration is not None:
            g[0] = self.penetration
        if g.size == 3 and self.tilt is not None:
            g[1:] = self.tilt
        return np.concatenate([np.maximum(self.forces, 0.0), g])


def mapped(values: np.ndarray, index) -> np.ndarray:
    """``values`` taken at ``index`` (-1: 0), or ``values`` itself without an index."""
    values = np.asarray(values, dtype=float)
    if index is None:
        return values
    index = np.asarray(index, dtype=int)
    if index.ndim != 1 or np.any(index >= len(values)) or np.any(index < -1):
        raise ValueError(f"index must be 1-D with entries in [-1, {len(values) - 1}], got {index!r}")
    return np.where(index >= 0, values[np.maximum(index, 0)], 0.0)


#: A tilt's cold start turns the face to the tips' least-squares plane when that plane
#: explains at least this share of the heights' variance (a face set askew); otherwise none.
LEVELLING_SHARE = 0.5


def levelling_tilt(G: np.ndarray, z: np.ndarray) -> tuple[float, float]:
    """The tilt ``(alpha, beta)`` that lays the face along the tips' least-squares plane
    ``z ~ c - alpha Y - beta X`` (``G = [1, -Y, -X]``, positions from the pivot) where that
    plane explains at least :data:`LEVELLING_SHARE` of the heights' variance, else ``(0, 0)``.

    From no tilt, Newton sees only the tips the untilted face reaches: where the face is set
    askew (four spheres on a 20 mm square, heights rising 0.4 mm across it, 1 N each) those
    lie on one side of the pivot, no step balances the moments and the safe path stalls. The
    levelled start reaches them all."""
    spread = float(np.sum((z - z.mean()) ** 2))
    if spread == 0.0:
        return 0.0, 0.0
    g, _, rank, _ = np.linalg.lstsq(G, z, rcond=None)
    if rank < 3 or float(np.sum((z - G @ g) ** 2)) > (1.0 - LEVELLING_SHARE) * spread:
        return 0.0, 0.0
    return float(g[1]), float(g[2])


def independent_approach(z: np.ndarray, stack, W: float) -> float:
    """``d`` with ``sum_k f_k(d - z_k) = W`` (no interaction), by bracketing and Brent's method.

    The bracket grows from a small step by half each time, so the laws are asked only for
    tips within about 1.5 times the final approach: a tabulated law built on first use
    (a height map's stones) is never built for a stone far below the load's reach."""
    lo = float(np.min(z))
    step = max(float(np.ptp(z)) / 64.0, 1e-3 * max(abs(lo), 1.0) / 64.0, 1e-6)
    hi = lo + step
    with np.errstate(over="ignore", invalid="ignore"):  # a load beyond floating point: refused below
        while np.sum(stack.force(hi - z)) < W:
            lo, hi = hi, hi + 0.5 * (hi - float(np.min(z)))
            if not np.isfinite(hi):
                raise ValueError(f"load.total = {W!r} N: the asperities' laws cannot carry it at any finite approach")
    # Brent's method on the bracket: 8-12 law evaluations where bisection to the last bit
    # took about 50 (40 % of a one-sphere solve's CPU time went to this start); 1e-100 N takes ~200
    excess = lambda d: float(np.sum(stack.force(d - z))) - W
    return float(brentq(excess, lo, hi, xtol=1e-300, rtol=4.0 * np.finfo(float).eps, maxiter=2000))


def levelled_start(system: MacroSystem, z, stack: LawStack, total_load) -> np.ndarray | None:
    """The cold start with the face along the tips' plane (:func:`levelling_tilt`) or None."""
    alpha, beta = levelling_tilt(system.G, z)
    if alpha == 0.0 and beta == 0.0:
        return None
    level = z - system.G[:, 1:] @ np.array([alpha, beta])  # the heights under that tilt
    return np.concatenate([np.zeros(system.n), [independent_approach(level, stack, float(total_load)), alpha, beta]])


def rigid_start(z, stack: LawStack, total_load, tilt, start: MacroStart) -> np.ndarray:
    """The cold start's rigid-body unknowns (:func:`cold_start`) that a warm ``start``
    does not replace: the approach ``d0`` only when the start has none, zero tilts."""
    if total_load is None:
        return np.zeros(0)
    d0 = start.penetration if start.penetration is not None else independent_approach(z, stack, float(total_load))
    return np.array([d0, 0.0, 0.0] if tilt else [d0], dtype=float)


@dataclass(frozen=True)
class ColdStart:
    """The cold start's unknowns ``x`` and whether the secant start found its linear problem
    not positive definite (``merging``: contacts about to merge, :func:`secant_forces`)."""

    x: np.ndarray
    merging: bool = False


def cold_start(system: MacroSystem, z, stack: LawStack, penetration, total_load, tilt) -> ColdStart:
    """Cold start: under penetration control the secant start (:func:`secant_forces`);
    under load control the approach ``d0`` at which the asperities, ignoring interaction,
    carry ``W``, and no force."""
    n = len(z)
    if total_load is None:
        P = secant_forces(system, stack)
        return ColdStart(np.zeros(n), merging=True) if P is None else ColdStart(P)
    d0 = independent_approach(z, stack, float(total_load))
    return ColdStart(np.concatenate([np.zeros(n), [d0, 0.0, 0.0] if tilt else [d0]]))  # no force


def secant_forces(system: MacroSystem, stack: LawStack) -> np.ndarray | None:
    """Penetration control: the forces of the linear problem in which each law is replaced
    by its secant at the approach it would have alone, ``P_k = S_k delta_k`` with
    ``S_k = f_k(o_k) / o_k`` (``o_k = d - z_k``), coupled by the interaction:
    ``(diag(1/S) + T) P = o`` on the tips that reach the body. Interaction lowers the
    approaches, where the secant of a stiffening law overestimates the force less than
    its value alone does: Newton then needs fewer steps (the paper's seven spheres at
    d/2R = 0.1: 5 against 8 from no force; 3 against 4 at 0.5; same forces to 5e-13).
    No force (the plain cold start) with a matrix-free interaction; None where that linear
    problem is not positive definite (contacts about to merge)."""
    o = system.offset
    P = np.zeros(system.n)
    A = np.flatnonzero(o > 0)
    if A.size == 0 or not isinstance(system.T, np.ndarray):
        return P
    f = np.asarray(stack.force(o), dtype=float)[A]
    if not np.all(np.isfinite(f) & (f > 0)):
        return P
    # in single precision (a copy, so T is not changed): only a start, at half the double
    # factor's cost (1,215 tips: 10 against 18 ms); on 180 sweep scenes within 6.4e-6 of the
    # double start's largest force, and Newton's steps and outcome the same on all
    K = symmetric_part(system.T if A.size == system.n else system.T[np.ix_(A, A)]).astype(np.float32)
    K[np.arange(A.size), np.arange(A.size)] += o[A] / f
    factor = cholesky_in_place(K)
    if factor is None:
        return None
    P[A] = np.maximum(cho_solve(factor, o[A].astype(np.float32), check_finite=False), 0.0)  # not two LU solves
    return P
