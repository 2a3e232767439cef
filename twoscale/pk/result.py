"""What the Polonsky-Keer kernel is asked (:class:`Tolerance`: when a row stops) and what it
answers (:class:`PKResult`: pressures, displacements, multipliers and a stop reason per row).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..stopping import StopReason

#: Give up (STAGNATED) when the KKT residual has not halved for this many iterations.
STALL_ITERATIONS = 1000


@dataclass(frozen=True)
class Tolerance:
    """When a row stops.

    Attributes
    ----------
    residual : float or None
        Converged when the KKT residual (largest |gap| on the loaded cells and largest
        interpenetration elsewhere, over the largest displacement; the constraint
        violation with moments) is at most this. None: not tested.
    change : float or None
        Converged when ``||p_new - p_old|| <= change ||p_new||`` over the last step and no
        cell off the contact penetrates (below ``-GAP_RTOL max|z|``). None: not tested.
    max_iter : int
        Most steps.
    stall : int
        With ``residual``: give up when the residual has not halved in this many steps.
    stop : callable, optional
        The caller's own test on a one-row stack, before each step after the stopping
        rule: ``stop(iteration, residual, pressure)`` (the row's flat pressure, MPa, which
        it must not keep or change) returning True ends the row (``STOPPED``), e.g. to
        enlarge the grid its pressure reached the edge of.
    """

    residual: float | None = None
    change: float | None = None
    max_iter: int = 1000
    stall: int = STALL_ITERATIONS
    stop: Callable[[int, float, np.ndarray], bool] | None = None

    def __post_init__(self):
        if self.residual is None and self.change is None:
            raise ValueError("Tolerance needs residual or change (or both), got neither")
        if self.max_iter < 0:
            raise ValueError(f"Tolerance.max_iter must be >= 0, got {self.max_iter}")

    def caller_stops(self, it: int, res: np.ndarray | None, p: np.ndarray, done: np.ndarray) -> bool:
        """Whether ``stop`` ends a one-row stack not yet finished (``res``, ``p``, ``done``:
        its residuals, pressures and finished flags, per live row)."""
        one = self.stop is not None and res is not None and len(res) == 1 and not done[0]
        return one and bool(self.stop(it, float(res[0]), p[0]))


@dataclass(frozen=True)
class PKResult:
    """Solution of :func:`pk_solve`, one entry per row of the stack.

    Attributes
    ----------
    pressure, displacement : (B, ...) arrays
        ``p`` (MPa) and ``A p`` (mm), the field shape of the input.
    multipliers : (B, k) array
        Projection coefficients of the gap on the constraint basis (load control: the
        rigid shift, mm).
    reasons : tuple of StopReason
    iterations : (B,) int array
        Steps taken.
    residual, best : (B,) arrays
        Last and best KKT residual (nan where the residual was not tested).
    denominator : (B,) array
        ``t.A t`` at a breakdown (nan elsewhere).
    products : int
        Operator products, counted per row.
    history : tuple of float
        Largest KKT residual over the live rows, per iteration (residual rule only).
    tolerance : Tolerance
    """

    pressure: np.ndarray
    displacement: np.ndarray
    multipliers: np.ndarray
    reasons: tuple
    iterations: np.ndarray
    residual: np.ndarray
    best: np.ndarray
    denominator: np.ndarray
    products: int
    history: tuple
    tolerance: Tolerance

    @property
    def converged(self) -> np.ndarray:
        """(B,) bool: which rows met the stopping test."""
        return np.array([r is StopReason.CONVERGED for r in self.reasons], dtype=bool)

    def message(self, row: int = 0) -> str:
        """The sentence a user reads for ``row``, derived from its stop reason."""
        reason, it, res = self.reasons[row], int(self.iterations[row]), float(self.residual[row])
        tol = self.tolerance
        if reason is StopReason.CONVERGED:
            return (
                f"KKT residual {res:.2e} <= tol after {it} iterations"
                if tol.residual is not None
                else f"pressure change <= {tol.change:g} after {it} iterations"
            )
        if reason is StopReason.STAGNATED:
            return (
                f"no progress: KKT residual {res:.2e} has not halved in {tol.stall} iterations "
                f"(best {float(self.best[row]):.2e}, tol {tol.residual:g})"
            )
        if reason is StopReason.STOPPED:
            return f"stopped by the caller's test after {it} iterations (KKT residual {res:.2e})"
        if reason is StopReason.BREAKDOWN:
            return f"CG breakdown (t.A t = {float(self.denominator[row]):.3e}) after {it} iterations"
        if tol.residual is not None:
            return f"KKT residual {res:.2e} > tol={tol.residual:g} after max_iter={tol.max_iter}"
        return f"pressure change > {tol.change:g} after max_iter={tol.max_iter}"
