"""Block Gauss-Seidel sweeps over the patches (paper eqs. 8 and 9).

At sweep ``m+1``, for ``k = 1..N``:
``A_kk p_k^{m+1} = b_k - sum_{l<k} A_kl p_l^{m+1} - sum_{l>k} A_kl p_l^m``,
solved as a contact problem on block ``k`` (negative pressures removed, penetrating cells
added). Stop (eq. 9) when no block changed its contact set during the sweep and
``||p^{m+1} - p^m||_2 / ||p^{m+1}||_2 <= tol`` (the paper writes the squared norms; the
ratio here is their square root).

:func:`linear_gauss_seidel` runs the same sweeps on fixed contact sets, for the
sensitivities of the pressure to the approach and the tilt.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..stopping import StopReason
from .blocks import Coupling
from .localblock import LocalBlock
from .local import contact_solve
from .local_batch import batchable, final_first_passes
from .segments import laid_end_to_end

#: Local solves stop at this fraction of the last sweep's relative change (never below it of tol).
LOCAL_FACTOR = 1e-2
#: A level's dense blocks take their first pass in stacks from this many (a canvas a size
#: class costs more than a few blocks' gathers: seed 5's #130, +0.02 s of 0.47 s).
STACKED_PASSES_MIN = 32


@dataclass(frozen=True)
class SweepResult:
    """Outcome of block Gauss-Seidel.

    Attributes
    ----------
    pressures : list of (n_k,) or (n_k, m) arrays, MPa (per unit for linear solves).
    active : list of (n_k,) bool arrays.
    converged : bool
    sweeps : int
    history : tuple of float
        Relative change ``||p^{m+1} - p^m|| / ||p^{m+1}||`` after each sweep.
    message : str
    reason : StopReason
        Why the sweeps ended (``STOPPED``: the caller's ``stop`` test).
    """

    pressures: list
    active: list
    converged: bool
    sweeps: int
    history: tuple
    message: str
    reason: StopReason


def coupled_rhs(coupling: Coupling, k: int, values: list, rhs: np.ndarray) -> np.ndarray:
    """``rhs - sum_{l != k} A_kl v_l`` using the latest values of the other blocks
    (exact, or with the far field approximated: :mod:`.farfield`)."""
    return coupling.rhs(k, values, rhs)


@dataclass(frozen=True)
class Sweep:
    """One sweep of eq. 8: new pressures and contact sets (also laid end to end: ``flat``,
    ``flat_active``), and what changed."""

    pressures: list
    active: list
    changed: bool
    change: float
    failed: tuple
    flat: np.ndarray
    flat_active: np.ndarray


def sweep(
    blocks: list[LocalBlock],
    coupling: Coupling,
    b: list,
    p: list,
    active: list,
    *,
    local_rtol: float | None = None,
    levels: list | None = None,
    stacks=None,
) -> Sweep:
    """One block Gauss-Seidel sweep (eq. 8) over ``k = 1..N`` from pressures ``p``;
    ``local_rtol`` is the conjugate-gradient tolerance of large blocks (default theirs).

    ``levels`` (ascending lists of block indices) may group blocks that see none of each
    other's new pressures (with a held far field: no near pair within a level, and every
    near pair ``l < k`` in an earlier level than ``k``'s): each block then sees exactly
    what it sees in the plain order, and ``stacks`` (:class:`~.pk_stack.BlockStacks`)
    solves a level's large blocks of one size class together."""
    before, was = list(p), list(active)
    p, active = list(p), list(active)
    n = len(blocks)
    failed = np.zeros(n, bool)

    def take(k, pressure, now, ok):
        failed[k] = not ok
        p[k], active[k] = pressure, now

    # a held far field gives a level's right-hand sides together (:mod:`.level_far`)
    by_level = None if levels is None else getattr(coupling, "rhs_level", None)
    for level in [[k] for k in range(n)] if levels is None else levels:
        rhs = {k: coupled_rhs(coupling, k, p, b[k]) for k in level} if by_level is None else by_level(level, p, b)
        stacked = [] if stacks is None else [k for k in level if not blocks[k].dense and blocks[k].n]
        if len(stacked) > 1:
            for k, (pressure, ok, _) in stacks.solve(blocks, stacked, rhs, p, local_rtol).items():
                take(k, pressure, pressure > 0.0, ok)
            done = set(stacked)
            level = [k for k in level if k not in done]
        # the dense blocks' first pass in stacks; the one-block loop where it is not final
        small = [] if stacks is None or not stacks.whole_kernel else [k for k in level if batchable(blocks[k])]
        if len(small) >= STACKED_PASSES_MIN:
            final = final_first_passes(blocks, small, rhs, p, stacks)
            for k, (pressure, now) in final.items():
                take(k, pressure, now, True)
            level = [k for k in level if k not in final]
        for k in level:
            sol = contact_solve(blocks[k], rhs[k], p[k], rtol=local_rtol)
            take(k, sol.pressure, sol.active, sol.converged)
    # the change and the contact sets over all blocks laid end to end, not block by block
    # (3,756 local solves a two-level iteration on 939 blocks: 15 us each in these sums)
    now = laid_end_to_end(active, bool)
    changed = bool(np.any(now != laid_end_to_end(was, bool)))
    new = laid_end_to_end(p)
    diff = new - laid_end_to_end(before)
    norm2 = float(new @ new)
    rel = float(np.sqrt(float(diff @ diff) / norm2)) if norm2 > 0 else 0.0
    return Sweep(p, active, changed, rel, tuple(np.flatnonzero(failed).tolist()), new, now)


def gauss_seidel(
    blocks: list[LocalBlock],
    coupling: Coupling,
    b: list,
    start: list,
    *,
    tol: float,
    max_sweeps: int,
    stop=None,
    monitor=None,
) -> SweepResult:
    """Contact by block Gauss-Seidel (eq. 8), stopped by eq. 9.

    Parameters
    ----------
    blocks : list of LocalBlock
    coupling : Coupling
    b : list of (n_k,) arrays, mm
        ``d - z - tilt`` on each block.
    start : list of (n_k,) arrays, MPa
        Initial pressures (e.g. eq. 7).
    tol : float
        Relative change at which to stop.
    max_sweeps : int
    stop : callable, optional
        ``stop(pressures) -> bool`` checked after each sweep; True ends the sweeps early
        (``converged=False``, reason ``STOPPED``, message "stopped"), e.g. to enlarge a patch.
    monitor : callable, optional
        ``monitor(sweep, change)`` after each sweep (progress display).
    """
    p = [np.array(s, dtype=float) for s in start]
    active = [s > 0.0 for s in p]
    history = []
    for m in range(1, max_sweeps + 1):
        # inexact local solves while far from convergence: 1 % of the last change
        local_rtol = LOCAL_FACTOR * max(history[-1] if history else 0.1, tol)
        sw = sweep(blocks, coupling, b, p, active, local_rtol=local_rtol)
        p, active = sw.pressures, sw.active
        history.append(sw.change)
        if monitor is not None:
            monitor(m, sw.change)
        if sw.failed:
            return SweepResult(
                p,
                active,
                False,
                m,
                tuple(history),
                f"local active-set solve did not converge on blocks {list(sw.failed)}",
                StopReason.FAILED,
            )
        if sw.change <= tol and not sw.changed:
            return SweepResult(p, active, True, m, tuple(history), "", StopReason.CONVERGED)
        if stop is not None and stop(p):
            return SweepResult(p, active, False, m, tuple(history), "stopped", StopReason.STOPPED)
    return SweepResult(
        p,
        active,
        False,
        max_sweeps,
        tuple(history),
        f"block Gauss-Seidel reached {max_sweeps} sweeps (last change {history[-1]:.3g})",
        StopReason.MAX_ITER,
    )


def linear_gauss_seidel(
    blocks: list[LocalBlock],
    coupling: Coupling,
    rhs: list,
    active: list,
    *,
    tol: float,
    max_sweeps: int,
    start: list | None = None,
) -> SweepResult:
    """Solve ``A_SS x = rhs`` on the fixed contact sets ``active`` by block Gauss-Seidel.

    ``rhs[k]`` has shape (n_k, m): ``m`` right-hand sides solved together; ``x`` is zero
    off the contact sets. Converges for any SPD influence matrix. ``start`` (same shapes
    as ``rhs``) is a warm start.
    """
    x = (
        [np.zeros_like(r) for r in rhs]
        if start is None
        else [np.where(a[:, None], s, 0.0) for a, s in zip(active, start)]
    )
    history = []
    for m in range(1, max_sweeps + 1):
        diff2 = 0.0
        for k, blk in enumerate(blocks):
            r = coupled_rhs(coupling, k, x, rhs[k])
            new = np.zeros_like(r)
            new[active[k]] = blk.solve(
                active[k], r[active[k]], x[k][active[k]], rtol=1e-2 * max(history[-1] if history else 0.1, tol)
            )
            diff2 += float(np.sum((new - x[k]) ** 2))
            x[k] = new
        norm2 = sum(float(np.sum(v * v)) for v in x)
        rel = np.sqrt(diff2 / norm2) if norm2 > 0 else 0.0
        history.append(rel)
        if rel <= tol:
            return SweepResult(x, active, True, m, tuple(history), "", StopReason.CONVERGED)
    return SweepResult(
        x,
        active,
        False,
        max_sweeps,
        tuple(history),
        f"linear block Gauss-Seidel reached {max_sweeps} sweeps",
        StopReason.MAX_ITER,
    )
