"""Polonsky-Keer's constrained conjugate gradients on many blocks at once.

The local solves (:func:`~.pk.fixed_approach`, :func:`~.pk.fixed_force`) of ``B``
independent blocks whose owned cells fit one canvas shape (a size class,
:func:`~.blocks.size_class`): the blocks' vectors are stacked as (B, ny, nx) arrays (zero
and held out of contact off each block's mask) and every product is one
:meth:`~twoscale.influence.base.GridOperator.apply_stack` call with the canvas's
self-operator (its ``kept_stack``: the transforms' arrays from one workspace this object
keeps for the solve, at most 4 MB, :mod:`twoscale.influence.stacked`). The iteration is the one kernel (:func:`twoscale.pk.pk_solve`), whose rows
leave the loop when their own test says so; the others go on. With many small patches
(10,000 sparse tips: ~10^5 local solves of ~500 cells a run) the cost is in the calls,
not the arithmetic, and one call per iteration for B blocks replaces B calls.

The canvas's operator is the translation-invariant part of the provider's kernel
(:meth:`~twoscale.influence.base.InfluenceProvider.split`), every block's whatever its
place. A body with a smooth low-rank correction (the finite block) has each block's
correction of itself taken at the block's previous pressure into its right-hand side
(lagged, as the far field of the two-level iteration: the fixed point is the same, and
the correction of a patch of a millimetre on itself is nearly a rigid shift, a few
percent of its half-space displacement). Eq. 7's start on such a body is the half-space's.
2,799 spheres on the block: the local solves one by one took 55 of 134 s.

The canvas's iterations are preconditioned by the canvas operator's approximate inverse
(:class:`~twoscale.influence.circulant.CirculantInverse`, an unpadded FFT pair of the
canvas, about a quarter of a product) and take float32 products for their search
directions (:class:`~twoscale.pk.products.Products`; refreshes and the confirmation of a
converged row stay exact). On 102 spheres of R 8.3 mm (blocks of 2,000-23,000 cells) eq. 7's
stacked solves from Hertz's shape took 25-114 iterations to 1e-5, and 2.7 s of a 10.9 s
solve; preconditioned 0.5 s; the sweeps' local solves 5.9 -> 3.3 iterations on average
(12 instead of 16 sweeps, the more exact local solves), the whole solve 6.0 s.
"""

from __future__ import annotations

import numpy as np

from ..influence.stacked import Workspace
from ..pk.products import Products
from .pk import fixed_approach, fixed_force


class _Canvas:
    """One size class's canvas: its self-operator's products (float32 search directions
    where the operator has a cheaper single-precision form) and the preconditioner of its
    iterations (None where the operator has none)."""

    def __init__(self, op, workspace: Workspace):
        single = op.single_precision()
        fast = None if single is op else single.kept_stack(workspace)
        self.products = Products(op.kept_stack(workspace), fast=fast)
        # the approximate inverse in float32 where the operator has one (its rounding, ~1e-7,
        # is far below what it approximates; on 122 x 122 cells 0.53 -> ~0.3 ms a field)
        inverse = (single.preconditioner() if single is not op else None) or op.preconditioner()
        kept = None if inverse is None else inverse.kept_stack(workspace)
        self.precondition = None if kept is None else (lambda v, on: kept(v))


