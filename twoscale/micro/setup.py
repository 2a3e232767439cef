"""The block iterations of the micro step, set up (:func:`block_setup`): the patches, their
blocks and the coupling's engine (:mod:`.workset`, :mod:`.couplings`), the first pressure
(eq. 7, or a previous solve's, :mod:`.start`), merged blocks. The loops are in
:mod:`.block_iterations`; the iteration objects of :mod:`.strategies` call both."""

from __future__ import annotations

import numpy as np

from ..analytic import hertz
from ..grid import Grid
from .block_iterations import BlockSetup
from .blocks import scatter
from .constraints import Control
from .localblock import LocalBlock
from .local import initial_pressures
from .pk_stack import BlockStacks
from .patches import merge_groups, merge_overlapping, transfer
from .sampling import BOX_MIN_PATCH_SHARE, build_patches, patch_grids, sampled_patches
from .problem import MicroContext
from .touching import touching_groups
from .workset import WorkingSet, heights, tip_approaches


#: Relative change at which the local conjugate gradients of eq. 7 (the start p0) stop.
P0_RTOL = 1e-5


def _initial(provider, asperities, patches, blocks, forces, z_blocks, h, rtol: float = P0_RTOL) -> list:
    """Paper eq. 7 on every (one-asperity) block (``rtol``: conjugate gradients of large blocks)."""
    E_star = provider.material.E_star
    P = [float(forces[pt.asperity]) for pt in patches]
    R = np.array([asperities[pt.asperity].R for pt in patches], dtype=float)
    approaches = [float(d) for d in hertz.penetration(R, P, E_star)]  # each tip alone (Hertz)
    stacks = BlockStacks(provider) if BlockStacks.usable(provider) else None
    return initial_pressures(blocks, z_blocks, P, approaches, h, rtol=rtol, stacks=stacks)


def _starts(provider, asperities, patches, blocks, forces, z_blocks, h, start) -> list:
    """The first pressure of every (one-asperity) block: ``start``'s where it has one, eq. 7
    elsewhere."""
    warm = [None] * len(patches) if start is None else [start.for_patch(pt, asperities, forces) for pt in patches]
    cold = [k for k, w in enumerate(warm) if w is None]
    if cold:
        # p0 is a start: the sweeps correct it, and at 1e-5 its reported distance from the final
        # pressure (the paper's Fig. 6, percent-level) moves by ~1e-4 %; 1e-8 cost 10-20 % of the
        # paper cases' time (two spheres at d/2R = 1: 81 -> 65 ms)
        eq7 = _initial(
            provider,
            asperities,
            [patches[k] for k in cold],
            [blocks[k] for k in cold],
            forces,
            [z_blocks[k] for k in cold],
            h,
            rtol=P0_RTOL,
        )
        for k, v in zip(cold, eq7):
            warm[k] = v
    return warm


def _kept_starts(ctx: MicroContext, patches: list, blocks: list, theta: np.ndarray) -> list:
    """:func:`_starts` of ``patches``, taken from the context's ``kept_starts`` where an
    earlier attempt of the same micro step made them (and kept there, read-only)."""
    pb = ctx.problem

    def key(pt):
        return (pt.asperity, pt.grid, float(pb.forces[pt.asperity]), tuple(map(float, theta)), tuple(pb.pivot))

    kept = ctx.kept_starts
    todo = [k for k, pt in enumerate(patches) if key(pt) not in kept]
    if todo:
        sub = [patches[k] for k in todo]
        made = _starts(
            ctx.provider,
            ctx.asperities,
            sub,
            [blocks[k] for k in todo],
            pb.forces,
            heights(sub, theta, pb.pivot),
            pb.h,
            pb.start,
        )
        for pt, p in zip(sub, made):
            p.setflags(write=False)
            kept[key(pt)] = p
    return [kept[key(pt)] for pt in patches]


def initial_on_patches(ctx: MicroContext) -> tuple:
    """Paper eq. 7 on the context's one-asperity patches, summed onto the grid covering
    them: ``(grid, p0 (ny, nx) MPa)``."""
    pb, patches = ctx.problem, ctx.patches
    h, pivot = pb.h, pb.pivot
    blocks = [LocalBlock(ctx.provider, pt, dense_max_cells=ctx.options.dense_max_cells) for pt in patches]
    p0 = _initial(ctx.provider, ctx.asperities, patches, blocks, pb.forces, heights(patches, pb.theta, pivot), h)
    b = np.array([pt.grid.bounds for pt in patches])
    grid = Grid.covering(b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max(), h, anchor=pb.anchor)
    out = np.zeros(grid.shape)
    for pt, pk in zip(patches, p0):
        di, dj = pt.grid.offset_in(grid)
        out[dj : dj + pt.grid.ny, di : di + pt.grid.nx] += scatter(pt, pk)
    return grid, out


