"""The block iterations of the micro step, set up: the patches, their blocks and coupling
(:mod:`.workset`), the first pressure (eq. 7, or a previous solve's, :mod:`.start`), merged
blocks; then the loop of :mod:`.block_iterations` (block Gauss-Seidel, eq. 8-9, or its
two-level variant). :mod:`.driver` chooses between these and the union CG (:mod:`.union`)."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..analytic import hertz
from ..grid import Grid
from ..indenters import Asperity
from ..influence.base import InfluenceProvider
from .blocks import scatter
from .localblock import LocalBlock
from .local import initial_pressures
from .pk_stack import BlockStacks
from .patches import TipTable, build_patches, merge_overlapping, transfer
from .block_iterations import finish, run_block_gauss_seidel, run_two_level
from .result import MicroResult
from .workset import WorkingSet, heights, tip_approaches


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



def _initial(provider, asperities, patches, blocks, forces, z_blocks, h, rtol: float = P0_RTOL) -> list:
    """Paper eq. 7 on every (one-asperity) block (``rtol``: conjugate gradients of large blocks)."""
    E_star = provider.material.E_star
    P = [float(forces[pt.asperity]) for pt in patches]
    R = np.array([asperities[pt.asperity].R for pt in patches], dtype=float)
    approaches = [float(d) for d in hertz.penetration(R, P, E_star)]   # each tip alone (Hertz)
    stacks = BlockStacks(provider) if BlockStacks.usable(provider) else None
    return initial_pressures(blocks, z_blocks, P, approaches, h, rtol=rtol, stacks=stacks)


def _starts(provider, asperities, patches, blocks, forces, z_blocks, h, start) -> list:
    """The first pressure of every (one-asperity) block: ``start``'s where it has one, eq. 7
    elsewhere."""
    warm = [None] * len(patches) if start is None else \
        [start.for_patch(pt, asperities, forces) for pt in patches]
    cold = [k for k, w in enumerate(warm) if w is None]
    if cold:
        # p0 is a start: the sweeps correct it, and at 1e-5 its reported distance from the final
        # pressure (the paper's Fig. 6, percent-level) moves by ~1e-4 %; 1e-8 cost 10-20 % of the
        # paper cases' time (two spheres at d/2R = 1: 81 -> 65 ms)
        eq7 = _initial(provider, asperities, [patches[k] for k in cold], [blocks[k] for k in cold], forces,
                       [z_blocks[k] for k in cold], h, rtol=P0_RTOL)
        for k, v in zip(cold, eq7):
            warm[k] = v
    return warm


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
                max_corrections: int = 20, max_growths: int | None = None,
                size_from_forces: bool = True, far_tol: float | None = None,
                sizing_approaches: np.ndarray | None = None, coarse: bool = False,
                separated_rtol: float | None = 1e-8, merge: bool = True,
                merge_growth: float = MERGE_GROWTH, monitor=None, patches: list | None = None,
                start=None) -> MicroResult:
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
    max_growths : int or None, default None
        Patch enlargements allowed in all; None: 50, or ``GROWTHS_PER_PATCH`` a patch if
        more (unloading a viscoelastic body leaves contacts wider than the macro step's
        elastic estimate on every tip at once).
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
    start : MicroStart or None
        A previous solve's pressure (:mod:`.start`): the sweeps start from it on the
        patches of the asperities it loaded, from eq. 7 elsewhere.
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
    p0 = _starts(provider, asperities, patches, blocks, forces, heights(patches, theta, pivot), h, start)
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
        return finish(state, [], [], theta, tilt, pivot, True, "no asperity reaches the body",
                       {"sweeps": 0, "corrections": 0, "growths": 0, "linear_sweeps": 0}, ())
    p = [v.copy() for v in p0]
    target = None if total_load is None else np.array([total_load, 0.0, 0.0])[:n_unknowns]
    if coarse:
        out_tilt = (tilt if tilt is not None else (0.0, 0.0)) if (tilt is not None or free_tilt) else None
        return run_two_level(state, p, p0, theta, out_tilt, pivot, n_unknowns, target, tol=tol,
                                max_sweeps=max_sweeps, max_growths=max_growths, monitor=monitor)
    return run_block_gauss_seidel(state, p, p0, theta, tilt, pivot, n_unknowns, target, free_tilt=free_tilt, tol=tol,
                           max_sweeps=max_sweeps, max_growths=max_growths, max_corrections=max_corrections,
                           monitor=monitor)
