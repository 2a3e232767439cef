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

one small dense product per stone (the blocks padded to a few sizes and applied by one
batched product per size) and an ``m x m`` product per application. Replayed positions of
the tyre: 8 CG iterations to the KKT residual 1e-8 against 16 with the circulant inverse
(13 with the blocks alone, no coupling). The blocks' inverses depend on the loaded cells'
offsets only (a translation-invariant body). Each stone's is kept between the iterations
and the positions of a run, known by the stone's number on the road and its cells'
places on the road (a stone's contact changes by a few cells a position): the same cells
reuse it, a large stone's few cells gained or lost update it (:func:`~.inverses.updated`), another
stone's block of the same offsets is reused, and what a position did not use is dropped.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from ..indenters import Surface
from ..influence.cached import CachedBody
from .inverses import UPDATE_MIN_CELLS, fresh_blocks, size_class, stacked, updated

#: The blocks are rebuilt when the cells that entered the contact since they were built
#: are more than this fraction of the cells they cover (fewer: each its diagonal alone;
#: the cells that left are left out of the blocks' inverses, which stays symmetric and
#: positive).
REBUILD_FRACTION = 0.2
#: Largest stone contact (cells) inverted as one dense block, and most stones coupled: a
#: contact with more (a sphere's, a flat face's) or more stones take the circulant inverse
#: instead, until it settles smaller (:data:`RETRY_SETTLED`; a block costs its cells
#: squared in memory and cubed in time; on the tyre's footprint the largest contact is ~250
#: cells, the stones ~250).
MAX_BLOCK_CELLS = 600
MAX_STONES = 1500
#: A solve on the circulant inverse (its contact too large for blocks) tries the blocks again
#: once its loaded cells have settled (fewer by less than :data:`RETRY_SETTLED` since the
#: last application) below :data:`RETRY_SHRINK` of those of the last attempt. A run's first
#: position starts from the geometric interference (the tyre's: 91,000 loaded cells, stones
#: of more than 600) and settles at 13,000: its blocks then, built once on nearly its answer's
#: contact, took it from 27 to 22 CG iterations for ~60 ms, and are the second position's
#: (its linearised step built 68 blocks afresh instead of 237).
RETRY_SETTLED = 0.05
RETRY_SHRINK = 0.9
#: Blocks built on such a contact still settling are built once more when it has settled:
#: its loaded cells changed by at most this fraction since the last application, and some
#: differ from the build's (the tyre's first position: built at 13,074 cells, settled at
#: 13,083 with ~110 cells gained or lost over ~70 stones, which the second position's
#: linearised step then inverted afresh).
SETTLED_AGAIN = 0.001
#: A stone's kept inverse is updated (:func:`~.inverses.updated`, when its cells changed by
#: few: :data:`~.inverses.UPDATE_CELLS`) at most :data:`MAX_UPDATES` times in a row (then
#: afresh: rounding does not pile up).
MAX_UPDATES = 20
#: Most memory the stacked inverses of one contact may take (bytes; the tyre's: ~8 MB).
MAX_BLOCK_BYTES = 400e6


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
        self._kept: dict = {}  # stone -> (its cells' keys, sorted; padded inverse; row sums; updates)
        self._patterns: dict = {}  # cells' offsets -> (padded inverse, row sums)
        self._used: set = set()
        self._used_patterns: set = set()
        self._tables: dict = {}  # grid shape -> the kernel's padded table
        self.built = 0  # inverses computed afresh
        self.updated = 0  # inverses updated from a kept one (cells gained or lost)

    def __call__(self, surface: Surface, stones: np.ndarray | None = None, shift_cells: int = 0) -> "BlockInverse":
        """The preconditioner of a solve on ``surface`` (its grid and the cells' stones);
        the inverses the last solve did not use are dropped. A stone is known across
        solves by ``stones[owner]`` (the road's numbers; the owner itself without them) and
        its cells by their place on the road, ``shift_cells`` columns behind the body's."""
        self._kept = {k: v for k, v in self._kept.items() if k in self._used}
        self._patterns = {k: v for k, v in self._patterns.items() if k in self._used_patterns}
        self._used, self._used_patterns = set(), set()
        return BlockInverse(self, surface, stones, shift_cells)

    def at(self, stones: np.ndarray, shift: float, h: float):
        """The preconditioner factory of a position (``solve_cg(preconditioner=...)``): its
        stones' road numbers and the road's shift (mm) on cells of ``h`` mm; a shift that
        is not a whole number of cells forgets the kept inverses (the cells moved off the
        lattice)."""
        cells = round(shift / h)
        if abs(shift / h - cells) > 1e-6:
            self._kept.clear()  # (the patterns stay: offsets do not move)
        return lambda surface: self(surface, stones, cells)

    def table(self, grid) -> np.ndarray:
        """The kernel's offset table on ``grid`` (entry ``(ny - 1, nx - 1)`` the offset 0), kept by
        the grid's shape (a translation-invariant body): the operator's own
        (:meth:`~twoscale.influence.convolution.ConvolutionOperator.offset_table`, which its
        kernel columns use too: one inverse transform for both)."""
        if grid.shape not in self._tables:
            self._tables = {grid.shape: self.body.grid_operator(grid).op.offset_table()}
        return self._tables[grid.shape]

    def inverses(self, idents: list, keys: np.ndarray, flat: np.ndarray, bounds: list, table: np.ndarray, centre: int):
        """The inverse of the operator on each stone's cells (stone ``idents[i]``, its cells
        ``keys[a:b]``: their places on the road, sorted, and ``flat[a:b]``: their places in
        ``table``'s rows, ``table.ravel()[centre + flat_i - flat_j]`` the operator's entry, for
        ``(a, b) = bounds[i]``), full and zero-padded to its size class (:data:`~.inverses.SIZE_CLASSES`),
        and its row sums: the stone's kept one when its cells are the same, another's of the
        same cell offsets, the stone's updated when its cells changed by a few
        (:func:`~.inverses.updated`), else computed afresh, those together
        (:func:`~.inverses.fresh_blocks`)."""
        entries = table.ravel()
        out: list = [None] * len(idents)
        fresh: dict = {}  # pattern -> the stones (their places in ``out``) to invert afresh
        for i, (stone, (a, b)) in enumerate(zip(idents, bounds)):
            found, pattern = self._known(stone, keys[a:b], flat[a:b], entries, centre, fresh)
            if found is None:
                fresh.setdefault(pattern, []).append(i)
            out[i] = found
        made = fresh_blocks(entries, centre, [flat[slice(*bounds[i[0]])] for i in fresh.values()])
        for (pattern, places), inverse in zip(fresh.items(), made):
            self._patterns[pattern] = inverse
            for i in places:
                a, b = bounds[i]
                self._kept[idents[i]] = (keys[a:b], *inverse, 0)
                out[i] = inverse
            self.built += 1
        return out

    def _known(self, stone: int, keys: np.ndarray, flat: np.ndarray, entries: np.ndarray, centre: int, fresh: dict):
        """One stone's inverse as :meth:`inverses` finds it without computing it afresh, and
        its cells' offsets (the pattern); None for the inverse when it must be (or when a
        stone before it of the same offsets will be: ``fresh``)."""
        self._used.add(stone)
        found = self._kept.get(stone)
        # (the same int64 keys: their bytes compared, ~10x cheaper than np.array_equal)
        if found is not None and found[0].size == keys.size and found[0].tobytes() == keys.tobytes():
            return (found[1], found[2]), None
        pattern = (keys - keys[0]).tobytes()  # the cells' offsets: the same block elsewhere
        self._used_patterns.add(pattern)
        same = self._patterns.get(pattern)
        if same is not None:
            self._kept[stone] = (keys, *same, 0)
            return same, pattern
        if (
            pattern in fresh
            or found is None
            or found[3] >= MAX_UPDATES
            or min(found[0].size, keys.size) < UPDATE_MIN_CELLS
        ):
            return None, pattern
        update = updated(found[0], found[1], keys, flat, entries, centre)
        if update is None:
            return None, pattern
        self._kept[stone] = (keys, *update, found[3] + 1)
        self._patterns[pattern] = update
        self.updated += 1
        return update, pattern


class BlockInverse:
    """``Ã^-1`` (module docstring) on the loaded cells of one solve, rebuilt when they
    change; :meth:`apply` is the kernel's preconditioner (``solve_cg(preconditioner=...)``)."""

    def __init__(self, blocks: StoneBlocks, surface: Surface, stones: np.ndarray | None, shift_cells: int):
        self.blocks, self.grid = blocks, surface.grid
        self.owner = surface.owner.ravel()
        self.stones, self.shift_cells = stones, shift_cells
        self.table = blocks.table(surface.grid)
        self.centre = (self.grid.ny - 1, self.grid.nx - 1)  # the table's entry of offset 0
        self._on: np.ndarray | None = None  # the loaded cells at the build (rows of ``_part``)
        self._part: np.ndarray | None = None  # the cells the rows are of (None: the grid)
        self.circulant = None  # the operator's inverse, while the contact is too large for blocks
        self._last = self._failed = 0  # loaded cells at the last application, at the last failed build
        self._settling = False  # built on a contact still settling (:data:`SETTLED_AGAIN`)

    def apply(self, gap: np.ndarray, on: np.ndarray) -> np.ndarray:
        """The pressure ``Ã^-1 gap`` on the loaded cells ``on`` (both ``(ny, nx)``), 0 elsewhere."""
        return self._apply(gap.ravel(), on.ravel(), None).reshape(self.grid.shape)

    def on_part(self, cells: np.ndarray) -> Callable:
        """:meth:`apply` on the grid's flat ``cells`` (increasing) only: ``(gap, on)`` and the
        answer are rows of those cells (the CG's part, :mod:`twoscale.pk.compact`: no
        grid-sized pass an application; the loaded cells must lie among ``cells``)."""
        return lambda gap, on: self._apply(gap, on, cells)

    def _apply(self, gap: np.ndarray, on: np.ndarray, part: np.ndarray | None) -> np.ndarray:
        """:meth:`apply` on flat rows of the grid (``part`` None) or of its cells ``part``."""
        count, last = np.count_nonzero(on), self._last
        self._last = count
        if self.circulant is not None:
            if count < (1.0 - RETRY_SETTLED) * last or count > RETRY_SHRINK * self._failed:
                return self._circulant(gap, part)
            self.circulant, self._on = None, None  # settled smaller (:data:`RETRY_SETTLED`): blocks again
            self._settling = True
        new = None if self._on is None or self._part is not part else on & ~self._on
        if new is not None and self._settling and abs(count - last) <= SETTLED_AGAIN * count:
            self._settling = False  # settled: once more on its cells if they moved
            new = None if np.count_nonzero(new) or np.count_nonzero(self._on) != count else new
        if new is None or np.count_nonzero(new) > REBUILD_FRACTION * self.cells.size:
            idx = np.flatnonzero(on)
            if not self._build(idx if part is None else part[idx]):
                self._failed = count
                self.circulant = self.blocks.body.grid_operator(self.grid).preconditioner()
                return self._circulant(gap, part)
            self._on, self._part = on.copy(), part
            self._at = self.cells if part is None else np.searchsorted(part, self.cells)
            new = None
        out = np.zeros(gap.size)
        if new is not None:  # cells that entered since the build: the kernel's diagonal
            out[new] = gap[new] / self.table[self.centre]
        if not self.cells.size:
            return out
        # in float32 (the stacked inverses' precision): the products read the ~10 MB of the
        # tyre's inverses at every application, half of it so
        r = np.append(gap[self._at], 0.0).astype(np.float32)  # (the padding's slot, last)
        y32 = np.empty_like(r)
        for inv, pos in self.classes:
            y32[pos] = np.matmul(inv, r[pos][:, :, None])[:, :, 0]
        y = y32[:-1].astype(np.float64)
        y -= self.v * lu_solve(self.coupling, self.k @ np.add.reduceat(y, self.starts), check_finite=False)[self.stone]
        out[self._at] = y
        return out

    def _circulant(self, gap: np.ndarray, part: np.ndarray | None) -> np.ndarray:
        """The circulant inverse's answer on the flat rows ``gap`` (of the cells ``part``)."""
        if part is None:
            return self.circulant.apply(gap.reshape(self.grid.shape)).ravel()
        full = np.zeros(self.grid.size)
        full[part] = gap
        return self.circulant.apply(full.reshape(self.grid.shape)).ravel()[part]

    def _road_keys(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """The cells' places on the road (the body's lattice moved back by the shift), one
        integer each, in the order of the cells' flat indices."""
        g = self.grid
        row0, col0 = round(g.y0 / g.h), round(g.x0 / g.h) - self.shift_cells
        return (rows + row0).astype(np.int64) * (1 << 32) + (cols + col0 + (1 << 31))

    def _build(self, idx: np.ndarray) -> bool:
        """The blocks of the stones' loaded cells ``idx`` (flat, increasing; kept or updated
        inverses found by their stones), and the coupling ``(I + K W)^-1 K``; False when a
        contact or the stones are too many cells for it (:data:`MAX_BLOCK_CELLS`,
        :data:`MAX_STONES`)."""
        stone = self.owner[idx]
        # (the stones' indices as 16-bit keys where they fit: numpy's stable sort is then a
        # radix sort, the same order; on the tyre's ~13,000 cells 0.08 against 1.3 ms)
        order = np.argsort(stone.astype(np.int16) if stone.size and stone.max() < 2**15 else stone, kind="stable")
        _, starts, counts = np.unique(stone[order], return_index=True, return_counts=True)
        if len(counts) > MAX_STONES or counts.max(initial=0) > MAX_BLOCK_CELLS:
            return False
        if 8 * np.sum(size_class(counts).astype(float) ** 2) > MAX_BLOCK_BYTES:
            return False
        self.cells, self.starts = idx[order], starts
        rows, cols = np.divmod(self.cells, self.grid.nx)
        ends = self.starts + counts
        width = self.table.shape[1]
        flat = rows * width + cols
        keys = self._road_keys(rows, cols)
        owners = self.owner[self.cells[self.starts]]
        idents = (owners if self.stones is None else self.stones[owners]).tolist()
        centre = self.centre[0] * width + self.centre[1]
        bounds = list(zip(self.starts.tolist(), ends.tolist()))
        inverses, sums = (
            zip(*self.blocks.inverses(idents, keys, flat, bounds, self.table, centre)) if idents else ((), ())
        )
        self.classes = stacked(inverses, self.starts, counts)
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
        k = _point_compliance(self.blocks.body.provider, centroids) * h**2
        k[~np.isfinite(k)] = 0.0
        np.fill_diagonal(k, 0.0)
        # (I + K W)^-1 K applied as a factor and a solve: the m x m product's inverse formed
        # once cost ~4x the factor (m right-hand sides), and it is applied ~10 times only
        self.k, self.coupling = k, lu_factor(np.eye(len(w)) + k * w[None, :], check_finite=False)
        return True


def _point_compliance(provider, points: np.ndarray) -> np.ndarray:
    """The compliance among ``points`` by the body itself: a solver's caching wrapper
    (:class:`~twoscale.influence.cached.CachedBody`) keeps the last set of points, which a
    position's stones' centroids never repeat (its look-up and copy cost ~1 of ~4 ms)."""
    body = provider.body if isinstance(provider, CachedBody) else provider
    return np.asarray(body.point_compliance(points, points), dtype=float)
