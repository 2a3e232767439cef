"""Two-level block Gauss-Seidel for many asperities.

Each iteration is

1. one far-field evaluation for all blocks (:meth:`.farfield.LaggedFarField.refresh`:
   one fast point-operator product);
2. one sweep of paper eq. 8 with the near blocks exact and up to date and the far field
   held from step 1;
3. one coarse correction (:mod:`.coarse`): the linearised macro equations on the
   resultant changes of the sweep, which also corrects the approach and the tilt under
   load control, so no separate sensitivity sweeps are needed.

It stops, as eq. 9, when no contact set changed and the relative change of the pressure
over the whole iteration is at most ``tol``. The fixed point is that of plain block
Gauss-Seidel with the far field by resultants; the coarse step only makes the bulk
deflection shared by thousands of patches converge in a number of iterations that does
not grow with their count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

from ..stopping import StopReason
from .coarse import CoarseSpace
from .constraints import Control
from .costmodel import FITTED
from .gauss_seidel import LOCAL_FACTOR, sweep
from .pk_stack import BlockStacks
from .segments import laid_end_to_end, segment_sums, starts_of

#: The iteration stops (not converged) when no sweep in this many has made the relative
#: change smaller than before: where contacts merge it can cycle at a change of ~0.5 for
#: its whole budget (100 sweeps, 90-125 s on an 80-tip scene).
STALL_SWEEPS = FITTED.stall_sweeps
#: Sweeps over which the contraction rate is measured (:func:`too_slow`), and the rate
#: above which an iteration that cannot reach its tolerance in its budget stops early
#: (both fields of the cost model, :mod:`.costmodel`).
RATE_SWEEPS = FITTED.rate_sweeps
SLOW_RATE = FITTED.slow_rate
#: Coarse systems up to this many patches in contact are solved densely.
COARSE_DENSE_MAX = 2000
#: The change at or below which a round asks :attr:`SweepLimits.early_growth` whether its
#: patches must grow before it converges. 8,380 clustered spheres under load (tip heights
#: spread 3 mm): after the first sweep (change 0.15) 22 asperities penetrated outside their
#: blocks, after the second (4.3e-3) the same 21, with the same cells, as after the round
#: converged four sweeps later (1.6e-7).
EARLY_GROWTH_CHANGE = 1e-2


@dataclass(frozen=True)
class SweepLimits:
    """When a round of sweeps ends.

    Attributes
    ----------
    tol : float
        Eq. 9 relative change at which to stop.
    max_sweeps : int
    stop : callable, optional
        ``stop(pressures) -> bool`` after each iteration (e.g. a loaded patch edge).
    monitor : callable, optional
        ``monitor(sweep, change)`` after each iteration (progress display).
    earlier : tuple of float, default ()
        Changes of the earlier rounds of the same solve (a round ends when ``stop`` asks
        for larger patches): the stall and rate rules count them, so an iteration that
        grows its patches every few sweeps without converging still stops (281 paraboloids
        under penetration control: changes of 0.3-12 for 11 sweeps over four rounds).
    trial : int or None, default None
        Sweeps (all rounds together) after which the iteration goes on only while its change
        falls by less than :data:`SLOW_RATE` a sweep (:func:`converging`); None: no trial.
        A trial cut at a fixed count threw away an iteration that was converging (859 light
        clustered spheres: 20 sweeps at 0.7 a sweep to a change of 2.8e-5, then block
        Gauss-Seidel from the start again, 25 s more).
    early_growth : callable, optional
        ``early_growth(pressures, theta) -> bool``, asked after each sweep whose change is
        at most :data:`EARLY_GROWTH_CHANGE` (and not converged): True ends the round as
        ``stop`` does, so patches that must grow grow before the round converges on the
        old ones (its sweeps since that change would be spent on a problem the growth
        changes). The caller decides how often it answers True.
    """

    tol: float
    max_sweeps: int
    stop: Callable | None = None
    monitor: Callable | None = None
    earlier: tuple = ()
    trial: int | None = None
    early_growth: Callable | None = None


@dataclass(frozen=True)
class TwoLevelResult:
    """Outcome of :func:`two_level`.

    Attributes
    ----------
    pressures, active : per block.
    theta : (3,) array: d (mm), alpha, beta (radians).
    converged : bool
    sweeps : int
    history : tuple of float
        Relative change of the pressure over each iteration.
    coarse_iterations : int
        Conjugate-gradient iterations of all coarse solves.
    message : str
        "" when converged, "stopped" when ``stop`` ended it, else the reason.
    reason : StopReason
        Why the iteration ended (``STOPPED``: the caller's ``stop`` test).
    """

    pressures: list
    active: list
    theta: np.ndarray
    converged: bool
    sweeps: int
    history: tuple
    coarse_iterations: int
    message: str
    reason: StopReason


def too_slow(history: list, tol: float, remaining: int) -> str:
    """Why to stop an iteration that will not reach ``tol`` in the ``remaining`` sweeps
    at the rate of its last :data:`RATE_SWEEPS` sweeps, or "" (keep going). Where contacts
    are light and many, the coarse step can leave a contraction of ~0.9 a sweep (321 light
    spheres under penetration control: 20 sweeps to a change of 3.5e-3, where plain block
    Gauss-Seidel with the same far field converged in 15); the driver's next strategy then
    starts sooner."""
    if len(history) <= RATE_SWEEPS or remaining <= 0:
        return ""
    first, last = history[-1 - RATE_SWEEPS], history[-1]
    if not (first > 0.0 and last > tol):
        return ""
    rate = (last / first) ** (1.0 / RATE_SWEEPS)
    if rate < SLOW_RATE:
        return ""
    needed = math.log(tol / last) / math.log(rate) if rate < 1.0 else math.inf
    if needed <= remaining:
        return ""
    if rate >= 1.0:
        return (
            f"two-level iteration not converging: change {last:.3g}, up {rate:.2f}x a sweep over the last {RATE_SWEEPS}"
        )
    return (
        f"two-level iteration converging too slowly: change {last:.3g} falling by {rate:.2f} a sweep, "
        f"about {needed:.0f} more sweeps needed, {remaining} left"
    )


def converging(history: list) -> bool:
    """The change fell by less than :data:`SLOW_RATE` a sweep over the last
    :data:`RATE_SWEEPS` sweeps of ``history``."""
    if len(history) <= RATE_SWEEPS:
        return False
    first, last = history[-1 - RATE_SWEEPS], history[-1]
    return first > 0.0 and (last / first) ** (1.0 / RATE_SWEEPS) < SLOW_RATE


def lower_near_pattern(coupling) -> sp.csr_matrix:
    """Pairs ``(k, l)``, ``l < k``, that block ``k`` sees exactly and up to date in a sweep."""
    n = len(coupling.patches)
    near = [coupling.near(k) for k in range(n)]
    cols = np.concatenate(near) if n else np.zeros(0, int)
    rows = np.repeat(np.arange(n), [len(c) for c in near])
    lower = cols < rows
    rows, cols = rows[lower], cols[lower]
    return sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))


def sweep_levels(coupling) -> list:
    """Blocks grouped for a sweep with the far field held: block ``k``'s level is one more
    than the highest level of its near blocks ``l < k`` (0 without), so no two blocks of a
    level are near each other and every near ``l < k`` is solved in an earlier level; the
    sweep then gives what the plain order ``k = 1..N`` gives."""
    n = len(coupling.patches)
    level = np.zeros(n, dtype=np.int64)
    for k in range(n):
        near = coupling.near(k)
        near = near[near < k]
        if near.size:
            level[k] = level[near].max() + 1
    order = np.argsort(level, kind="stable")
    bounds = np.flatnonzero(np.diff(level[order])) + 1
    return [part.tolist() for part in np.split(order, bounds)] if n else []


def _prepared(coupling, tips: np.ndarray):
    """What every sweep of :func:`two_level` reuses: the near pattern (its dense blocks made
    together where the coupling can), the coarse space, the sweep's levels and the stacked
    local solves where the provider allows them."""
    lower = lower_near_pattern(coupling)
    prepare = getattr(coupling, "prepare_dense", None)
    pairs = list(zip(*lower.nonzero()))
    if prepare is not None:
        prepare(pairs)  # the near pairs' dense blocks made together
    routes = getattr(coupling, "plan_routes", None)
    if routes is not None:
        routes(pairs)  # the others' routes by their bytes where the budget needs it
    coarse = CoarseSpace(coupling.provider, tips, lower, dense_max=COARSE_DENSE_MAX)
    stacks = BlockStacks(coupling.provider) if BlockStacks.usable(coupling.provider) else None
    return coarse, sweep_levels(coupling), stacks


def relative_change(new: np.ndarray, old: np.ndarray) -> float:
    """``||new - old|| / ||new||`` over all blocks' pressures, laid end to end (0 where
    ``new`` is 0)."""
    diff = new - old
    norm2 = float(new @ new)
    return float(np.sqrt(float(diff @ diff) / norm2)) if norm2 > 0 else 0.0


def verdict(seen: list, changed: bool, limits: SweepLimits, sweeps: int, p: list, theta: np.ndarray):
    """Whether the iteration ends after ``sweeps`` sweeps at pressures ``p`` and ``theta``,
    ``seen`` the changes of all its rounds: ``(message, reason, converged)``, or None to go
    on. In order: a stall (no new smallest change in :data:`STALL_SWEEPS` sweeps: merged
    contacts make cells flip), convergence (eq. 9), a rate too slow for the budget, the
    trial sweeps without converging, the caller's ``stop``, then its ``early_growth``."""
    change = seen[-1]
    if len(seen) > STALL_SWEEPS and min(seen[-STALL_SWEEPS:]) >= min(seen[:-STALL_SWEEPS]):
        message = (
            f"two-level iteration stalled: no smaller change in {STALL_SWEEPS} sweeps "
            f"(last {change:.3g}, best {min(seen):.3g})"
        )
        return message, StopReason.STAGNATED, False
    if change <= limits.tol and not changed:
        return "", StopReason.CONVERGED, True
    slow = too_slow(seen, limits.tol, limits.max_sweeps - sweeps)
    if slow:
        return slow, StopReason.STAGNATED, False
    if limits.trial is not None and len(seen) >= limits.trial and not converging(seen):
        message = (
            f"two-level block Gauss-Seidel reached its {limits.trial} trial sweeps without converging "
            f"(last change {change:.3g})"
        )
        return message, StopReason.MAX_ITER, False
    if limits.stop is not None and limits.stop(p):
        return "stopped", StopReason.STOPPED, False
    if limits.early_growth is not None and change <= EARLY_GROWTH_CHANGE and limits.early_growth(p, theta):
        return "stopped", StopReason.STOPPED, False
    return None


