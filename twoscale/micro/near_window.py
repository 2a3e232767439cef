"""Near pairs' products gathered from one window of the kernel, where no dense block is kept.

On a translation-invariant body (the half-space) the displacement on patch ``k`` from the
pressure on patch ``l`` is ``sum_b K(y_a - y_b, x_a - x_b) p_b``: every entry is the cell
kernel at a lattice offset. One window of the kernel over the offsets ``|dy|, |dx| <= D``
serves every pair whose cells are within ``D`` of each other, and a product is one gather of
the entries of the loaded columns (the cells where ``p_l`` is not zero) and one matrix-vector
product, made and dropped at each call. Where the coupling's budget for kept dense blocks is
spent (9,204 small patches: about 1.5 near pairs a block past it), the pairs past it took an
FFT operator per pair and per product, made again at every product once the operators'
budget was spent too (a third of the two-level iteration's CPU); the gather needs no
memory that stays but the window (at most :data:`WINDOW_MAX_ENTRIES` entries, 8 MB).
The numbers are the provider's own ``grid_entries`` at those offsets (those of the pair's
dense block), so the products agree with the FFT operator's to rounding.
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from .pair_entries import WINDOW_MAX_ENTRIES

#: Largest block (entries) gathered for one product; a larger pair keeps its other route
#: (its transient gather: 16 bytes an entry, 4 MB at this size).
GATHER_MAX_ENTRIES = 250_000
#: A pair past the dense blocks' size is gathered instead of its FFT route up to this many
#: entries (the route's per-pair cost; 7,339 clustered spheres: ~8,000 a pair): larger
#: patches keep the route (a few blocks of ~1,000 cells: gathers of 10^5 doubled the sums).
FIRST_GATHER_ENTRIES = 16_384


class NearWindow:
    """The kernel at the lattice offsets within a reach ``D`` of one cell, grown (up to
    :data:`WINDOW_MAX_ENTRIES` entries) when a pair reaches farther, and per patch its cells'
    flat indices on the window's lattice. Only for a translation-invariant provider with
    ``grid_entries`` (:meth:`usable`)."""

    def __init__(self, provider):
        self.provider = provider
        self.reach = -1
        self._window: np.ndarray | None = None
        self._origin: Grid | None = None
        # per patch index: [patch, its corner (i, j) on the lattice, its owned cells, the
        # window's width, its cells' and its owned cells' flat indices on the window's lattice]
        self._cells: dict = {}
        #: The pairs ``(k, l)`` its coupling took it for, until a patch changes (:meth:`forget`).
        self.pairs: set = set()
        self._reaches: dict = {}  # per pair (k, l) taken by :meth:`total`, its reach
        self._sources: dict = {}  # per block: its last vector's loaded cells (:meth:`_loaded`)

    @staticmethod
    def usable(provider) -> bool:
        """The provider's kernel depends on the lattice offset alone and it gathers entries."""
        return bool(getattr(provider, "translation_invariant", False)) and hasattr(provider, "grid_entries")

    @property
    def nbytes(self) -> int:
        return 0 if self._window is None else int(self._window.nbytes)

    def forget(self, k: int) -> None:
        """Patch ``k`` was replaced: its indices go (the old patch is not kept alive), and
        the pairs taken (made again at their next product)."""
        self._cells.pop(k, None)
        self._sources.pop(k, None)
        self.pairs.clear()
        self._reaches.clear()

    def _grow(self, reach: int) -> bool:
        """Make the window cover ``reach``; False when it would pass its largest size."""
        if reach <= self.reach:
            return True
        largest = (int(np.sqrt(WINDOW_MAX_ENTRIES)) - 1) // 2
        if reach > largest:  # the pair itself reaches past the largest window
            return False
        reach = min(max(reach, int(1.25 * self.reach)), largest)  # a few larger windows at most
        o, w = self._origin, 2 * reach + 1
        assert o is not None
        around = Grid(o.x0 - reach * o.h, o.y0 - reach * o.h, o.h, w, w)
        centre = Grid(o.x0, o.y0, o.h, 1, 1)
        self._window = self.provider.grid_entries(around, centre, np.arange(w * w), np.zeros(1, np.int64)).ravel()
        self.reach = reach
        return True

    def _entry(self, k: int, patch) -> list:
        hit = self._cells.get(k)
        if hit is None or hit[0] is not patch:
            if self._origin is None:
                self._origin = patch.grid
            corner = patch.grid.offset_in(self._origin)
            hit = self._cells[k] = [patch, corner, int(patch.owned.sum()), 0, None, None]
        return hit

    def _flat(self, entry: list) -> list:
        """The entry with its flat indices on the current window's lattice."""
        w = 2 * self.reach + 1
        if entry[3] != w:
            patch, (i0, j0) = entry[0], entry[1]
            j, i = np.divmod(np.arange(patch.grid.size), patch.grid.nx)
            flat = (j + j0) * w + (i + i0)
            entry[3:] = [w, flat, flat[patch.owned.ravel()]]
        return entry

    def product(self, k: int, pk, l: int, pl, v: np.ndarray, *, whole: bool = False) -> np.ndarray | None:
        """``A_kl v`` for a vector (n_l,) or (n_l, m) on patch ``pl``'s (index ``l``) owned
        cells: on ``pk``'s owned cells, or (``whole``, 1-D ``v``) on its whole grid (ny, nx);
        None when the pair is off one lattice, reaches past the largest window or its
        gather would pass :data:`GATHER_MAX_ENTRIES` (the caller's other route then)."""
        try:
            ek, el = self._entry(k, pk), self._entry(l, pl)
        except ValueError:  # off the window's lattice or another cell size
            return None
        reach = _reach(ek[1], el[1], pk.grid, pl.grid)
        loaded = (v if v.ndim == 1 else v.any(axis=1)).nonzero()[0]
        rows = pk.grid.size if whole else ek[2]
        if rows * len(loaded) > GATHER_MAX_ENTRIES or not self._grow(reach):
            return None
        target = self._flat(ek)[4 if whole else 5] + self.reach * (2 * self.reach + 2)
        cols = self._flat(el)[5][loaded]
        out = np.take(self._window, target[:, None] - cols[None, :]) @ v[loaded]
        return out.reshape(pk.grid.shape) if whole else out

    def total(self, k: int, pk, sources: list) -> np.ndarray | None:
        """``sum_l A_kl v_l`` on ``pk``'s owned cells for ``sources`` ``[(l, pl, v_l)]`` (1-D
        vectors) by one gather of all their loaded columns (the window grown to the pairs'
        reach); None when a pair reaches past the largest window or the gather would pass
        :data:`GATHER_MAX_ENTRIES`."""
        ek = self._entry(k, pk)
        for l, pl, _ in sources:
            reach = self._reaches.get((k, l))
            if reach is None:
                reach = self._reaches[(k, l)] = _reach(ek[1], self._entry(l, pl)[1], pk.grid, pl.grid)
            if not self._grow(reach):
                return None
        loaded = [self._loaded(l, pl, v) for l, pl, v in sources]
        col = np.concatenate([c for c, _ in loaded])
        if ek[2] * len(col) > GATHER_MAX_ENTRIES:
            return None
        target = self._flat(ek)[5] + self.reach * (2 * self.reach + 2)
        return np.take(self._window, target[:, None] - col[None, :]) @ np.concatenate([x for _, x in loaded])

    def _loaded(self, l: int, pl, v: np.ndarray) -> tuple:
        """Block ``l``'s loaded cells on the window's lattice and their values, kept while
        its vector is the same object (the sweeps replace a changed one) and the window
        the same size: a block is the source of a few targets a sweep."""
        hit = self._sources.get(l)
        w = 2 * self.reach + 1
        if hit is None or hit[0] is not v or hit[1] != w:
            loaded = v.nonzero()[0]
            hit = self._sources[l] = (v, w, self._flat(self._entry(l, pl))[5][loaded], v[loaded])
        return hit[2], hit[3]


def _reach(corner_k: tuple, corner_l: tuple, gk: Grid, gl: Grid) -> int:
    """The largest ``|dy|`` or ``|dx|`` between a cell of grid ``gk`` and one of ``gl``
    (corners: their first cells on the window's lattice)."""
    (ik, jk), (il, jl) = corner_k, corner_l
    return max(abs(ik - il - gl.nx + 1), abs(ik + gk.nx - 1 - il), abs(jk - jl - gl.ny + 1), abs(jk + gk.ny - 1 - jl))
