"""A sweep level's right-hand sides (eq. 8) over flat arrays, for a held far field.

Block ``k``'s right-hand side is ``b_k - (far field on k) - sum_{l near k} A_kl p_l``
(:meth:`.farfield.FarFieldCoupling.rhs`). On the 1,000-tip scenes each call is ~20 array
calls on blocks of ~100 cells (1,013 spheres: 3,756 calls a two-level iteration, ~90 us
each). Here, with every block's cells numbered in one flat vector:

* the held far field on every cell is one product per sweep (the blocks' interpolation
  weights stacked, each row times its block's stencil values);
* the near sums of a level are one sparse product: each target block keeps its rows of
  ``[A_kl1[:, S_l1] A_kl2[:, S_l2] ...]``, ``S_l`` the cells source ``l`` has loaded so
  far in the iteration (a set that only grows: the contacts settle after a sweep or two,
  and a cell unloaded since only adds zeros), with their flat column indices; a level's
  rows are concatenated into one CSR matrix, kept until a near source loads a new cell,
  that multiplies the flat pressure.

A block with a near pair that has no dense block (a spectral or separated route), and a
level whose matrix would go beyond :data:`ROWS_BYTES`, take the coupling's own :meth:`rhs`. The sums are those of :meth:`rhs` in another order of addition.
"""

from __future__ import annotations

import operator

import numpy as np
import scipy.sparse as sp

#: Bytes of kept rows and level matrices (12 an entry, each entry twice); a level whose
#: matrix would go beyond them takes the coupling's right-hand sides block by block.
ROWS_BYTES = 128 << 20


