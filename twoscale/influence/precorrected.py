"""A precorrected-FFT product on a sparse part of a square grid (:class:`Precorrected`): ``A v``
for pressures on a few cells of a large box, to a relative accuracy of about 1e-3, for a small
fraction of the padded FFT product's cost.

The far field goes through a grid ``c`` times coarser: each cell's value is spread onto the
four coarse nodes around it by bilinear (area) weights, the coarse values are convolved with
the kernel sampled at the nodes' offsets (one small zero-padded FFT convolution, its spectrum
kept), and the coarse displacement is interpolated back with the same weights. Pairs of cells
within a Chebyshev radius ``r`` (cells) are then *precorrected*: their exact coefficient from
the kernel's offset table less the coarse route's approximation of it, summed by a sparse
matrix. The coarse route's coefficient of a pair depends only on its offset ``d`` and on the
target's position ``s`` modulo ``c`` (the source's is ``(s - d) mod c``), so the near matrix's
values are lookups in a table of ``(2r + 1)^2 c^2`` corrections. Phillips & White (1997).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.fft as sfft
from scipy import sparse

from .circulant import CirculantInverse

#: The coarse grid's spacing (cells) and the near pairs' Chebyshev radius (cells). On a lattice
#: of 8,772 contacts (a part of 29,696 cells of 1337 x 1337): relative L2 error 4.2e-4 (7, 21),
#: 8e-4 (7, 14), 1.5e-3 (14, 28), a product 2-3 ms (the float32 padded one 50-55 ms); the CG
#: took 22, 21 and (7, 10) 29 iterations.
COARSE = 7
RADIUS = 21
#: The relative L2 error taken for the kernel's re-anchoring rule (measured 4.2-4.3e-4 at
#: (7, 21) on converged and random pressures).
PRODUCT_ERROR = 5e-4
#: Parts of at most this fraction of their grid take the precorrected product: #185's
#: lattice 1.66 % (32 near pairs a cell at r 21); the roads' parts, 5-30 % and spread over
#: every row and column of their boxes, keep the exact route (their pressures bit-identical).
MAX_FRACTION = 0.03


def _kernel_at(table: np.ndarray, shape: tuple[int, int], dy: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """The kernel at cell offsets ``(dy, dx)`` from the offset ``table`` (entry ``(m, n)`` the
    offset ``(m - ny + 1, n - nx + 1)``); offsets past the table (the coarse grid's last nodes
    lie up to ``c - 1`` cells beyond the box) from the table's edge scaled by ``1/rho`` (the
    kernel's decay far from the load)."""
    ny, nx = shape
    dy, dx = np.broadcast_arrays(dy, dx)
    cy, cx = np.clip(dy, 1 - ny, ny - 1), np.clip(dx, 1 - nx, nx - 1)
    k = table[cy + ny - 1, cx + nx - 1]
    out = (cy != dy) | (cx != dx)
    if np.any(out):
        far = np.hypot(dy[out], dx[out])
        k = np.array(k, dtype=float)
        k[out] *= np.hypot(cy[out], cx[out]) / far
    return k


def _row_runs(y: np.ndarray, x: np.ndarray, shape: tuple, r: int):
    """For each cell ``(y, x)`` (int32, increasing flat order) and grid row ``y + dy``,
    ``dy = -r .. r``: the index of the first part cell at ``|x' - x| <= r`` in that row and
    their count, both (m (2r + 1),) int32 (0 for rows off the grid)."""
    ny, nx = shape
    before = np.zeros(ny * nx + 1, np.int32)
    before[y * nx + x + 1] = 1
    np.cumsum(before, out=before)  # part cells before each flat index
    rows = y[:, None] + np.arange(-r, r + 1, dtype=np.int32)
    inside = (rows >= 0) & (rows < ny)
    flat = np.where(inside, rows, 0) * nx
    lo = before[flat + np.maximum(x - r, 0)[:, None]].ravel()
    length = before[flat + (np.minimum(x + r, nx - 1) + 1)[:, None]].ravel()
    length -= lo
    length *= inside.ravel()
    return lo, length


