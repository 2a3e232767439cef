"""A near pair's dense block times a block vector, by the columns the vector loads.

A sweep's right-hand side of block ``k`` subtracts ``A_kl p_l`` for each near pair whose
dense block is kept (:class:`~.blocks.Coupling`). ``p_l`` is zero off its contact: on the
1,000-tip scenes ~17 of ~100 cells, so the product ``A_kl p_l`` streams ~6 times the bytes
it needs (1,013 spheres: 2,364 products of 11,600 entries a sweep, 60 ms of the sweep's
80 ms of right-hand sides, bound by memory). Here the columns ``A_kl[:, S_l]`` of the
loaded cells are kept per pair while ``S_l`` stays the same (the contacts settle after the
first sweep), and the product is ``A_kl[:, S_l] p_l[S_l]``: the same sum without its zero
terms (the same numbers up to the order of the additions).
"""

from __future__ import annotations

import numpy as np

#: Bytes of kept columns over all pairs; beyond them a pair's product takes its whole block.
COLUMNS_BYTES = 64 << 20


class ActiveColumns:
    """Kept active columns of near pairs' dense blocks (module docstring), checked by the
    very block array and the very source vector they were made for (the sweeps replace a
    block's vector, never modify it)."""

    def __init__(self, budget: float = COLUMNS_BYTES):
        self.budget = budget
        self.nbytes = 0
        self._vectors: dict = {}  # l -> (v, loaded cells, v on them, their bytes)
        self._pairs: dict = {}  # (k, l) -> (A_kl, loaded cells' bytes, A_kl[:, loaded])

    def product(self, k: int, l: int, M: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``M @ v`` for the dense block ``M`` = ``A_kl`` and block ``l``'s vector ``v`` (n_l,)."""
        hit = self._vectors.get(l)
        if hit is None or hit[0] is not v:
            cells = np.flatnonzero(v)
            hit = (v, cells, v[cells], cells.tobytes())
            self._vectors[l] = hit
        _, cells, loaded, key = hit
        if 2 * cells.size > v.size:
            return M @ v  # loaded on most cells: the whole block
        kept = self._pairs.get((k, l))
        if kept is None or kept[0] is not M or kept[1] != key:
            old = 0 if kept is None else kept[2].nbytes
            size = 8 * M.shape[0] * cells.size
            if self.nbytes - old + size > self.budget:
                return M @ v
            kept = (M, key, M[:, cells])  # not np.take: it copies a transposed view whole first
            self._pairs[(k, l)] = kept
            self.nbytes += size - old
        return kept[2] @ loaded

    def drop(self, k: int) -> None:
        """Forget every pair and vector of block ``k`` (its patch changed)."""
        self._vectors.pop(k, None)
        for key in [key for key in self._pairs if k in key]:
            self.nbytes -= self._pairs.pop(key)[2].nbytes
