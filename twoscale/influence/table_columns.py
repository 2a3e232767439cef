"""A translation-invariant kernel's columns from its offset table: ``A dp`` added for a
``dp`` on a few source cells, column by column (:meth:`ConvolutionOperator.columns
<twoscale.influence.convolution.ConvolutionOperator.columns>`), on the whole target grid
(:class:`GridColumns`: a window of the table a column) or on some of its cells
(:class:`TargetColumns`: a gather of the table a column).

A column is a pass over the targets, and the same few columns are summed into one field:
the targets run in chunks of :data:`COLUMN_CHUNK` cells, every column summed into a chunk
before the next (the chunk stays in cache across the columns: the field is read and
written once, not once a column). Each target's terms are added in the columns' order,
as column by column: the same values to the bit (604 x 593 targets, 15 columns: 7.9
against 11 ms).
"""

from __future__ import annotations

import numpy as np

#: Target cells a chunk (about 1 MB of float64 a term buffer).
COLUMN_CHUNK = 1 << 17


class GridColumns:
    """``add(out, cells, values)``: ``out`` (the target grid's cells, flat) += the columns of
    the flat source ``cells`` times ``values``, each a window of ``table`` (entry ``(m, n)``
    the offset ``(m - nys + 1, n - nxs + 1)``)."""

    def __init__(self, table: np.ndarray, target_shape: tuple, source_shape: tuple):
        self.table, self.target_shape, self.source_shape = table, tuple(target_shape), tuple(source_shape)
        self._term: np.ndarray | None = None  # (kept: a new array each call was a page-faulting allocation)

    def __call__(self, out: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
        (nyt, nxt), (nys, nxs) = self.target_shape, self.source_shape
        o = out.reshape(nyt, nxt)
        js, i_s = np.divmod(np.asarray(cells), nxs)
        # each column's window corner in the table, and its value
        columns = list(zip((nys - 1 - js).tolist(), (nxs - 1 - i_s).tolist(), np.asarray(values).tolist()))
        rows = max(1, min(nyt, COLUMN_CHUNK // max(nxt, 1)))
        if self._term is None or self._term.shape[0] < rows:
            self._term = np.empty((rows, nxt), self.table.dtype)
        for r0 in range(0, nyt, rows):
            r1 = min(r0 + rows, nyt)
            chunk, term = o[r0:r1], self._term[: r1 - r0]
            for a, b, v in columns:
                np.multiply(self.table[a + r0 : a + r1, b : b + nxt], v, out=term)
                chunk += term


class TargetColumns:
    """:class:`GridColumns` on the flat target cells ``targets`` only: a source cell's column
    there is the offset table (flat) at the targets' offsets moved by the cell's, one
    gather (a part of the grid: :mod:`twoscale.pk.compact`)."""

    def __init__(self, table: np.ndarray, source_shape: tuple, targets: np.ndarray, nxt: int):
        self.flat, self.source_shape, self.width = table.ravel(), source_shape, table.shape[1]
        jt, it = np.divmod(targets, nxt)
        self.offsets = (jt * self.width + it).astype(np.intp)
        # the offsets and the column of a chunk, kept (fresh ones each column page-faulted: 4 M targets, 0.7 s)
        self._at: np.ndarray | None = None
        self._term: np.ndarray | None = None

    def __call__(self, out: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
        nys, nxs = self.source_shape
        js, i_s = np.divmod(np.asarray(cells), nxs)
        shifts = ((nys - 1 - js) * self.width + nxs - 1 - i_s).tolist()
        columns = list(zip(shifts, np.asarray(values).tolist()))
        m = len(self.offsets)
        if self._at is None:
            size = min(COLUMN_CHUNK, m)
            self._at, self._term = np.empty(size, np.intp), np.empty(size, self.flat.dtype)
        for c0 in range(0, m, COLUMN_CHUNK):
            c1 = min(c0 + COLUMN_CHUNK, m)
            offsets, chunk = self.offsets[c0:c1], out[c0:c1]
            at, term = self._at[: c1 - c0], self._term[: c1 - c0]
            for shift, v in columns:
                np.add(offsets, shift, out=at)
                np.take(self.flat, at, out=term, mode="clip")  # (in the table; "raise" buffers a copy)
                term *= v
                chunk += term