def two_level(
    blocks, coupling, tips: np.ndarray, heights, p: list, theta: np.ndarray, control: Control, limits: SweepLimits
) -> TwoLevelResult:
    """Two-level block Gauss-Seidel; see the module docstring.

    Parameters
    ----------
    blocks : list of LocalBlock
    coupling : an engine with a held far field
        :class:`~.farfield.LaggedFarField`, or :class:`~.couplings.ExactProducts` (every
        pair near, nothing held).
    tips : (N, 2) array, mm
        Tip of each block's asperity, in block order.
    heights : callable, theta -> list of (n_k,) arrays
        Indenter height with tilt on every block, mm.
    p : list of (n_k,) arrays, MPa
        Start (e.g. paper eq. 7).
    theta : (3,) array
        (d, alpha, beta) to start from; corrected under load control.
    control : Control
        Pivot (mm), rigid-body unknowns (0, 1 or 3) and their target (load N, moments 0).
    limits : SweepLimits
        Tolerance, sweeps, the caller's stop test, monitor and the earlier rounds' changes.
    """
    patches = coupling.patches
    coarse, levels, stacks = _prepared(coupling, tips)
    theta = np.array(theta, dtype=float)
    p = [np.asarray(v, dtype=float) for v in p]  # replaced, never modified
    active = [v > 0.0 for v in p]
    history: list = []
    cg_iters = 0
    # the per-block sums of every sweep (forces, change, contact sets) over the blocks laid end to end
    starts = starts_of(p)
    h2 = np.array([pt.grid.h**2 for pt in patches], dtype=float)
    flat = laid_end_to_end(p)
    for m in range(1, limits.max_sweeps + 1):
        coupling.refresh(p)
        b = [theta[0] - z for z in heights(theta)]
        before = h2 * segment_sums(flat, starts)
        local_rtol = LOCAL_FACTOR * max(history[-1] if history else 0.1, limits.tol)
        sw = sweep(blocks, coupling, b, p, active, local_rtol=local_rtol, levels=levels, stacks=stacks)
        if sw.failed:
            message = f"local active-set solve did not converge on blocks {list(sw.failed)}"
            history.append(sw.change)
            return TwoLevelResult(
                sw.pressures, sw.active, theta, False, m, tuple(history), cg_iters, message, StopReason.FAILED
            )
        dF = h2 * segment_sums(sw.flat, starts) - before
        step = coarse.correct(blocks, patches, sw.pressures, sw.active, dF, theta, control, stacks)
        cg_iters += step.iterations
        new_active = [v > 0.0 for v in step.pressures]
        new = laid_end_to_end(step.pressures)
        change = relative_change(new, flat)
        changed = sw.changed or bool(np.any((new > 0.0) != sw.flat_active))
        p, active, theta, flat = step.pressures, new_active, step.theta, new
        history.append(change)
        if limits.monitor is not None:
            limits.monitor(m, change)
        ends = verdict(list(limits.earlier) + history, changed, limits, m, p, theta)
        if ends is not None:
            message, reason, converged = ends
            return TwoLevelResult(p, active, theta, converged, m, tuple(history), cg_iters, message, reason)
    message = f"two-level block Gauss-Seidel reached {limits.max_sweeps} sweeps (last change {history[-1]:.3g})"
    return TwoLevelResult(
        p, active, theta, False, limits.max_sweeps, tuple(history), cg_iters, message, StopReason.MAX_ITER
    )
