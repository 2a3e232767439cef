"""The mutable state of one finite-block provider: its factorisation and lattice fields.

A :class:`~fem_influence.provider.BlockProvider` is a frozen description of a body; what
it learns while answering (the factorisation, built lazily, and the correction fields of
the source-lattice nodes solved so far) lives here, owned by that provider.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twoscale.influence.cache import BoundedCache

from .cache import FieldCache
from .interpolate import TopInterpolator

#: Bytes of Love offset tables kept for the half-space part of the block's grid products (a
#: quadrant of Love values per cell size, 16 MB, and patch-sized tables): a dense block or
#: an operator is then a gather, not new Love values (4,753 tips: 17 s of 126 s).
LOVE_TABLE_BYTES = 64e6
#: Bytes of the half-space part's self-operators kept per grid shape (:meth:`LatticeState.halfspace_operator`).
SELF_OPERATOR_BYTES = 32e6


@dataclass
class LatticeState:
    """Mutable, explicit cache of one provider: factorisation (lazy) and lattice fields.

    ``table`` holds the known fields as columns (n_top, K) and ``index`` maps a
    lattice node ``(i, j)`` to its column; both are rebuilt by :meth:`refresh`.
    """

    fields: FieldCache
    solver: object = None
    timings_s: dict = field(default_factory=dict)
    table: np.ndarray = None
    index: dict = field(default_factory=dict)
    interpolator: TopInterpolator = None
    grid_memo: dict = field(default_factory=dict)
    love_tables: BoundedCache = field(default_factory=lambda: BoundedCache(LOVE_TABLE_BYTES, name="block love tables"))
    mirror: object = None
    self_operators: BoundedCache = field(
        default_factory=lambda: BoundedCache(SELF_OPERATOR_BYTES, name="block half-space self-operators")
    )

    def halfspace_operator(self, halfspace, target, source):
        """The half-space part's grid operator of a pair: a grid on itself as the kept one of
        its shape moved there (Love's kernel depends on the cells' offsets only: the same
        spectrum), so that every patch's own product at the result's gaps (5,930 spheres:
        5,713 patches of a few hundred shapes) does not transform its kernel again."""
        if target != source:
            return halfspace.grid_operator(target, source, tables=self.love_tables)
        key = (float(target.h), target.nx, target.ny)
        op = self.self_operators.get(key)
        if op is None:
            op = halfspace.grid_operator(target, target, tables=self.love_tables)
            self.self_operators.put(key, op, op.nbytes)
        return op.moved(target, target)

    def refresh(self) -> None:
        keys = list(self.fields.fields)
        self.index = {k: c for c, k in enumerate(keys)}
        self.table = np.array([self.fields.fields[k] for k in keys]).T if keys else None
        if self.interpolator is None and self.fields.top_xy is not None:
            self.interpolator = TopInterpolator(self.fields.top_xy)

    def scaled_table(self, E: float) -> np.ndarray:
        """``table / E`` (mm/N), kept in ``grid_memo`` (made again as lattice nodes are solved)."""
        T = self.grid_memo.get(("T",))
        if T is None or T.shape != self.table.shape:
            T = self.grid_memo[("T",)] = self.table / E
        return T

    def interpolation(self, target, origin) -> tuple:
        """``(M, rows)`` of :func:`~.grid_factors.grid_interpolation` for the grid ``target``
        (scene frame; ``origin`` the provider's), kept per grid in ``grid_memo``."""
        kept = self.grid_memo.get(("M", target))
        if kept is None:
            from .grid_factors import grid_interpolation

            kept = self.grid_memo[("M", target)] = grid_interpolation(self.interpolator, target, origin)
        return kept

    def column_of(self, nodes: np.ndarray) -> np.ndarray:
        get = self.index.get
        return np.array([get((i, j), -1) for i, j in nodes.tolist()], dtype=np.int64)

    def nodes_of(self, cols: np.ndarray) -> np.ndarray:
        """Lattice nodes ``(i, j)`` of the table columns ``cols``, (len(cols), 2)."""
        keys = list(self.index)
        return np.array([keys[c] for c in cols], dtype=np.int64).reshape(-1, 2)

    def mirror_permutations(self, mesh):
        """Top-node permutations for x -> -x and y -> -y of ``mesh``, or None if it is not
        mirror-symmetric (kept: the mesh of one provider does not change)."""
        if self.mirror is None:
            p = np.round(mesh.p.T, 9)
            pts = {tuple(q) for q in p.tolist()}
            sym = all((-x, y, z) in pts and (x, -y, z) in pts for x, y, z in p.tolist())
            if not sym:
                self.mirror = False
            else:
                if self.fields.top_xy is None:
                    self.mirror = None
                    return "pending"
                xy = np.round(self.fields.top_xy, 9)
                where = {tuple(q): k for k, q in enumerate(xy.tolist())}
                px = np.array([where[(-x, y)] for x, y in xy.tolist()])
                py = np.array([where[(x, -y)] for x, y in xy.tolist()])
                self.mirror = (px, py)
        return self.mirror or None
