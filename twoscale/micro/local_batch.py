"""Paper eq. 7's first active-set pass on many dense blocks together.

:func:`.local.initial_pressure` solves, on each dense block, ``A_SS [x1 x2] = [1 z]`` on
Hertz's contact ``S``, sets the shift from the force and checks the signs and the gaps; most
of its cost on blocks of 41-266 cells whose contact holds ~16 cells is per-call Python
(1,013 blocks: ~0.4 ms a block). Here that first pass runs on stacks of blocks whose contact
sizes share a class: the padded systems (the identity on the padding, which leaves each
block's own system and Cholesky factor as they are) factorised and solved in one call a
class, the shifts, pressures and sign checks over the stack. A block whose first pass is
final gives its pressure; the others go on in the one-block loop from the active set the
pass leaves (the same rules). Each block keeps the factor of its contact, as the one-block
pass would have made it, for the sweeps that start there.
"""

from __future__ import annotations

import numpy as np

from .localblock import COLUMNS_MAX_ENTRIES

#: Stack classes: a block's contact size is padded to the first of these at or above it.
CLASSES = (8, 16, 32, 64, 128, 256, 512)
#: Bytes of one stack's arrays (its systems, factors and solutions, ``3 m^2`` numbers a
#: block, and the blocks' active columns, ``n m``): a class of more blocks goes in several
#: stacks. Unbounded, 4,128 blocks of one class held ~0.8 GB at once.
STACK_BYTES = 32 << 20


def hertz_contact(z: np.ndarray, approach: float) -> np.ndarray:
    """The first active set of eq. 7: Hertz's contact ``z - min z < approach / 2``, else
    the lowest cells."""
    zmin = float(z.min())
    active = (z - zmin) < 0.5 * max(approach, 0.0)
    return active if active.any() else z == zmin


def batchable(block) -> bool:
    """A dense block whose own entries come from its box window (a translation-invariant
    kernel, or the finite block's kept factors) and whose matrix is not stored."""
    return bool(block.dense and block.n and block._matrix is None and block._box_window() is not None)


def first_passes(blocks, z: list, forces: list, approaches: list, h: float, *, gap_rtol: float = 1e-12) -> dict:
    """Eq. 7's first pass on ``blocks`` (all :func:`batchable`, positive forces): ``{i:
    ("done", pressure)}`` where it is final, ``{i: ("next", active, removed, seen)}`` where
    the one-block loop goes on (``i`` indexes ``blocks``)."""
    actives = [hertz_contact(zk, a) for zk, a in zip(z, approaches)]
    sizes = np.array([int(a.sum()) for a in actives])
    cls = np.searchsorted(CLASSES, sizes)
    out: dict = {}
    for c in np.unique(cls).tolist():
        which = np.flatnonzero(cls == c).tolist()
        if c >= len(CLASSES):
            continue  # left to the one-block loop
        m = CLASSES[c]
        for part in _stacks(which, [8 * (3 * m * m + blocks[k].n * m) for k in which]):
            out.update(_class_pass(blocks, z, forces, h, actives, part, m, gap_rtol))
    return out


def _stacks(which: list, nbytes: list) -> list:
    """``which`` cut in runs whose ``nbytes`` add up to at most ``STACK_BYTES`` (one
    block at least a run)."""
    runs: list = [[]]
    total = 0
    for k, b in zip(which, nbytes):
        if runs[-1] and total + b > STACK_BYTES:
            runs.append([])
            total = 0
        runs[-1].append(k)
        total += b
    return runs


