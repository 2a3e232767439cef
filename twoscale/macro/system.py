"""The macro equations as a residual and its Newton step (paper eqs. 4-5, 11-12).

Unknowns ``x = [P_1..P_N, g]`` with ``g`` empty (penetration control), ``[d]`` (load
control) or ``[d, alpha, beta]`` (load control with tilt). With ``X_k = x_k - px``,
``Y_k = y_k - py``:

    delta_k = d - z_k - beta X_k - alpha Y_k - sum_l T_kl P_l
    r_k     = P_k - f_k(delta_k)              (f_k = 0 for delta_k <= 0)
    r_W     = sum_k P_k - W
    r_x     = sum_k X_k P_k / L,  r_y = sum_k Y_k P_k / L

``T`` is the point compliance with its singular diagonal replaced by the smooth
self-compliance ``c_k`` (0 on the half-space), and ``L`` a length that puts the moment
rows in newtons. ``r`` is C1 in ``x`` where the laws start with zero slope (Hertz), and
semismooth otherwise; the Jacobian used is ``dr/dx`` with ``f_k' = 0`` for
``delta_k <= 0``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..laws import LawStack
from ..mixed_precision import refined_solve
from .interaction import MatrixFreeInteraction, krylov_newton_step


@dataclass(frozen=True)
class MacroSystem:
    """Residual and Newton step of the macro equations; see the module docstring.

    Attributes
    ----------
    T : (N, N) array or MatrixFreeInteraction, mm/N
        Interaction compliance, diagonal = smooth self-compliance; matrix-free for many
        asperities (:mod:`twoscale.macro.interaction`: Newton steps by CG).
    offset : (N,) array, mm
        ``d - z_k`` under penetration control, ``-z_k`` otherwise.
    G : (N, m) array
        ``d delta / d g`` (columns for d, alpha, beta; m = 0, 1 or 3).
    E : (m, N) array
        Equilibrium rows (1, X/L, Y/L).
    e : (m,) array, N
        Their right-hand sides (W, 0, 0).
    laws : LawStack
    last_delta : LastDelta
        The local penetrations at the last unknowns asked for (:meth:`delta`).
    """

    T: np.ndarray
    offset: np.ndarray
    G: np.ndarray
    E: np.ndarray
    e: np.ndarray
    laws: LawStack
    last_delta: "LastDelta" = field(default_factory=lambda: LastDelta(), repr=False, compare=False)

    @property
    def n(self) -> int:
        return self.T.shape[0]

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return x[: self.n], x[self.n :]

    def delta(self, x: np.ndarray) -> np.ndarray:
        """Local penetrations (mm) at unknowns ``x`` (a new array). Newton asks for them at
        the same ``x`` twice a step (its residual, then its step's stiffnesses) and once more
        at the end (the stability check): the last answer is kept (:class:`LastDelta`), so
        each costs one product with ``T`` (1,652 tips: 1 ms dense; 4,437 matrix-free: 1.6 ms)."""
        kept = self.last_delta.at(x)
        if kept is not None:
            return kept
        P, g = self.split(x)
        return self.last_delta.keep(x, self.offset + self.G @ g - self.T @ P)

    def residual(self, x: np.ndarray) -> np.ndarray:
        """``[r_P, r_g]`` in N; see the module docstring."""
        P, _ = self.split(x)
        dl = self.delta(x)
        return np.concatenate([P - self.laws.force(dl), self.E @ P - self.e])

    def at(self, g: np.ndarray) -> "MacroSystem":
        """The penetration-control system with the extra unknowns frozen at ``g``."""
        n = self.n
        return MacroSystem(
            self.T,
            self.offset + self.G @ np.asarray(g, float),
            np.zeros((n, 0)),
            np.zeros((0, n)),
            np.zeros(0),
            self.laws,
        )

    def energy(self, P: np.ndarray) -> float:
        """Potential of the penetration-control problem (N mm), forces ``P >= 0``:
        ``sum_k Phi_k(P_k) + P.S.P / 2 - offset.P`` with ``S`` the symmetric part of T
        and ``Phi_k`` the complementary energy of law k. Its minimisers over ``P >= 0``
        solve the macro equations when ``T`` is symmetric (reciprocity)."""
        return float(np.sum(self.laws.complementary_energy(P)) + 0.5 * P @ (self.T @ P) - self.offset @ P)

    def energy_gradient(self, P: np.ndarray) -> np.ndarray:
        """Gradient of :meth:`energy` (mm): ``delta_law_k(P_k) + (S P)_k - offset_k``."""
        return self.laws.penetration(P) + 0.5 * (self.T @ P + self.T.T @ P) - self.offset

    def contact_stiffness(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Law stiffnesses ``f_k'`` (N/mm) at ``x`` and the mask of the asperities in
        contact with a positive stiffness (the active rows of the Jacobian)."""
        dl = self.delta(x)
        D = self.laws.stiffness(dl)
        return D, (dl > 0) & (D > 0)

    def force_sensitivity(self, P: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """``dP/dg`` (N per unit g) of the penetration-control solution ``P`` when the
        offset moves by ``directions @ g``: ``(I + D T) dP = D directions`` on the
        asperities in contact, zero elsewhere."""
        D, act = self.contact_stiffness(P)
        A = np.flatnonzero(act)
        out = np.zeros((self.n, directions.shape[1]))
        if A.size and isinstance(self.T, MatrixFreeInteraction):
            out[A] = self.T.solve_active(A, 1.0 / D[A], directions[A], rtol=self.T.cg_rtol).x
        elif A.size:
            K = D[A][:, None] * self.T[np.ix_(A, A)]
            K[np.arange(A.size), np.arange(A.size)] += 1.0
            out[A] = _solve(K, D[A][:, None] * directions[A])
        return out

    def stable(self, x: np.ndarray) -> bool:
        """Whether ``x`` is a stable equilibrium: the active compliance
        ``diag(1/f_k') + T_AA`` is positive definite, so the potential has a strict local
        minimum in the active forces. Where contacts merge, Newton can converge to a
        saddle instead (a solution of the equations that no loading path reaches); the
        solver then takes the safe path, whose minimiser is the stable solution."""
        D, act = self.contact_stiffness(x)
        A = np.flatnonzero(act)
        if A.size == 0:
            return True
        if isinstance(self.T, MatrixFreeInteraction):
            return self.T.definite_on(A, 1.0 / D[A])
        s = np.sqrt(D[A])
        # every tip in contact: T itself, and its symmetric part is T where T is exactly
        # symmetric (the same numbers without two copies of T: 1,013 tips, 10 of 30 ms)
        K = s[:, None] * symmetric_part(self.T if A.size == self.n else self.T[np.ix_(A, A)])
        K *= s[None, :]
        K[np.arange(A.size), np.arange(A.size)] += 1.0
        return cholesky_in_place(K) is not None

    def newton_step(self, x: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Solve ``J s = -r``. Rows of asperities out of contact (``delta_k <= 0``) are
        ``s_k = -r_k``; only the active rows and the equilibrium rows form a dense system,
        solved by :func:`_refined_solve` (with a matrix-free ``T``, by CG:
        :func:`.interaction.krylov_newton_step`)."""
        if isinstance(self.T, MatrixFreeInteraction):
            return krylov_newton_step(self, x, r)
        D, act = self.contact_stiffness(x)
        A, I = np.flatnonzero(act), np.flatnonzero(~act)
        n, m = self.n, self.G.shape[1]
        rP, rg = r[:n], r[n:]
        s = np.empty(n + m)
        s[I] = -rP[I]
        DA = D[A][:, None]
        na = A.size
        K = np.empty((na + m, na + m))
        # every tip in contact (the common case): T itself, not a gathered copy of it
        # (1,013 tips: 2 against 12 ms a step)
        np.multiply(DA, self.T if na == n else self.T[np.ix_(A, A)], out=K[:na, :na])
        K[np.arange(na), np.arange(na)] += 1.0
        K[:na, na:] = -DA * self.G[A]
        K[na:, :na] = self.E[:, A]
        K[na:, na:] = 0.0
        rhs = np.concatenate([-rP[A] - (DA * self.T[np.ix_(A, I)]) @ s[I], -rg - self.E[:, I] @ s[I]])
        sol = _refined_solve(K, rhs)
        s[A] = sol[:na]
        s[n:] = sol[na:]
        return s


class LastDelta:
    """One entry: the unknowns ``x`` last asked for and their local penetrations, held by
    copies (a caller may change its arrays after). Owned by one :class:`MacroSystem`."""

    def __init__(self) -> None:
        self._x: np.ndarray | None = None
        self._delta: np.ndarray | None = None

    def at(self, x: np.ndarray) -> np.ndarray | None:
        """A copy of the penetrations kept for unknowns equal to ``x``, else None."""
        if self._x is None or self._x.shape != np.shape(x) or not np.array_equal(self._x, x):
            return None
        return self._delta.copy()

    def keep(self, x: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """Keep ``delta`` for ``x``; returns ``delta``."""
        self._x, self._delta = np.array(x, dtype=float, copy=True), np.array(delta, copy=True)
        return delta


def cholesky_in_place(K: np.ndarray):
    """The Cholesky factor of the symmetric ``K`` (overwritten) for ``scipy.linalg.cho_solve``,
    or None where ``K`` is not positive definite. LAPACK works on ``K``'s own memory (its
    transpose is ``K`` in Fortran order): no copy in or out, where numpy's factor and a
    solve by it copy the matrix twice (1,652 tips: 0.05 against 0.10-0.15 s in a fresh
    process)."""
    try:
        return sla.cho_factor(K.T, lower=False, overwrite_a=True, check_finite=False)
    except np.linalg.LinAlgError:
        return None


def symmetric_part(M: np.ndarray) -> np.ndarray:
    """``(M + M^T) / 2``; ``M`` itself (not a copy) where it is exactly symmetric, which
    gives the same numbers (``x + x`` and the halving are exact)."""
    return M if exactly_symmetric(M) else 0.5 * (M + M.T)


#: Entries compared at a time by :func:`exactly_symmetric`.
SYMMETRY_BLOCK_ENTRIES = 1 << 16


def exactly_symmetric(M: np.ndarray) -> bool:
    """``np.array_equal(M, M.T)`` by blocks of rows against the same columns, without a
    mask of ``M``'s size (1,652 tips: 2.7 MB a fresh process pays in pages)."""
    if M.ndim != 2 or M.shape[0] != M.shape[1]:
        return False
    n = M.shape[0]
    step = max(1, SYMMETRY_BLOCK_ENTRIES // max(n, 1))
    return all(np.array_equal(M[a : a + step], M[:, a : a + step].T) for a in range(0, n, step))


def _refined_solve(K: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``K x = rhs`` by a single-precision LU refined in double precision
    (:func:`~twoscale.mixed_precision.refined_solve`), else :func:`_solve`. The Jacobian
    ``I + D T`` is not symmetric, and its symmetric form ``diag(1/D) + T`` is not definite
    where close tips' point compliances outweigh ``1/D`` (eigenvalues down to -61 on 1,485
    clustered tips), so Cholesky does not apply; the single-precision LU costs half the
    double one (1,485 unknowns: 0.06 against 0.13 s a Newton step)."""
    x = refined_solve(K, rhs)
    return _solve(K, rhs) if x is None else x


def _solve(K: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    # A singular Jacobian happens (e.g. load control with no asperity in contact, or a
    # tilt no contact set can balance): fall back to the least-squares step, also when
    # LAPACK only warns that the matrix is singular to working precision.
    if K.size == 0:
        return rhs.copy()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", sla.LinAlgWarning)
            sol = sla.solve(K, rhs, check_finite=False)
        if np.all(np.isfinite(sol)):
            return sol
    except (sla.LinAlgError, sla.LinAlgWarning, ValueError):
        pass
    return np.linalg.lstsq(K, rhs, rcond=None)[0]
