"""The block iterations' loops: block Gauss-Seidel (eq. 8-9) with patch growth and, under
load control, Newton corrections of the approach and tilt from sensitivity sweeps; and the
two-level iteration with patch growth. :func:`.setup.block_setup` sets them up (patches,
blocks, the coupling's engine, the first pressure: a :class:`BlockSetup`); the iteration
objects of :mod:`.strategies` call one of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..stopping import StopReason
from .blocks import scatter
from .constraints import Control, block_coordinates, newton_step, resultants, rhs_derivatives
from .gauss_seidel import gauss_seidel, linear_gauss_seidel
from .result import MicroResult
from .twolevel import SweepLimits, two_level
from .workset import WorkingSet, comes_to_touch, edges_loaded_any, grow, merge_touching, penetrates_outside

#: Relative change at which the sensitivity sweeps (load and tilt corrections) stop.
SENSITIVITY_TOL = 1e-3


@dataclass(frozen=True)
class BlockSetup:
    """A block iteration ready to run.

    Attributes
    ----------
    state : WorkingSet
        Patches, blocks and the coupling's engine (changed as patches grow).
    p0 : list of (n_k,) arrays, MPa
        The first pressure of every block (eq. 7 or a previous solve's); carried over
        when patches grow (the list is updated in place).
    theta : (3,) array
        (d, alpha, beta) to start from.
    tilt : (alpha, beta) or None
        The tilt reported when the iteration fails early (radians).
    control : Control
        Pivot, rigid-body unknowns and their target.
    """

    state: WorkingSet
    p0: list
    theta: np.ndarray
    tilt: tuple | None
    control: Control


def run_block_gauss_seidel(
    setup: BlockSetup,
    *,
    free_tilt: bool,
    tol: float,
    max_sweeps: int,
    max_growths: int | None,
    max_corrections: int,
    monitor: Callable | None = None,
) -> MicroResult:
    """The micro step by block Gauss-Seidel (eq. 8-9) with patch growth and, under load
    control, Newton corrections of the approach and tilt from sensitivity sweeps."""
    state, p0, theta, tilt = setup.state, setup.p0, setup.theta, setup.tilt
    pivot, n_unknowns, target = setup.control.pivot, setup.control.n_unknowns, setup.control.target
    p = [v.copy() for v in p0]
    sweeps = corrections = growths = linear_sweeps = 0
    history: list = []

    def counts():
        return {"sweeps": sweeps, "corrections": corrections, "growths": growths, "linear_sweeps": linear_sweeps}

    while True:
        z = state.heights(theta, pivot)
        can_grow = growths < _budget(state, max_growths)
        gs = gauss_seidel(
            state.blocks,
            state.coupling,
            [theta[0] - zk for zk in z],
            p,
            tol=tol,
            max_sweeps=max(max_sweeps - sweeps, 1),
            stop=(lambda q: edges_loaded_any(state, q)) if can_grow else None,
            monitor=None if monitor is None else (lambda m, c: monitor(sweeps + m, c)),
        )
        sweeps += gs.sweeps
        history += gs.history
        p = gs.pressures
        grown, ended = _round_end(setup, gs, p, theta, tilt, tol, can_grow, growths, counts, history)
        if grown:
            growths += grown
            continue
        if ended is not None:
            return ended
        if target is None:
            break
        residual = target - resultants(state.patches, p, pivot, n_unknowns)
        if corrections >= max_corrections:
            return finish(
                setup,
                p,
                theta,
                tilt,
                StopReason.MAX_ITER,
                f"load/moment corrections reached {max_corrections} (residual {residual})",
                counts(),
                history,
            )
        corrections += 1
        p, theta, done, lin = _correct(state, p, gs.active, theta, residual, pivot, n_unknowns, tol)
        linear_sweeps += lin
        if done:
            # the corrected approach and tilt may bring in asperities without a patch
            grown = grow(state, p, p0, theta, pivot, tol) if growths < _budget(state, max_growths) else 0
            if not grown:
                break
            growths += grown
    out_tilt = (float(theta[1]), float(theta[2])) if (tilt is not None or free_tilt) else None
    return finish(setup, p, theta, out_tilt, StopReason.CONVERGED, "", counts(), history)


def run_two_level(
    setup: BlockSetup,
    *,
    tol: float,
    max_sweeps: int,
    max_growths: int | None,
    monitor: Callable | None = None,
    trial: int | None = None,
) -> MicroResult:
    """The micro step by two-level block Gauss-Seidel (:mod:`.twolevel`), with patch growth
    (``trial``: :attr:`~.twolevel.SweepLimits.trial`)."""
    state, p0, theta, tilt = setup.state, setup.p0, setup.theta, setup.tilt
    pivot, n_unknowns = setup.control.pivot, setup.control.n_unknowns
    p = [v.copy() for v in p0]
    sweeps = growths = 0
    history: list = []
    counted = 0  # the rounds' changes the stall, rate and trial rules count start here
    tips = state.tips()
    early = EarlyGrowth(state, pivot, tol)

    def counts():
        return {"sweeps": sweeps, "corrections": sweeps if n_unknowns else 0, "growths": growths, "linear_sweeps": 0}

    while True:
        can_grow = growths < _budget(state, max_growths)
        limits = SweepLimits(
            tol=tol,
            max_sweeps=max(max_sweeps - sweeps, 1),
            stop=lambda q: (can_grow and edges_loaded_any(state, q)) or comes_to_touch(state, q),
            monitor=None if monitor is None else (lambda m, c: monitor(sweeps + m, c)),
            earlier=tuple(history[counted:]),
            trial=trial,
            early_growth=early if can_grow else None,
        )
        res = two_level(
            state.blocks,
            state.coupling,
            block_tips(tips, state.patches),
            lambda th: state.heights(th, pivot),
            p,
            theta,
            setup.control,
            limits,
        )
        sweeps += res.sweeps
        history += res.history
        p, theta = res.pressures, res.theta
        if res.reason is StopReason.STOPPED and merge_touching(state, p, p0):
            growths += _grow_merged(setup, p, theta, tol, can_grow)
            continue  # contacts that came to touch are one block now: the next round
        state.coupling.refresh(p)
        grown, ended = _round_end(setup, res, p, theta, tilt, tol, can_grow, growths, counts, history)
        if grown:
            growths += grown
            merge_touching(state, p, p0)
            if res.converged or early.answered:
                # a round that converged (or that the early check ended, once a solve) before
                # its patches grew starts the rules afresh: its sweeps say nothing of the next
                # round's rate (845 paraboloids: 6e-7 after 14 sweeps, then 0.21, read with
                # them as a rate of 20x after one sweep)
                counted = len(history)
            early.answered = False
            continue
        if ended is not None:
            if early.answered and res.reason is StopReason.STOPPED:
                early.answered = False
                continue  # nothing to grow at the refreshed far field: the sweeps go on
            return ended
        break
    failure = residual_failure(state.patches, p, setup.control, tol)
    if failure:
        return finish(setup, p, theta, tilt, StopReason.FAILED, failure, counts(), history)
    out_tilt = (float(theta[1]), float(theta[2])) if tilt is not None else None
    return finish(setup, p, theta, out_tilt, StopReason.CONVERGED, "", counts(), history)


class EarlyGrowth:
    """:attr:`~.twolevel.SweepLimits.early_growth` of :func:`run_two_level`: whether some
    asperity penetrates outside its block (:func:`~.workset.penetrates_outside`), asked once
    a solve. Once: the macro step's patches are those a neighbour's contact pushes out of; a
    round after a growth starts from patches the check has seen, and an unneeded check costs
    what the check at a round's end does (the gaps of the patches holding cells of other
    asperities: 1.5-2 s on 7,179 patches, against 1.2-1.6 s a sweep).

    ``answered`` is True from a True answer until the caller has grown the patches (or found
    nothing to grow at the refreshed far field, and swept on)."""

    def __init__(self, state: WorkingSet, pivot, tol: float):
        self.state, self.pivot, self.tol = state, pivot, tol
        self.asked = self.answered = False

    def __call__(self, pressures: list, theta) -> bool:
        if self.asked:
            return False
        self.asked = True
        self.answered = penetrates_outside(self.state, pressures, theta, self.pivot, self.tol)
        return self.answered


def residual_failure(patches, p: list, control, tol: float) -> str:
    """Why converged sweeps still fail the load control (the load off its target by more
    than ``10 tol`` of it, or a moment by more than that times the load's arm about the
    pivot), or "" where they hold or nothing is controlled."""
    pivot, n_unknowns, target = control.pivot, control.n_unknowns, control.target
    if not n_unknowns:
        return ""
    residual = np.asarray(target) - np.atleast_1d(resultants(patches, p, pivot, n_unknowns))
    if abs(residual[0]) > 10.0 * tol * abs(target[0]):
        return f"two-level iteration stopped with load residual {residual[0]:.3g} N"
    if n_unknowns == 3:
        # moments against the load times the load-weighted distance from the pivot
        arm = _load_arm(patches, p, pivot)
        if np.max(np.abs(residual[1:])) > 10.0 * tol * abs(target[0]) * arm:
            return f"two-level iteration stopped with moment residuals {residual[1]:.3g}, {residual[2]:.3g} N mm"
    return ""


def block_tips(tips: np.ndarray, patches) -> np.ndarray:
    """The point that stands for each block in the coarse space, (N, 2) mm: its asperity's
    tip, the mean of its members' tips for a merged block."""
    return np.array([tips[list(pt.members)].mean(axis=0) for pt in patches], dtype=float).reshape(-1, 2)


