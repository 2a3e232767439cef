"""``A_kk``: the influence block of one patch on its own owned cells, with linear solves
on active subsets (dense factorisations for small blocks, CG on the provider's operator for
large ones). Every number comes from the influence provider.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
import scipy.linalg as sla
from scipy.linalg.lapack import dpotrs

from ..influence.base import InfluenceProvider
from .pair_entries import BoxWindow
from .patches import Patch

#: A dense block whose matrix is not stored keeps the columns ``A[:, S]`` of its last active
#: set ``S`` up to this many entries (32 KB): the active-set loops' check ``A p`` is then one
#: small product, not an FFT of its box (939 blocks: a third of the local solves' CPU).
COLUMNS_MAX_ENTRIES = 4096
#: Above that, the active columns are gathered for one product and not kept, up to this
#: many entries (512 KB), where the block keeps its box's offsets (:meth:`LocalBlock._entries`):
#: a gather of 10,000 entries costs a tenth of an FFT of the box.
COLUMNS_GATHER_MAX_ENTRIES = 65536
#: The largest grid matrix (entries, 32 MB) :func:`grid_entries` cuts entries from ...
GRID_MATRIX_MAX_ENTRIES = 4_000_000
#: ... and one it cuts from however few entries are wanted (2 MB: a small box's matrix).
GRID_MATRIX_SMALL_ENTRIES = 250_000
#: The largest block :func:`whole_patch` makes for the cells a neighbour owns (entries,
#: 32 MB), else an FFT of the pair's boxes (large merged paraboloids: 4.5 GB of peak).
WHOLE_PATCH_MAX_ENTRIES = 4_000_000


def _is_symmetric(M: np.ndarray) -> bool:
    # exact equality first: the half-space's Toeplitz blocks have it, and it is ~5x cheaper
    return bool(np.array_equal(M, M.T) or np.allclose(M, M.T, rtol=1e-10, atol=0.0))


def _factorise(M: np.ndarray, symmetric: bool):
    """``("cholesky", factor)`` for a symmetric positive definite ``M``, else ``("lu", factor)``."""
    if symmetric:
        try:
            return "cholesky", sla.cho_factor(M, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            pass
    return "lu", sla.lu_factor(M, check_finite=False)


def grid_entries(provider, target, source, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``provider.grid_matrix(target, source)[np.ix_(rows, cols)]`` (flat cell indices of
    the two grids), cut from that matrix (~1/50 of a Love value an entry) only when the
    provider says it is cheap, it holds at most :data:`GRID_MATRIX_MAX_ENTRIES` and not much
    more than 50 times the entries wanted; else from the provider's cell block (a tilted
    sphere's few owned cells on a box of 17,700 cut from its whole matrix: 2.5 GB)."""
    rows, cols = np.asarray(rows), np.asarray(cols)
    if not (rows.size and cols.size):
        return np.zeros((rows.size, cols.size))
    full = target.size * source.size
    if getattr(provider, "cheap_grid_matrix", False) and full <= min(
        GRID_MATRIX_MAX_ENTRIES, max(50 * rows.size * cols.size, GRID_MATRIX_SMALL_ENTRIES)
    ):
        entries = getattr(provider, "grid_entries", None)  # the same numbers, without the whole matrix
        if entries is not None:
            return entries(target, source, rows, cols)
        return provider.grid_matrix(target, source)[np.ix_(rows, cols)]
    X, Y = target.centres()
    S, T = source.centres()
    return provider.cell_block(
        np.column_stack([X.ravel()[rows], Y.ravel()[rows]]),
        np.column_stack([S.ravel()[cols], T.ravel()[cols]]),
        source.h,
    )


def whole_patch_is_large(patch: Patch, v: np.ndarray) -> bool:
    """Whether :func:`whole_patch` on ``patch`` from a source vector ``v`` would make a
    block over :data:`WHOLE_PATCH_MAX_ENTRIES` (the cells a neighbour owns x ``v``'s
    loaded cells): the caller then takes the FFT route."""
    return int((~patch.owned).sum()) * int(np.count_nonzero(v)) > WHOLE_PATCH_MAX_ENTRIES


def whole_patch(provider, patch: Patch, owned_rows: np.ndarray, source: Patch, v: np.ndarray) -> np.ndarray:
    """Displacement (ny, nx) mm on the whole ``patch`` from the block vector ``v`` (MPa) of
    the patch ``source`` (``patch`` itself for its own pressure), given its values
    ``owned_rows`` (n,) on the patch's own cells: the cells a neighbour owns (where patches
    overlap) from the loaded cells by :func:`grid_entries`."""
    out = np.zeros(patch.grid.shape)
    out[patch.owned] = owned_rows
    other = ~patch.owned
    loaded = v != 0.0
    if other.any() and loaded.any():
        cols = np.flatnonzero(source.owned.ravel())[loaded]
        block = grid_entries(provider, patch.grid, source.grid, np.flatnonzero(other.ravel()), cols)
        out[other] = block @ v[loaded]
    return out