def reach_approaches(asperities, problem) -> np.ndarray:
    """Each tip's approach that sizes its patch, mm (<= 0: none): the geometric one at the
    problem's approach and tilt, raised by the problem's ``lift`` (a rising surface's)."""
    approaches = tip_approaches(asperities, problem.theta, problem.pivot)
    return approaches if problem.lift is None else approaches + problem.lift


def one_asperity_patches(
    provider, asperities, problem, margin: float, box_share: float = BOX_MIN_PATCH_SHARE, low_share: float | None = None
) -> list:
    """One patch per asperity the problem's approach and tilt reach, sized from the macro
    forces (or the indenters' reach where the macro step did not converge), half-width
    ``margin`` times the Hertz-like contact radius (:func:`~.sampling.build_patches`), cut
    from their box sampled once from ``box_share`` of it, or ``low_share`` on a box of few
    cells a patch (:func:`~.sampling.sampled_patches`)."""
    sizing = np.asarray(problem.forces, dtype=float) if problem.size_from_forces else np.full(len(asperities), np.inf)
    wanted = patch_grids(
        asperities,
        h=problem.h,
        forces=sizing,
        approaches=reach_approaches(asperities, problem),
        E_star=provider.material.E_star,
        margin=margin,
        anchor=problem.anchor,
    )
    return sampled_patches(
        asperities, wanted, h=problem.h, anchor=problem.anchor, box_share=box_share, low_share=low_share
    )


def block_setup(
    ctx: MicroContext, coupling, *, held: bool, merge: bool, sizing_approaches=None, merge_touching: bool = False
) -> BlockSetup:
    """A block iteration ready to run on ``ctx`` with ``coupling`` (an object of
    :mod:`.couplings`, whose engine is built here for the final patches; ``held``: the
    far field held for a sweep, the two-level iteration).

    The one-asperity patches are the context's, or built from the problem (and, given
    ``sizing_approaches`` (N,) mm, sized anew from them, reusing the context's); each
    block starts from the problem's ``start`` where it has one, eq. 7 elsewhere; with
    ``merge`` close patches become one block (:func:`~.patches.merge_overlapping`, the
    block Gauss-Seidel iteration with exact coupling); with ``merge_touching`` (and not
    ``merge``) the patches whose start pressures touch become one block
    (:func:`~.touching.touching_groups`, the two-level iteration with far-field coupling).
    """
    pb, opts, settings = ctx.problem, ctx.options, ctx.settings
    provider, asperities, h, pivot = ctx.provider, ctx.asperities, pb.h, pb.pivot
    theta = pb.theta
    patches = None if ctx.patches is None else list(ctx.patches)
    if patches is None or sizing_approaches is not None:
        approaches = reach_approaches(asperities, pb)
        if sizing_approaches is not None:
            sizing_approaches = np.asarray(sizing_approaches, dtype=float)
            if sizing_approaches.shape != approaches.shape or not np.all(np.isfinite(sizing_approaches)):
                raise ValueError(
                    f"sizing_approaches must be {len(approaches)} finite numbers (mm), "
                    f"got shape {sizing_approaches.shape}"
                )
            approaches = np.minimum(approaches, sizing_approaches)
        sizing = np.asarray(pb.forces, dtype=float) if pb.size_from_forces else np.full(len(asperities), np.inf)
        patches = build_patches(
            asperities,
            h=h,
            forces=sizing,
            approaches=approaches,
            E_star=provider.material.E_star,
            margin=opts.margin,
            anchor=pb.anchor,
            reuse=patches or (),
        )
    windows: dict = {}  # the blocks' box windows, shared by shape (:class:`.localblock.LocalBlock`)
    blocks = [LocalBlock(provider, pt, dense_max_cells=opts.dense_max_cells, windows=windows) for pt in patches]
    p0 = _kept_starts(ctx, patches, blocks, theta)
    covers = None
    if merge:
        carries = [bool(pt.owned.any()) and bool(np.any(q > 0)) for pt, q in zip(patches, p0)]
        merged, covers = merge_overlapping(patches, asperities, growth=settings.merge_growth, carries=carries)
    elif merge_touching:
        groups = touching_groups(patches, p0)
        if len(groups) < len(patches):
            merged, covers = merge_groups(patches, asperities, groups)
    if covers is not None:
        p0 = [
            p0[c[0]] if len(c) == 1 else sum(transfer(patches[i], pt, scatter(patches[i], p0[i])) for i in c)[pt.owned]
            for pt, c in zip(merged, covers)
        ]
        blocks = [blocks[c[0]] if len(c) == 1 else None for c in covers]
        patches = merged

    def engine(patches):
        return coupling.build(
            provider,
            patches,
            held=held,
            dense_max_entries=settings.dense_max_entries,
            separated_rtol=opts.separated_rtol,
        )

    state = WorkingSet(
        provider,
        asperities,
        patches,
        engine(patches),
        dense_max_cells=opts.dense_max_cells,
        blocks=blocks,
        rebuild=engine if merge_touching and not merge else None,
    )
    return BlockSetup(state, p0, theta, pb.tilt, Control(pivot, pb.n_unknowns, pb.target))
