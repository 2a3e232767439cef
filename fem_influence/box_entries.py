"""A small grid's own entries of the block's cell kernel, from factors kept per grid.

A dense local block (one patch's owned cells on their bounding box) asks for entries of
``grid_matrix(box)`` on each new active set: its factorisation and the columns of its
active cells. The provider's ``grid_matrix`` makes the box's whole matrix for each of
them (Love's strided copy plus ``h^2 U W``, ``U`` made again from the sparse top-face
interpolation); a product that cannot use kept columns goes by the box's FFT. On 4,753
tips that was 11,483 whole matrices and 37,685 FFT products of a box.

:class:`BoxEntries` keeps, per box,

* Love's kernel at every lattice offset within the box (a window of ``(2 nx - 1)(2 ny -
  1)`` values, the half-space's own numbers from the provider's Love tables): an entry is
  one gather at the difference of two flat indices;
* the correction in rank-``r`` form ``C = L R``: ``L`` (cells x r) the top-face Q2
  interpolation at the cells from the ``r`` top-face nodes around the box (9 inside one
  element), ``R = T_r W`` (r x cells) those nodes' values of the lattice fields times the
  cells' source weights onto the lattice.

``entries(rows, cols)`` is then ``Love[rows, cols] + h^2 L[rows] R[:, cols]``: the same
numbers as the whole matrix's cut up to the order of the correction's sums (``(L T) W``
there, ``L (T W)`` here; a few units in the last place of a correction that is itself a
small part of an entry). The entries are not exactly symmetric (the correction's source
and target interpolations differ), so :attr:`BoxEntries.symmetric` is False.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twoscale.grid import Grid

if TYPE_CHECKING:
    from .provider import BlockProvider

#: Largest window of Love offsets a box keeps (entries, 32 KB): the half-space's box window's
#: bound, boxes of up to about 32 x 32 cells.
WINDOW_MAX_ENTRIES = 4096
#: Largest number of top-face nodes around a box for the rank form (a box across two
#: elements each way has 25).
RANK_MAX = 25


class BoxEntries:
    """``grid_matrix(box)[np.ix_(rows, cols)]`` of a block provider for flat cell indices
    of ``box``, from the kept Love window and correction factors (module docstring)."""

    #: The entries are not exactly symmetric: a solver that needs exact symmetry (a
    #: Cholesky factor of a stack) must not take them as such.
    symmetric = False

    def __init__(self, box: Grid, window: np.ndarray, L: np.ndarray, R: np.ndarray):
        self._window, self._L, self._R, self._area = window, L, R, box.h**2
        wx = 2 * box.nx - 1
        j, i = np.divmod(np.arange(box.size), box.nx)
        # a cell's flat index on the window's lattice, and the index of offset (0, 0)
        self._flat = j * wx + i
        self._zero = (box.ny - 1) * wx + box.nx - 1

    def entries(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        love = np.take(self._window, (self._flat[rows] + self._zero)[:, None] - self._flat[cols][None, :])
        return love + self._area * (self._L[rows] @ self._R[:, cols])

    def product(self, rows: np.ndarray, cols: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``entries(rows, cols) @ v``, the correction by its rank form (``L[rows] (R[:, cols]
        v)``, not the ``rows x cols`` product of the factors)."""
        love = np.take(self._window, (self._flat[rows] + self._zero)[:, None] - self._flat[cols][None, :])
        return love @ v + self._area * (self._L[rows] @ (self._R[:, cols] @ v))

    @property
    def nbytes(self) -> int:
        return self._window.nbytes + self._L.nbytes + self._R.nbytes + self._flat.nbytes


def box_entries(provider: "BlockProvider", box: Grid) -> BoxEntries | None:
    """The :class:`BoxEntries` of ``box`` (scene frame), or None where the window would be
    large or the top face is not rectilinear (the provider's whole matrix then serves)."""
    from .grid_factors import _axis_weights, grid_weights, kron
    from .interpolate import _quadratic_weights

    if (2 * box.nx - 1) * (2 * box.ny - 1) > WINDOW_MAX_ENTRIES:
        return None
    nodes, W = grid_weights(provider, box)
    cols = provider._ensure(nodes)  # the first fields solved also make the interpolator
    st = provider._state
    top = st.interpolator
    if not top.rectilinear:
        return None
    # the top-face interpolation at the cells, one axis at a time (as ``grid_target``), and
    # the table's rows of those nodes only (not the whole table's columns, 1,681 x 16)
    ox, oy = provider.origin
    x_nodes, mx = _axis_weights(box.x, *_quadratic_weights(box.x + ox, top._xs))
    y_nodes, my = _axis_weights(box.y, *_quadratic_weights(box.y + oy, top._ys))
    if len(x_nodes) * len(y_nodes) > RANK_MAX:
        return None
    T = st.table[np.ix_(top._node[np.ix_(y_nodes, x_nodes)].ravel(), cols)] / provider.material.E
    L = kron(my.T, mx.T)  # (cells, r): cell j * nx + i, node a * rx + b
    R = T @ W.toarray()
    # Love's kernel at the offsets (dy, dx), |dy| < ny, |dx| < nx: the cells of a grid of
    # (2 ny - 1) x (2 nx - 1) around one source cell, row-major
    around = Grid(box.x0 - (box.nx - 1) * box.h, box.y0 - (box.ny - 1) * box.h, box.h, 2 * box.nx - 1, 2 * box.ny - 1)
    centre = Grid(box.x0, box.y0, box.h, 1, 1)
    window = provider._halfspace.grid_entries(
        around, centre, np.arange(around.size), np.zeros(1, np.int64), tables=st.love_tables
    ).ravel()
    return BoxEntries(box, window, L, R)
