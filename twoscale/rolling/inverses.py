"""The stones' dense block inverses for :mod:`.blocks`: afresh by size class
(:func:`fresh_blocks`), updated from a kept one when a few cells changed (:func:`updated`),
and stacked by size class in float32 for the batched products (:func:`stacked`)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import blas, lapack

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
    and their row sums: the entries gathered and the inverses mirrored by size class, one
    pass each (a block at a time cost about as much again as its LAPACK calls)."""
    sizes = np.array([f.size for f in flats], dtype=np.int64)
    classes = size_class(sizes)
    out: list = [None] * len(flats)
    for c in np.unique(classes).tolist():
        members = np.flatnonzero(classes == c)
        cells = np.zeros((members.size, c), dtype=np.int64)  # (the padding: cell 0, an entry in range)
        cells[np.arange(c)[None, :] < sizes[members][:, None]] = np.concatenate([flats[m] for m in members.tolist()])
        blocks = entries[centre + cells[:, :, None] - cells[:, None, :]]
        padded = np.zeros_like(blocks)
        sums = []
        for k, n in enumerate(sizes[members].tolist()):
            inv = spd_inverse(blocks[k, :n, :n])
            padded[k, :n, :n] = inv
            sums.append(blas.dsymv(1.0, inv, np.ones(n)))
        upper = np.triu(padded, 1)  # (the upper triangle mirrored: potri's lower one is not the inverse's)
        padded = np.triu(padded)
        padded += upper.transpose(0, 2, 1)
        for k, m in enumerate(members.tolist()):
            out[m] = (padded[k], sums[k])
    return out


def updated(old: np.ndarray, inverse: np.ndarray, keys: np.ndarray, flat: np.ndarray, entries: np.ndarray, centre: int):
    """The inverse on the cells ``keys`` from ``inverse`` (padded) on the cells ``old`` (both
    sorted road places) when they differ by few cells (:data:`UPDATE_CELLS`): the cells
    lost taken out by the Schur complement of the inverse (``B_KK - B_KL B_LL^-1 B_LK``, as
    ``B_KK - Y Y^T`` with ``Y = B_KL C``, ``C C^T = B_LL^-1``: symmetric as it is made), the
    cells gained bordered in (``S = A_NN - A_NK B A_KN``, the inverse ``[[B + X S^-1 X^T,
    -X S^-1], [-S^-1 X^T, S^-1]]`` with ``X = B A_KN``): ``O(n^2)`` per cell against
    ``O(n^3)`` afresh (``entries[centre + flat_i - flat_j]``: the operator's entries).
    None when the change is too large or the blocks too small to gain."""
    n_old, n = old.size, keys.size
    if min(n_old, n) < UPDATE_MIN_CELLS:
        return None
    kept = keys[np.minimum(np.searchsorted(keys, old), n - 1)] == old
    new = old[np.minimum(np.searchsorted(old, keys), n_old - 1)] != keys
    if (n_old - np.count_nonzero(kept)) + np.count_nonzero(new) > UPDATE_CELLS * n_old:
        return None
    K, L, N = np.flatnonzero(kept), np.flatnonzero(~kept), np.flatnonzero(new)
    b = inverse[:n_old, :n_old]
    if L.size:  # (rows and columns taken out as blocks: a 2-d fancy index costs ~3x)
        b_kl = np.delete(b[:, L], L, axis=0)
        if L.size == 1:  # (one cell, the common case: B_LL a number)
            b_kl /= np.sqrt(b[L[0], L[0]])
        else:
            b_kl = b_kl @ np.linalg.cholesky(np.linalg.inv(inverse[np.ix_(L, L)]))
        b = np.delete(np.delete(b, L, axis=0), L, axis=1)
        b -= b_kl @ b_kl.T
    out = np.zeros((int(size_class(n)),) * 2)
    if N.size:
        place = np.searchsorted(keys, old[K])  # the kept cells' places among ``keys``
        a_kn = entries[centre + flat[place][:, None] - flat[N][None, :]]
        a_nn = entries[centre + flat[N][:, None] - flat[N][None, :]]
        x = b @ a_kn
        s_inv = np.linalg.inv(a_nn - a_kn.T @ x)
        xs = x @ s_inv
        # the kept cells first, the gained ones after, then put in the cells' order by one
        # permutation (np.insert of rows and columns copied the whole inverse three times)
        whole = np.empty((n, n))
        k = K.size
        np.matmul(xs, x.T, out=whole[:k, :k])
        whole[:k, :k] += b
        whole[:k, k:], whole[k:, :k], whole[k:, k:] = -xs, -xs.T, s_inv
        order = np.empty(n, dtype=np.int64)
        order[place], order[N] = np.arange(k), np.arange(k, n)
        out[:n, :n] = whole[order][:, order]
    else:  # (the kept cells are all the cells, in their order)
        out[:n, :n] = b
    return out, out[:n, :n].sum(axis=1)


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
