"""The Polonsky-Keer iteration on a part of a grid: the cells that can be in contact, held as
a flat index set (:class:`Part`).

The kernel's array passes (the gap, its projection, the residual, the step, the clipping
and entering cells: some forty a step) run over every cell of its rows, and on a grid where
most cells can carry pressure but few come near contact (a tyre's footprint on a road: 96 %
of the cut's cells have material, 7 % are loaded, 10 % lie within 0.1 mm of the road) they
are memory-bound passes over cells that stay off. On a part the kernel's rows are the part's
cells; each operator product scatters the pressure into the grid (the other cells 0) and
gathers the displacement back, the preconditioner likewise. The answer holds on the whole
grid only if no cell outside the part would touch: :meth:`Part.touching` checks that on
the answer's displacement (the caller solves the whole grid from the answer if one would).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .products import Products
from .result import PKResult


class Part:
    """A part ``cells`` (flat indices, increasing) of a grid of ``shape`` on which the kernel
    runs, with the wrappers of the grid's operator, preconditioner and columns.

    The products' scratch field is kept (a fresh grid-sized array each product page-faults):
    the wrapped callables must not keep their arguments.
    """

    def __init__(self, cells: np.ndarray, shape: tuple):
        self.cells, self.shape = np.asarray(cells, dtype=np.intp), tuple(shape)
        self.size = int(np.prod(self.shape))
        self._field: np.ndarray | None = None
        self._on: np.ndarray | None = None
        self.last: tuple | None = None  # the last exact product's (part's pressure, grid's displacement)

    def take(self, a: np.ndarray) -> np.ndarray:
        """The part's cells of (b, grid) rows ``a`` (flattened or in the grid's shape): (b, m)."""
        return np.take(a.reshape(len(a), -1), self.cells, axis=1)  # (4 times faster than [:, cells])

    def field(self, v: np.ndarray) -> np.ndarray:
        """(b, m) part rows in (b, *shape) grid rows, 0 off the part (a kept buffer)."""
        if self._field is None or len(self._field) != len(v):
            self._field = np.zeros((len(v), self.size))
        self._put(self._field, v)
        return self._field.reshape(len(v), *self.shape)

    def _put(self, rows: np.ndarray, v: np.ndarray) -> None:
        """``rows[:, cells] = v``, one row by indexing the row itself (``rows[0, cells]``
        took 1.5x as long on a tyre's part of 28,000 of 200,000 cells: 165 against 110 us)."""
        if len(v) == 1:
            rows[0][self.cells] = v[0]
        else:
            rows[:, self.cells] = v

    def expand(self, v: np.ndarray) -> np.ndarray:
        """(b, m) part rows as new (b, n) grid rows, 0 off the part."""
        out = np.zeros((len(v), self.size))
        out[:, self.cells] = v
        return out

    def product(self, apply: Callable, exact: bool = False) -> Callable:
        """``apply`` (on (b, *shape) grid rows) on the part's rows; ``exact``: keep the last
        product's grid displacement (:meth:`displacement`). Else ``apply``'s own
        ``on_part(cells)`` where it gives one (e.g. :class:`~.products.OneRow`: the part's
        values in and out, no grid-sized field)."""
        own = None if exact else getattr(apply, "on_part", None)
        direct = None if own is None else own(self.cells)
        if direct is not None:
            return direct

        def on_part(v: np.ndarray) -> np.ndarray:
            u = apply(self.field(v.reshape(len(v), -1)))
            if exact:
                self.last = (np.array(v), u)
            return self.take(u)

        return on_part

    def precondition(self, pc: Callable | None) -> Callable | None:
        """The preconditioner ``pc(v, on)`` (grid rows) on the part's rows: its own
        ``pc.on_part(cells)`` when it has one (rows of the part's cells in and out, no grid
        pass), else scattered to the grid and gathered back."""
        if pc is None:
            return None
        own = getattr(pc, "on_part", None)
        direct = None if own is None else own(self.cells)
        if direct is not None:
            return direct

        def on_part(v: np.ndarray, on: np.ndarray) -> np.ndarray:
            b = len(v)
            if self._on is None or len(self._on) != b:
                self._on = np.zeros((b, self.size), bool)
            self._put(self._on, on.reshape(b, -1))
            return self.take(pc(self.field(v.reshape(b, -1)), self._on.reshape(b, *self.shape)))

        return on_part

    def columns(self, columns: Callable | None) -> Callable | None:
        """The kernel's ``columns(out, cells, values)`` (one grid row) on one part row."""
        if columns is None:
            return None

        def on_part(out: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
            full = np.zeros(self.size)
            columns(full, self.cells[cells], values)
            out += full[self.cells]

        return on_part

    def sources(self, columns: Callable) -> Callable:
        """Columns on the part's cells as targets (``columns(out, grid cells, values)``) taking
        the part's cells as sources too."""

        def on_part(out: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
            columns(out, self.cells[cells], values)

        return on_part

    def displacement(self, p: np.ndarray, apply: Callable) -> np.ndarray:
        """The grid displacement (b, n) of the part's pressure ``p`` (b, m): the last exact
        product's when it was of ``p`` (a converged row stops on one), else ``apply``'s."""
        if self.last is not None and self.last[0].shape == p.shape and np.array_equal(self.last[0], p):
            return self.last[1].reshape(len(p), -1)
        return apply(self.field(p)).reshape(len(p), -1)

    def inputs(self, z, p, candidates, basis, products: Products, pc, columns: Callable | None = None):
        """The kernel's inputs on the grid (``z``, start, candidates, basis: flat rows or
        columns of it; the products and the preconditioner on grid rows) on the part;
        ``columns``: the operator's columns on the part's cells as targets, if it has them
        (else the grid's columns, summed on the grid)."""
        cells = self.cells
        products = Products(
            self.product(products.exact, exact=True),
            None if products.fast is None else self.product(products.fast),
            self.columns(products.columns) if columns is None else self.sources(columns),
            products.keep_conjugacy,
        )
        return z[cells], p[cells], candidates[cells], basis[cells], products, self.precondition(pc)

    def answer(self, out: PKResult, exact: Callable, z, candidates, basis, tol: float):
        """The kernel's one-row answer on the part as the grid's pressure and displacement
        (flat), and whether a candidate cell off the part would touch (its gap ``u + z - B m``
        below ``-tol`` times the part's largest displacement; checked on a converged row)."""
        p = out.pressure.reshape(1, -1)
        u = self.displacement(p, exact)[0]
        scale = max(float(np.abs(u[self.cells]).max()), np.finfo(float).tiny)
        gap = (u + z - basis @ out.multipliers[0])[None]
        touching = bool(out.converged[0]) and bool(self.touching(gap, candidates[None], np.array([tol * scale]))[0])
        return self.expand(p)[0], u, touching

    def touching(self, gap: np.ndarray, candidates: np.ndarray, tolerance: np.ndarray) -> np.ndarray:
        """Per row, whether a candidate cell off the part has ``gap`` (b, n) below
        ``-tolerance`` (per row): the part's answer is not the grid's."""
        off = candidates.reshape(len(gap), -1).copy()
        off[:, self.cells] = False
        low = np.where(off, gap, np.inf).min(axis=1, initial=np.inf)
        return low < -tolerance
