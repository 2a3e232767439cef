"""Polonsky-Keer's constrained conjugate gradients on many blocks at once.

:func:`~.pk.pk_fixed_approach` on ``B`` independent blocks whose owned cells fit one
canvas shape (a size class, :func:`~.blocks.size_class`): the blocks' vectors are stacked
as (B, ny, nx) arrays (zero and held out of contact off each block's mask), every product
is one :meth:`~twoscale.influence.base.GridOperator.apply_stack` call with the canvas's
self-operator, and the step lengths are per-block vectors. Each block follows the same
iteration as :func:`~.pk.pk_fixed_approach` (the same tests, in the same order) and
leaves the loop when its own test says so; the others go on. With many small patches
(10,000 sparse tips: ~10^5 local solves of ~500 cells a run) the cost is in the calls,
not the arithmetic, and one call per iteration for B blocks replaces B calls.

Only for a translation-invariant body (the provider's :meth:`split` has no correction):
the canvas's operator is then every block's, whatever its place.
"""
from __future__ import annotations

import numpy as np


def _dot(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per-block ``a[S] . b[S]`` for stacks (B, ny, nx) and a mask ``S``."""
    return np.einsum("bij,bij->b", np.where(mask, a, 0.0), b)


def _any(mask: np.ndarray) -> np.ndarray:
    return mask.reshape(len(mask), -1).any(axis=1)


def _direction(g, S, t, delta, G_old, live):
    """Conjugate directions (zero off ``S`` and on finished blocks) and the new ``|g_S|^2``."""
    G = _dot(g, g, S)
    beta = np.where(G_old > 0.0, delta * G / np.where(G_old > 0.0, G_old, 1.0), 0.0)
    t = np.where(S & live[:, None, None], g + beta[:, None, None] * t, 0.0)
    return t, np.where(live, G, G_old)


def _contact_sets(p, g, mask, gtol, live):
    """:func:`~.pk.pk_fixed_approach`'s first tests per block: the contact cells ``S``,
    the blocks already solved, and those where cells entered (their ``delta`` restarts)."""
    S = p > 0.0
    solved = np.zeros(len(p), bool)
    empty = ~_any(S) & live
    if np.any(empty):
        S[empty] = (g[empty] < 0.0) & mask[empty]
        solved |= empty & ~_any(S)
    flat = ~_any(np.where(S, g, 0.0) != 0.0) & live & ~solved
    if np.any(flat):   # exact on the contact cells
        entering = ~S[flat] & mask[flat] & (g[flat] < -gtol[flat])
        solved[np.flatnonzero(flat)[~_any(entering)]] = True
        S[flat] |= entering
    return S, solved, flat


def _project(p, S, t, g, tau, mask, live, *, outside: bool):
    """Polonsky-Keer's step on the live blocks: ``p - tau t`` on ``S``, clipped at zero, and
    the cells with ``g < 0`` (only off ``S`` when ``outside``) given ``-tau g``. Returns the
    new pressures and, per block, whether cells were added and whether the step went negative."""
    live3 = live[:, None, None]
    trial = np.where(S & live3, p - tau * t, p)
    p = np.where(live3, np.maximum(trial, 0.0), p)     # finished blocks keep theirs
    overlap = (p == 0.0) & (g < 0.0) & mask & live3
    if outside:
        overlap &= ~S
    p = np.where(overlap, p - tau * g, p)
    return p, _any(overlap), _any((trial < 0.0) & live3)


def _changes(p, p_old):
    """Per block ``||p - p_old||`` and ``||p||``."""
    d = p - p_old
    return np.sqrt(np.einsum("bij,bij->b", d, d)), np.sqrt(np.einsum("bij,bij->b", p, p))


class _Out:
    """Results of the rows of a stack; rows that finished leave the working arrays once
    they are half of them (the lock-step iteration then costs the live rows only)."""

    def __init__(self, p: np.ndarray, max_iter: int):
        self.p, self.s = np.zeros_like(p), np.full(len(p), np.nan)
        self.ok, self.iters = np.zeros(len(p), bool), np.full(len(p), max_iter)
        self.index = np.arange(len(p))

    def store(self, rows, p, ok, iters, s=None) -> None:
        at = self.index[rows]
        self.p[at], self.ok[at], self.iters[at] = p[rows], ok[rows], iters[rows]
        if s is not None:
            self.s[at] = s[rows]

    def compact(self, done: np.ndarray, arrays: list, p, ok, iters, s=None) -> list | None:
        """The working arrays without the finished rows (stored), or None while few finished."""
        if 2 * int(done.sum()) < len(done) or done.all():
            return None
        self.store(done, p, ok, iters, s)
        self.index = self.index[~done]
        return [a[~done] for a in arrays]


def pk_stack_fixed_approach(operator, b: np.ndarray, p_start: np.ndarray, mask: np.ndarray, *,
                            rtol: float, max_iter: int = 1000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~.pk.pk_fixed_approach` on a stack of blocks.

    Parameters
    ----------
    operator : GridOperator
        Self-operator of the canvas (ny, nx), with ``apply_stack``.
    b : (B, ny, nx) array, mm
        Right-hand side of each block (zero off its mask).
    p_start : (B, ny, nx) array, MPa
        Warm starts (zero off the masks; negative entries are clipped).
    mask : (B, ny, nx) bool array
        Each block's cells on the canvas.
    rtol : float
        Relative change of a block's pressure at which it stops.
    max_iter : int, default 1000

    Returns
    -------
    pressure (B, ny, nx), converged (B,) bool, iterations (B,) int
    """
    nb = len(b)
    p = np.where(mask, np.maximum(p_start, 0.0), 0.0)
    t = np.zeros_like(p)
    delta, G_old = np.zeros(nb), np.zeros(nb)
    gtol = (1e-12 * np.abs(b).reshape(nb, -1).max(axis=1, initial=0.0))[:, None, None]
    u = operator.apply_stack(p)
    done, ok, iters = np.zeros(nb, bool), np.zeros(nb, bool), np.full(nb, max_iter)

    def finish(which, it, good):
        done[which], ok[which], iters[which] = True, good, it

    out = _Out(p, max_iter)
    for it in range(1, max_iter + 1):
        kept = out.compact(done, [p, t, u, b, mask, gtol, delta, G_old, done, ok, iters], p, ok, iters)
        if kept is not None:
            p, t, u, b, mask, gtol, delta, G_old, done, ok, iters = kept
        g = u - b
        S, solved, entered = _contact_sets(p, g, mask, gtol, ~done)
        finish(solved, it, True)
        delta[entered] = 0.0
        live = ~done
        if not np.any(live):
            break
        t, G_old = _direction(g, S, t, delta, G_old, live)
        r = np.zeros_like(t)
        r[live] = operator.apply_stack(t[live])
        denom = _dot(t, r, S)
        finish(live & ~(denom > 0.0), it, False)
        live = ~done
        tau = np.where(live, _dot(g, t, S) / np.where(live, denom, 1.0), 0.0)[:, None, None]
        p_old = p
        p, clipped, negative = _project(p, S, t, g, tau, mask, live, outside=True)
        delta = np.where(live, np.where(clipped, 0.0, 1.0), delta)
        # the product is linear: without clipping or new cells, A p follows from A t
        # (re-evaluated every 25 steps against drift)
        u = np.where(live[:, None, None], u - tau * r, u)
        redo = live & ~(~clipped & ~negative & bool(it % 25))
        if np.any(redo):
            u[redo] = operator.apply_stack(p[redo])
        change, norm = _changes(p, p_old)
        small = live & ((norm == 0.0) | (change <= rtol * norm))
        if np.any(small):
            fresh = small & ~redo   # rows just recomputed above need no second product
            if np.any(fresh):
                u[fresh] = operator.apply_stack(p[fresh])
            pen = _any((p[small] == 0.0) & mask[small] & (u[small] - b[small] < -gtol[small]))
            finish(np.flatnonzero(small)[~pen], it, True)
        if np.all(done):
            break
    out.store(np.ones(len(p), bool), p, ok, iters)
    return out.p, out.ok, out.iters


def pk_stack_fixed_force(operator, z: np.ndarray, target: np.ndarray, p_start: np.ndarray, mask: np.ndarray, *,
                         rtol: float, max_iter: int = 1000):
    """:func:`~.pk.pk_fixed_force` on a stack of blocks: ``z`` (B, ny, nx) mm, ``target``
    (B,) the load over ``h^2`` (MPa cells), starts (> 0 somewhere on each mask).

    Returns pressure (B, ny, nx), shift (B,) mm, converged (B,), iterations (B,)."""
    nb = len(z)
    z = np.where(mask, z, 0.0)
    p = np.where(mask, np.maximum(p_start, 0.0), 0.0)
    p *= (target / p.reshape(nb, -1).sum(axis=1))[:, None, None]
    t = np.zeros_like(p)
    delta, G_old = np.zeros(nb), np.zeros(nb)
    s = np.full(nb, np.nan)
    u = operator.apply_stack(p)
    done, ok, iters = np.zeros(nb, bool), np.zeros(nb, bool), np.full(nb, max_iter)
    out = _Out(p, max_iter)
    for it in range(1, max_iter + 1):
        kept = out.compact(done, [p, t, u, z, target, delta, G_old, s, mask, done, ok, iters], p, ok, iters, s)
        if kept is not None:
            p, t, u, z, target, delta, G_old, s, mask, done, ok, iters = kept
        nb = len(p)
        live = ~done
        S = p > 0.0
        count = np.maximum(S.reshape(nb, -1).sum(axis=1), 1)
        g = u + z
        s = np.where(live, np.where(S, g, 0.0).reshape(nb, -1).sum(axis=1) / count, s)
        g = g - s[:, None, None]
        t, G_old = _direction(g, S, t, delta, G_old, live)
        At = np.zeros_like(t)
        At[live] = operator.apply_stack(t[live])
        r = At - (np.where(S, At, 0.0).reshape(nb, -1).sum(axis=1) / count)[:, None, None]
        denom = _dot(t, r, S)
        bad = live & ~(denom > 0.0)
        done[bad], iters[bad] = True, it
        live = ~done
        tau = np.where(live, _dot(g, t, S) / np.where(live, denom, 1.0), 0.0)[:, None, None]
        p_old = p
        p, clipped, negative = _project(p, S, t, g, tau, mask, live, outside=False)
        delta = np.where(live, np.where(clipped, 0.0, 1.0), delta)
        total = np.where(live, p.reshape(nb, -1).sum(axis=1), 1.0)
        scale = np.where(live, target / total, 1.0)[:, None, None]
        p = p * scale
        # A p follows from A t when nothing was clipped or added (every 25 steps: recomputed)
        u = np.where(live[:, None, None], scale * (u - tau * At), u)
        redo = live & ~(~clipped & ~negative & bool(it % 25))
        if np.any(redo):
            u[redo] = operator.apply_stack(p[redo])
        change, norm = _changes(p, p_old)
        good = live & (change <= rtol * norm)
        done[good], ok[good], iters[good] = True, True, it
        if np.all(done):
            break
    out.store(np.ones(len(p), bool), p, ok, iters, s)
    return out.p, out.s, out.ok, out.iters


class BlockStacks:
    """Local contact solves of many FFT blocks of one size class at once (see the module
    docstring); owns one canvas operator per class. Internal to a sweep's caller.

    Parameters
    ----------
    provider : InfluenceProvider
        Must be translation-invariant (``provider.split()`` without correction).
    """

    def __init__(self, provider):
        self.provider = provider
        self._ops: dict = {}

    @staticmethod
    def usable(provider) -> bool:
        """Whether ``provider``'s cell kernel depends on cell offsets only."""
        return provider.split()[1] is None

    def _canvas(self, blk):
        from .blocks import size_class
        key = (size_class(blk.box.ny), size_class(blk.box.nx))
        op = self._ops.get(key)
        if op is None:
            op = self._ops[key] = self.provider.grid_operator(blk.box.subgrid(0, 0, key[1], key[0]))
        return key, op

    def _groups(self, blocks, ks, tol_of) -> dict:
        groups: dict = {}
        for k in ks:
            key, op = self._canvas(blocks[k])
            groups.setdefault((key, tol_of(blocks[k])), (op, []))[1].append(k)
        return groups

    @staticmethod
    def _stack(blocks, members, key, *vectors):
        """The members' canvas masks (B, ny, nx) and each of ``vectors`` (dicts or lists of
        block vectors) placed on the canvases, zero elsewhere."""
        mask = np.zeros((len(members), *key), bool)
        out = [np.zeros(mask.shape) for _ in vectors]
        for i, k in enumerate(members):
            mask[i] = m = blocks[k].canvas_mask(key)
            for a, v in zip(out, vectors):
                a[i][m] = v[k]
        return mask, out

    def initial(self, blocks, ks, z: list, forces: list, starts: dict, h: float, *, rtol: float) -> dict:
        """Eq. 7 (:func:`~.local.initial_pressure`'s FFT branch) on the blocks ``ks`` (FFT
        blocks owning cells, force > 0): ``{k: pressure}``."""
        out = {}
        for (key, tol), (op, members) in self._groups(blocks, ks, lambda blk: rtol).items():
            mask, (zs, p0) = self._stack(blocks, members, key, z, starts)
            target = np.array([forces[k] / (h * h) for k in members])
            p, _, _, _ = pk_stack_fixed_force(op, zs, target, p0, mask, rtol=tol)
            out.update((k, p[i][mask[i]]) for i, k in enumerate(members))
        return out

    def solve(self, blocks, ks, rhs: dict, previous: list, rtol: float | None) -> dict:
        """Contact on the blocks ``ks`` (FFT blocks owning cells) with right-hand sides
        ``rhs[k]`` from starts ``previous[k]``: ``{k: (pressure, converged, iterations)}``."""
        out = {}
        for (key, tol), (op, members) in self._groups(blocks, ks, lambda blk: blk.cg_rtol if rtol is None else rtol).items():
            mask, (b, p0) = self._stack(blocks, members, key, rhs, previous)
            p, ok, it = pk_stack_fixed_approach(op, b, p0, mask, rtol=tol)
            out.update((k, (p[i][mask[i]], bool(ok[i]), int(it[i]))) for i, k in enumerate(members))
        return out
