"""Johnson's matrix-inversion method with an active set, on the dense cell matrix.

The classical reference of the paper (its p_r): the influence matrix of every cell
where an indenter has material is formed once (``provider.grid_matrix``); on a trial
contact set S the equations

    A_SS p_S - B_S m = -z_S,      h^2 B_S^T p_S = target

are solved (``B``, ``m``, ``target`` as in :mod:`twoscale.reference._problem`: no
unknown for penetration control, ``d`` for load control, ``d, beta, alpha`` with tilt)
by a factorisation of ``A_SS`` and a small Schur complement for ``m``. Cells with
negative pressure leave S, cells that interpenetrate join it, until S is stable; the
answer then satisfies the KKT conditions exactly (``p >= 0`` on S, gap ``>= -tol``
outside). Memory is ``8 n^2`` bytes and each pass costs ``n_S^3 / 3`` flops (n = cells
with material, n_S = trial contact cells): about 10^4 cells is the practical limit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..indenters import Surface
from ..influence.base import InfluenceProvider
from ..options import settings_from
from ..results import ContactResult
from ._problem import ContactProblem, Outcome, build_result, initial_active_set, make_problem, trivial_result

#: Largest number of cells with material the dense solver accepts by default.
MAX_DENSE_CELLS = 12_000


def is_symmetric(A: np.ndarray) -> bool:
    """Whether ``A`` equals its transpose to within ~1e-9 (relative), by one pair of
    products: ``y.A x = x.A y`` for random ``x, y`` (two matrix-vector products, not a pass
    over the transpose). A finite block's cell matrix is not symmetric: its sources sit on
    the mesh and its receivers are interpolated, so it is reciprocal to ~1e-3 only."""
    x, y = np.random.default_rng(0).standard_normal((2, A.shape[0]))
    Ax = A @ x
    return abs(float(y @ Ax) - float(x @ (A @ y))) <= 1e-9 * float(np.linalg.norm(y) * np.linalg.norm(Ax))


def _factor_solve(A: np.ndarray, rhs: np.ndarray, symmetric: bool) -> np.ndarray:
    """Solve ``A x = rhs``: Cholesky for a symmetric positive definite A, LU otherwise
    (Cholesky reads one triangle only, so on a matrix that is not symmetric it would solve
    another system without a word)."""
    if symmetric:
        try:
            return sla.cho_solve(sla.cho_factor(A, lower=False, check_finite=False), rhs, check_finite=False)
        except np.linalg.LinAlgError:
            pass
    return sla.lu_solve(sla.lu_factor(A, check_finite=False), rhs, check_finite=False)


def _solve_on_set(A, z, B, target, S, d: float | None, symmetric: bool):
    """Pressure on the trial set S (indices) and the rigid-motion multipliers ``m``."""
    AS = A[np.ix_(S, S)]
    zS, BS = z[S], B[S]
    if BS.shape[1] == 0:
        return _factor_solve(AS, d - zS, symmetric), np.zeros(0)
    sol = _factor_solve(AS, np.column_stack([zS, BS]), symmetric)
    Az, AB = sol[:, 0], sol[:, 1:]
    # h^2 B^T (A^-1 (-z + B m)) = target  ->  (B^T A^-1 B) m = target + B^T A^-1 z
    schur = BS.T @ AB
    m = np.linalg.lstsq(schur, target + BS.T @ Az, rcond=1e-13)[0]
    return -Az + AB @ m, m


@dataclass(frozen=True)
class DenseSettings:
    """How :func:`solve_dense` iterates (its keywords ``tol``, ``max_iter``, ``max_cells``;
    documented there)."""

    tol: float = 1e-10
    max_iter: int = 200
    max_cells: int = MAX_DENSE_CELLS


def solve_dense(
    provider: InfluenceProvider,
    surface: Surface,
    *,
    penetration: float | None = None,
    total_load: float | None = None,
    tilt: bool = False,
    pivot=(0.0, 0.0),
    **settings,
) -> ContactResult:
    """Full-grid contact by Johnson's active-set matrix inversion.

    Parameters
    ----------
    provider : InfluenceProvider
        The elastic body (any provider; ``grid_matrix``, or ``cell_block`` on the
        cells with material when the grid itself exceeds ``max_cells``).
    surface : Surface
        Indenter heights on the grid (mm); ``inf`` cells never touch.
    penetration : float, optional
        Rigid approach d, mm (penetration control).
    total_load : float, optional
        Total load W >= 0, N (load control). Exactly one of the two.
    tilt : bool, default False
        With ``total_load``: also solve the tilt angles (alpha about x, beta about y,
        rad) of a ball-and-socket joint at ``pivot`` so that both moments vanish.
    pivot : (float, float), default (0, 0)
        Joint position, mm.
    **settings
        The iteration's settings (:class:`DenseSettings`), below; an unknown one is
        refused by name.
    tol : float, default 1e-10
        Interpenetration allowed outside the contact, relative to the largest
        displacement.
    max_iter : int, default 200
        Most active-set passes.
    max_cells : int, default 12000
        Refuse (ValueError) grids with more cells with material than this (memory).

    Returns
    -------
    ContactResult
        ``method="reference"``, ``solver="dense"``; ``iterations={"outer": passes}``; residuals hold the number of
        cells changed per pass (``"changes"``) and the size of the trial set (``"active"``).
    """
    t0 = time.perf_counter()
    dense = settings_from(DenseSettings, settings, "solve_dense")
    tol, max_iter, max_cells = dense.tol, dense.max_iter, dense.max_cells
    problem = make_problem(surface, penetration=penetration, total_load=total_load, tilt=tilt, pivot=pivot)
    trivial = trivial_result(problem, "dense", {"total": time.perf_counter() - t0})
    if trivial is not None:
        return trivial
    cand = problem.candidates.ravel()
    idx = np.flatnonzero(cand)
    if idx.size > max_cells:
        raise ValueError(
            f"dense solver: {idx.size} cells with material exceed max_cells={max_cells}; "
            f"use method='cg' (or 'reference', which picks), or a coarser h"
        )
    if problem.grid.size <= max_cells:
        A = provider.grid_matrix(problem.grid)  # fast path on aligned grids
        if idx.size < A.shape[0]:
            A = A[np.ix_(idx, idx)]
    else:  # mostly empty grid: never form the full matrix
        pts = problem.grid.points()[idx]
        A = provider.cell_block(pts, pts, problem.grid.h)
    t_matrix = time.perf_counter()
    return _active_set(problem, provider, A, idx, tol, max_iter, t0, t_matrix)


def _gap(A, z, B, m, d_given, q):
    """Displacement ``A q`` and gap ``z + A q - B m`` (or ``- d``) on the cells."""
    u = A @ q
    motion = B @ m if B.shape[1] else d_given
    return u, z + u - motion


def _active_set(problem: ContactProblem, provider, A, idx, tol, max_iter, t0, t_matrix) -> ContactResult:
    """Johnson's iteration, made monotone once a feasible pressure is known.

    Phase 1 (no trial solution with p >= 0 yet): drop every cell with negative pressure
    and add every cell that interpenetrates under the trial solution (Johnson).
    Phase 2: from the last feasible pressure step towards the new trial solution only
    until the first pressure reaches zero and drop those cells (as in Lawson & Hanson's
    NNLS), so the energy decreases and trial sets cannot cycle; add every interpenetrating
    cell at once. A repeated set switches to one-cell moves: in phase 2, where the
    energy argument needs a symmetric matrix that a block's is only to ~1e-3, Murty's
    least-index rule (:func:`_least_index_move`), finite for every P-matrix.
    """
    z = problem.surface.height.ravel()[idx]
    B = problem.basis()[idx]
    target = problem.target()
    d_given = problem.penetration
    active = initial_active_set(problem, provider.material.E_star).ravel()[idx]
    symmetric = is_symmetric(A)
    seen: set[bytes] = set()
    changes, sizes = [], []
    converged, message = False, f"active set not stable after max_iter={max_iter} passes"
    p = np.zeros(idx.size)  # last feasible pressure (support inside the trial set)
    feasible = False
    m = np.zeros(B.shape[1])
    least_index = False
    for it in range(1, max_iter + 1):
        key = np.packbits(active).tobytes()
        cycling = key in seen
        least_index = least_index or (cycling and feasible)
        seen.add(key)
        S = np.flatnonzero(active)
        if S.size == 0:  # penetration control only: nothing touches
            p[:] = 0.0
            converged, message = True, "all trial pressures negative: zero pressure"
            break
        qS, m_trial = _solve_on_set(A, z, B, target, S, d_given, symmetric)
        sizes.append(S.size)
        if least_index and _least_index_move(A, z, B, d_given, S, qS, m_trial, active, tol):
            changes.append(1)
            continue
        if np.any(qS < 0):
            if feasible:  # phase 2: towards the trial solution until a pressure reaches zero
                m = _step_back(p, m, S, qS, m_trial, active, changes)
                continue
            changes.append(_johnson_move(A, z, B, d_given, S, qS, m_trial, active, cycling, tol))
            continue
        p[:] = 0.0
        p[S] = qS
        m, feasible = m_trial, True
        u, gap = _gap(A, z, B, m, d_given, p)
        scale = max(float(np.max(np.abs(u))), np.finfo(float).tiny)
        viol = (~active) & (gap < -tol * scale)
        if not np.any(viol):
            converged, message = True, f"active set stable after {it} passes"
            changes.append(0)
            break
        add = np.flatnonzero(viol)
        if cycling:
            add = add[[np.argmin(gap[add])]]
        active[add] = True
        changes.append(add.size)
    d, tilt = problem.rigid_motion(m)
    pressure = np.zeros(problem.grid.size)
    pressure[idx] = p
    disp = provider.grid_operator(problem.grid).apply(pressure.reshape(problem.grid.shape))
    t_end = time.perf_counter()
    timings = {"matrix": t_matrix - t0, "solve": t_end - t_matrix, "total": t_end - t0}
    return build_result(
        problem,
        "dense",
        pressure.reshape(problem.grid.shape),
        disp,
        d,
        tilt,
        Outcome(converged, message, {"outer": it}, {"changes": changes, "active": sizes}, timings),
    )


def _johnson_move(A, z, B, d_given, S, qS, m_trial, active, cycling: bool, tol: float) -> int:
    """Phase 1's move (Johnson): drop the cells of ``S`` whose trial pressure ``qS`` is
    negative (the most negative alone on a repeated set) and add every cell that
    interpenetrates under the trial solution (none on a repeated set). Updates ``active``
    in place; returns how many cells moved."""
    q = np.zeros(active.size)
    q[S] = qS
    drop = S[[np.argmin(qS)]] if cycling else S[qS < 0]
    active[drop] = False
    add = np.zeros(0, dtype=int)
    if not cycling:
        _, gap = _gap(A, z, B, m_trial, d_given, q)
        scale = max(float(np.max(np.abs(gap))), np.finfo(float).tiny)
        add = np.flatnonzero(~active & (gap < -tol * scale) & (q == 0))
        active[add] = True
    return drop.size + add.size


def _least_index_move(A, z, B, d_given, S, qS, m_trial, active, tol: float) -> bool:
    """Murty's move: of the cells that break the conditions under the trial solution (a
    negative pressure in ``S``, an interpenetration outside it), the one of least index
    changes side. Updates ``active`` in place; returns whether a cell moved (none: the
    trial solution is the answer)."""
    q = np.zeros(active.size)
    q[S] = qS
    u, gap = _gap(A, z, B, m_trial, d_given, q)
    scale = max(float(np.max(np.abs(u))), np.finfo(float).tiny)
    wrong = np.flatnonzero((active & (q < 0)) | (~active & (gap < -tol * scale)))
    if wrong.size:
        active[wrong[0]] = not active[wrong[0]]
    return bool(wrong.size)


def _step_back(p, m, S, qS, m_trial, active, changes: list) -> np.ndarray:
    """Phase 2's move (Lawson & Hanson): from the feasible pressure ``p`` towards the trial
    solution ``qS`` on the set ``S`` until the first pressure reaches zero; those cells
    leave the set. Updates ``p``, ``active`` and ``changes`` in place; returns the rigid
    motion moved by the same step.

    Cells just added (``p`` zero there) whose trial pressure is negative would stop the step
    at zero length and, with it, drop every new cell: only they leave, without a step, so
    that the new cells that do carry stay (a bonded block's bulge adds hundreds of cells at
    once, of which Lawson & Hanson's rule would keep one a pass)."""
    pS = p[S]
    neg = qS < 0
    new = neg & (pS <= 0.0)
    if np.any(new):
        active[S[new]] = False
        changes.append(int(np.count_nonzero(new)))
        return m
    step = float(np.min(pS[neg] / (pS[neg] - qS[neg])))
    p[S] = pS + step * (qS - pS)
    m = m + step * (m_trial - m)
    hit = S[(p[S] <= 0.0) | (np.arange(S.size) == np.argmin(np.where(neg, p[S], np.inf)))]
    p[hit] = 0.0
    active[hit] = False
    changes.append(hit.size)
    return m
