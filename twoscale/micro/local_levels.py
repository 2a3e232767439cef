"""A sweep level's dense local solves (eq. 8) in one pass over flat arrays.

:func:`.local.contact_solve` on a dense block starts from the contact ``S`` of the block's
previous pressure, solves ``A_SS p_S = b_S``, and is done when no pressure is negative and
no cell off ``S`` penetrates (``(A p - b)_i < -gap_rtol max|b|``). On the 1,000-tip scenes
almost every local solve ends there (3,483 of a two-level iteration's 3,756 on 1,013
spheres), on blocks of ~100 cells whose contact holds ~17: its arithmetic is a few
microseconds, its per-call Python ~90. Here that first pass runs for all the dense blocks of
a level at once: each block keeps, per contact, ``A_SS^{-1}`` (from its Cholesky factor) and
the columns ``A[:, S]`` as flat arrays (a *piece*); a level's pieces are concatenated with
index arrays (rows, columns, owning block) made once per set of pieces, and the products,
the sign checks and the penetration checks of all its blocks are a few array calls. A block
whose first pass is not final (or that has no piece: an empty contact, an unsymmetric or
non-window block, columns above :data:`PIECE_MAX_ENTRIES`, or beyond :data:`STACKS_BYTES`) is left to
:func:`.local.contact_solve`, which runs its whole loop as before.

The blocks solved here give what :func:`.local.contact_solve` gives, up to rounding:
``A_SS^{-1} b_S`` is the Cholesky solve written as one product.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dpotrs

from .local_batch import CLASSES, batchable

#: A block's piece holds its columns ``A[:, S]`` up to this many entries (128 KB) ...
PIECE_MAX_ENTRIES = 16384
#: ... and all pieces and levels' stacks at most these bytes (beyond: one block at a time).
STACKS_BYTES = 96 << 20


@dataclass(frozen=True)
class Piece:
    """One block's first pass on one contact: ``key`` (the contact's bytes), ``cells`` (its
    indices over the block's cells), ``inverse`` ``A_SS^{-1}`` and ``columns`` ``A[:, S]``,
    and the block's size ``n``."""

    key: bytes
    cells: np.ndarray
    inverse: np.ndarray
    columns: np.ndarray
    n: int


@dataclass(frozen=True)
class _Group:
    """Pieces of one contact size class, padded: ``inverse`` (G, m, m) and ``columns``
    (G, nmax, m) zero on the padding; ``contact`` (G, m) and ``rows`` (G, nmax) index the
    level's cells (the padding: one cell past them, where the right-hand side is 0);
    ``inside`` and ``active`` (G, nmax) mark the blocks' cells and contacts; ``which``: the
    pieces' places in the level."""

    which: np.ndarray
    inverse: np.ndarray
    columns: np.ndarray
    contact: np.ndarray
    rows: np.ndarray
    inside: np.ndarray
    active: np.ndarray


@dataclass(frozen=True)
class _Level:
    """A level's pieces in their size classes' groups; ``n_off``: the blocks' offsets in the
    level's cells; ``active``: the contacts over those cells."""

    pieces: tuple
    n_off: np.ndarray
    groups: tuple
    active: np.ndarray


def _group(pieces: tuple, which: np.ndarray, n_off: np.ndarray, m: int) -> _Group:
    size = len(which)
    nmax = max(pieces[i].n for i in which)
    pad = int(n_off[-1])
    inverse = np.zeros((size, m, m))
    columns = np.zeros((size, nmax, m))
    contact = np.full((size, m), pad)
    rows = np.full((size, nmax), pad)
    inside = np.zeros((size, nmax), bool)
    active = np.zeros((size, nmax), bool)
    for g, i in enumerate(which.tolist()):
        pc = pieces[i]
        s, n, first = pc.cells.size, pc.n, int(n_off[i])
        inverse[g, :s, :s] = pc.inverse
        columns[g, :n, :s] = pc.columns
        contact[g, :s] = pc.cells + first
        rows[g, :n] = np.arange(first, first + n)
        inside[g, :n] = True
        active[g, pc.cells] = True
    return _Group(which, inverse, columns, contact, rows, inside, active)


class LevelSolves:
    """The dense blocks' first passes of the sweeps' levels (module docstring); kept by one
    two-level iteration (its blocks do not change), with each block's last piece and each
    level's last concatenation.

    Parameters
    ----------
    blocks : list of LocalBlock
    gap_rtol : float, default 1e-12
        As :func:`.local.contact_solve`'s.
    """

    def __init__(self, blocks, *, gap_rtol: float = 1e-12):
        self.blocks = blocks
        self.gap_rtol = gap_rtol
        self._eligible = [batchable(blk) for blk in blocks]
        self._pieces: dict = {}
        self._levels: dict = {}
        self.nbytes = 0

    def piece(self, k: int, contact: np.ndarray) -> Piece | None:
        """Block ``k``'s piece on ``contact`` (kept while the contact is the same), or None."""
        key = contact.tobytes()
        hit = self._pieces.get(k)
        if hit is not None and hit[0] == key:
            return hit[1]
        blk = self.blocks[k]
        s = int(np.count_nonzero(contact))
        out = None
        size = 8 * (s * s + blk.n * s)
        old = 0 if hit is None or hit[1] is None else 8 * (hit[1].inverse.size + hit[1].columns.size)
        if s and blk.n * s <= PIECE_MAX_ENTRIES and self.nbytes - old + size <= STACKS_BYTES:
            kind, f = blk._factor(contact)
            if kind == "cholesky":
                inverse, info = dpotrs(f[0], np.eye(s), lower=f[1])
                kept = blk._columns
                cols = kept[1] if kept is not None and kept[0] == key else blk._entries(blk._idx, blk._idx[contact])
                if info == 0:
                    out = Piece(key, np.flatnonzero(contact), inverse, cols, blk.n)
        self.nbytes += (0 if out is None else size) - old
        self._pieces[k] = (key, out)
        return out

    def _level(self, ks: tuple, pieces: tuple) -> _Level | None:
        """The level's stacks (kept while its pieces are), or None beyond :data:`STACKS_BYTES`."""
        hit = self._levels.pop(ks, None)
        if hit is not None and all(map(operator.is_, hit.pieces, pieces)):
            self._levels[ks] = hit
            return hit
        self.nbytes -= 0 if hit is None else sum(g.inverse.nbytes + g.columns.nbytes for g in hit.groups)
        n_off = np.concatenate([[0], np.cumsum([pc.n for pc in pieces])])
        # by the classes of the contact's size and the block's (padding at most ~2x each way)
        s_class = np.searchsorted(CLASSES, [pc.cells.size for pc in pieces])
        n_class = np.searchsorted(CLASSES, [pc.n for pc in pieces])
        classes = s_class * (len(CLASSES) + 1) + n_class
        found = [np.flatnonzero(classes == c) for c in np.unique(classes).tolist()]
        sizes = [CLASSES[min(s_class[w[0]], len(CLASSES) - 1)] for w in found]
        sizes = [max(m, max(pieces[i].cells.size for i in w)) for m, w in zip(sizes, found)]
        size = sum(8 * len(w) * (m * m + m * max(pieces[i].n for i in w)) for m, w in zip(sizes, found))
        if self.nbytes + size > STACKS_BYTES:
            return None
        self.nbytes += size
        groups = [_group(pieces, which, n_off, m) for m, which in zip(sizes, found)]
        active = np.zeros(int(n_off[-1]) + 1, bool)
        for grp in groups:
            active[grp.contact] = True
        active[-1] = False
        active.flags.writeable = False
        level = _Level(pieces, n_off, tuple(groups), active)
        self._levels[ks] = level
        return level

    def solve(self, level, rhs: dict, p: list) -> dict:
        """``{k: (pressure, active)}`` for the blocks of ``level`` whose first pass from the
        contact of ``p[k]`` is final (the others are left out)."""
        ks, pieces = [], []
        for k in level:
            if self._eligible[k]:
                pc = self.piece(k, p[k] > 0.0)
                if pc is not None:
                    ks.append(k)
                    pieces.append(pc)
        if not ks:
            return {}
        lv = self._level(tuple(ks), tuple(pieces))
        if lv is None:
            return {}
        b = np.concatenate([rhs[k] for k in ks] + [np.zeros(1)])
        pressure = np.zeros(b.size)
        final = np.zeros(len(ks), bool)
        for grp in lv.groups:
            pS = np.matmul(grp.inverse, b[grp.contact][:, :, None])
            bn = b[grp.rows]
            gap = np.matmul(grp.columns, pS)[:, :, 0] - bn
            tol = self.gap_rtol * np.abs(bn).max(axis=1)
            pS = pS[:, :, 0]
            penetrating = (~grp.active & grp.inside & (gap < -tol[:, None])).any(axis=1)
            final[grp.which] = ~((pS < 0.0).any(axis=1) | penetrating)
            pressure[grp.contact] = pS
        pressure[-1] = 0.0
        pressure.flags.writeable = False
        bounds = lv.n_off.tolist()
        return {
            ks[i]: (pressure[bounds[i] : bounds[i + 1]], lv.active[bounds[i] : bounds[i + 1]])
            for i in np.flatnonzero(final).tolist()
        }
