"""Dense blocks ``A_kl`` of many near pairs at once on a translation-invariant body.

Where the cell kernel depends only on the lattice offset between two cells (the half-space),
every entry of every near pair's block is the kernel at one offset ``(dy, dx)``: one window
of the kernel over the offsets ``|dy|, |dx| <= D`` that the pairs reach serves them all, and
a pair's block is one gather from it (the outer difference of its cells' flat indices in
the window). The provider's own ``grid_entries`` makes a window per pair (939 patches,
1,182 pairs: 0.15-0.2 ms a pair, most of it the window's bookkeeping); the numbers are the
same, gathered from the same kernel values.

:func:`near_correction`: where a kernel's smooth correction is split off (the finite
block), the near pairs' correction on a target from its sources' coefficients.
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid

#: Largest window of offsets (entries, 8 MB) made for one call; pairs that reach farther
#: are left to the caller's one-pair route.
WINDOW_MAX_ENTRIES = 1_000_000


def _lattice(grid: Grid, corner: tuple, owned: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lattice rows and columns of the owned cells, the grid's first cell at ``corner`` (i, j)."""
    j, i = np.divmod(np.flatnonzero(owned.ravel()), grid.nx)
    return j + corner[1], i + corner[0]


def affordable_pairs(patches, pairs, kept: dict, max_entries: int, fits, grid_block_max: int) -> list:
    """The ``pairs`` ``(k, l)`` whose dense blocks a coupling would make one by one, in
    order until the budget is spent (``fits(bytes)``: the planned blocks' bytes within it):
    neither it nor its reverse ``kept``, at most ``max_entries`` owned-cell entries, and
    grids small enough to cut the block from (``grid_block_max`` entries, or four times
    the owned cells' block; else the coupling makes the owned cells' own block)."""
    owned = [int(pt.owned.sum()) for pt in patches]
    todo, planned = [], 0.0
    for k, l in pairs:
        nk, nl = owned[k], owned[l]
        size = 8.0 * nk * nl
        if (k, l) in kept or (l, k) in kept or nk * nl > max_entries:
            continue
        if not fits(planned + size):
            break
        if patches[k].grid.size * patches[l].grid.size <= max(4 * nk * nl, grid_block_max):
            todo.append((k, l))
            planned += size
    return todo


def pair_blocks(provider, patches, pairs: list) -> dict:
    """``{(k, l): A_kl}`` on the owned cells of ``patches[k]`` (rows) and ``patches[l]``
    (columns) for the ``pairs`` whose offsets fit one window of at most
    :data:`WINDOW_MAX_ENTRIES` entries, each equal to
    ``provider.grid_entries(grid_k, grid_l, owned_k, owned_l)``; the provider must be
    translation-invariant and have ``grid_entries``. Pairs left out are not in the dict."""
    if not pairs:
        return {}
    origin = patches[pairs[0][0]].grid
    k_, l_ = (np.array(c, dtype=np.int64) for c in zip(*pairs))
    # per patch: its first cell's lattice column and row (from the origin's), nx, ny
    geo = np.zeros((len(patches), 4), dtype=np.int64)
    for k in np.union1d(k_, l_).tolist():
        g = patches[k].grid
        geo[k] = (*g.offset_in(origin), g.nx, g.ny)
    (ik, jk, nxk, nyk), (il, jl, nxl, nyl) = geo[k_].T, geo[l_].T
    # each pair's reach: the largest |dy| or |dx| between a cell of k and one of l
    reach = np.abs([ik - (il + nxl - 1), ik + nxk - 1 - il, jk - (jl + nyl - 1), jk + nyk - 1 - jl]).max(axis=0)
    limit = (int(np.sqrt(WINDOW_MAX_ENTRIES)) - 1) // 2
    todo = [pair for pair, r in zip(pairs, reach.tolist()) if r <= limit]
    if not todo:
        return {}
    D = int(reach[reach <= limit].max())
    w = 2 * D + 1
    # the kernel at the offsets (dy, dx), |dy|, |dx| <= D: target cells of a (w x w) grid
    # centred on one source cell, row-major (the provider's numbers for that pair of grids)
    centre = Grid(origin.x0, origin.y0, origin.h, 1, 1)
    around = Grid(origin.x0 - D * origin.h, origin.y0 - D * origin.h, origin.h, w, w)
    window = provider.grid_entries(around, centre, np.arange(w * w), np.zeros(1, np.int64)).ravel()
    cells: dict = {}

    def flat(k: int) -> np.ndarray:
        # the cell's flat index in the window's lattice (the window's first cell at -D, -D)
        hit = cells.get(k)
        if hit is None:
            j, i = _lattice(patches[k].grid, geo[k, :2], patches[k].owned)
            hit = cells[k] = j * w + i
        return hit

    out = {}
    for k, l in todo:
        # entry (a, b) is the kernel at offset (y_a - y_b, x_a - x_b): window index
        # (y_a - y_b + D) w + (x_a - x_b + D)
        out[(k, l)] = np.take(window, (flat(k) + D * (w + 1))[:, None] - flat(l)[None, :])
    return out


