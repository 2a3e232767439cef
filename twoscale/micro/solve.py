"""The block iterations of the micro step: eq. 7, then block Gauss-Seidel (eq. 8-9) with
sensitivity corrections of the load and tilt, or its two-level variant; patch growth in
:mod:`.workset`. :mod:`.driver` chooses between these and the union CG (:mod:`.union`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..analytic import hertz
from ..grid import Grid
from ..indenters import Asperity
from ..influence.base import InfluenceProvider
from .blocks import scatter
from .localblock import LocalBlock
from .constraints import block_coordinates, newton_step, resultants, rhs_derivatives
from .gauss_seidel import gauss_seidel, linear_gauss_seidel
from .local import initial_pressures
from .pk_stack import BlockStacks
from .patches import TipTable, build_patches, merge_overlapping, transfer
from .twolevel import two_level
from .workset import WorkingSet, edges_loaded_any, grow, heights, tip_approaches


@dataclass(frozen=True)
class MicroResult:
    """Pressure on the patches after the micro step.

    Attributes
    ----------
    patches : tuple of Patch
    pressures : tuple of (ny, nx) arrays, MPa: final pressure on each patch's block.
    initial : tuple of (ny, nx) arrays, MPa: eq. 7 pressures ``p0`` on the final patches
        (empty when they were not computed: the union CG without ``p0``).
    gaps : tuple of (ny, nx) arrays, mm: ``z + tilt + u - d`` (``inf`` where no indenter).
    penetration : float
        Approach d, mm (given, or corrected under load control).
    tilt : (alpha, beta) or None, radians.
    converged : bool
    message : str
    sweeps : int
        Block Gauss-Seidel sweeps, all rounds together.
    corrections : int
        Newton corrections of (d, alpha, beta) (load control only).
    growths : int
        Patch enlargements.
    linear_sweeps : int
        Sweeps of the sensitivity solves behind the corrections (each with 1 or 3
        right-hand sides).
    history : tuple of float
        Relative change after every sweep (eq. 9).
    coupling : dict
        How the cross-patch products were made: pairs per route (``dense``, ``fft``,
        ``separated``, ``spectral``; :class:`~.blocks.Coupling`) and ``separated_rtol``.
    merged : tuple of tuple of int
        Asperities solved together as one block (``merge``), one tuple per merged patch.
    """

    patches: tuple
    pressures: tuple
    initial: tuple
    gaps: tuple
    penetration: float
    tilt: tuple | None
    converged: bool
    message: str
    sweeps: int
    corrections: int
    growths: int
    linear_sweeps: int
    history: tuple
    coupling: dict = field(default_factory=dict)
    merged: tuple = ()


#: Relative change at which the local conjugate gradients of eq. 7 (the start p0) stop.
P0_RTOL = 1e-5

#: Merged blocks may cover this many times the cells of their patches: one constrained CG
#: on the common grid then costs about what the sweeps over the separate patches do (paper
#: cases, best of 4: seven spheres at d/2R = 0.5 248 -> 177 ms, at 1 241 -> 181 ms against
#: no growth, 1; two at d/2R = 1 stays apart; at 3, two at d/2R = 1 merged and went
#: 66 -> 122 ms).
MERGE_GROWTH = 2.0

#: far_tol that makes every pair of patches "near": the two-level iteration with exact coupling.
EXACT_FAR_TOL = 1e-12

#: Relative change at which the sensitivity sweeps (load and tilt corrections) stop.
SENSITIVITY_TOL = 1e-3


def _initial(provider, asperities, patches, blocks, forces, z_blocks, h, rtol: float = P0_RTOL) -> list:
    """Paper eq. 7 on every (one-asperity) block (``rtol``: conjugate gradients of large blocks)."""
    E_star = provider.material.E_star
    P = [float(forces[pt.asperity]) for pt in patches]
    R = np.array([asperities[pt.asperity].R for pt in patches], dtype=float)
    approaches = [float(d) for d in hertz.penetration(R, P, E_star)]   # each tip alone (Hertz)
    stacks = BlockStacks(provider) if BlockStacks.usable(provider) else None
    return initial_pressures(blocks, z_blocks, P, approaches, h, rtol=rtol, stacks=stacks)


def initial_on_patches(provider, asperities, patches, common) -> tuple:
    """Paper eq. 7 on one-asperity ``patches``, summed onto the grid covering them:
    ``(grid, p0 (ny, nx) MPa)``. ``common`` holds h, forces, penetration, tilt, pivot."""
    h, pivot = common["h"], common["pivot"]
    theta = np.array([common["penetration"], *(common["tilt"] or (0.0, 0.0))], dtype=float)
    blocks = [LocalBlock(provider, pt, dense_max_cells=common.get("dense_max_cells", 400)) for pt in patches]
    p0 = _initial(provider, asperities, patches, blocks, common["forces"], heights(patches, theta, pivot), h)
    b = np.array([pt.grid.bounds for pt in patches])
    grid = Grid.covering(b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max(), h,
                         anchor=common.get("anchor", (0.0, 0.0)))
    out = np.zeros(grid.shape)
    for pt, pk in zip(patches, p0):
        di, dj = pt.grid.offset_in(grid)
        out[dj:dj + pt.grid.ny, di:di + pt.grid.nx] += scatter(pt, pk)
    return grid, out


def solve_micro(provider: InfluenceProvider, asperities: Sequence[Asperity], *, h: float,
                forces: np.ndarray, penetration: float, tilt: tuple[float, float] | None = None,
                pivot: tuple[float, float] = (0.0, 0.0), total_load: float | None = None,
                free_tilt: bool = False, tol: float = 1e-6, max_sweeps: int = 100,
                margin: float = 1.3, anchor: tuple[float, float] = (0.0, 0.0),
                dense_max_cells: int = 400, dense_max_entries: int = 40_000,
                max_corrections: int = 20, max_growths: int = 50,
                size_from_forces: bool = True, far_tol: float | None = None,
                sizing_approaches: np.ndarray | None = None, coarse: bool = False,
                separated_rtol: float | None = 1e-8, merge: bool = True,
                merge_growth: float = MERGE_GROWTH, monitor=None, patches: list | None = None) -> MicroResult:
    """Pressure on patches from the macro forces (docs/method.md section 3).

    Parameters
    ----------
    provider : InfluenceProvider
    asperities : sequence of Asperity
    h : float
        Cell side, mm.
    forces : (N,) array
        Macro tip forces, N (eq. 7 and patch sizes).
    penetration : float
        Approach d, mm (the macro one under load control).
    tilt : (alpha, beta) or None
        Tilt angles, radians (the macro ones when ``free_tilt``).
    pivot : (float, float), default (0, 0)
        Tilt pivot, mm.
    total_load : float or None
        Load control: the approach (and the tilt when ``free_tilt``) are corrected until
        the pressure carries ``total_load`` N (and zero moments about the pivot).
    free_tilt : bool, default False
        Ball-and-socket joint (needs ``total_load``).
    tol : float, default 1e-6
        Eq. 9 relative change at which the sweeps stop.
    max_sweeps : int, default 100
        Sweeps allowed in all rounds together.
    margin : float, default 1.3
        Patch half-width over the Hertz-like contact radius.
    anchor : (float, float), default (0, 0)
        A cell centre of the common lattice, mm.
    dense_max_cells : int, default 400
        Blocks up to this size are solved densely (Cholesky), larger ones by FFT + CG.
    dense_max_entries : int, default 40000
        Cross blocks ``A_kl`` up to this many entries are formed densely, larger by FFT.
    max_corrections : int, default 20
        Newton corrections of (d, alpha, beta) allowed.
    max_growths : int, default 50
        Patch enlargements allowed.
    size_from_forces : bool, default True
        Size the patches from the macro forces; False sizes them by the geometric reach
        of each indenter (use when the macro step did not converge).
    far_tol : float or None, default None
        None: every cross block ``A_kl`` exact. A number in (0, 1): patches farther apart
        than ``(r_k + r_l) / sqrt(far_tol)`` act through their resultant force
        (:class:`~.farfield.FarFieldCoupling`; relative error per far pair about
        ``far_tol``), for scenes with many asperities.
    sizing_approaches : (N,) array or None, default None
        Approach of each tip used to size the patches, mm (<= 0: no patch); default the
        geometric ``d - z_k - tilt``. Asperities penetrating outside every block are still
        given a patch by the growth step.
    coarse : bool, default False
        Two-level iteration (:mod:`.twolevel`, needs ``far_tol``): the far field is
        evaluated for all blocks once per sweep by the provider's point operator, and a
        coarse correction (the linearised macro equations on the sweep's resultant changes,
        :mod:`.coarse`) removes the bulk error and corrects the approach and tilt, in place
        of the sensitivity sweeps. For thousands of asperities.
    separated_rtol : float or None, default 1e-8
        Cross blocks between patches far apart for their size go through the provider's
        low-rank separated operator, accurate to this fraction of the pair's displacement
        (:class:`~.blocks.Coupling`); None: FFT products only.
    merge : bool, default True
        Solve close patches together: after eq. 7 (always one asperity per patch), patches
        whose common grid has at most ``merge_growth`` times the cells they have apart
        become one block (:func:`~.patches.merge_overlapping`; close or merged contacts),
        so the sweeps do not pass their strong interaction back and forth. False: one
        block per asperity, the paper's iteration. Only without ``far_tol`` (the far field
        acts through each asperity's resultant).
    merge_growth : float, default ``MERGE_GROWTH`` (2)
        Cells a merged grid may have over its members' grids together (>= 1).
    monitor : callable, optional
        ``monitor(sweep, change)`` after each sweep (progress display).
    patches : list of Patch or None
        The one-asperity patches these arguments give, already built (the driver builds
        them for its policy); ignored with ``sizing_approaches``, which sizes them anew.
    """
    if coarse and far_tol is None:
        raise ValueError("coarse=True needs far_tol (the two-level iteration holds the far field by resultants)")
    asperities = TipTable.of(asperities)  # tip arrays once for every patch built
    theta = np.array([penetration, *(tilt if tilt is not None else (0.0, 0.0))], dtype=float)
    n_unknowns = 0 if total_load is None else (3 if free_tilt else 1)
    sizing = np.asarray(forces, dtype=float) if size_from_forces else np.full(len(asperities), np.inf)
    approaches = tip_approaches(asperities, theta, pivot)
    if sizing_approaches is not None:
        sizing_approaches = np.asarray(sizing_approaches, dtype=float)
        if sizing_approaches.shape != approaches.shape or not np.all(np.isfinite(sizing_approaches)):
            raise ValueError(f"sizing_approaches must be {len(approaches)} finite numbers (mm), "
                             f"got shape {sizing_approaches.shape}")
        approaches = np.minimum(approaches, sizing_approaches)
    if patches is None or sizing_approaches is not None:
        patches = build_patches(asperities, h=h, forces=sizing, approaches=approaches,
                                E_star=provider.material.E_star, margin=margin, anchor=anchor, reuse=patches or ())
    blocks = [LocalBlock(provider, pt, dense_max_cells=dense_max_cells) for pt in patches]
    # p0 is a start: the sweeps correct it, and at 1e-5 its reported distance from the final
    # pressure (the paper's Fig. 6, percent-level) moves by ~1e-4 %; 1e-8 cost 10-20 % of the
    # paper cases' time (two spheres at d/2R = 1: 81 -> 65 ms)
    p0 = _initial(provider, asperities, patches, blocks, forces, heights(patches, theta, pivot), h,
                  rtol=P0_RTOL)
    if merge and far_tol is None:
        merged, covers = merge_overlapping(patches, asperities, growth=merge_growth)
        p0 = [p0[c[0]] if len(c) == 1 else
              sum(transfer(patches[i], pt, scatter(patches[i], p0[i])) for i in c)[pt.owned]
              for pt, c in zip(merged, covers)]
        blocks = [blocks[c[0]] if len(c) == 1 else None for c in covers]
        patches = merged
    state = WorkingSet(provider, asperities, patches, dense_max_cells, dense_max_entries, far_tol, lagged=coarse,
                   separated_rtol=separated_rtol, blocks=blocks)
    if not patches:
        return _finish(state, [], [], theta, tilt, pivot, True, "no asperity reaches the body",
                       {"sweeps": 0, "corrections": 0, "growths": 0, "linear_sweeps": 0}, ())
    p = [v.copy() for v in p0]
    target = None if total_load is None else np.array([total_load, 0.0, 0.0])[:n_unknowns]
    if coarse:
        out_tilt = (tilt if tilt is not None else (0.0, 0.0)) if (tilt is not None or free_tilt) else None
        return _solve_two_level(state, p, p0, theta, out_tilt, pivot, n_unknowns, target, tol=tol,
                                max_sweeps=max_sweeps, max_growths=max_growths, monitor=monitor)
    return _solve_block_gs(state, p, p0, theta, tilt, pivot, n_unknowns, target, free_tilt=free_tilt, tol=tol,
                           max_sweeps=max_sweeps, max_growths=max_growths, max_corrections=max_corrections,
                           monitor=monitor)


def _solve_block_gs(state: WorkingSet, p: list, p0: list, theta, tilt, pivot, n_unknowns, target, *,
                    free_tilt: bool, tol: float, max_sweeps: int, max_growths: int, max_corrections: int,
                    monitor=None) -> MicroResult:
    """The micro step by block Gauss-Seidel (eq. 8-9) with patch growth and, under load
    control, Newton corrections of the approach and tilt from sensitivity sweeps."""
    sweeps = corrections = growths = linear_sweeps = 0
    history: list = []

    def counts():
        return {"sweeps": sweeps, "corrections": corrections, "growths": growths, "linear_sweeps": linear_sweeps}

    while True:
        z = state.heights(theta, pivot)
        can_grow = growths < max_growths
        gs = gauss_seidel(state.blocks, state.coupling, [theta[0] - zk for zk in z], p, tol=tol,
                          max_sweeps=max(max_sweeps - sweeps, 1),
                          stop=(lambda q: edges_loaded_any(state, q)) if can_grow else None,
                          monitor=None if monitor is None else (lambda m, c: monitor(sweeps + m, c)))
        sweeps += gs.sweeps
        history += gs.history
        p = gs.pressures
        if gs.converged or gs.message == "stopped":
            grown = grow(state, p, p0, theta, pivot, tol) if can_grow else 0
            if grown:
                growths += grown
                continue
        if not gs.converged:
            return _finish(state, p, p0, theta, tilt, pivot, False, gs.message, counts(), history)
        if edges_loaded_any(state, p):
            return _finish(state, p, p0, theta, tilt, pivot, False,
                           f"pressure still reaches a patch edge after {max_growths} enlargements", counts(), history)
        if target is None:
            break
        residual = target - resultants(state.patches, p, pivot, n_unknowns)
        if corrections >= max_corrections:
            return _finish(state, p, p0, theta, tilt, pivot, False,
                           f"load/moment corrections reached {max_corrections} (residual {residual})",
                           counts(), history)
        corrections += 1
        p, theta, done, lin = _correct(state, p, gs.active, theta, residual, pivot, n_unknowns, tol)
        linear_sweeps += lin
        if done:
            # the corrected approach and tilt may bring in asperities without a patch
            grown = grow(state, p, p0, theta, pivot, tol) if growths < max_growths else 0
            if not grown:
                break
            growths += grown
    out_tilt = (float(theta[1]), float(theta[2])) if (tilt is not None or free_tilt) else None
    return _finish(state, p, p0, theta, out_tilt, pivot, True, "", counts(), history)


def _solve_two_level(state: WorkingSet, p: list, p0: list, theta, tilt, pivot, n_unknowns, target, *,
                     tol: float, max_sweeps: int, max_growths: int, monitor=None) -> MicroResult:
    """The micro step by two-level block Gauss-Seidel (:mod:`.twolevel`), with patch growth."""
    sweeps = growths = 0
    history: list = []
    tips = state.tips()

    def counts():
        return {"sweeps": sweeps, "corrections": sweeps if n_unknowns else 0, "growths": growths,
                "linear_sweeps": 0}

    while True:
        can_grow = growths < max_growths
        res = two_level(state.blocks, state.coupling, tips[[pt.asperity for pt in state.patches]],
                        lambda th: state.heights(th, pivot), p, theta, pivot=pivot, n_unknowns=n_unknowns,
                        target=target, tol=tol, max_sweeps=max(max_sweeps - sweeps, 1),
                        stop=(lambda q: edges_loaded_any(state, q)) if can_grow else None,
                        monitor=None if monitor is None else (lambda m, c: monitor(sweeps + m, c)),
                        earlier=tuple(history))
        sweeps += res.sweeps
        history += res.history
        p, theta = res.pressures, res.theta
        state.coupling.refresh(p)
        if res.converged or res.message == "stopped":
            grown = grow(state, p, p0, theta, pivot, tol) if can_grow else 0
            if grown:
                growths += grown
                continue
        if not res.converged:
            return _finish(state, p, p0, theta, tilt, pivot, False, res.message, counts(), history)
        if edges_loaded_any(state, p):
            return _finish(state, p, p0, theta, tilt, pivot, False,
                           f"pressure still reaches a patch edge after {max_growths} enlargements", counts(), history)
        break
    if n_unknowns:
        residual = np.asarray(target) - np.atleast_1d(resultants(state.patches, p, pivot, n_unknowns))
        if abs(residual[0]) > 10.0 * tol * abs(target[0]):
            return _finish(state, p, p0, theta, tilt, pivot, False,
                           f"two-level iteration stopped with load residual {residual[0]:.3g} N", counts(), history)
        if n_unknowns == 3:
            # moments against the load times the load-weighted distance from the pivot
            arm = _load_arm(state.patches, p, pivot)
            if np.max(np.abs(residual[1:])) > 10.0 * tol * abs(target[0]) * arm:
                return _finish(state, p, p0, theta, tilt, pivot, False,
                               f"two-level iteration stopped with moment residuals {residual[1]:.3g}, "
                               f"{residual[2]:.3g} N mm", counts(), history)
    out_tilt = (float(theta[1]), float(theta[2])) if tilt is not None else None
    return _finish(state, p, p0, theta, out_tilt, pivot, True, "", counts(), history)


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
    lin = linear_gauss_seidel(state.blocks, state.coupling, rhs, active,
                              tol=max(tol, SENSITIVITY_TOL), max_sweeps=500, start=start)
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


def _finish(state, p, p0, theta, tilt, pivot, converged, message, counts, history):
    pressures = [scatter(pt, v) for pt, v in zip(state.patches, p)]
    initial = [scatter(pt, v) for pt, v in zip(state.patches, p0)]
    gaps = state.gaps(p, theta, pivot) if state.patches else []
    return MicroResult(tuple(state.patches), tuple(pressures), tuple(initial), tuple(gaps),
                       float(theta[0]), tilt, converged, message, counts["sweeps"], counts["corrections"],
                       counts["growths"], counts["linear_sweeps"], tuple(history),
                       state.coupling.route_counts(),
                       tuple(pt.members for pt in state.patches if len(pt.members) > 1))
