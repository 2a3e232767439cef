"""The stones' dense block inverses for :mod:`.blocks`: afresh by size class
(:func:`fresh_blocks`), updated from a kept one when a few cells changed (:func:`updated`),
and stacked by size class in float32 for the batched products (:func:`stacked`)."""

from __future__ import annotations

import functools

import numpy as np
from scipy.linalg import lapack

#: A stone's kept inverse is updated (:func:`updated`) when the cells it gained and lost
#: are at most this fraction of its cells and it has at least :data:`UPDATE_MIN_CELLS`
#: (smaller blocks cost less afresh than the update's steps).
UPDATE_CELLS = 0.25
UPDATE_MIN_CELLS = 96
#: Block sizes the inverses are padded to and applied by, a batched product per size
#: (:func:`stacked`): steps of 8 cells, ~1.3x apart past 64 (the padding costs at most
#: ~1.7x the products' work; a product per stone cost ~6 us of Python each, 250 stones).
SIZE_CLASSES = np.array([8, 16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256, 320, 384, 448, 512, 600])


def fresh_blocks(entries: np.ndarray, centre: int, flats: list) -> list:
    """The inverses (:func:`spd_inverse`) of the blocks of cells ``flats`` (the operator's
    entries ``entries[centre + flat_i - flat_j]``), full and zero-padded to their size class,
    and their row sums: each block gathered and inverted on its own cells, written into its
    class's zero stack, the stack's lower triangles mirrored from the upper ones and its
    rows summed in one pass each (the blocks gathered padded by class, the triangles by
    ``np.triu`` and the sums by BLAS ``symv`` a block cost ~1.8x the LAPACK calls: 149
    blocks of 40 cells on average, ~18 against ~9 ms)."""
    sizes = np.array([f.size for f in flats], dtype=np.int64)
    classes = size_class(sizes)
    out: list = [None] * len(flats)
    for c in np.unique(classes).tolist():
        members = np.flatnonzero(classes == c).tolist()
        padded = np.zeros((len(members), c, c))
        for k, m in enumerate(members):
            f = flats[m]
            padded[k, : f.size, : f.size] = spd_inverse(entries[centre + f[:, None] - f[None, :]])
        lower, upper = _triangles(c)  # (potri's lower triangle is not the inverse's)
        flat = padded.reshape(len(members), c * c)
        flat[:, lower] = flat[:, upper]
        sums = padded.sum(axis=2)  # (the padding's rows and columns 0)
        for k, m in enumerate(members):
            out[m] = (padded[k], sums[k, : flats[m].size])
    return out


@functools.lru_cache(maxsize=len(SIZE_CLASSES))
def _triangles(c: int) -> tuple[np.ndarray, np.ndarray]:
    """The flat places of a ``c x c`` block's strictly lower triangle and of their mirror
    images in the upper one."""
    i, j = np.tril_indices(c, -1)
    return i * c + j, j * c + i


def updated(old: np.ndarray, inverse: np.ndarray, keys: np.ndarray, flat: np.ndarray, entries: np.ndarray, centre: int):
    """The inverse on the cells ``keys`` from ``inverse`` (padded) on the cells ``old`` (both
    sorted road places) when they differ by few cells (:data:`UPDATE_CELLS`): the cells
    lost taken out by the Schur complement of the inverse (``B_KK - B_KL B_LL^-1 B_LK``, as
    ``B_KK - Y Y^T`` with ``Y = B_KL C``, ``C C^T = B_LL^-1``: symmetric as it is made), the
    cells gained bordered in (``S = A_NN - A_NK B A_KN``, the inverse ``[[B + X S^-1 X^T,
    -X S^-1], [-S^-1 X^T, S^-1]]`` with ``X = B A_KN``): ``O(n^2)`` per cell against
    ``O(n^3)`` afresh (``entries[centre + flat_i - flat_j]``: the operator's entries).
    The kept cells' rows and columns are copied as the blocks between the lost (gained)
    ones, a slice each (fancy indices and ``np.delete`` copied the inverse ~8 times: ~130
    cells, 1-2 lost and gained, ~450 against ~230 us). None when the change is too large or
    the blocks too small to gain."""
    n_old, n = old.size, keys.size
    if min(n_old, n) < UPDATE_MIN_CELLS:
        return None
    kept = keys[np.minimum(np.searchsorted(keys, old), n - 1)] == old
    new = old[np.minimum(np.searchsorted(old, keys), n_old - 1)] != keys
    lost, gained = n_old - np.count_nonzero(kept), np.count_nonzero(new)
    if lost + gained > UPDATE_CELLS * n_old:
        return None
    b = inverse[:n_old, :n_old]
    if lost:
        L = np.flatnonzero(~kept)
        b_kl = np.delete(b[:, L], L, axis=0)
        if lost == 1:  # (one cell, the common case: B_LL a number)
            b_kl /= np.sqrt(b[L[0], L[0]])
        else:
            b_kl = b_kl @ np.linalg.cholesky(np.linalg.inv(inverse[np.ix_(L, L)]))
        b = _without(b, L)
        b -= b_kl @ b_kl.T
    out = np.zeros((int(size_class(n)),) * 2)
    if not gained:  # (the kept cells are all the cells, in their order)
        out[:n, :n] = b
        return out, out[:n, :n].sum(axis=1)
    N = np.flatnonzero(new)
    place = np.flatnonzero(~new)  # the kept cells' places among ``keys``
    a_kn = entries[centre + flat[place][:, None] - flat[N][None, :]]
    a_nn = entries[centre + flat[N][:, None] - flat[N][None, :]]
    x = b @ a_kn
    s_inv = np.linalg.inv(a_nn - a_kn.T @ x)
    xs = x @ s_inv
    inner = xs @ x.T
    inner += b
    _around(inner, out, N)
    out[place[:, None], N], out[N[:, None], place], out[N[:, None], N] = -xs, -xs.T, s_inv
    return out, out[:n, :n].sum(axis=1)