def _run_columns(lo: np.ndarray, length: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """The runs' columns laid end to end (``lo``, ``lo + 1``, ... per run): one cumulative sum
    of unit steps with a jump at each run's start."""
    cols = np.ones(int(ends[-1]) if len(ends) else 0, np.int32)
    keep = length > 0
    first, starts = lo[keep], (ends - length)[keep]
    if len(first):
        cols[starts[1:]] = first[1:] - (first[:-1] + length[keep][:-1] - 1)
        cols[0] = first[0]
    return np.cumsum(cols, out=cols)


class Precorrected:
    """``A v`` (m,) for pressures ``v`` (m,) on the flat ``cells`` (increasing) of a square
    grid of ``shape``, from the kernel's offset ``table`` (``ConvolutionOperator.offset_table``).

    Parameters
    ----------
    table : (2 ny - 1, 2 nx - 1) array, mm/MPa
    shape : (ny, nx)
    cells : (m,) int array
    coarse, radius : int
        The coarse grid's spacing and the near pairs' Chebyshev radius, in cells.
    """

    def __init__(self, table: np.ndarray, shape: tuple, cells: np.ndarray, coarse: int = COARSE, radius: int = RADIUS):
        self.shape, self.c, self.r = (int(shape[0]), int(shape[1])), int(coarse), int(radius)
        ny, nx = self.shape
        c = self.c
        y, x = np.divmod(np.asarray(cells, dtype=np.intp), nx)
        self.m = len(y)
        self.nodes = ((ny - 1) // c + 2, (nx - 1) // c + 2)
        self.at, self.w = self._weights(y, x)
        self._spectrum, self._fft = self._coarse_spectrum(table)
        self.near = self._near(table, y, x)
        self.products = 0  # (calls of rows)

    def _weights(self, y: np.ndarray, x: np.ndarray):
        """The four coarse nodes around each cell (4, m) flat indices and their bilinear weights."""
        c, (_, ncx) = self.c, self.nodes
        iy, sy = np.divmod(y, c)
        ix, sx = np.divmod(x, c)
        fy, fx = sy / c, sx / c
        at = np.stack([iy * ncx + ix, iy * ncx + ix + 1, (iy + 1) * ncx + ix, (iy + 1) * ncx + ix + 1])
        w = np.stack([(1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx])
        return at, w

    def _coarse_kernel(self, table: np.ndarray, dy: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """The kernel between coarse nodes ``(dy, dx)`` nodes apart."""
        return _kernel_at(table, self.shape, self.c * dy, self.c * dx)

    def _coarse_spectrum(self, table: np.ndarray):
        ncy, ncx = self.nodes
        fft = (sfft.next_fast_len(2 * ncy - 1, real=True), sfft.next_fast_len(2 * ncx - 1, real=True))
        dy, dx = np.meshgrid(np.arange(1 - ncy, ncy), np.arange(1 - ncx, ncx), indexing="ij")
        return sfft.rfft2(self._coarse_kernel(table, dy, dx), s=fft), fft

    def correction_table(self, table: np.ndarray) -> np.ndarray:
        """``T[dy + r, dx + r, sy, sx]``: the exact coefficient of a pair at offset ``(dy, dx)``
        (target less source) whose target sits at ``(sy, sx)`` modulo ``c``, less the coarse
        route's (16 terms: the two cells' four nodes each)."""
        c, r = self.c, self.r
        d, s = np.arange(-r, r + 1)[:, None], np.arange(c)[None, :]
        t = (s - d) % c  # the source's position modulo c
        between = (d - s + t) // c  # target's node less source's node (exact division)
        ws = np.stack([np.broadcast_to(1 - s / c, t.shape), np.broadcast_to(s / c, t.shape)])  # the target's nodes
        wt = np.stack([1 - t / c, t / c])
        approx = np.zeros((2 * r + 1, 2 * r + 1, c, c))
        for ay in (0, 1):
            for by in (0, 1):
                wy, ny_ = ws[ay] * wt[by], between + ay - by
                for ax in (0, 1):
                    for bx in (0, 1):
                        wx, nx_ = ws[ax] * wt[bx], between + ax - bx
                        k = self._coarse_kernel(table, ny_[:, None, :, None], nx_[None, :, None, :])
                        approx += wy[:, None, :, None] * wx[None, :, None, :] * k
        dy, dx = np.meshgrid(np.arange(-r, r + 1), np.arange(-r, r + 1), indexing="ij")
        exact = _kernel_at(table, self.shape, dy, dx)
        return exact[:, :, None, None] - approx

    def _near(self, table: np.ndarray, y: np.ndarray, x: np.ndarray) -> sparse.csr_matrix:
        """The near pairs' corrections as a sparse (m, m) matrix. The cells are increasing flat
        indices, so a cell's neighbours in one grid row are a run of them (its ends from the
        count of part cells before each flat index), and each cell's ``2r + 1`` runs in turn
        give the matrix's rows in order. A pair's entry in the correction table is its run's
        (the target's position modulo ``c`` and ``(r - dy, x_t + r)``) less ``x_s c^2``."""
        r, c, m = self.r, self.c, self.m
        (ny, nx), corr = self.shape, self.correction_table(table).ravel()
        width, cc = 2 * r + 1, c * c
        y, x = y.astype(np.int32), x.astype(np.int32)
        lo, length = _row_runs(y, x, (ny, nx), r)
        ends = np.cumsum(length, dtype=np.int64)
        indptr = np.zeros(m + 1, np.int64)
        indptr[1:] = ends[width - 1 :: width]
        cols = _run_columns(lo, length, ends)
        d = np.arange(-r, r + 1, dtype=np.int32)
        run = (((r - d) * width + r)[None, :] + x[:, None]) * cc + ((y % c) * c + x % c)[:, None]
        key = np.repeat(run.ravel(), length)  # each entry's place in the correction table
        key -= (x * cc)[cols]
        self._pairs = (cols, indptr, key)  # the CSR structure, each entry's table place
        return sparse.csr_matrix((corr[key], cols, indptr), shape=(m, m))

    def on_near_pairs(self, window: np.ndarray) -> sparse.csr_matrix:
        """The (m, m) matrix of a kernel given at the offsets ``-r .. r`` per axis (``window``,
        ``(2r + 1)^2``) on the near pairs (the same structure as :attr:`near`)."""
        cols, indptr, key = self._pairs
        per_place = np.repeat(np.asarray(window, dtype=float).ravel(), self.c * self.c)
        return sparse.csr_matrix((per_place[key], cols, indptr), shape=(self.m,) * 2)

    def far(self, v: np.ndarray) -> np.ndarray:
        """The coarse route's product (every pair by its coarse approximation)."""
        ncy, ncx = self.nodes
        q = np.bincount(self.at.ravel(), weights=(self.w * v).ravel(), minlength=ncy * ncx).reshape(ncy, ncx)
        back = sfft.irfft2(sfft.rfft2(q, s=self._fft) * self._spectrum, s=self._fft)
        u = back[ncy - 1 : 2 * ncy - 1, ncx - 1 : 2 * ncx - 1].ravel()
        return (self.w * u[self.at]).sum(axis=0)

    def __call__(self, v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, dtype=float)
        return self.far(v) + self.near @ v

    def rows(self, v: np.ndarray) -> np.ndarray:
        """The product on a stack of one row (1, m), the kernel's ``cheap``; counted in
        ``products``."""
        self.products += 1
        return self(v[0])[None]


def cheap_products(products, op, part, grid_pc=None, precondition=None):
    """``products`` (:class:`~twoscale.pk.products.Products` on ``part``'s cells) with the
    search directions' ``cheap`` product by :class:`Precorrected` where the part holds at most
    :data:`MAX_FRACTION` of its square convolution operator ``op``'s grid, and the kernel's
    ``precondition`` on the part then the torus inverse's kernel on the near pairs alone
    where the grid's preconditioner ``grid_pc`` is one (:class:`~.circulant.CirculantInverse`,
    wrapped in ``.op``); else both unchanged. Returns ``(products, precondition)``.

    The torus inverse's kernel falls off fast (its off-diagonal entries negative, about
    ``1/rho^3``): cut at the near radius its rows still sum to a positive value (an M-matrix,
    symmetric positive definite on any set of cells), a sparse product instead of a torus FFT
    pair. #185: the same 22 iterations cut at 10 or 21 cells, 0.6 against 16 ms a product."""
    table = getattr(op, "offset_table", None)
    if table is None or op.target != op.source or part.cells.size > MAX_FRACTION * part.size:
        return products, precondition
    pc = Precorrected(table(), op.source.shape, part.cells)
    inverse = getattr(grid_pc, "op", None)
    if isinstance(inverse, CirculantInverse) and inverse.source == op.source:
        near = pc.on_near_pairs(inverse.offsets(pc.r))
        precondition = lambda v, on: (near @ v[0])[None]  # noqa: E731
    return replace(products, cheap=pc.rows, cheap_error=PRODUCT_ERROR), precondition