def _load_arm(patches, pressures: list, pivot) -> float:
    """Load-weighted rms distance of the pressure from the pivot, mm (at least one cell)."""
    num = den = 0.0
    for pt, pk in zip(patches, pressures):
        xr, yr = block_coordinates(pt, pivot)
        num += float(np.sum(pk * (xr * xr + yr * yr)))
        den += float(np.sum(pk))
    h = patches[0].grid.h if patches else 1.0
    return max(math.sqrt(num / den), h) if den > 0 else h


def _correct(state: WorkingSet, p, active, theta, residual, pivot, n_unknowns, tol):
    """One Newton correction of (d, alpha, beta) on the current contact sets."""
    rhs = [rhs_derivatives(pt, pivot, n_unknowns) for pt in state.patches]
    # The sensitivities need little accuracy: the load and moments hold exactly for any
    # of them (K is built from the same ones), and their error enters the pressure only
    # times the (small) correction. Reuse the previous ones when the blocks are the same.
    prev = state.sensitivities
    start = prev if prev is not None and [len(v) for v in prev] == [len(r) for r in rhs] else None
    lin = linear_gauss_seidel(
        state.blocks, state.coupling, rhs, active, tol=max(tol, SENSITIVITY_TOL), max_sweeps=500, start=start
    )
    state.sensitivities = lin.pressures
    K = np.atleast_2d(resultants(state.patches, lin.pressures, pivot, n_unknowns))
    step = newton_step(K, residual)
    theta = theta.copy()
    theta[:n_unknowns] += step
    trial = [pk + s @ step for pk, s in zip(p, lin.pressures)]
    pmax = max(float(np.max(t, initial=0.0)) for t in trial)
    ok = all(np.min(t, initial=0.0) >= -1e-9 * pmax for t in trial)
    if ok:
        z = state.heights(theta, pivot)
        u = state.displacement(trial)
        scale = max(abs(theta[0] - float(np.min(zk, initial=np.inf))) for zk in z if zk.size)
        for a, uk, zk in zip(active, u, z):
            gap = uk + zk - theta[0]
            if np.any(gap[~a] < -10.0 * tol * scale):
                ok = False
                break
    trial = [np.maximum(t, 0.0) for t in trial]
    return trial, theta, ok, lin.sweeps