#: Largest window a block keeps of its own box's offsets (entries, 32 KB; the size of the
#: active columns it keeps, :data:`~.localblock.COLUMNS_MAX_ENTRIES`).
BOX_WINDOW_MAX_ENTRIES = 4096


class BoxWindow:
    """The kernel at every lattice offset within one grid (the box of a dense block), for
    the grid's own entries ``grid_matrix(box)[np.ix_(rows, cols)]`` by one gather: the same
    numbers as the provider's ``grid_entries`` for the pair ``(box, box)``, without its
    per-call window (a block's columns and factorisations on each new active set: 3,446
    calls on 939 blocks of 41-266 cells, ~60 us each). Only for a translation-invariant
    provider with ``grid_entries`` (:meth:`of`)."""

    #: The kernel is even: the box's entries are exactly symmetric.
    symmetric = True

    def __init__(self, provider, box: Grid):
        dx, dy = box.nx - 1, box.ny - 1
        wx = 2 * dx + 1
        around = Grid(box.x0 - dx * box.h, box.y0 - dy * box.h, box.h, wx, 2 * dy + 1)
        centre = Grid(box.x0, box.y0, box.h, 1, 1)
        self._window = provider.grid_entries(around, centre, np.arange(around.size), np.zeros(1, np.int64)).ravel()
        j, i = np.divmod(np.arange(box.size), box.nx)
        # a cell's flat index on the window's lattice, and the offset of offset (0, 0)
        self._flat = j * wx + i
        self._zero = dy * wx + dx

    @staticmethod
    def of(provider, box: Grid) -> "BoxWindow | None":
        """The window of ``box``, or None where it does not apply or would be large; a
        provider's own ``box_window`` where it has one (the finite block: not
        translation-invariant, its entries from factors kept per box)."""
        own = getattr(provider, "box_window", None)
        if own is not None:
            return own(box)
        if not (getattr(provider, "translation_invariant", False) and hasattr(provider, "grid_entries")):
            return None
        if (2 * box.nx - 1) * (2 * box.ny - 1) > BOX_WINDOW_MAX_ENTRIES:
            return None
        return BoxWindow(provider, box)

    def entries(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """``grid_matrix(box)[np.ix_(rows, cols)]`` for flat cell indices of the box."""
        return np.take(self._window, (self._flat[rows] + self._zero)[:, None] - self._flat[cols][None, :])


def near_correction(coupling, grid, smooth: list, values: list) -> np.ndarray:
    """The split-off correction of ``coupling``'s kernel on ``grid`` from the blocks
    ``smooth`` (their vectors ``values[l]``), their coefficients kept per vector: compact and
    summed pair by pair where the correction has a ``near_sum`` (the block's), else the
    contract's vectors over every node, summed and evaluated once."""
    corr = coupling._correction
    near = getattr(corr, "near_sum", None)
    make = corr.coefficients if near is None else corr.compact

    def coefficient(l: int):
        pt, v = coupling.patches[l], values[l]

        def compute():
            p = np.zeros(pt.grid.shape)
            p[pt.owned] = v
            return make(pt.grid, p)

        return coupling._per_vector(coupling._coefficients, (l, near is None), v, compute)

    coeffs = [coefficient(l) for l in smooth]
    if near is not None:
        return near(grid, [(coupling.patches[l].grid, c) for l, c in zip(smooth, coeffs)])
    c = np.zeros(max(len(p) for p in coeffs))
    for p in coeffs:
        c[: len(p)] += p
    return corr.evaluate(grid, c)