def _class_pass(blocks, z, forces, h, actives, which: list, m: int, gap_rtol: float) -> dict:
    """:func:`first_passes` on the blocks ``which``, whose contacts hold at most ``m`` cells."""
    B = len(which)
    A = np.zeros((B, m, m))
    R = np.zeros((B, m, 2))
    sizes = np.zeros(B, dtype=np.int64)
    columns = []
    for i, k in enumerate(which):
        blk, S = blocks[k], actives[k]
        C = blk._entries(blk._idx, blk._idx[S])  # A[:, S]: its rows S are A_SS
        s = C.shape[1]
        A[i, :s, :s] = C[S]
        R[i, :s, 0] = 1.0
        R[i, :s, 1] = z[k][S]
        sizes[i] = s
        columns.append(C)
    pad = np.arange(m)[None, :] >= sizes[:, None]
    A[:, np.arange(m), np.arange(m)] += pad  # the identity on the padding
    # exactly symmetric entries: each block keeps its Cholesky factor; else (the finite
    # block's) the solves alone, and a block factorises its final set itself
    exact = all(blocks[k]._box_window().symmetric for k in which)
    try:
        L = np.linalg.cholesky(A) if exact else None
        X = np.linalg.solve(A, R)
    except np.linalg.LinAlgError:
        return {}  # a block not positive definite: the one-block loop decides
    target = np.array([forces[k] for k in which]) / (h * h)
    shift = (target + X[:, :, 1].sum(axis=1)) / X[:, :, 0].sum(axis=1)
    P = shift[:, None] * X[:, :, 0] - X[:, :, 1]
    negative = (P < 0.0).any(axis=1)
    out: dict = {}
    for i, k in enumerate(which):
        blk, S, s = blocks[k], actives[k], int(sizes[i])
        if L is not None:
            blk.adopt_factor(
                S,
                ("cholesky", (np.array(L[i, :s, :s]), True)),
                columns[i] if blk.n * s <= COLUMNS_MAX_ENTRIES else None,
            )
        seen = {S.tobytes()}
        p = np.zeros(blk.n)
        p[S] = P[i, :s]
        if negative[i]:
            out[k] = ("next", next_active(S, p, seen), True, seen)
            continue
        zk = z[k]
        gap = columns[i] @ P[i, :s] + zk - shift[i]
        tol = gap_rtol * max(abs(float(shift[i]) - float(zk.min())), 1e-300)
        pen = ~S & (gap < -tol)
        out[k] = ("next", S | pen, False, seen) if pen.any() else ("done", p)
    return out


def next_active(active: np.ndarray, p: np.ndarray, seen: set) -> np.ndarray:
    """Johnson's active-set step: drop every negative cell; if that set was already
    visited (cycling), drop only the most negative one."""
    neg = p < 0.0
    out = active & ~neg
    if out.tobytes() in seen:
        out = active.copy()
        out[np.argmin(p)] = False
    return out


def final_first_passes(blocks, ks, rhs: dict, previous: list, stacks, *, gap_rtol: float = 1e-12) -> dict:
    """:func:`.local.contact_solve`'s first pass on the dense blocks ``ks`` (all
    :func:`batchable`) from their previous contacts, ``{k: (pressure, active)}`` where it
    is final: the solves on the kept factors one by one, the check of the gaps (``A p``
    on every cell) by one stacked FFT product a size class (:meth:`.pk_stack.BlockStacks.products`,
    the whole kernel), not a gather of the active columns a block (7,339 clustered
    spheres: 100,000 gathers of ~8,000 entries). The others are left to the one-block loop."""
    tried: dict = {}
    for k in ks:
        blk, b = blocks[k], rhs[k]
        active = previous[k] > 0.0
        if not np.count_nonzero(active):
            continue
        x = blk.solve(active, b[active])
        if np.count_nonzero(x < 0.0):
            continue
        p = np.zeros(blk.n)
        p[active] = x
        tried[k] = (p, active)
    # every block of ``ks`` in the stack (a level's stack is then the same every sweep)
    vectors = {k: tried[k][0] if k in tried else np.zeros(blocks[k].n) for k in ks}
    out = {}
    for k, u in stacks.products(blocks, ks, vectors).items():
        if k in tried:
            p, active = tried[k]
            tol = gap_rtol * float(np.abs(rhs[k]).max(initial=0.0))
            if not np.count_nonzero(~active & (u - rhs[k] < -tol)):
                out[k] = (p, active)
    return out