#: Patch enlargements allowed by default: this many in all, or ``GROWTHS_PER_PATCH`` a patch.
MAX_GROWTHS = 50
GROWTHS_PER_PATCH = 5


def _budget(state: WorkingSet, max_growths: int | None) -> int:
    """Enlargements allowed in all: ``max_growths`` when given, else the default budget."""
    if max_growths is not None:
        return int(max_growths)
    return max(MAX_GROWTHS, GROWTHS_PER_PATCH * len(state.patches))


def _grow_merged(setup: BlockSetup, p: list, theta, tol: float, can_grow: bool) -> int:
    """After a round stopped and its touching contacts were merged: where pressure also
    reaches a patch edge, the patches grown now (:func:`~.workset.grow`, as a round's end
    grows them) rather than after a further sweep that stops on the same edges (6,104
    clustered paraboloids: a round of one sweep, 6-7 s of 107, spent to stop there again).
    Returns the patches grown."""
    state = setup.state
    if not (can_grow and edges_loaded_any(state, p)):
        return 0
    state.coupling.refresh(p)
    grown = grow(state, p, setup.p0, theta, setup.control.pivot, tol)
    if grown:
        merge_touching(state, p, setup.p0)
    return grown


def _round_end(setup: BlockSetup, res, p, theta, tilt, tol, can_grow, growths, counts, history):
    """What follows a round of sweeps ``res``: ``(grown, None)`` with the patches grown (> 0:
    sweep again), or ``(0, result)`` when the round failed or pressure still reaches a patch
    edge, or ``(0, None)`` to go on."""
    state, p0, pivot = setup.state, setup.p0, setup.control.pivot
    if res.converged or res.reason is StopReason.STOPPED:
        grown = grow(state, p, p0, theta, pivot, tol) if can_grow else 0
        if grown:
            return grown, None
    if not res.converged:
        return 0, finish(setup, p, theta, tilt, res.reason, res.message, counts(), history)
    if edges_loaded_any(state, p):
        return 0, finish(
            setup,
            p,
            theta,
            tilt,
            StopReason.MAX_ITER,
            f"pressure still reaches a patch edge after {growths} enlargements",
            counts(),
            history,
        )
    return 0, None


def finish(
    setup: BlockSetup, p: list, theta, tilt, reason: StopReason, message: str, counts: dict, history
) -> MicroResult:
    """The :class:`MicroResult` of ``setup``'s iteration ending at pressures ``p`` and
    ``theta`` for ``reason`` (``counts``: sweeps, corrections, growths, linear_sweeps)."""
    state, p0, pivot = setup.state, setup.p0, setup.control.pivot
    pressures = [scatter(pt, v) for pt, v in zip(state.patches, p)]
    initial = [scatter(pt, v) for pt, v in zip(state.patches, p0)]
    gaps = state.gaps(p, theta, pivot) if state.patches else []
    return MicroResult(
        tuple(state.patches),
        tuple(pressures),
        tuple(initial),
        tuple(gaps),
        float(theta[0]),
        tilt,
        reason.converged,
        message,
        counts["sweeps"],
        counts["corrections"],
        counts["growths"],
        counts["linear_sweeps"],
        tuple(history),
        state.coupling.route_counts(),
        tuple(pt.members for pt in state.patches if len(pt.members) > 1),
        reason,
    )
