"""The pieces of Polonsky & Keer's iteration that depend on the constraints: projecting the
gap on the constraint basis, restoring the load (and moments) after a step, and the
residuals the stopping rule reads. Every function works row by row on (B, n) stacks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .plane import PlaneBasis


#: Rows up to this many cells take ``np.vecdot`` (numpy >= 2: least call overhead), longer
#: ones ``np.einsum`` (several times faster than ``vecdot`` on a million cells).
SHORT_ROW = 4096
_vecdot = getattr(np, "vecdot", None)
#: Normal equations of a constraint fit (:func:`fit`) up to this condition number are
#: solved (with one refinement step: about the rounding of ``lstsq``); beyond, ``lstsq``.
FIT_MAX_CONDITION = 1e10


def column(v: np.ndarray):
    """A per-row value ready to scale (B, n) rows: ``v[:, None]``, or the scalar itself for
    one row (numpy's broadcasting costs more than the product on small blocks)."""
    return v[0] if len(v) == 1 else v[:, None]


def row_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise inner products of (B, n) arrays."""
    if _vecdot is not None and a.shape[1] <= SHORT_ROW:
        return _vecdot(a, b)
    return np.einsum("bi,bi->b", a, b)


def project(
    v: np.ndarray,
    basis: np.ndarray,
    on: np.ndarray,
    count: np.ndarray | None = None,
    basis_t: np.ndarray | None = None,
    plane: PlaneBasis | None = None,
    loaded_only: bool = False,
) -> np.ndarray:
    """Remove from each row of ``v`` (in place) its least-squares fit by the columns of
    ``basis`` over the row's cells ``on``; return the coefficients (B, k). One column is
    taken to be constant: the fit is the mean over ``on`` (0 where ``on`` is empty;
    ``count``, if given, is ``max(on.sum(axis=1), 1)``). ``basis_t``: ``basis.T``
    contiguous, if the caller keeps it (:func:`fit`); ``plane``: the basis's separable
    form, if the caller gives it (:class:`~.plane.PlaneBasis`). ``loaded_only``: ``v`` is
    0 off ``on``, so on long rows its mean over ``on`` is its sum over ``count`` (the same
    sum, without :func:`masked_sum`'s masked copy)."""
    rows, k = v.shape[0], basis.shape[1]
    if k == 0:
        return np.zeros((rows, 0))
    if k == 1:
        count = np.maximum(on.sum(axis=1), 1) if count is None else count
        long_row = loaded_only and v.shape[1] > SHORT_ROW
        c = (np.einsum("bi->b", v) if long_row else masked_sum(v, on)) / count
        v -= column(c)
        return c[:, None]
    basis_t = np.ascontiguousarray(basis.T) if basis_t is None else basis_t
    c = fit(v, basis, on, basis_t, plane)
    for i in range(rows):
        if plane is not None:
            plane.subtract(v[i], c[i])
        else:
            v[i] -= c[i] @ basis_t
    return c


def masked_sum(v: np.ndarray, on: np.ndarray, scratch: np.ndarray | None = None) -> np.ndarray:
    """Per row, the sum of ``v`` over the cells ``on`` (a product and a sum: four times
    faster than ``np.add.reduce(..., where=on)`` on a million cells). On long rows ``on``
    may be the cells as 0/1 floats (the same product, twice as fast as by the bools);
    ``scratch``: a float array shaped like ``v`` the caller keeps for the product."""
    if v.shape[1] <= SHORT_ROW:
        return np.add.reduce(v, axis=1, where=on)
    return np.einsum("bi->b", np.multiply(v, on, out=scratch))


def row_count(on: np.ndarray) -> np.ndarray:
    """Per row, the number of true cells of a (B, n) bool array (``np.count_nonzero`` on
    each row: 2 against 10 us for ``on.sum(axis=1)`` on a row of 28,000 cells)."""
    if len(on) <= 4:
        return np.array([np.count_nonzero(row) for row in on], dtype=np.int64)
    return on.sum(axis=1)


def denominator(r: np.ndarray, t: np.ndarray, on: np.ndarray, count, basis, basis_t, plane, scratch=None) -> np.ndarray:
    """Per row, a step's ``t.A t`` projected on the constraints (the columns of ``basis``),
    from ``r = A t`` (``t`` 0 off the loaded cells ``on``; ``count`` their number per row
    under load control, and then ``on`` may be :func:`masked_sum`'s 0/1 floats, its
    product into ``scratch``)."""
    k = basis.shape[1]
    denom = row_dot(r, t)
    if k == 1:  # the projected product: r minus its mean over the loaded cells
        denom -= masked_sum(r, on, scratch) / count * t.sum(axis=1)
    elif k:  # (r - B c).t with c the fit of r over the loaded cells; B^T t by the plane's sums on long rows
        held = t @ basis_t.T if plane is None or t.shape[1] <= SHORT_ROW else np.array([plane.moments(v) for v in t])
        denom -= np.einsum("bk,bk->b", fit(r, basis, on, basis_t, plane), held)
    return denom


def fit(
    v: np.ndarray,
    basis: np.ndarray,
    on: np.ndarray,
    basis_t: np.ndarray | None = None,
    plane: PlaneBasis | None = None,
) -> np.ndarray:
    """Per row, the least-squares coefficients (B, k) of ``v`` by the columns of ``basis``
    over the cells ``on`` (``v`` unchanged). On long rows by the k x k normal equations and
    one step of iterative refinement, through ``basis_t`` (``basis.T`` contiguous; made
    here if not given): passes over the row instead of ``lstsq`` on a copy of the loaded
    cells' rows of ``basis`` (5 M cells: 130 against 190 ms, and 20 against 47 ms to
    subtract the fit); by ``lstsq`` on short rows and where the equations are
    ill-conditioned (fewer loaded cells than columns, or cells on a line). With ``plane``
    (:class:`~.plane.PlaneBasis`) by its sums along the grid's rows where well-conditioned."""
    rows, k = v.shape[0], basis.shape[1]
    c = np.zeros((rows, k))
    for i in range(rows):
        w = on[i]
        fitted = None if plane is None else plane.fit(v[i], w)
        if fitted is not None:
            c[i] = fitted
            continue
        if v.shape[1] > SHORT_ROW and np.count_nonzero(w) >= k:
            bt = np.ascontiguousarray(basis.T) if basis_t is None else basis_t
            masked = bt * w  # (k, n): the basis on the loaded cells, 0 elsewhere
            gram = masked @ bt.T
            if np.linalg.cond(gram) <= FIT_MAX_CONDITION:
                c[i] = np.linalg.solve(gram, masked @ v[i])
                c[i] += np.linalg.solve(gram, masked @ (v[i] - c[i] @ bt))  # the rounding's residual fitted again
                continue
        c[i] = np.linalg.lstsq(basis[w], v[i, w], rcond=1e-13)[0]
    return c


def restore(
    p: np.ndarray,
    basis: np.ndarray,
    target: np.ndarray,
    sweeps: int = 4,
    basis_t: np.ndarray | None = None,
    plane: PlaneBasis | None = None,
) -> np.ndarray | None:
    """Make ``B^T p = target`` on every row by ``p <- p * (B c)`` (in place), keeping
    ``p >= 0``. Returns the per-row factors when the correction was a constant (so ``A p``
    scales by them too), None when it was not (moments; by ``plane``'s sums if given)."""
    rows, k = p.shape[0], basis.shape[1]
    if k == 0:
        return np.ones(rows)
    if k == 1:
        # long rows without BLAS: OpenBLAS threads a long dot product, and its idle threads
        # then spin beside the FFTs (a rolling run took twice the CPU with its default threads)
        s = p @ basis[:, 0] if p.shape[1] <= SHORT_ROW else np.einsum("bi,i->b", p, basis[:, 0])
        f = target[:, 0] / s if (s > 0).all() else np.where(s > 0, target[:, 0] / np.where(s > 0, s, 1.0), 1.0)
        p *= column(f)
        return f
    for i in range(rows):
        if plane is not None:
            plane.restore(p[i], target[i], sweeps)
        else:
            _restore_plane(p[i], np.ascontiguousarray(basis.T) if basis_t is None else basis_t, target[i], sweeps)
    return None


def _restore_plane(p: np.ndarray, bt: np.ndarray, target: np.ndarray, sweeps: int) -> None:
    """:func:`restore` on one row with a plane ``c0 + c1 x + c2 y`` as factor, ``bt`` the
    basis transposed (``p`` is 0 off the loaded cells, so the weighted sums run over the
    whole row: 5 M cells, 135 against 220 ms with a copy of the loaded cells' rows)."""
    for _ in range(sweeps):
        M = (bt * p) @ bt.T
        p *= np.linalg.lstsq(M, target, rcond=1e-13)[0] @ bt
        if p.min() >= 0.0:
            return
        np.maximum(p, 0.0, out=p)


def kkt_residual(
    g: np.ndarray,
    g_on: np.ndarray,
    on: np.ndarray,
    free: np.ndarray | None,
    scale: np.ndarray,
    scratch: np.ndarray | None = None,
) -> np.ndarray:
    """Per row: largest |gap| on loaded cells and largest interpenetration elsewhere
    (cells in ``free``, if given, are not checked), over ``scale``. ``g_on`` is ``g`` on
    the loaded cells and 0 elsewhere. Without ``free``, the largest of the two is that of
    ``max g_on``, ``-min g`` over the whole row and 0: ``-min g_on`` is at most the larger
    of ``-min g`` and 0 (on the loaded cells the gap counts either way), the same number
    by two reductions instead of three and a pass. With ``free``, ``g - g_on`` is the gap
    off the loaded cells and 0 on them, one pass (``np.where(on, 0, g)`` with an ``on |
    free`` pass before it: 0.34 against 0.13 ms on a row of 218,000 cells). ``scratch``:
    an array shaped like ``g`` the caller keeps for it, else one is made. ``free`` may also
    be the flat indices of its cells in the (B, n) rows (:func:`free_cells`): a few cells
    zeroed by index, not a pass of the mask (a box whose 180 free cells of 356,000 took a
    0.27 ms ``putmask`` a check)."""
    if free is None:
        return np.maximum(np.maximum(g_on.max(axis=1), -g.min(axis=1)), 0.0) / scale
    worst_on = np.maximum(g_on.max(axis=1), -g_on.min(axis=1))
    off = np.subtract(g, g_on, out=scratch)
    if free.dtype == bool:
        np.putmask(off, free, 0.0)
    else:
        off.reshape(-1)[free] = 0.0
    return np.maximum(np.maximum(worst_on, -off.min(axis=1)), 0.0) / scale


#: Free cells (:func:`kkt_residual`) up to this fraction of the rows' cells are zeroed by index.
FREE_BY_INDEX = 1 / 16


def free_cells(free: np.ndarray) -> np.ndarray:
    """``free`` (a (B, n) bool array) as :func:`kkt_residual` takes it fastest: the flat
    indices of its cells when they are few (:data:`FREE_BY_INDEX`), else itself."""
    count = np.count_nonzero(free)
    return np.flatnonzero(free) if count <= FREE_BY_INDEX * free.size else free


def constraint_residual(
    p: np.ndarray, basis: np.ndarray, target: np.ndarray, basis_scale: np.ndarray, plane: PlaneBasis | None = None
) -> np.ndarray:
    """Per row: relative violation of the load and moment constraints (0 with fewer than
    two constraints or no load: restored exactly); ``B^T p`` by ``plane``'s sums if given."""
    if basis.shape[1] < 2:
        return np.zeros(len(p))
    held = p @ basis if plane is None else np.array([plane.moments(row) for row in p])
    viol = np.abs(held - target) / (np.maximum(target[:, :1], 1e-300) * np.maximum(basis_scale, 1e-300))
    return np.where(target[:, 0] > 0, viol.max(axis=1), 0.0)
