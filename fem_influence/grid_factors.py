"""The block's correction factors on an aligned grid, kept separable.

The correction's source weights are tensor products (cubic Lagrange in x times cubic
Lagrange in y, :func:`~fem_influence.operators.lagrange_1d`) and so is its top-face
interpolation on rectilinear meshes (quadratic in x times quadratic in y). On a grid of
cells, whose centres are the product of one x row and one y column, both factors are
Kronecker products of two small dense matrices:

* :class:`GridWeights`: ``W = Wy (x) Wx`` from the grid's cells to the lattice nodes it
  touches, ``W p = Wy P Wx^T``;
* :class:`GridTarget`: the correction at the grid's cells from lattice-node coefficients,
  ``My (T c)[rows, cols] Mx^T`` with ``T`` the provider's shared table of top-face node
  values.

Built from one axis at a time they cost the grid's side, not its cells: the sparse
weights of a 525 x 526-cell union box (16 a cell) took 0.8 s to assemble (a ``np.unique``
over 4.4 M node indices) and 2.5 ms a product; the separable ones take milliseconds and
about 1 ms a product.
"""

from __future__ import annotations

import numpy as np

from twoscale.grid import Grid


def _axis_weights(x: np.ndarray, idx: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct nodes ``used`` of one axis' stencils ``idx`` (n, s) with weights ``w``,
    and the dense weights (len(used), n) of each point on them."""
    lo, hi = int(idx.min()), int(idx.max())
    if hi - lo < 4 * idx.size and np.bincount(idx.ravel() - lo, minlength=hi - lo + 1).all():
        used, inv = np.arange(lo, hi + 1), idx - lo  # the stencils of ascending points: every node between
    else:
        used, inv = np.unique(idx, return_inverse=True)
    out = np.zeros((len(used), len(x)))
    out[inv.reshape(idx.shape), np.arange(len(x))[:, None]] = w  # a point's stencil nodes are distinct
    return used, out


def kron(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.kron`` of two matrices (the same products), without its general-shape overhead."""
    return (a[:, None, :, None] * b[None, :, None, :]).reshape(a.shape[0] * b.shape[0], a.shape[1] * b.shape[1])


class GridWeights:
    """Source-interpolation weights (lattice nodes x cells) of a grid, ``Wy (x) Wx``.

    Rows are the nodes ``(xs[b], ys[a])`` in the order ``a * len(xs) + b``; columns the
    grid's cells, x fastest. Acts like the sparse matrix it replaces: ``@`` a flat
    pressure, :meth:`toarray`, :attr:`shape`, :meth:`times_cells` for a few cells.
    """

    def __init__(self, wy: np.ndarray, wx: np.ndarray):
        self.wy, self.wx = wy, wx
        self.shape = (wy.shape[0] * wx.shape[0], wy.shape[1] * wx.shape[1])

    def __matmul__(self, p: np.ndarray) -> np.ndarray:
        P = np.asarray(p).reshape(self.wy.shape[1], self.wx.shape[1])
        return ((self.wy @ P) @ self.wx.T).ravel()

    def toarray(self) -> np.ndarray:
        return kron(self.wy, self.wx)

    def times_cells(self, cells: np.ndarray, values: np.ndarray) -> np.ndarray:
        """``W[:, cells] @ values`` for a few flat ``cells``."""
        iy, ix = np.divmod(np.asarray(cells), self.wx.shape[1])
        return ((self.wy[:, iy] * np.asarray(values, dtype=float)) @ self.wx[:, ix].T).ravel()

    @property
    def nbytes(self) -> int:
        return self.wy.nbytes + self.wx.nbytes

    @property
    def flops(self) -> float:
        """Multiply-adds of one product, doubled."""
        ny, nx = self.wy.shape[1], self.wx.shape[1]
        return 2.0 * (self.wy.shape[0] * ny * nx + self.shape[0] * nx)


def grid_weights(provider, grid: Grid) -> tuple[np.ndarray, GridWeights]:
    """The lattice nodes ``(i, j)`` (K, 2) a grid's cells are interpolated from and their
    :class:`GridWeights` (the same weights as ``provider._weights(grid.points())``, whose
    check of the answered region it runs on the grid's corners)."""
    from .operators import lagrange_1d

    x0, x1, y0, y1 = provider._lattice_bounds()
    corners = np.array([[grid.x[0], grid.y[0]], [grid.x[-1], grid.y[-1]]])
    provider.check_answered(corners)
    d = provider.source_spacing
    ox, oy = provider.origin
    xs, wxs = _axis_weights(grid.x, *lagrange_1d(grid.x + ox, d, x0, x1))
    ys, wys = _axis_weights(grid.y, *lagrange_1d(grid.y + oy, d, y0, y1))
    nodes = np.column_stack([np.tile(xs, len(ys)), np.repeat(ys, len(xs))])
    return nodes, GridWeights(wys, wxs)


class GridTarget:
    """The correction (mm/N) at a grid's cells from lattice-node coefficients ``c``:
    ``V = T c`` on the rows and columns of top-face nodes around the grid (``T`` the
    provider's table, already divided by E, cut to those nodes and the columns of ``c``),
    interpolated ``My V Mx^T``. Stands where
    :class:`~fem_influence.operators.TargetFactor` does (``@`` a coefficient vector)."""

    def __init__(self, my: np.ndarray, mx: np.ndarray, node: np.ndarray, T: np.ndarray):
        self.my, self.mx, self.T = my, mx, T[node.ravel()]  # the table's rows of those nodes
        self._rows = node.shape

    def __matmul__(self, c: np.ndarray) -> np.ndarray:
        """The correction at the cells (flat) from coefficients ``c`` (K,), or (cells, m)
        from ``m`` columns (K, m)."""
        c = np.asarray(c, dtype=float)
        if c.ndim == 1:
            V = (self.T @ c).reshape(self._rows)
            return ((self.my @ V) @ self.mx.T).ravel()
        (ry, rx), m = self._rows, c.shape[1]
        A = (self.my @ (self.T @ c).reshape(ry, rx * m)).reshape(-1, rx, m)
        return np.einsum("jb,ibm->ijm", self.mx, A).reshape(-1, m)

    @property
    def nbytes(self) -> int:
        return self.my.nbytes + self.mx.nbytes + self.T.nbytes

    @property
    def flops(self) -> float:
        """Multiply-adds of one product with one vector, doubled."""
        (ny, ry), (nx, rx) = self.my.shape, self.mx.shape
        return 2.0 * (self.T.size + ny * ry * rx + ny * nx * rx)


def grid_target(interpolator, grid: Grid, origin, T: np.ndarray) -> GridTarget:
    """:class:`GridTarget` of ``grid`` (scene frame, shifted by ``origin`` to the block's)
    on a rectilinear top face (``interpolator`` a
    :class:`~fem_influence.interpolate.TopInterpolator`)."""
    from .interpolate import _quadratic_weights

    P = np.array([[grid.x[0], grid.y[0]], [grid.x[-1], grid.y[-1]]]) + np.asarray(origin)
    interpolator._check(P)
    cols, mx = _axis_weights(grid.x, *_quadratic_weights(grid.x + origin[0], interpolator._xs))
    rows, my = _axis_weights(grid.y, *_quadratic_weights(grid.y + origin[1], interpolator._ys))
    return GridTarget(my.T.copy(), mx.T.copy(), interpolator._node[np.ix_(rows, cols)], T)


class KronMatrix:
    """``kron(my, mx)`` (cells x top-face nodes, x fastest both ways) kept as its two axis
    factors ``my`` (ny, ry) and ``mx`` (nx, rx): a grid's interpolation from the nodes
    around it, ``@`` a flat node vector (ry * rx,) or (ry * rx, m) columns, as the dense
    matrix's products (summed along y, then x). A patch's dense form is 58 kB (812 cells,
    9 nodes; 5,930 spheres kept 0.3 GB of them), its factors under 1 kB."""

    def __init__(self, my: np.ndarray, mx: np.ndarray):
        self.my, self.mx = my, mx
        self.shape = (my.shape[0] * mx.shape[0], my.shape[1] * mx.shape[1])

    def __matmul__(self, v):
        v = np.asarray(v, dtype=float)
        (ny, ry), rx = self.my.shape, self.mx.shape[1]
        if v.ndim == 1:
            return ((self.my @ v.reshape(ry, rx)) @ self.mx.T).ravel()
        m = v.shape[1]
        A = (self.my @ v.reshape(ry, rx * m)).reshape(ny, rx, m)
        return np.matmul(self.mx, A).reshape(-1, m)  # one (nx, rx) @ (rx, m) a row (einsum: 8x slower)

    def toarray(self) -> np.ndarray:
        return kron(self.my, self.mx)

    @property
    def nbytes(self) -> int:
        return self.my.nbytes + self.mx.nbytes

    @property
    def nnz(self) -> int:
        """Multiply-adds of one product with one vector (as a sparse matrix's entries)."""
        (ny, ry), (nx, rx) = self.my.shape, self.mx.shape
        return ny * ry * rx + ny * nx * rx


#: Most top-face nodes around a grid whose interpolation :func:`grid_interpolation` keeps
#: dense (a patch across two elements each way has 25).
DENSE_NODES = 25


def grid_interpolation(interpolator, grid: Grid, origin) -> tuple:
    """The top-face interpolation at a grid's cells on the nodes it uses, and those nodes:
    ``(M, nodes)`` with ``M @ values[nodes]`` the values at the cells. From one axis at a
    time, ``kron(My, Mx)`` kept as its factors (:class:`KronMatrix`) where
    the grid touches at most :data:`DENSE_NODES` nodes (a patch: a few elements' worth of
    Python a grid, not one stencil a cell); else the pointwise matrix, compressed
    (:meth:`~fem_influence.interpolate.TopInterpolator.compressed`)."""
    from .interpolate import _quadratic_weights

    ox, oy = origin
    interpolator._check(np.array([[grid.x[0], grid.y[0]], [grid.x[-1], grid.y[-1]]]) + np.asarray(origin))
    cols, mx = _axis_weights(grid.x, *_quadratic_weights(grid.x + ox, interpolator._xs))
    rows, my = _axis_weights(grid.y, *_quadratic_weights(grid.y + oy, interpolator._ys))
    if len(rows) * len(cols) > DENSE_NODES:
        return interpolator.compressed(grid.points() + np.asarray(origin))
    return KronMatrix(my.T.copy(), mx.T.copy()), interpolator._node[np.ix_(rows, cols)].ravel()
