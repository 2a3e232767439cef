"""The interaction ``T`` of the macro step without an ``N x N`` matrix (for many asperities).

With 10^4 asperities the dense ``T`` is 800 MB and each Newton step factorises the
active block (``O(N_A^3)``). :class:`MatrixFreeInteraction` keeps only the provider's
:meth:`~twoscale.influence.base.InfluenceProvider.point_operator` (the half-space: an
Ewald split, ``O(N log N)`` per product and error ``<= rtol`` of ``max |u|``) and the
smooth self-compliance on the diagonal; the Newton step of the macro equations is then
solved by conjugate gradients (:func:`krylov_newton_step`).

The Newton system, with ``D`` the law stiffnesses on the active set ``A`` (``delta_k > 0``),
``I`` the rest, and ``(G, E)`` the rigid-body columns and equilibrium rows::

    s_I = -r_I
    (D^-1 + T_AA) s_A - G_A s_g = -D^-1 r_A - T_AI s_I
    E_A s_A = -r_g - E_I s_I

``M = D^-1 + T_AA`` is symmetric (reciprocity: ``T_kl = T_lk`` on any linear elastic
body) and positive definite while the contacts are distinct; the ``m <= 3`` rigid-body
unknowns are eliminated by their Schur complement, so one block CG with ``m + 1``
columns gives the step. The CG tolerance follows the Newton residual (inexact Newton:
``min(0.1, ||r|| / ||P||)``, never below ``cg_rtol``), the line search of
:func:`~twoscale.macro.newton.newton` keeps the iteration globalised.
"""

from __future__ import annotations

import numpy as np

from ..influence.points import PointOperator
from ..krylov import block_cg


class MatrixFreeInteraction:
    """``T = G_off + diag(c)`` applied through a point operator; stands in for the dense
    matrix in :class:`~twoscale.macro.system.MacroSystem` (``T @ P``, ``T.T``, ``shape``).

    Parameters
    ----------
    operator : PointOperator
        Point compliance from the tips to themselves (coincident pairs contribute 0).
    diag : (N,) array, mm/N
        Smooth self-compliance ``c_k`` (0 on the half-space).
    cg_rtol : float, default 1e-12
        Tightest CG tolerance of a Newton step.
    cg_max_iter : int, default 2000
        CG iterations allowed per Newton step.

    Attributes
    ----------
    cg_iterations : int
        CG iterations taken so far (Newton steps, sensitivities, stability probes).
    cg_failures : int
        Newton steps whose CG did not reach its tolerance (the line search then judges
        the step; the final residual decides convergence).
    """

    def __init__(self, operator: PointOperator, diag: np.ndarray, *, cg_rtol: float = 1e-12, cg_max_iter: int = 2000):
        self.operator = operator
        self.diag = np.asarray(diag, dtype=float)
        self.cg_rtol, self.cg_max_iter = float(cg_rtol), int(cg_max_iter)
        n = len(self.diag)
        if operator.shape != (n, n):
            raise ValueError(f"point operator has shape {operator.shape}, expected {(n, n)}")
        self.cg_iterations = 0
        self.cg_failures = 0

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.diag), len(self.diag))

    @property
    def T(self) -> "MatrixFreeInteraction":
        """Transpose: the same operator (reciprocity)."""
        return self

    def __matmul__(self, P: np.ndarray) -> np.ndarray:
        P = np.asarray(P, dtype=float)
        d = self.diag if P.ndim == 1 else self.diag[:, None]
        return self.operator.apply(P) + d * P

    def solve_active(self, A: np.ndarray, w: np.ndarray, rhs: np.ndarray, *, rtol: float):
        """Solve ``(diag(w) + T_AA) X = rhs`` by block CG; returns the CGOutcome (an
        inexact solve counts in ``cg_failures``)."""
        out = self._cg(A, w, rhs, rtol)
        self.cg_failures += int(not out.converged)
        return out

    def _cg(self, A: np.ndarray, w: np.ndarray, rhs: np.ndarray, rtol: float):
        n = self.shape[0]
        rhs = np.asarray(rhs, dtype=float).reshape(len(A), -1)

        def matvec(x):
            full = np.zeros((n, x.shape[1]))
            full[A] = x
            return (self @ full)[A] + w[:, None] * x

        out = block_cg(matvec, 1.0 / (w + self.diag[A]), rhs, rtol=max(rtol, self.cg_rtol), max_iter=self.cg_max_iter)
        self.cg_iterations += out.iterations
        return out

    def definite_on(self, A: np.ndarray, w: np.ndarray, *, probes: int = 1, rtol: float = 1e-6, seed: int = 0) -> bool:
        """Whether ``diag(w) + T_AA`` is positive definite, as far as CG can tell: CG on
        ``probes`` random right-hand sides (to ``rtol``) meets a direction of non-positive
        curvature once its Krylov space reaches a negative eigenvalue; an eigenvalue at the
        end of the spectrum is reached in a few products (N = 10^4: 12-18 products)."""
        rhs = np.random.default_rng(seed).standard_normal((len(A), probes))
        return not self._cg(A, w, rhs, rtol).breakdown


