"""The cells a Polonsky-Keer step clips or lets enter beyond its move ``-tau t``
(:class:`CellChange`, :func:`clip_and_enter`), and the displacement ``u = A p`` after a step
(:func:`update_displacement`): from the search direction's product, plus the change of those
cells by the kernel's columns or by the fast product (:func:`fast_changes`), or from scratch."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .products import COLUMN_CELLS, FAST_CHANGE_ROUNDING, Halves
from .projection import column

#: Recompute ``u = A p`` from scratch at least this often (the cheap update
#: ``u <- s (u - tau A t)`` accumulates rounding).
REFRESH_EVERY = 25


@dataclass
class CellChange:
    """The pressure change of one step beyond ``-tau t`` on each row: the clipped cells
    (back from their negative value to 0) and the cells that entered (from 0 to
    ``-tau g``), as flat (row, cell, value) triples."""

    rows: list
    cells: list
    values: list

    @classmethod
    def empty(cls) -> "CellChange":
        return cls([], [], [])

    def add(self, rows: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
        self.rows.append(rows)
        self.cells.append(cells)
        self.values.append(values)

    def per_row(self, n_rows: int) -> np.ndarray:
        """Changed cells per row (a cell clipped and entered in one step counts twice)."""
        if not self.rows:
            return np.zeros(n_rows, int)
        return np.bincount(np.concatenate(self.rows), minlength=n_rows)

    def stack(self, which: np.ndarray, n: int) -> np.ndarray:
        """The change of the rows ``which`` (bool) as a dense (count, n) stack (a cell
        clipped and entered in one step: its two values summed)."""
        out = np.zeros((int(np.count_nonzero(which)), n))
        if self.rows:
            rows, cells, values = (np.concatenate(a) for a in (self.rows, self.cells, self.values))
            at = np.cumsum(which) - 1  # each kept row's place in the stack
            keep = which[rows]
            np.add.at(out, (at[rows[keep]], cells[keep]), values[keep])
        return out

    def apply(self, u: np.ndarray, which: np.ndarray, factor, columns) -> None:
        """Add ``A dp`` (by ``columns``) to the rows of ``u`` in ``which`` (bool), each
        scaled by its restoring ``factor`` (per row, or a scalar)."""
        rows, cells, values = (np.concatenate(a) for a in (self.rows, self.cells, self.values))
        f = np.broadcast_to(np.asarray(factor, dtype=float), (len(u),))
        for row in np.flatnonzero(which):
            at = rows == row
            columns(u[row], cells[at], values[at] * f[row])


def clip_and_enter(p: np.ndarray, g: np.ndarray, tau: np.ndarray, mask, record: bool):
    """Polonsky & Keer's projection after ``p <- p - tau t`` (in place): negative cells
    clipped to 0, unloaded cells of ``mask`` (None: all) whose gap ``g`` is negative
    entering with ``-tau g``. Returns the rows that clipped, the entering cells (bool) and,
    when ``record``, the :class:`CellChange` beyond ``-tau t`` (else None)."""
    clipped = p.min(axis=1) < 0.0
    change = CellChange.empty() if record else None
    if np.count_nonzero(clipped):  # (else no pass: the linear steps clip nothing)
        if change is not None:
            ri, ci = _nonzero(p < 0.0)
            change.add(ri, ci, -p[ri, ci])  # back from below 0 to 0
        np.maximum(p, 0.0, out=p)
    reenter = (g < 0.0) & (p == 0.0)
    if mask is not None:
        reenter &= mask
    if np.count_nonzero(reenter):
        ri, ci = _nonzero(reenter)
        p[ri, ci] -= tau[ri] * g[ri, ci]
        if change is not None:
            change.add(ri, ci, p[ri, ci])
    return clipped, reenter, change


def _nonzero(on: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.nonzero`` of a (B, n) bool array, the same (row, cell) pairs in the same order, by
    the flat indices (``np.nonzero`` on two axes: 1.3 ms on a row of 190,000 cells with 30
    true, the flat indices 0.1 ms)."""
    return np.divmod(np.flatnonzero(on), on.shape[1])


def fast_changes(it, n2: np.ndarray) -> np.ndarray | None:
    """The rows of the iteration ``it`` (:class:`~.iteration.Iteration`) whose displacement after a step that clipped or let in cells may take the
    ``fast`` product of that change (:attr:`~.products.Products.fast_changes`): those
    whose travel since their last exact product, times
    :data:`~.products.FAST_CHANGE_ROUNDING`, is within the change rule's tolerance of
    the pressure (``n2``: its squared norm per row); None where the products have no such rule."""
    if not (it.ops.fast_changes and it.ops.fast is not None):
        return None
    return FAST_CHANGE_ROUNDING * it.travel <= it.tol.change * np.sqrt(n2)


def update_displacement(it, r, tau_c, factor, changed, change: CellChange | None = None, fast_ok=None) -> None:
    """The iteration ``it``'s ``u = A p`` after a step: from ``A t`` where ``p`` changed by ``-tau t`` and a
    constant factor only, plus the kernel's columns where at most
    :data:`~.products.COLUMN_CELLS` cells were clipped or entered (``change``), or the
    fast product of that change on the rows ``fast_ok`` (:func:`fast_changes`), from
    scratch elsewhere (by the fast product while the row is on it) and every
    :data:`REFRESH_EVERY` steps."""
    summed = added = None
    if change is not None and factor is not None and np.count_nonzero(changed):
        if it.ops.columns is not None:
            summed = changed & (change.per_row(len(changed)) <= COLUMN_CELLS) & (it.stale < REFRESH_EVERY)
            changed = changed & ~summed
        if fast_ok is not None:
            added = changed & fast_ok & (it.stale < REFRESH_EVERY)  # ``fast``'s product of the change
            changed = changed & ~added
    redo = changed | (it.stale >= REFRESH_EVERY) | (False if it.cheap is None else it.cheap.due(it))
    count = np.count_nonzero(redo)
    if factor is None or count == len(redo):
        # every row from scratch: fast only if all still are (``redo`` may be empty)
        it.refresh(np.ones(len(changed), bool), bool(it.fast.all()))
        return
    fast = bool(it.fast[redo].all())
    r = r.finish() if isinstance(r, Halves) else r
    r *= tau_c
    it.u -= r
    if it.k:
        it.u *= column(factor)
    if summed is not None and np.count_nonzero(summed):
        change.apply(it.u, summed, factor, it.ops.columns)
    if added is not None and np.count_nonzero(added):
        _add_change(it, change, added, factor)
    it.stale += 1
    if count:
        it.refresh(redo, fast)


def _add_change(it, change: CellChange, rows: np.ndarray, factor) -> None:
    """``u += factor A dp`` on ``rows`` (bool) by the ``fast`` product, ``dp`` the cells'
    change beyond ``-tau t`` (:class:`CellChange`); the rows stay stale."""
    dp = change.stack(rows, it.u.shape[1])
    f = np.broadcast_to(np.asarray(factor, dtype=float), (len(rows),))[rows]
    dp *= column(f)
    it.u[rows] += it.product(dp, fast=True)
    it.products += len(dp)