class LevelRhs:
    """The flat right-hand sides of one two-level iteration's sweeps (module docstring).

    Parameters
    ----------
    coupling : LaggedFarField
        Its near pairs' dense blocks are made here where its routes would make them.
    levels : list of lists of block indices
        The sweeps' levels (:func:`.twolevel.sweep_levels`).
    """

    def __init__(self, coupling, levels: list):
        self.coupling = coupling
        self.levels = levels
        patches = coupling.patches
        sizes = np.array([int(pt.owned.sum()) for pt in patches])
        self.offsets = np.concatenate([[0], np.cumsum(sizes)])
        self._pairs = [self._dense_pairs(k) for k in range(len(patches))]
        self._weights = np.vstack([coupling._interpolation(k, False) for k in range(len(patches))])
        self._owner = np.repeat(np.arange(len(patches)), sizes)
        self._level_of = np.zeros(len(patches), np.int64)
        for i, level in enumerate(levels):
            self._level_of[level] = i
        self._loaded = None  # (cells,) bool: every cell loaded in this iteration so far
        self._columns: list = [None] * len(patches)  # per source: its loaded cells' indices
        self._rows: dict = {}  # target k -> (sources' columns, data, flat columns, row length, pairs)
        self._matrices: dict = {}  # level index -> (its blocks, CSR, their cells, bounds, pairs)
        self._flat = self._base = None
        self.nbytes = 0

    def _dense_pairs(self, k: int) -> list | None:
        """``[(l, A_kl)]`` over the near blocks of ``k``, or None if one has no dense block."""
        c, out = self.coupling, []
        for l in c.near(k).tolist():
            M = c._ops.get((k, l))
            if M is None and c._route(k, l)[0] == "plain":
                M = c._dense(k, l)
            if M is None:
                return None
            out.append((l, M))
        return out

    def start(self, p: list, b: list) -> None:
        """A sweep from the pressures ``p`` with the rigid right-hand sides ``b``: the flat
        pressure, and ``b`` less the held far field on every cell."""
        c = self.coupling
        if c._table is None or c._table.shape[2] != 1:
            c.refresh(p)
        self._flat = np.concatenate(p)
        if self._loaded is None:
            self._loaded = self._flat != 0.0
        self._cover(np.arange(self._flat.size))
        table = c._table[:, :, 0]
        self._base = np.concatenate(b) - np.einsum("ij,ij->i", self._weights, table[self._owner])

    def update(self, level, p: list) -> None:
        """The pressures of ``level``'s blocks were replaced: into the flat pressure."""
        cells = []
        for k in level:
            self._flat[self.offsets[k] : self.offsets[k + 1]] = p[k]
            cells.append(np.arange(self.offsets[k], self.offsets[k + 1]))
        if cells:
            self._cover(np.concatenate(cells))

    def _cover(self, cells: np.ndarray) -> None:
        """Add the loaded ones of ``cells`` to the kept columns: their blocks' columns are
        made again, and the rows and matrices that use them."""
        new = cells[(self._flat[cells] != 0.0) & ~self._loaded[cells]]
        if not new.size:
            return
        self._loaded[new] = True
        for l in np.unique(self._owner[new]).tolist():
            self._columns[l] = None
            for k in self.coupling.near(l).tolist():
                gone = self._matrices.pop(self._level_of[k], None)
                self.nbytes -= 0 if gone is None else 12 * gone[1].nnz

    def _source(self, l: int) -> np.ndarray:
        """Block ``l``'s kept columns: the cells it has loaded in this iteration."""
        cols = self._columns[l]
        if cols is None:
            cols = self._columns[l] = np.flatnonzero(self._loaded[self.offsets[l] : self.offsets[l + 1]])
        return cols

    def _target(self, k: int) -> tuple:
        """Block ``k``'s kept rows (made again when a source's columns changed)."""
        cells = [self._source(l) for l, _ in self._pairs[k]]
        hit = self._rows.get(k)
        if hit is not None and all(map(operator.is_, hit[0], cells)):
            return hit
        blocks = [M[:, c] for (_, M), c in zip(self._pairs[k], cells) if c.size]  # a reverse pair's: rows
        cols = [c + self.offsets[l] for (l, _), c in zip(self._pairs[k], cells) if c.size]
        n = int(self.offsets[k + 1] - self.offsets[k])
        width = sum(c.size for c in cols)
        data = np.hstack(blocks).ravel() if blocks else np.zeros(0)
        flat = np.tile(np.concatenate(cols).astype(np.int32), n) if cols else np.zeros(0, np.int32)
        self.nbytes += 12 * (data.size - (0 if hit is None else hit[1].size))
        hit = self._rows[k] = (cells, data, flat, width, len(blocks))
        return hit

    def rhs(self, index: int, level, p: list, b: list) -> dict:
        """``{k: rhs_k}`` for the blocks of level ``index`` (its list ``level``)."""
        c = self.coupling
        out = {k: c.rhs(k, p, b[k]) for k in level if self._pairs[k] is None}
        kept = self._matrices.get(index)
        if kept is None:
            flat = [k for k in level if self._pairs[k] is not None]
            sizes = self.offsets[np.array(flat, np.int64) + 1] - self.offsets[np.array(flat, np.int64)]
            widths = [sum(self._source(l).size for l, _ in self._pairs[k]) for k in flat]
            if not flat or self.nbytes + 24 * int(np.dot(sizes, widths)) > ROWS_BYTES:
                out.update((k, c.rhs(k, p, b[k])) for k in flat)
                return out
            rows = [self._target(k) for k in flat]
            lengths = np.repeat([r[3] for r in rows], sizes)
            indptr = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int32)
            data = np.concatenate([r[1] for r in rows])
            cols = np.concatenate([r[2] for r in rows])
            matrix = sp.csr_matrix((data, cols, indptr), shape=(int(sizes.sum()), self._flat.size))
            cells = np.concatenate([np.arange(self.offsets[k], self.offsets[k + 1]) for k in flat])
            kept = (flat, matrix, cells, np.cumsum(sizes)[:-1], sum(r[4] for r in rows))
            self._matrices[index] = kept
            self.nbytes += 12 * matrix.nnz
        flat, matrix, cells, bounds, pairs = kept
        c.near_products += pairs
        out.update(zip(flat, np.split(self._base[cells] - matrix @ self._flat, bounds)))
        return out
