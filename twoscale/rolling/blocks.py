"""The window CG's preconditioner: each stone's contact inverted exactly, the stones coupled
through their total forces (:class:`StoneBlocks`).

Under a tyre the contact is ~250 islands of ~50 cells (one per stone) scattered over the
footprint. The circulant inverse (the kernel's inverse on the grid's torus, restricted to
the loaded cells) is poor there: the inverse of the restricted operator is not the
restriction of the inverse, least of all on small islands and for the smooth mode that
shares the load between the stones; the warm-started CG then gains a factor of about 2.4
an iteration. Here the approximate operator on the loaded cells ``S`` is

    Ã = D + Z K Z^T

with ``D`` the exact operator within each stone's loaded cells (block diagonal: the
kernel's table at the cells' offsets), ``Z`` the cells-to-stones incidence and ``K`` the
point compliance between the stones' centroids times the cell area squared (0 on the
diagonal: a monopole for every pair of stones). ``Ã`` is a block diagonal plus a rank
``m`` term (``m`` stones), so its inverse is exact by the Woodbury identity:

    Ã^-1 r = D^-1 r - V (I + K W)^-1 K Z^T D^-1 r,   V = D^-1 Z,  W = Z^T D^-1 Z (diagonal)

one small dense product per stone and an ``m x m`` product per application. Replayed
positions of the tyre: 8 CG iterations to the KKT residual 1e-8 against 16 with the
circulant inverse (13 with the blocks alone, no coupling). The blocks' inverses depend on
the loaded cells' offsets only (a translation-invariant body), so they are kept by that
pattern between the iterations and the positions of a run (a stone's contact changes by a
few cells a position) and dropped when a position did not use them.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import blas, lapack

from ..indenters import Surface

#: The blocks are rebuilt when the cells that entered the contact since they were built
#: are more than this fraction of the cells they cover (fewer: each its diagonal alone;
#: the cells that left are left out of the blocks' inverses, which stays symmetric and
#: positive).
REBUILD_FRACTION = 0.2
#: Largest stone contact (cells) inverted as one dense block, and most stones coupled: a
#: contact with more (a sphere's, a flat face's) or more stones take the circulant inverse
#: instead (a block costs its cells squared in memory and cubed in time; on the tyre's
#: footprint the largest contact is ~250 cells, the stones ~250).
MAX_BLOCK_CELLS = 600
MAX_STONES = 1500
#: Most memory the stacked inverses of one contact may take (bytes; the tyre's: ~8 MB).
MAX_BLOCK_BYTES = 400e6
#: Block sizes the inverses are padded to and applied by, a batched product per size
#: (:func:`_stacked`): steps of 8 cells, ~1.3x apart past 64 (the padding costs at most
#: ~1.7x the products' work; a product per stone cost ~6 us of Python each, 250 stones).
SIZE_CLASSES = np.array([8, 16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256, 320, 384, 448, 512, 600])


class StoneBlocks:
    """The preconditioners of a run's positions and the block inverses they share.

    Parameters
    ----------
    body : KeptBody
        The window's body (:class:`twoscale.rolling.window.KeptBody`): its kept operators'
        kernel tables, and its provider's point compliance for the stones' coupling.
    """

    def __init__(self, body):
        self.body = body
        self._inverses: dict = {}  # cell offsets -> (inverse, its row sums)
        self._used: set = set()
        self._tables: dict = {}  # grid shape -> the kernel's padded table
        self.built = 0  # inverses computed (the others were found kept)

    def __call__(self, surface: Surface) -> "BlockInverse":
        """The preconditioner of a solve on ``surface`` (its grid and the cells' stones);
        the inverses the last solve did not use are dropped."""
        self._inverses = {k: v for k, v in self._inverses.items() if k in self._used}
        self._used = set()
        return BlockInverse(self, surface)

    def table(self, grid) -> np.ndarray:
        """The kernel's padded table on ``grid`` (entry ``(ny - 1, nx - 1)`` the offset 0), kept by
        the grid's shape (a translation-invariant body)."""
        if grid.shape not in self._tables:
            self._tables = {grid.shape: self.body.grid_operator(grid).op.padded_table()}
        return self._tables[grid.shape]

    def inverse(self, rows: np.ndarray, cols: np.ndarray, table: np.ndarray, centre: tuple[int, int]):
        """The inverse of the operator on the cells ``(rows, cols)`` (one stone's), full and
        zero-padded to its size class (:data:`SIZE_CLASSES`), and its row sums, kept by the
        cells' offsets."""
        key = (rows - rows[0]).tobytes() + b"|" + (cols - cols[0]).tobytes()
        self._used.add(key)
        found = self._inverses.get(key)
        if found is None:
            width = table.shape[1]
            flat = rows * width + cols
            block = table.ravel()[(centre[0] * width + centre[1]) + flat[:, None] - flat[None, :]]
            n = len(rows)
            inv = _spd_inverse(block)
            padded = np.zeros((int(_size_class(n)),) * 2)
            padded[:n, :n] = np.triu(inv)
            padded[:n, :n] += np.triu(inv, 1).T
            found = self._inverses[key] = (padded, blas.dsymv(1.0, inv, np.ones(n)))
            self.built += 1
        return found


def _spd_inverse(block: np.ndarray) -> np.ndarray:
    """The inverse of a symmetric positive definite ``block`` by Cholesky (LAPACK potrf and
    potri: half the time of numpy's LU inverse on the tyre's blocks), valid in its upper
    triangle only (read by BLAS ``symv``)."""
    factor, info = lapack.dpotrf(block, lower=False, overwrite_a=True)
    if info == 0:
        inv, info = lapack.dpotri(factor, lower=False, overwrite_c=True)
        if info == 0:
            return inv
    raise np.linalg.LinAlgError(f"a stone's block is not positive definite (LAPACK info {info})")


class BlockInverse:
    """``Ã^-1`` (module docstring) on the loaded cells of one solve, rebuilt when they
    change; :meth:`apply` is the kernel's preconditioner (``solve_cg(preconditioner=...)``)."""

    def __init__(self, blocks: StoneBlocks, surface: Surface):
        self.blocks, self.grid = blocks, surface.grid
        self.owner = surface.owner.ravel()
        self.table = blocks.table(surface.grid)
        self.centre = (self.grid.ny - 1, self.grid.nx - 1)  # the table's entry of offset 0
        self._on: np.ndarray | None = None
        self.circulant = None  # the operator's inverse, once the contact is too large for blocks

    def apply(self, gap: np.ndarray, on: np.ndarray) -> np.ndarray:
        """The pressure ``Ã^-1 gap`` on the loaded cells ``on`` (both ``(ny, nx)``), 0 elsewhere."""
        if self.circulant is not None:
            return self.circulant.apply(gap)
        on = on.ravel()
        new = None if self._on is None else on & ~self._on
        if new is None or np.count_nonzero(new) > REBUILD_FRACTION * self.cells.size:
            if not self._build(on):
                self.circulant = self.blocks.body.grid_operator(self.grid).preconditioner()
                return self.circulant.apply(gap)
            new = None
        out = np.zeros(self.grid.size)
        if new is not None:  # cells that entered since the build: the kernel's diagonal
            out[new] = gap.ravel()[new] / self.table[self.centre]
        if not self.cells.size:
            return out.reshape(self.grid.shape)
        r = np.append(gap.ravel()[self.cells], 0.0)  # (the padding's slot, last)
        y = np.empty_like(r)
        for inv, pos in self.classes:
            y[pos] = np.matmul(inv, r[pos][:, :, None])[:, :, 0]
        y = y[:-1]
        y -= self.v * (self.coupling @ np.add.reduceat(y, self.starts))[self.stone]
        out[self.cells] = y
        return out.reshape(self.grid.shape)

    def _build(self, on: np.ndarray) -> bool:
        """The blocks of the stones' loaded cells (kept ones found by their offsets), and
        the coupling ``(I + K W)^-1 K``; False when a contact or the stones are too many
        cells for it (:data:`MAX_BLOCK_CELLS`, :data:`MAX_STONES`)."""
        idx = np.flatnonzero(on)
        stone = self.owner[idx]
        order = np.argsort(stone, kind="stable")
        _, starts, counts = np.unique(stone[order], return_index=True, return_counts=True)
        if len(counts) > MAX_STONES or counts.max(initial=0) > MAX_BLOCK_CELLS:
            return False
        if 8 * np.sum(_size_class(counts).astype(float) ** 2) > MAX_BLOCK_BYTES:
            return False
        self._on, self.cells, self.starts = on.copy(), idx[order], starts
        rows, cols = np.divmod(self.cells, self.grid.nx)
        ends = self.starts + counts
        inverses, sums = [], []
        for a, b in zip(self.starts.tolist(), ends.tolist()):
            inv, s = self.blocks.inverse(rows[a:b], cols[a:b], self.table, self.centre)
            inverses.append(inv)
            sums.append(s)
        self.classes = _stacked(inverses, self.starts, counts)
        self.v = np.concatenate(sums) if sums else np.zeros(0)
        self.stone = np.repeat(np.arange(len(counts)), counts)
        w = np.add.reduceat(self.v, self.starts) if len(counts) else np.zeros(0)
        h = self.grid.h
        centroids = np.column_stack(
            [
                self.grid.x0 + h * np.add.reduceat(cols, self.starts) / counts,
                self.grid.y0 + h * np.add.reduceat(rows, self.starts) / counts,
            ]
        )
        k = self.blocks.body.provider.point_compliance(centroids, centroids) * h**2
        k[~np.isfinite(k)] = 0.0
        np.fill_diagonal(k, 0.0)
        self.coupling = np.linalg.solve(np.eye(len(w)) + k * w[None, :], k)
        return True


def _size_class(counts):
    """The padded size (:data:`SIZE_CLASSES`) of blocks of ``counts`` cells."""
    return SIZE_CLASSES[np.searchsorted(SIZE_CLASSES, counts)]


def _stacked(inverses: list, starts: np.ndarray, counts: np.ndarray) -> list:
    """The stones' padded inverses (:meth:`StoneBlocks.inverse`) stacked by size class, each
    ``(k, c, c)`` with the ``(k, c)`` places of its cells in the contact's cell order (the
    padding at place ``sum(counts)``, a slot holding 0)."""
    size = np.array([len(inv) for inv in inverses], dtype=np.int64)
    total = int(counts.sum())
    out = []
    for c in np.unique(size).tolist():
        members = np.flatnonzero(size == c)
        stack = np.stack([inverses[m] for m in members.tolist()])
        j = np.arange(c)
        pos = np.where(j[None, :] < counts[members][:, None], starts[members][:, None] + j[None, :], total)
        out.append((stack, pos))
    return out
