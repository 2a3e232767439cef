"""The coarse step's shape of each patch: ``s_k = A_SS^{-1} 1`` on its contact cells.

``s_k`` is the pressure on patch ``k``'s contact cells per mm of rigid approach of that patch
alone; ``kappa_k = h^2 sum s_k`` (N/mm) is its contact stiffness (:mod:`.coarse`). It is kept
with the block (``LocalBlock.coarse_shape``: the active set it was solved on and ``s_k``)
through the rounds of a solve, reused while the contact moves little, found for all blocks at
once (:func:`block_shapes`), and, on large blocks, solved together per size class
(:func:`solve_shapes`). A solver object (``provider.remembered``) keeps them between solves
of the same patches.
"""

from __future__ import annotations

import numpy as np

from ..krylov import masked_cg
from .segments import laid_end_to_end, segment_sums

#: Relative residual of the conjugate-gradient solves for ``s_k`` on large blocks.
SHAPE_RTOL = 1e-4
#: A block whose active set differs from the one its ``s_k`` was solved on in at most this
#: fraction of its active cells keeps that ``s_k`` (zero on the cells that entered): the
#: contact edges move by a cell or two in most sweeps, and solving ``s_k`` again for every
#: block each sweep was a third of the two-level iteration's CPU on 4,548 scattered
#: paraboloids under load control (43,690 solves in 10 sweeps).
SHAPE_REUSE = 0.1


def block_shapes(provider, blocks, active: list, starts: np.ndarray) -> list:
    """:func:`shape` of every block in contact (None for the others; ``starts``: the blocks'
    first indices laid end to end, :func:`.segments.starts_of`). A block whose active set is
    the one of its kept ``s_k`` takes it without a call, found over all blocks at once (most
    after the first sweep: 939 blocks, 3 us a block and a comparison)."""
    olds = [blk.coarse_shape for blk in blocks]
    kept = [o is not None and len(o[0]) == len(a) for o, a in zip(olds, active)]
    flat = laid_end_to_end(active, bool)
    moved = segment_sums(
        flat != laid_end_to_end([o[0] if c else a for o, c, a in zip(olds, kept, active)], bool), starts
    )
    out: list = [None] * len(blocks)
    for k in np.flatnonzero(segment_sums(flat, starts)).tolist():
        out[k] = olds[k][1] if kept[k] and moved[k] == 0 else shape(provider, blocks[k], active[k])
    return out


def shape(provider, blk, active: np.ndarray) -> np.ndarray:
    """``s_k = A_SS^{-1} 1`` on the active cells of block ``blk``, kept with the block and
    reused while its active set differs from the one ``s_k`` was solved on in at most
    ``SHAPE_REUSE`` of its cells (zero on the cells that entered); large blocks
    warm-start the conjugate gradients from the previous one and stop at
    ``SHAPE_RTOL`` (the load and moments after the step hold exactly for any ``s_k``,
    which only sets how fast the iteration goes)."""
    old = blk.coarse_shape  # kept with the block through the rounds of the solve
    moved = -1 if old is None else int(np.count_nonzero(active != old[0]))
    if moved == 0:
        return old[1]
    s = np.zeros(blk.n)
    where, kept = remembered(provider, blk, active)
    if kept is not None:
        s[active] = kept
        blk.coarse_shape = (active.copy(), s)
        return s
    if 0 < moved <= SHAPE_REUSE * int(np.count_nonzero(active)):
        s = np.where(active, old[1], 0.0)  # the solved one's, kept as the reference
    else:
        x0 = None if old is None else old[1][active]
        s[active] = blk.solve(active, np.ones(int(active.sum())), x0, rtol=SHAPE_RTOL)
        blk.coarse_shape = (active.copy(), s)
    if where is not None:  # a later solve of the same patches finds it for this active set
        provider.remember("shape", where, s[active].copy())
    return s


def remembered(provider, blk, active: np.ndarray) -> tuple:
    """``(key, s_k on the active cells)`` a solver object kept for this block's geometry
    and active set (``(key, None)``: none yet; ``(None, None)``: no solver object)."""
    kept_of = getattr(provider, "remembered", None)  # a solver object's kept shapes
    if kept_of is None:
        return None, None
    key = (float(blk.box.h), blk.box.nx, blk.box.ny, np.packbits(blk.cells_of(active)).tobytes(), SHAPE_RTOL)
    return key, kept_of("shape", key)


def stale(blk, active: np.ndarray) -> bool:
    """:func:`shape` would solve ``s_k`` again for ``blk`` by conjugate gradients."""
    old = blk.coarse_shape
    if blk.dense or not active.any():
        return False
    if old is None:
        return True
    return int(np.count_nonzero(active != old[0])) > SHAPE_REUSE * int(np.count_nonzero(active))


def solve_shapes(provider, stacks, blocks, todo: list, active: list) -> None:
    """``s_k`` of the FFT blocks ``todo`` by preconditioned conjugate gradients run
    together per size class (:class:`~.pk_stack.BlockStacks`' canvases: one stacked
    product and one circulant inverse an iteration for the class, not a product per
    block and iteration), warm from the kept ``s_k``; each kept with its block as
    :func:`shape` keeps it (4,548 paraboloids: 4,376 solves one by one, 41,059
    products, 10 % of the solve)."""
    groups: dict = {}
    for k in todo:
        if remembered(provider, blocks[k], active[k])[1] is None:  # else :func:`shape` takes it
            key, canvas = stacks.canvas(blocks[k])
            groups.setdefault(key, (canvas, []))[1].append(k)
    for key, (canvas, members) in groups.items():
        on = np.zeros((len(members), *key), bool)
        x = np.zeros(on.shape)
        for i, k in enumerate(members):
            blk, m = blocks[k], blocks[k].canvas_mask(key)
            on[i][m] = active[k]
            if blk.coarse_shape is not None:
                x[i][m] = np.where(active[k], blk.coarse_shape[1], 0.0)
        # float32 products where the canvas has them: ~1e-7 of rounding against SHAPE_RTOL
        product = canvas.products.fast or canvas.products.exact
        x = masked_cg(product, canvas.precondition, on, x, SHAPE_RTOL, blocks[members[0]].cg_max_iter)
        for i, k in enumerate(members):
            s = np.where(active[k], x[i][blocks[k].canvas_mask(key)], 0.0)
            blocks[k].coarse_shape = (active[k].copy(), s)
            where = remembered(provider, blocks[k], active[k])[0]
            if where is not None:
                provider.remember("shape", where, s[active[k]].copy())