def krylov_newton_step(system, x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Newton direction of ``system`` (a MacroSystem whose ``T`` is a
    :class:`MatrixFreeInteraction`) by CG on the active set; see the module docstring."""
    T: MatrixFreeInteraction = system.T
    n, m = system.n, system.G.shape[1]
    D, act = system.contact_stiffness(x)
    A, I = np.flatnonzero(act), np.flatnonzero(~act)
    rP, rg = r[:n], r[n:]
    s = np.zeros(n + m)
    s[I] = -rP[I]
    if A.size == 0:  # the rigid-body rows are then singular: no step for them (as the dense lstsq)
        return s
    coupling = (T @ s[:n])[A] if I.size else np.zeros(A.size)
    DA = D[A]
    f = -rP[A] / DA - coupling
    P = x[:n]
    rel = float(np.linalg.norm(r)) / max(float(np.linalg.norm(P)), float(system.e[0]) if m else 0.0, 1e-300)
    out = T.solve_active(A, 1.0 / DA, np.column_stack([f, system.G[A]]), rtol=min(0.1, rel))
    Y = out.x
    if m:
        S = system.E[:, A] @ Y[:, 1:]
        q = -rg - system.E[:, I] @ s[I] - system.E[:, A] @ Y[:, 0]
        s_g = np.linalg.lstsq(S, q, rcond=None)[0]
        s[A] = Y[:, 0] + Y[:, 1:] @ s_g
        s[n:] = s_g
    else:
        s[A] = Y[:, 0]
    return s


#: Exact rows of the operator error check made at a time: 16 rows of 6,933 tips stay in
#: the cache through the few passes that make them (the 256 rows at once: 0.10-0.12 s of
#: CPU, by 16: 0.05 s, the same values).
_ERROR_ROWS = 16


def sampled_operator_error(
    provider, tips: np.ndarray, interaction: MatrixFreeInteraction, P: np.ndarray, *, samples: int = 256, seed: int = 0
) -> float:
    """Measured error of the fast product at the solution: ``max_i |(T P)_i - (T_exact P)_i|
    / max_i |(T_exact P)_i|`` over ``samples`` tips drawn at random (exact rows from
    ``provider.point_compliance``, ``_ERROR_ROWS`` at a time, on the columns of the tips
    that carry a force only: 3,088 of 8,807 tips, 2,253 of 9,545 on a block, whose
    compliance each call makes anew; the diagonal is common to both and left out)."""
    n = len(tips)
    rng = np.random.default_rng(seed)
    rows = np.sort(rng.choice(n, size=min(samples, n), replace=False))
    loaded = np.flatnonzero(P)
    exact = np.zeros(len(rows))
    for a in range(0, len(rows) if loaded.size else 0, _ERROR_ROWS):
        part = rows[a : a + _ERROR_ROWS]
        G = np.array(provider.point_compliance(tips[part], tips[loaded]), dtype=float)
        own = np.searchsorted(loaded, part)
        hit = (own < loaded.size) & (loaded[np.minimum(own, loaded.size - 1)] == part)
        G[np.flatnonzero(hit), own[hit]] = 0.0
        G[~np.isfinite(G)] = 0.0
        exact[a : a + len(part)] = G @ P[loaded]
    fast = interaction.operator.apply(P)[rows]
    scale = float(np.max(np.abs(exact)))
    return float(np.max(np.abs(fast - exact))) / scale if scale > 0 else 0.0
