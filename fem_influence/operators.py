"""Grid-level pieces of the finite-block provider (:mod:`fem_influence.provider`).

* :func:`lagrange_1d`: the cubic Lagrange stencil that interpolates the correction in
  the source point from its lattice, and :func:`point_weights` its weights for points;
* :class:`TargetFactor`: the correction at a grid's cells from lattice nodes, kept as
  the sparse top-face interpolation times the field table (not the dense ``U``);
* :class:`BlockGridOperator`: a grid product, half-space FFT convolution plus the
  low-rank correction ``h^2 U (W p)`` (on large grids ``U`` and ``W`` separable,
  :mod:`fem_influence.grid_factors`), and its float32 form;
* :class:`BlockPointOperator`: sums of point forces, the half-space's fast operator plus
  the same low-rank correction.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from twoscale.influence.base import GridOperator
from twoscale.influence.points import PointOperator

from .cell_product import BlockCellProduct

if TYPE_CHECKING:
    from .provider import BlockProvider


def lagrange_1d(x: np.ndarray, d: float, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Lagrange stencil on the lattice ``d * [lo..hi]``: indices and weights, (N, 4) each."""
    n = min(4, hi - lo + 1)
    i0 = np.floor(x / d).astype(int) - (n // 2 - 1)
    i0 = np.clip(i0, lo, hi - n + 1)
    idx = i0[:, None] + np.arange(n)[None, :]
    return idx, lagrange_weights(np.asarray(x, dtype=float), idx * d)


def lagrange_weights(x: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Lagrange weights (N, n) of the points ``x`` (N,) on their stencils ``nodes`` (N, n):
    ``w[:, m]`` the product over ``k != m`` of ``(x - nodes[:, k]) / (nodes[:, m] - nodes[:, k])``
    in ascending ``k``, all ``m`` at once for each ``k`` (the factor for ``k == m`` is
    exactly 1: the same numbers as the product made column by column)."""
    n = nodes.shape[1]
    w = np.ones_like(nodes, dtype=float)
    for k in range(n):
        num = np.repeat((x - nodes[:, k])[:, None], n, axis=1)
        den = nodes - nodes[:, k : k + 1]
        num[:, k] = den[:, k] = 1.0
        w *= num / den
    return w


#: Up to this many points, the last set of sources' weights is kept on the provider (one
#: entry): the macro step's operator error check asks for the loaded tips' compliance sixteen
#: rows at a time (2,253 loaded tips of 9,545 on a block: their weights made sixteen times,
#: 0.06 of the check's 0.11 s).
KEPT_POINT_WEIGHTS = 20_000


def point_weights(provider: "BlockProvider", sources: np.ndarray):
    """The lattice nodes ``(i, j)`` (K, 2) around ``sources`` (scene frame, (N, 2)) and
    the sparse source-interpolation weights (K, N) onto them, tensor cubic Lagrange
    (the points checked to lie in the answered region first). The last set's answer is
    kept (``KEPT_POINT_WEIGHTS``; the callers only read it)."""
    S = np.asarray(sources, dtype=float).reshape(-1, 2)
    memo = provider._state.grid_memo
    kept = memo.get(("points",))
    if kept is not None and kept[0].shape == S.shape and np.array_equal(kept[0], S):
        return kept[1]
    out = _point_weights(provider, S)
    if len(S) <= KEPT_POINT_WEIGHTS:
        memo[("points",)] = (S.copy(), out)
    return out


def _point_weights(provider: "BlockProvider", sources: np.ndarray):
    provider.check_answered(sources)
    d = provider.source_spacing
    S = np.asarray(sources, dtype=float).reshape(-1, 2) + np.asarray(provider.origin)
    x0, x1, y0, y1 = provider._lattice_bounds()
    ix, wx = lagrange_1d(S[:, 0], d, x0, x1)
    iy, wy = lagrange_1d(S[:, 1], d, y0, y1)
    nx = x1 - x0 + 1
    lin = ((iy[:, None, :] - y0) * nx + (ix[:, :, None] - x0)).reshape(len(S), -1)  # (N, 16)
    Wt = (wx[:, :, None] * wy[:, None, :]).reshape(len(S), -1)
    used, inv = np.unique(lin, return_inverse=True)
    cols = np.repeat(np.arange(len(S)), lin.shape[1])
    W = sp.csr_matrix((Wt.ravel(), (inv.ravel(), cols)), shape=(len(used), len(S)))
    nodes = np.column_stack([used % nx + x0, used // nx + y0])
    return nodes, W


class TargetFactor:
    """``U = M T``: the correction (mm/N) at ``M``'s points from the lattice nodes of the
    columns of ``T`` (top-face node values, already divided by E), ``M`` the sparse
    top-face interpolation (9 entries a point; ``None``: ``T`` is ``U`` itself, for meshes
    whose top face is not rectilinear). Kept factored: the dense ``U`` of one patch is
    its cells x ~500 lattice nodes (4.2 kB a cell; 2,799 tips on the block held 4.7 GB of
    them), ``M`` 108 bytes a cell and ``T`` one table shared by every grid."""

    def __init__(self, M, T: np.ndarray):
        self.M, self.T = M, T

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        if x.ndim == 1:  # summed coefficients of a few near sources: the columns they touch
            nz = np.flatnonzero(x)
            if 2 * len(nz) < len(x):
                u = self.T[:, nz] @ x[nz]
                return u if self.M is None else self.M @ u
        return self.T @ x if self.M is None else self.M @ (self.T @ x)

    @property
    def nbytes(self) -> int:
        M = self.M
        m = 0 if M is None else M.data.nbytes + M.indices.nbytes + M.indptr.nbytes if sp.issparse(M) else M.nbytes
        return m + self.T.nbytes

    @property
    def flops(self) -> float:
        """Multiply-adds of one product with one vector, doubled."""
        return 2.0 * (
            self.T.size + (0 if self.M is None else self.M.size if isinstance(self.M, np.ndarray) else self.M.nnz)
        )


class BlockGridOperator(GridOperator):
    """Half-space FFT convolution plus the low-rank correction ``h^2 U (W p)``.

    Its float32 form (:meth:`single_precision`) is the half-space part's float32 FFTs with
    the same correction in float64 (a few per cent of a product); its :meth:`columns` the
    half-space's columns plus the correction of the changed cells, one pass over the target.
    """

    def __init__(self, halfspace_op: GridOperator, U, W, area: float):
        self.target, self.source = halfspace_op.target, halfspace_op.source
        self._hs, self._U, self._W, self._area = halfspace_op, U, W, area

    def apply(self, p: np.ndarray) -> np.ndarray:
        u = self._hs.apply(p)
        corr = self._U @ (self._W @ np.asarray(p, dtype=float).ravel())  # (a new array: scaled and summed in place)
        corr *= self._area
        corr = corr.reshape(self.target.shape)
        corr += u
        return corr

    def single_precision(self) -> "BlockGridOperator":
        single = self._hs.single_precision()
        return self if single is self._hs else BlockGridOperator(single, self._U, self._W, self._area)

    def on_cells(self, cells: np.ndarray | None):
        """:meth:`apply` on the flat ``cells`` (None: every cell) and in two halves
        (:class:`~fem_influence.cell_product.BlockCellProduct`) where the half-space part has
        such a product (its float32 form); else None."""
        own = getattr(self._hs, "on_cells", None)
        halfspace = None if own is None else own(cells)
        if halfspace is None or not hasattr(halfspace, "forward"):
            return None
        return BlockCellProduct(halfspace, self._U, self._W, self._area, cells, self.target.shape)

    def columns(self, targets: np.ndarray | None = None):
        """:meth:`GridOperator.columns`: the half-space part's, plus ``h^2 U (W[:, cells] v)``
        (with ``targets``, on those flat target cells only)."""
        add_hs = self._hs.columns(targets)
        if add_hs is None:
            return None
        U = self._U if targets is None else _rows(self._U, np.asarray(targets))

        def add(out: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
            add_hs(out, cells, values)
            W = self._W
            c = W.times_cells(cells, values) if hasattr(W, "times_cells") else W[:, cells] @ values
            out += self._area * (U @ np.asarray(c).ravel()).ravel()

        return add

    def preconditioner(self):
        """The half-space part's preconditioner: the correction is smooth and of low rank,
        so the half-space kernel's inverse is as close to this operator's inverse as the
        CG needs (the preconditioned CG stays exact: only its iteration count changes)."""
        return self._hs.preconditioner()

    def coarse_table(self):
        """The half-space part's offset table (``GridOperator.coarse_table``): a coarse space's
        matrix and products from it leave the balancing preconditioner symmetric positive
        definite; the correction only changes how close it is to this operator."""
        return self._hs.coarse_table()

    @property
    def nbytes(self) -> int:
        W = self._W
        w = W.data.nbytes if sp.issparse(W) else W.nbytes
        return int(self._hs.nbytes) + self._U.nbytes + w

    @property
    def flops_estimate(self) -> float:
        W = self._W
        w = getattr(W, "flops", None) or 2.0 * (W.nnz if sp.issparse(W) else W.size)
        return self._hs.flops_estimate + self._U.flops + w


class BlockPointOperator(PointOperator):
    """Point forces on the block: the half-space's operator (fast above its size, the
    Ewald split) plus the correction ``U_t (W_s F)`` (``U_t`` :class:`TargetFactor` at the
    targets, ``W_s`` the sources' lattice weights), less the correction of the pairs left
    out (``exclude`` and coincident points, which contribute nothing by the contract).
    The default operator evaluated every pair's compliance on every product: 18,792
    far-field points of 2,088 patches, 353 M kernel values a sweep.

    Parameters
    ----------
    halfspace_op : PointOperator
        The half-space part with the same targets, sources and exclusions.
    U : TargetFactor
        Correction at the targets from the lattice nodes (mm/N).
    W : sparse (K, N)
        Source-interpolation weights onto those nodes.
    left_out : sparse (M, N)
        The pairs whose correction is subtracted again (pattern only).
    """

    def __init__(self, halfspace_op: PointOperator, U: TargetFactor, W, left_out):
        self.targets, self.sources = halfspace_op.targets, halfspace_op.sources
        self._hs, self._U, self._W = halfspace_op, U, sp.csr_matrix(W)
        self._out = _sampled_product(U, sp.csc_matrix(W), sp.csr_matrix(left_out).tocoo())

    def apply(self, forces):
        F = self._check_forces(forces)
        return self._hs.apply(F) + self._U @ (self._W @ F) - self._out @ F


def _sampled_product(U: TargetFactor, W, pattern, rows: int = 2048):
    """``(U W)`` at the entries of ``pattern`` only, as a CSR matrix (M, N): the rows of
    ``U`` are formed ``rows`` at a time, each entry the dot product of its row with the
    column of ``W`` (a source's 16 stencil weights)."""
    i, j = pattern.row.astype(np.int64), pattern.col.astype(np.int64)
    return sp.csr_matrix((_sampled_values(U, W, i, j, rows), (i, j)), shape=pattern.shape)


def _sampled_values(U: TargetFactor, W, i: np.ndarray, j: np.ndarray, rows: int = 2048) -> np.ndarray:
    """``(U W)[i, j]`` for the entries ``(i, j)`` (``i`` ascending, ``W`` CSC), as
    :func:`_sampled_product`."""
    per = np.diff(W.indptr)
    m = int(i[-1]) + 1 if len(i) else 0
    if len(per) and (per == per[0]).all():
        return _uniform_values(U, W, i, j, int(per[0]), m, rows)
    counts = per[j]
    entry = np.repeat(np.arange(len(i)), counts)
    offset = np.arange(len(entry)) - np.repeat(np.cumsum(counts) - counts, counts)
    pos = np.repeat(W.indptr[j], counts) + offset
    node, weight, row = W.indices[pos], W.data[pos], i[entry]  # rows ascending (CSR order)
    vals = np.zeros(len(entry))
    cuts = np.searchsorted(row, np.arange(0, m + rows, rows))
    for r0, a, b in zip(range(0, m, rows), cuts[:-1], cuts[1:]):
        if b > a:
            block = U.T[r0 : r0 + rows] if U.M is None else np.asarray(U.M[r0 : r0 + rows] @ U.T)
            vals[a:b] = block[row[a:b] - r0, node[a:b]] * weight[a:b]
    return np.bincount(entry, weights=vals, minlength=len(i))


def _uniform_values(U: TargetFactor, W, i: np.ndarray, j: np.ndarray, s: int, m: int, rows: int) -> np.ndarray:
    """:func:`_sampled_values` where every source has ``s`` stencil nodes (16 inside the
    lattice): the entries' nodes as an (n, s) table, not repeated index arrays, summed in
    the stencil's order (the same sums as the bincount's)."""
    pos = W.indptr[j][:, None] + np.arange(s)
    node, weight = W.indices[pos], W.data[pos]
    out = np.zeros(len(i))
    cuts = np.searchsorted(i, np.arange(0, m + rows, rows))
    for r0, a, b in zip(range(0, m, rows), cuts[:-1], cuts[1:]):
        if b > a:
            block = U.T[r0 : r0 + rows] if U.M is None else np.asarray(U.M[r0 : r0 + rows] @ U.T)
            v = block[(i[a:b] - r0)[:, None], node[a:b]] * weight[a:b]
            acc = out[a:b]
            for q in range(s):
                acc += v[:, q]
    return out


def pair_compliance(provider: "BlockProvider", points: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """``provider.point_compliance(points, points)[i, j]`` for the pairs ``(i, j)`` alone
    (mm/N): Boussinesq's plus the correction of the pairs by :func:`_sampled_values`, not
    a row of every pair per point (the coarse step's near pairs of 5,930 tips: 4,527
    calls, 16 s profiled)."""
    from twoscale.analytic.halfspace import boussinesq_point

    P = np.asarray(points, dtype=float).reshape(-1, 2)
    i, j = np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64)
    order = np.argsort(i, kind="stable")
    nodes, W = provider._weights(P)
    cols, st = provider._ensure(nodes), provider._state  # the first fields make the interpolator
    if not st.interpolator.rectilinear:
        C = np.array([provider.correction(P[a : a + 1], P[b : b + 1])[0, 0] for a, b in zip(i, j)])
    else:
        T = st.table[:, cols] / provider.material.E
        U = TargetFactor(st.interpolator.matrix(P + np.asarray(provider.origin)), T)
        C = np.empty(len(i))
        C[order] = _sampled_values(U, sp.csc_matrix(W), i[order], j[order])
    return boussinesq_point(np.hypot(*(P[i] - P[j]).T), provider.material.E_star) + C


def block_point_operator(provider: "BlockProvider", targets: np.ndarray, sources: np.ndarray, exclude, rtol: float):
    """:class:`BlockPointOperator` of ``provider`` (the arguments of
    :meth:`~twoscale.influence.base.InfluenceProvider.point_operator`, checked)."""
    from scipy.spatial import cKDTree

    from twoscale.influence.points import check_exclude

    hs = provider._halfspace.point_operator(targets, sources, exclude=exclude, rtol=rtol)
    nodes, W = provider._weights(sources)
    cols = provider._ensure(nodes)
    st = provider._state
    T = st.table[:, cols] / provider.material.E
    P = targets + np.asarray(provider.origin)
    U = TargetFactor(st.interpolator.matrix(P), T) if st.interpolator.rectilinear else TargetFactor(None, None)
    if U.T is None:
        U = TargetFactor(None, provider._top_values(targets, nodes))
    scale = 1.0 + float(np.max(np.abs(np.concatenate([targets, sources])), initial=0.0))
    near = cKDTree(targets).query_ball_tree(cKDTree(sources), 1e-12 * scale)
    rows = np.repeat(np.arange(len(targets)), [len(c) for c in near])
    same = sp.csr_matrix((np.ones(len(rows)), (rows, np.concatenate(near + [[]]).astype(np.int64))), hs.shape)
    left_out = same if exclude is None else same + check_exclude(exclude, *hs.shape)
    return BlockPointOperator(hs, U, W, left_out)


class _GatheredRows:
    """The rows ``targets`` of a target factor that cannot be indexed (a
    :class:`~fem_influence.grid_factors.GridTarget`: separable interpolation): its product
    with coefficients on the whole grid, then those rows (the kernel's columns on a part
    of the grid, a few changed cells at a time)."""

    def __init__(self, factor, targets: np.ndarray):
        self.factor, self.targets = factor, targets

    def __matmul__(self, c: np.ndarray) -> np.ndarray:
        return (self.factor @ c)[self.targets]


def _rows(factor, targets: np.ndarray):
    """``factor[targets]`` (a dense or sparse factor's rows), or :class:`_GatheredRows`."""
    return factor[targets] if hasattr(factor, "__getitem__") else _GatheredRows(factor, targets)
