"""A held far field interpolated on the cells of many blocks by one product.

:class:`~.farfield.LaggedFarField` holds the far field at every block's 3 x 3 stencil
(``table``, (N, 9, m)) and interpolates it on a block's owned cells with the weights
(n_k, 9) of its grid's shape (:func:`.sources.grid_interpolation`). A sweep asks it block by
block; the blocks of one level of a sweep (:func:`.twolevel.sweep_levels`) are independent,
so their weights are laid end to end once and the far field on all their cells is one
row-wise product with the stencil values gathered for each row: the same sums, not a small
matrix product and its call a block (7,339 blocks a sweep on 7,339 clustered spheres).
"""

from __future__ import annotations

from typing import Callable

import numpy as np


def stacked_weights(patches, level: list, weights_of: Callable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The interpolation weights of the blocks ``level`` laid end to end (R, 9), the block
    index of each row (R,) and each block's first row with the total (len(level) + 1,);
    ``weights_of(grid)`` gives a grid's whole-patch weights (ny nx, 9)."""
    parts = [weights_of(patches[k].grid)[patches[k].owned.ravel()] for k in level]
    counts = np.array([len(w) for w in parts], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    rows = np.repeat(np.asarray(level, dtype=np.int64), counts)
    W = np.concatenate(parts) if parts else np.zeros((0, 9))
    return W, rows, starts


class LevelWeights:
    """:func:`stacked_weights` of each level asked for, kept until :meth:`clear` (a patch
    changed): the weights a far field keeps for its owned cells, by level instead of by
    block (the same numbers, 72 bytes an owned cell)."""

    def __init__(self):
        self._kept: dict = {}

    def clear(self) -> None:
        self._kept = {}

    def far(self, patches, level: list, table: np.ndarray, weights_of: Callable) -> list:
        """The far field (mm) on each block of ``level`` (1-D, its owned cells) from the
        held stencil values ``table`` (N, 9, 1)."""
        key = tuple(level)
        hit = self._kept.get(key)
        if hit is None:
            hit = self._kept[key] = stacked_weights(patches, level, weights_of)
        W, rows, starts = hit
        flat = np.einsum("ij,ij->i", W, table[rows, :, 0])
        return [flat[a:b] for a, b in zip(starts[:-1].tolist(), starts[1:].tolist())]