def _without(a: np.ndarray, gone: np.ndarray) -> np.ndarray:
    """The square ``a`` without its rows and columns ``gone`` (sorted places): a slice copy
    for each pair of the runs between them."""
    runs = _runs(gone, len(a))
    out = np.empty((len(a) - len(gone),) * 2)
    for r0, r1, i in runs:
        for c0, c1, j in runs:
            out[i : i + r1 - r0, j : j + c1 - c0] = a[r0:r1, c0:c1]
    return out


def _around(a: np.ndarray, out: np.ndarray, new: np.ndarray) -> None:
    """The square ``a`` written into ``out``'s leading block of ``len(a) + len(new)`` rows and
    columns around its rows and columns ``new`` (sorted places; left as they are)."""
    runs = _runs(new, len(a) + len(new))
    for r0, r1, i in runs:
        for c0, c1, j in runs:
            out[r0:r1, c0:c1] = a[i : i + r1 - r0, j : j + c1 - c0]


def _runs(out: np.ndarray, total: int) -> list:
    """The runs of ``range(total)`` between the sorted places ``out``: ``(start, stop, its
    start among the places left)``."""
    runs, prev = [], 0
    for i, o in enumerate(out.tolist()):
        if o > prev:
            runs.append((prev, o, prev - i))
        prev = o + 1
    if total > prev:
        runs.append((prev, total, prev - len(out)))
    return runs


def spd_inverse(block: np.ndarray) -> np.ndarray:
    """The inverse of a symmetric positive definite ``block`` by Cholesky (LAPACK potrf and
    potri: half the time of numpy's LU inverse on the tyre's blocks), valid in its upper
    triangle only (read by BLAS ``symv``)."""
    factor, info = lapack.dpotrf(block, lower=False, overwrite_a=True)
    if info == 0:
        inv, info = lapack.dpotri(factor, lower=False, overwrite_c=True)
        if info == 0:
            return inv
    raise np.linalg.LinAlgError(f"a stone's block is not positive definite (LAPACK info {info})")


def size_class(counts):
    """The padded size (:data:`SIZE_CLASSES`) of blocks of ``counts`` cells."""
    return SIZE_CLASSES[np.searchsorted(SIZE_CLASSES, counts)]


def stacked(inverses: list, starts: np.ndarray, counts: np.ndarray) -> list:
    """The stones' padded inverses (:meth:`StoneBlocks.inverses`) stacked by size class in
    float32 (a preconditioner: it shapes the search directions only), each ``(k, c, c)``
    with the ``(k, c)`` places of its cells in the contact's cell order (the padding at
    place ``sum(counts)``, a slot holding 0)."""
    size = np.array([len(inv) for inv in inverses], dtype=np.int64)
    total = int(counts.sum())
    out = []
    for c in np.unique(size).tolist():
        members = np.flatnonzero(size == c)
        stack = np.stack([inverses[m] for m in members.tolist()], dtype=np.float32)
        j = np.arange(c)
        pos = np.where(j[None, :] < counts[members][:, None], starts[members][:, None] + j[None, :], total)
        out.append((stack, pos))
    return out