class BlockStacks:
    """Local contact solves of many FFT blocks of one size class at once (see the module
    docstring); owns one canvas operator per class. Internal to a sweep's caller.

    Parameters
    ----------
    provider : InfluenceProvider
        Its :meth:`split` base must be translation-invariant.
    """

    def __init__(self, provider):
        self.provider = provider
        self._base, self._correction = provider.split()
        self._ops: dict = {}
        # the canvases' stacked products' arrays (:mod:`twoscale.influence.stacked`), freed with this object
        self._workspace = Workspace()
        self._masks: dict = {}  # per size class and members: the blocks and their canvas masks
        self._own: dict = {}  # the same: the blocks and the correction's lagged term on them
        self._grouped: dict = {}  # per blocks of :meth:`products`: the blocks and their groups

    @staticmethod
    def usable(provider) -> bool:
        """Whether the base of ``provider``'s kernel (its :meth:`split`) depends on cell
        offsets only."""
        return bool(getattr(provider.split()[0], "translation_invariant", False))

    @property
    def whole_kernel(self) -> bool:
        """The canvases' operator is the provider's whole kernel (no correction split off)."""
        return self._correction is None

    def canvas(self, blk) -> tuple:
        """Block ``blk``'s size class ``(ny, nx)`` and its canvas (``products``, ``precondition``)."""
        return self._canvas(blk)

    def _lagged(self, blocks, k: int, rhs: np.ndarray, previous: np.ndarray) -> np.ndarray:
        """Block ``k``'s right-hand side less its correction of itself at ``previous``."""
        if self._correction is None or not np.any(previous):
            return rhs
        blk = blocks[k]
        mask = blk.canvas_mask(blk.box.shape)
        p = np.zeros(blk.box.shape)
        p[mask] = previous
        own = getattr(self._correction, "on_itself", None)  # the block's, from kept factors
        if own is not None:
            return rhs - own(blk.box, p)[mask]
        c = self._correction.coefficients(blk.box, p)
        return rhs - self._correction.evaluate(blk.box, c)[mask]

    def _own_stack(self, blocks, members, key):
        """The correction's lagged term of the members on their canvases in one pass (the
        block's ``own_stack``), kept while the same blocks come in the same stack; None
        where the correction has none."""
        if self._correction is None or not hasattr(self._correction, "own_stack"):
            return None
        kept = self._own.get((key, tuple(members)))
        if kept is None or any(a is not b for a, b in zip(kept[0], (blocks[k] for k in members))):
            made = self._correction.own_stack([blocks[k].box for k in members], key)
            kept = self._own[(key, tuple(members))] = ([blocks[k] for k in members], made)
        return kept[1]

    def _canvas(self, blk):
        from .blocks import size_class

        key = (size_class(blk.box.ny), size_class(blk.box.nx))
        canvas = self._ops.get(key)
        if canvas is None:
            canvas = self._ops[key] = _Canvas(
                self._base.grid_operator(blk.box.subgrid(0, 0, key[1], key[0])), self._workspace
            )
        return key, canvas

    def _groups(self, blocks, ks, tol_of) -> dict:
        groups: dict = {}
        for k in ks:
            key, op = self._canvas(blocks[k])
            groups.setdefault((key, tol_of(blocks[k])), (op, []))[1].append(k)
        return groups

    def _stack(self, blocks, members, key, *vectors):
        """The members' canvas masks (B, ny, nx), kept while the same blocks come in the
        same stack (a sweep's levels, every sweep of the round), and each of ``vectors``
        (dicts or lists of block vectors) placed on the canvases, zero elsewhere."""
        kept = self._masks.get((key, tuple(members)))
        if kept is None or any(a is not b for a, b in zip(kept[0], (blocks[k] for k in members))):
            mask = np.zeros((len(members), *key), bool)
            for i, k in enumerate(members):
                mask[i] = blocks[k].canvas_mask(key)
            mask.setflags(write=False)
            kept = self._masks[(key, tuple(members))] = ([blocks[k] for k in members], mask)
        mask, out = kept[1], [np.zeros((len(members), *key)) for _ in vectors]
        for a, v in zip(out, vectors):
            a[mask] = np.concatenate([v[k] for k in members])  # row-major: member by member
        return mask, out

    def initial(self, blocks, ks, z: list, forces: list, starts: dict, h: float, *, rtol: float) -> dict:
        """Eq. 7 (:func:`~.local.initial_pressure`'s FFT branch) on the blocks ``ks`` (FFT
        blocks owning cells, force > 0): ``{k: pressure}``."""
        out = {}
        for (key, tol), (op, members) in self._groups(blocks, ks, lambda blk: rtol).items():
            mask, (zs, p0) = self._stack(blocks, members, key, z, starts)
            target = np.array([forces[k] / (h * h) for k in members])
            p, _, _, _ = fixed_force(op.products, zs, target, p0, mask, rtol=tol, precondition=op.precondition)
            out.update((k, p[i][mask[i]]) for i, k in enumerate(members))
        return out

    def solve(self, blocks, ks, rhs: dict, previous: list, rtol: float | None) -> dict:
        """Contact on the blocks ``ks`` (FFT blocks owning cells) with right-hand sides
        ``rhs[k]`` from starts ``previous[k]``: ``{k: (pressure, converged, iterations)}``."""
        out, rhs = {}, dict(rhs)
        for (key, tol), (op, members) in self._groups(
            blocks, ks, lambda blk: blk.cg_rtol if rtol is None else rtol
        ).items():
            own = self._own_stack(blocks, members, key)
            if own is None:
                rhs.update((k, self._lagged(blocks, k, rhs[k], previous[k])) for k in members)
            mask, (b, p0) = self._stack(blocks, members, key, rhs, previous)
            if own is not None:
                b[mask] -= own.apply(p0)[mask]  # the members' corrections of themselves, lagged
            p, ok, it = fixed_approach(op.products, b, p0, mask, rtol=tol, precondition=op.precondition)
            out.update((k, (p[i][mask[i]], bool(ok[i]), int(it[i]))) for i, k in enumerate(members))
        return out

    def products(self, blocks, ks, vectors: dict) -> dict:
        """``{k: A_kk v_k}`` (mm) for the blocks ``ks`` and vectors ``vectors[k]`` (MPa, 1-D),
        by one stacked product a size class (the canvases' base kernel: the whole kernel
        only where :attr:`whole_kernel`)."""
        kept = self._grouped.get(tuple(ks))  # a sweep's level: the same blocks every sweep
        if kept is None or any(a is not b for a, b in zip(kept[0], (blocks[k] for k in ks))):
            kept = self._grouped[tuple(ks)] = ([blocks[k] for k in ks], self._groups(blocks, ks, lambda blk: None))
        out = {}
        for (key, _), (op, members) in kept[1].items():
            mask, (v,) = self._stack(blocks, members, key, vectors)
            u = op.products.exact(v)
            out.update((k, u[i][mask[i]]) for i, k in enumerate(members))
        return out
