"""Contact problems on one block (Johnson's matrix-inversion method applied locally).

* :func:`initial_pressure` — paper eq. 7: the pressure on block ``k`` alone that carries
  exactly the macro force ``P_k``, the rigid shift of the patch being the extra unknown;
* :func:`contact_solve` — the local step of a Gauss-Seidel sweep (eq. 8): pressure ``p >= 0``
  with ``A_kk p >= b`` and equality where ``p > 0``, ``b`` holding the approach, the
  indenter height and the displacement due to the other blocks.

Small (dense) blocks use Johnson's active-set loop: solve on the active cells by Cholesky,
drop the cells with negative pressure, add the cells that penetrate, until neither happens.
Large blocks use Polonsky and Keer's constrained conjugate gradients with the provider's
FFT products (:mod:`.pk`), warm-started from the previous pressure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .local_batch import batchable, first_passes, hertz_contact, next_active
from .localblock import LocalBlock
from .pk import pk_fixed_approach, pk_fixed_force


@dataclass(frozen=True)
class LocalSolution:
    """Pressure on one block.

    Attributes
    ----------
    pressure : (n,) array, MPa (>= 0) on the block's cells.
    active : (n,) bool array: cells in contact.
    shift : float
        Rigid shift of the patch, mm (eq. 7 only; ``nan`` for :func:`contact_solve`).
    negatives_removed : bool
        Whether a negative pressure appeared (and was removed) on the way.
    converged : bool
    iterations : int
        Active-set iterations.
    """

    pressure: np.ndarray
    active: np.ndarray
    shift: float
    negatives_removed: bool
    converged: bool
    iterations: int


def contact_solve(
    block: LocalBlock,
    b: np.ndarray,
    previous: np.ndarray,
    *,
    max_iter: int = 200,
    gap_rtol: float = 1e-12,
    rtol: float | None = None,
) -> LocalSolution:
    """Contact on one block with a fixed right-hand side (eq. 8 with clipping done right).

    Parameters
    ----------
    block : LocalBlock
    b : (n,) array, mm
        ``d - z - tilt - sum_{l != k} A_kl p_l`` on the block's cells.
    previous : (n,) array, MPa
        The previous sweep's pressure: its contact is the first active set (``b > 0`` if
        empty), and the conjugate-gradient start.
    max_iter : int, default 200
        Active-set passes (dense) or 5 x max_iter conjugate-gradient steps (FFT).
    gap_rtol : float, default 1e-12
        Penetration below ``gap_rtol * max|b|`` (mm) is accepted.
    rtol : float, optional
        Relative change at which the conjugate gradients stop (default ``block.cg_rtol``);
        the sweeps loosen it while they are far from converged.
    """
    if not block.dense:
        p, ok, it = pk_fixed_approach(
            block.matvec, b, previous, rtol=block.cg_rtol if rtol is None else rtol, max_iter=5 * max_iter
        )
        return LocalSolution(p, p > 0.0, float("nan"), False, ok, it)
    start = previous > 0.0
    active = start.copy() if np.count_nonzero(start) else b > 0.0
    seen: set = set()
    removed = False
    tol = gap_rtol * float(np.abs(b).max(initial=0.0))
    p = np.zeros(block.n)
    for it in range(1, max_iter + 1):
        seen.add(active.tobytes())
        p = np.zeros(block.n)
        p[active] = block.solve(active, b[active])
        if np.count_nonzero(p < 0.0):
            removed = True
            active = next_active(active, p, seen)
            continue
        gap = block.product_on(active, p) - b
        pen = ~active & (gap < -tol)
        if not np.count_nonzero(pen):
            return LocalSolution(p, active, float("nan"), removed, True, it)
        active = active | pen
    return LocalSolution(np.maximum(p, 0.0), p > 0.0, float("nan"), removed, False, max_iter)


def pk_start(z: np.ndarray, approach: float) -> np.ndarray:
    """Start of eq. 7's conjugate gradients: Hertz's shape ``sqrt(a^2 - r^2)`` over the
    Hertz radius (``z - min z < approach / 2``), positive at the lowest cell."""
    zmin = float(z.min())
    return np.sqrt(np.maximum(0.5 * max(approach, 0.0) - (z - zmin), 0.0)) + (z == zmin)


def initial_pressures(
    blocks: list, z: list, forces: list, approaches: list, h: float, *, rtol: float, stacks=None
) -> list:
    """:func:`initial_pressure` (eq. 7) on every block, MPa; with ``stacks``
    (:class:`~.pk_stack.BlockStacks`) the large blocks of one size class are solved together."""
    out = [None] * len(blocks)
    if stacks is not None:
        ks = [k for k, blk in enumerate(blocks) if not blk.dense and blk.n and forces[k] > 0.0]
        if len(ks) > 1:
            starts = {k: pk_start(z[k], approaches[k]) for k in ks}
            for k, p in stacks.initial(blocks, ks, z, forces, starts, h, rtol=rtol).items():
                out[k] = p
    # the dense blocks' first active-set pass in stacks (:mod:`.local_batch`)
    ks = [k for k, blk in enumerate(blocks) if out[k] is None and forces[k] > 0.0 and batchable(blk)]
    resume: dict = {}
    if len(ks) > 1:
        for i, res in first_passes(
            [blocks[k] for k in ks], [z[k] for k in ks], [forces[k] for k in ks], [approaches[k] for k in ks], h
        ).items():
            if res[0] == "done":
                out[ks[i]] = res[1]
            else:
                resume[ks[i]] = res[1:]
    for k, state in resume.items():
        out[k] = _dense_passes(blocks[k], z[k], forces[k] / (h * h), state, 2, 200, 1e-12).pressure
    return [
        p if p is not None else initial_pressure(blk, zk, P, h, approach=a, rtol=rtol).pressure
        for p, blk, zk, P, a in zip(out, blocks, z, forces, approaches)
    ]


def initial_pressure(
    block: LocalBlock,
    z: np.ndarray,
    force: float,
    h: float,
    *,
    approach: float,
    max_iter: int = 200,
    gap_rtol: float = 1e-12,
    rtol: float = 1e-8,
) -> LocalSolution:
    """Initial pressure ``p0_k`` of paper eq. 7.

    Solves ``[A_kk 1; 1^T 0] [p; -s] = [-z; P_k / h^2]`` on the active cells, i.e.
    ``A p = s - z`` with ``h^2 sum p = P_k``: written as ``p = s x1 - x2`` with
    ``A x1 = 1``, ``A x2 = z`` and ``s`` fixed by the force. Negative pressures are removed
    and penetrating cells added until neither occurs.

    Parameters
    ----------
    block : LocalBlock
    z : (n,) array, mm
        Indenter height (tilt included) on the block's cells.
    force : float
        Macro force ``P_k``, N (>= 0; zero gives zero pressure).
    h : float
        Cell side, mm.
    approach : float
        Local approach from the macro step, mm: the first active set is Hertz's contact
        ``z - min z < approach / 2`` (from the geometric overlap ``z - min z < approach``,
        a superset of the contact, 3-4 active-set passes a block on 1,013 spheres; from
        Hertz's, 1-2 and the same pressures).
    rtol : float, default 1e-8
        Relative change at which the conjugate gradients stop (large blocks).
    """
    n = block.n
    if force <= 0.0 or n == 0:
        return LocalSolution(np.zeros(n), np.zeros(n, bool), float("nan"), False, True, 0)
    if not block.dense:
        p, s, ok, it = pk_fixed_force(
            block.matvec, z, force, h, pk_start(z, approach), rtol=rtol, max_iter=5 * max_iter
        )
        return LocalSolution(p, p > 0.0, s, False, ok, it)
    return _dense_passes(block, z, force / (h * h), (hertz_contact(z, approach), False, set()), 1, max_iter, gap_rtol)


def _dense_passes(
    block: LocalBlock, z: np.ndarray, target: float, state: tuple, first: int, max_iter: int, gap_rtol: float
) -> LocalSolution:
    """:func:`initial_pressure`'s active-set loop on a dense block from pass ``first`` and
    ``state`` = ``(active, removed, seen)`` (``target`` = P / h^2): from the start, or after
    a first pass made in a stack (:func:`.local_batch.first_passes`)."""
    n, zmin = block.n, float(z.min())
    active, removed, seen = state
    ones = np.ones(n)
    for it in range(first, max_iter + 1):
        seen.add(active.tobytes())
        x = block.solve(active, np.column_stack([ones[active], z[active]]))
        s = (target + x[:, 1].sum()) / x[:, 0].sum()
        p = np.zeros(n)
        p[active] = s * x[:, 0] - x[:, 1]
        if np.count_nonzero(p < 0.0):
            removed = True
            active = next_active(active, p, seen)
            continue
        gap = block.product_on(active, p) + z - s
        tol = gap_rtol * max(abs(s - zmin), 1e-300)
        pen = ~active & (gap < -tol)
        if not np.count_nonzero(pen):
            return LocalSolution(p, active, s, removed, True, it)
        active = active | pen
    return LocalSolution(np.maximum(p, 0.0), p > 0.0, s, removed, False, max_iter)