class LocalBlock:
    """``A_kk`` on the owned cells of one patch, with linear solves on active subsets.

    Parameters
    ----------
    provider : InfluenceProvider
    patch : Patch
    dense_max_cells : int, default 400
        Blocks with at most this many owned cells solve by Cholesky (LU where the provider's
        matrix is not symmetric positive definite; factorisations cached per active set),
        storing ``A_kk`` unless the provider's ``cheap_grid_matrix`` says to cut it again for
        each new active set; larger blocks by CG on the provider's FFT operator.
    cg_rtol : float, default 1e-10
        Relative residual at which the CG solves stop.
    cg_max_iter : int, default 2000
    cache_size : int, default 2
        Number of Cholesky factorisations (active sets) kept: the last one and the one
        before, for a contact set that flips between two (4 kept 454 MB of factors at
        10,000 sparse tips for no measured gain).
    windows : dict, optional
        The box windows (:class:`~.pair_entries.BoxWindow`) shared by the blocks of one
        solve, by box shape and cell size, all a window depends on (1,013 blocks: 1,013 made).
    """

    def __init__(
        self,
        provider: InfluenceProvider,
        patch: Patch,
        *,
        dense_max_cells: int = 400,
        cg_rtol: float = 1e-10,
        cg_max_iter: int = 2000,
        cache_size: int = 2,
        windows: dict | None = None,
    ):
        self.patch = patch
        self._windows = windows
        self._provider = provider
        self.n = int(patch.owned.sum())
        self.dense = self.n <= dense_max_cells
        self.cg_rtol, self.cg_max_iter = cg_rtol, cg_max_iter
        self._cache: OrderedDict = OrderedDict()
        # the coarse step's ``s_k`` with its active set, and its coordinates (:mod:`.coarse`),
        # kept with the block through the rounds of a solve (a round rebuilds the coarse space)
        self.coarse_shape: tuple | None = None
        self.coarse_frame: tuple | None = None
        self._cache_size = cache_size
        self.cg_iterations = 0
        self.factorisations = 0
        # the block's products only involve its owned cells: work on their bounding box (where
        # neighbours own part of the patch, a smaller grid than the patch's)
        rows = np.flatnonzero(patch.owned.any(axis=1))
        cols = np.flatnonzero(patch.owned.any(axis=0))
        if rows.size:
            j0, i0 = int(rows[0]), int(cols[0])
            self.box = patch.grid.subgrid(i0, j0, int(cols[-1]) + 1 - i0, int(rows[-1]) + 1 - j0)
            self._mask = patch.owned[j0 : j0 + self.box.ny, i0 : i0 + self.box.nx]
        else:
            self.box, self._mask = patch.grid, patch.owned
        self._full = None
        self._columns: tuple | None = None  # (active set's bytes, A[:, S]): product_on
        self._idx = np.flatnonzero(self._mask.ravel()) if self.dense else None
        self._matrix = self._symmetric = None
        self._window: BoxWindow | None = None  # made on first use (:meth:`_entries`)
        self._windowless = False
        if self.dense and not getattr(provider, "cheap_grid_matrix", False):
            self._matrix = provider.grid_matrix(self.box)[np.ix_(self._idx, self._idx)]
            self._symmetric = _is_symmetric(self._matrix)
        # products by FFT (:meth:`_operator`, made on first use: a dense block whose entries
        # come from its box window may never need it); a dense block with a cheap provider
        # matrix is not stored (8 n^2 bytes: 2 GB on 10,000 sparse tips) but cut again for
        # each new active set
        self._op = None
        if not self.dense:
            self._symmetric = True

    def _entries(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """``A`` on the box's cells ``rows`` x ``cols`` by :func:`grid_entries`; from the box's
        kept :class:`~.pair_entries.BoxWindow` where that would cut them from the provider's
        offset table (the same numbers)."""
        full = self.box.size * self.box.size
        table = getattr(self._provider, "cheap_grid_matrix", False) and full <= min(
            GRID_MATRIX_MAX_ENTRIES, max(50 * rows.size * cols.size, GRID_MATRIX_SMALL_ENTRIES)
        )
        if not (table and self._box_window() is not None and rows.size and cols.size):
            return grid_entries(self._provider, self.box, self.box, rows, cols)
        return self._window.entries(rows, cols)

    def _box_window(self) -> BoxWindow | None:
        """The box's kept :class:`~.pair_entries.BoxWindow` (made on first use), or None."""
        if self._window is None and not self._windowless:
            shared = {} if self._windows is None or hasattr(self._provider, "box_window") else self._windows
            key = (float(self.box.h), self.box.nx, self.box.ny)
            self._window = shared.get(key) or BoxWindow.of(self._provider, self.box)
            if self._window is not None:
                shared[key] = self._window
            self._windowless = self._window is None
        return self._window

    @property
    def matrix(self) -> np.ndarray | None:
        """``A_kk`` on the owned cells (n, n), mm/MPa, for dense blocks (stored, or cut from the
        provider's matrix when that is cheap); ``None`` for FFT blocks."""
        if not self.dense:
            return None
        if self._matrix is not None:
            return self._matrix
        return self._entries(self._idx, self._idx)

    @matrix.setter
    def matrix(self, value: np.ndarray) -> None:
        self._matrix = value

    @property
    def symmetric(self) -> bool:
        """Whether ``A_kk`` is symmetric (a provider's matrix may be slightly unsymmetric,
        e.g. a finite-element body's); a block not stored is checked on first use."""
        if self._symmetric is None:
            self._symmetric = _is_symmetric(self.matrix)
        return self._symmetric

    @symmetric.setter
    def symmetric(self, value: bool) -> None:
        self._symmetric = bool(value)

    # ------------------------------------------------------------------ products
    def full_operator(self):
        """FFT operator of the whole patch on itself (built on first use)."""
        if self._full is None:
            self._full = (
                self._operator() if self.box == self.patch.grid else self._provider.grid_operator(self.patch.grid)
            )
        return self._full

    def _operator(self):
        """FFT operator of the box on itself (built on first use)."""
        if self._op is None:
            self._op = self._provider.grid_operator(self.box)
        return self._op

    def matvec(self, v: np.ndarray) -> np.ndarray:
        """``A_kk v`` for a block vector (n,) or (n, m): displacement (mm) from pressure (MPa)."""
        if self._matrix is not None:
            return self._matrix @ v
        if v.ndim == 1:
            a = np.zeros(self.box.shape)
            a[self._mask] = v
            return self._operator().apply(a)[self._mask]
        return np.column_stack([self.matvec(v[:, j]) for j in range(v.shape[1])])

    def product_on(self, active: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``A_kk v`` (n,) for a block vector ``v`` (n,) that is zero off ``active``: by the
        kept columns ``A[:, S]`` (:data:`COLUMNS_MAX_ENTRIES`) where the block has them or
        they are small, else as :meth:`matvec`."""
        if self._matrix is not None or not self.dense:
            return self.matvec(v)
        if not np.count_nonzero(active):
            return np.zeros(self.n)
        key = active.tobytes()
        if self._columns is None or self._columns[0] != key:
            entries = self.n * int(np.count_nonzero(active))
            if entries > COLUMNS_MAX_ENTRIES:
                if entries > COLUMNS_GATHER_MAX_ENTRIES or self._box_window() is None:
                    return self.matvec(v)
                # gathered for this product and not kept: cheaper than the box's FFT (a
                # window's own product where it has one: the finite block's low-rank part)
                product = getattr(self._window, "product", None)
                if product is not None:
                    return product(self._idx, self._idx[active], v[active])
                return self._entries(self._idx, self._idx[active]) @ v[active]
            self._columns = (key, self._entries(self._idx, self._idx[active]))
        return self._columns[1] @ v[active]

    def patch_product(self, v: np.ndarray) -> np.ndarray:
        """``A v`` (ny, nx) mm on the whole patch for a block vector ``v`` (n,) MPa: on a
        dense block whose matrix is not stored its own cells by :meth:`product_on` (the last
        solve's kept columns) and the cells a neighbour owns by :func:`whole_patch`, not an
        FFT of the whole patch made for this one product; else (or when that block would be
        large) by that FFT."""
        if not self.dense or self._matrix is not None or whole_patch_is_large(self.patch, v):
            out = np.zeros(self.patch.grid.shape)
            out[self.patch.owned] = v
            return self.full_operator().apply(out)
        rows = self.product_on(v > 0.0, v) if np.all(v >= 0.0) else self.matvec(v)
        return whole_patch(self._provider, self.patch, rows, self.patch, v)

    def canvas_mask(self, shape: tuple[int, int]) -> np.ndarray:
        """The block's cells on a canvas of ``shape`` (>= the box's) whose corner is the
        box's: a block vector ``v`` is ``canvas[mask] = v`` (the same cell order)."""
        out = np.zeros(shape, bool)
        out[: self.box.ny, : self.box.nx] = self._mask
        return out

    # ------------------------------------------------------------------ solves
    def solve(
        self, active: np.ndarray, rhs: np.ndarray, x0: np.ndarray | None = None, rtol: float | None = None
    ) -> np.ndarray:
        """Solve ``A_SS x = rhs`` on the active cells ``S`` (boolean mask over the block).

        ``rhs`` has shape (|S|,) or (|S|, m); returns the same shape. ``x0`` is a CG start
        and ``rtol`` its relative residual (default ``cg_rtol``).
        """
        if not np.count_nonzero(active):
            return np.zeros_like(rhs)
        if self.dense:
            kind, f = self._factor(active)
            if kind == "cholesky":
                # LAPACK's potrs itself: cho_solve's checks cost 7x the solve on small blocks
                x, info = dpotrs(f[0], rhs, lower=f[1])
                return x if info == 0 else sla.cho_solve(f, rhs, check_finite=False)
            return sla.lu_solve(f, rhs, check_finite=False)
        if rhs.ndim == 2:
            cols = [self._cg(active, rhs[:, j], None if x0 is None else x0[:, j], rtol) for j in range(rhs.shape[1])]
            return np.column_stack(cols)
        return self._cg(active, rhs, x0, rtol)

    def _factor(self, active: np.ndarray):
        key = active.tobytes()
        f = self._cache.get(key)
        if f is None:
            keep = getattr(self._provider, "factorisation", None)  # a solver object's kept ones
            if keep is None:
                f = self._make_factor(active)
            else:
                f = keep(self.box, self.cells_of(active), lambda: self._make_factor(active))
            self._cache[key] = f
            if len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        else:
            self._cache.move_to_end(key)
        return f

    def adopt_factor(self, active: np.ndarray, factor: tuple, columns: np.ndarray | None = None) -> None:
        """Keep ``factor`` (``(kind, factor)``, made elsewhere: a stack of blocks) as this
        block's factorisation on ``active``, where :meth:`_factor` keeps its own, and
        ``columns`` ``A[:, S]`` for :meth:`product_on`. Only for a block whose entries are
        exactly symmetric (a Cholesky factor)."""
        key = active.tobytes()
        keep = getattr(self._provider, "factorisation", None)
        if keep is not None:
            factor = keep(self.box, self.cells_of(active), lambda: factor)
        self._cache[key] = factor
        if len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        if columns is not None:
            self._columns = (key, columns)
        if self._symmetric is None:
            self._symmetric = True
        self.factorisations += 1

    def cells_of(self, active: np.ndarray) -> np.ndarray:
        """The cells of ``active`` (a mask over the block's owned cells) as a mask over the
        block's box, row-major: the block's geometry relative to its box."""
        cells = np.zeros(self.box.nx * self.box.ny, dtype=bool)
        cells[np.flatnonzero(self._mask.ravel())[active]] = True
        return cells

    def _make_factor(self, active: np.ndarray) -> tuple:
        if self._matrix is not None:
            sub = self._matrix[np.ix_(active, active)]
        elif self.n * int(np.count_nonzero(active)) <= COLUMNS_MAX_ENTRIES:
            # the columns of the active set, kept for product_on; the factor's block is theirs
            cols = self._entries(self._idx, self._idx[active])
            self._columns = (active.tobytes(), cols)
            sub = cols[active]
        else:
            cut = self._idx[active]
            sub = self._entries(cut, cut)
        if self._symmetric is None:
            # a principal sub-block of a symmetric matrix is symmetric, and an unsymmetric
            # provider matrix (finite elements) has unsymmetric sub-blocks too
            self._symmetric = _is_symmetric(sub)
        self.factorisations += 1
        return _factorise(sub, self._symmetric)

    def _cg(self, active: np.ndarray, rhs: np.ndarray, x0: np.ndarray | None, rtol: float | None) -> np.ndarray:
        # Plain CG on the SPD sub-matrix; the product is the FFT operator with the
        # inactive cells masked out on input and output.
        def A(x):
            v = np.zeros(self.n)
            v[active] = x
            return self.matvec(v)[active]

        x = np.zeros_like(rhs) if x0 is None else np.array(x0, dtype=float)
        r = rhs - A(x) if x0 is not None else rhs.copy()
        bnorm = np.linalg.norm(rhs)
        if bnorm == 0.0:
            return np.zeros_like(rhs)
        d = r.copy()
        rr = r @ r
        for _ in range(self.cg_max_iter):
            if np.sqrt(rr) <= (self.cg_rtol if rtol is None else rtol) * bnorm:
                break
            Ad = A(d)
            step = rr / (d @ Ad)
            x += step * d
            r -= step * Ad
            rr_new = r @ r
            d = r + (rr_new / rr) * d
            rr = rr_new
            self.cg_iterations += 1
        return x
