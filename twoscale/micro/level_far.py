"""A held far field interpolated on the cells of many blocks.

:class:`~.farfield.LaggedFarField` holds the far field at every block's 3 x 3 stencil
(``table``, (N, 9, m)) and interpolates it on a block's owned cells with the weights
(n_k, 9) of its grid's shape (:func:`.sources.grid_interpolation`). A sweep asks it block by
block; the blocks of one level of a sweep (:func:`.twolevel.sweep_levels`) are independent,
so the small blocks' weights are laid end to end once and the far field on all their cells is
one row-wise product with the stencil values gathered for each row: the same sums, not a
small matrix product and its call a block (7,339 blocks a sweep on 7,339 clustered spheres).

The weights are a tensor product, ``L_y(j, a) L_x(i, b)``, so on a large block the field is
``L_y T L_x^T`` on its grid (``T`` the 3 x 3 stencil values) taken on its owned cells
(:func:`separable_far`): three numbers a cell, no weight table. Laid end to end, the weights
of 233 merged patches of 10^4-10^5 cells (#129 of seed 8) were 72 bytes a cell of 4.9
million cells, and their gather and product 86 ms a level.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .sources import SEPARABLE_CELLS, lagrange3


def axis_weights(n: int) -> np.ndarray:
    """The (n, 3) quadratic Lagrange weights of :func:`.sources.grid_interpolation` along
    one axis of ``n`` cells (nodes on the outer cell centres and the middle)."""
    return lagrange3((np.arange(n) - 0.5 * (n - 1)) / max(0.5 * (n - 1), 1e-300))


def separable_far(grid, owned: np.ndarray | None, stencil: np.ndarray) -> np.ndarray:
    """The far field (mm) interpolated from the ``stencil`` values (9,) or (9, m) (3 y by 3
    x) on ``grid``'s cells: (ny nx[, m]) row-major, or on the cells ``owned`` (ny, nx bool) only."""
    Ly, Lx = axis_weights(grid.ny), axis_weights(grid.nx)
    if stencil.ndim == 1 or stencil.shape[1] == 1:
        u = (Ly @ np.reshape(stencil, (3, 3)) @ Lx.T).reshape(*grid.shape, *stencil.shape[1:])
    else:
        u = np.tensordot(Ly, np.tensordot(np.reshape(stencil, (3, 3, -1)), Lx, axes=(1, 1)), axes=(1, 0))
        u = u.transpose(0, 2, 1)  # (ny, nx, m)
    return u.reshape(grid.size, *u.shape[2:]) if owned is None else u[owned]


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
    """:func:`stacked_weights` of the small blocks of each level asked for, kept until a
    patch of that level changes (:meth:`forget`): the weights a far field keeps for its
    owned cells, by level instead of by block (the same numbers, 72 bytes an owned cell)."""

    def __init__(self):
        self._kept: dict = {}

    def forget(self, k: int) -> None:
        """Patch ``k`` changed: drop the weights of the levels holding it (the others stay)."""
        self._kept = {key: hit for key, hit in self._kept.items() if k not in hit[3]}

    def far(self, patches, level: list, table: np.ndarray, weights_of: Callable) -> list:
        """The far field (mm) on each block of ``level`` (1-D, its owned cells) from the
        held stencil values ``table`` (N, 9, 1)."""
        key = tuple(level)
        hit = self._kept.get(key)
        if hit is None:
            small = [k for k in level if int(patches[k].owned.sum()) < SEPARABLE_CELLS]
            hit = self._kept[key] = (*stacked_weights(patches, small, weights_of), frozenset(level), small)
        W, rows, starts, _, small = hit
        out = {}
        if small:
            flat = np.einsum("ij,ij->i", W, table[:, :, 0][rows])
            out = {k: flat[a:b] for k, a, b in zip(small, starts[:-1].tolist(), starts[1:].tolist())}
        return [out[k] if k in out else separable_far(patches[k].grid, patches[k].owned, table[k, :, 0]) for k in level]
