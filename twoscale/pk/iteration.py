"""The state of the Polonsky-Keer iteration on a stack of rows (:func:`~.kernel.pk_solve`).

The live rows' arrays are (b, n) (fields flattened), compacted as rows stop; the outputs
are indexed by the original row. One pass of the loop is :meth:`Iteration.check` (the
stopping rule, then the contact sets) and :meth:`Iteration.step` (one conjugate-gradient
step); the algorithm is in :mod:`.kernel`. A rarely true test is guarded by one cheap
reduction (numpy's per-call cost is most of a small block's time)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..stopping import StopReason
from .gap import GapBuffers
from .projection import column, constraint_residual, denominator, kkt_residual, project, restore, row_count, row_dot
from .products import COLUMN_CELLS, FAST_RESIDUAL, KEPT_GROWTH, CellChange, Halves, Products, clip_and_enter, halved
from .result import PKResult

#: Recompute ``u = A p`` from scratch at least this often (the cheap update
#: ``u <- s (u - tau A t)`` accumulates rounding).
REFRESH_EVERY = 25
#: Iterations between two calls of ``monitor``.
MONITOR_EVERY = 10
#: The change rule's penetration test: a cell off the contact penetrates when its gap is
#: below ``-GAP_RTOL max|z|`` (rounding of the products is ~1e-16 relative).
GAP_RTOL = 1e-12

_TINY = np.finfo(float).tiny


def _largest(u: np.ndarray) -> np.ndarray:
    """Per row the largest ``|u|`` (at least ``_TINY``), without ``np.abs``'s (B, n) copy."""
    return np.maximum(np.maximum(u.max(axis=1), -u.min(axis=1)), _TINY)


class Iteration:
    """Live rows of :func:`~.kernel.pk_solve` and the outputs.

    Parameters
    ----------
    products : Products (:mod:`.products`)
    precondition : callable on (b, ...) stacks, or None
    shape : tuple (one row's field)
    z, start, mask : (B, n) arrays
    basis, target : (n, k) and (B, k) arrays
    tol : Tolerance
    plane : PlaneBasis, optional
        The basis's separable form (:mod:`.plane`), for its fits and restoring.
    u0 : (B, n) array, optional: ``A start`` if known (:class:`~.kernel.Start`)."""

    PER_ROW = tuple(
        "p t u z mask target G_old conj kept stale scale best it_best gtol small index done count fast weight".split()
    ) + ("cheap",)  # the arrays (and the cheap product's state) with a row per live row

    def __init__(
        self, products: Products, precondition, shape, z, start, mask, basis, target, tol, plane=None, u0=None
    ):
        self.ops, self.pc, self.shape, self.basis, self.tol = products, precondition, shape, basis, tol
        self.plane = plane
        # the basis transposed, contiguous, for the moments' fits and plane (None: at most a load)
        self.basis_t = np.ascontiguousarray(basis.T) if basis.shape[1] > 1 else None
        self.change2 = None if tol.change is None else tol.change**2
        rows, self.k = len(z), basis.shape[1]
        self.masked = mask is not None  # some cells of some row cannot carry pressure
        self.mask, self.target = mask, target
        self.index: Any = None  # original row of each live row, once rows were dropped (else the identity)
        self.z = np.where(mask, z, 0.0) if self.masked else z
        self.p = np.maximum(start, 0.0)
        if self.masked:
            self.p[~mask] = 0.0
        if self.k:
            restore(self.p, basis, target, basis_t=self.basis_t, plane=plane)
        self.count: Any = None  # loaded cells per row (one constant constraint column)
        self.t = np.zeros_like(self.p)
        # rows whose refreshes still take the fast product (until their residual reaches
        # FAST_RESIDUAL; the search directions take it throughout)
        self.fast: Any = np.full(rows, products.fast is not None and tol.residual is not None)
        self.u = np.array(self.product(self.p, fast=bool(self.fast.all())) if u0 is None else u0, dtype=float)
        self.products = rows
        self.G_old, self.stale = np.ones(rows), self.fast.astype(int)
        self.conj, self.small, self.done, self.kept = np.zeros((4, rows), bool)
        self.pending = False  # rows finished but not yet dropped
        self.left = rows  # rows not finished
        self.buffers = GapBuffers()
        self.weight: Any = None  # the loaded cells, the masks' factor (:meth:`.gap.GapBuffers.weigh`)
        self.gtol: Any = None  # the change rule's penetration tolerance per row, when first needed
        self.scale: Any = None
        self.best: Any = None
        self.it_best: Any = None
        self.basis_scale: Any = None
        if tol.residual is not None:
            self.scale = _largest(self.u)
            self.best, self.it_best = np.full(rows, np.inf), np.zeros(rows, int)
            if self.k > 1:
                cells = mask.any(axis=0) if self.masked else slice(None)
                self.basis_scale = np.max(np.abs(basis[cells]), axis=0)
        self.history: list[float] = []
        self.cheap = products.cheap_rows(rows, tol)  # (the ``cheap`` product's state, if any)
        self.out_p: Any = None  # allocated when the first rows finish
        self.out_u: Any = None
        self.out_m = np.zeros((rows, self.k))
        self.reasons: list = [None] * rows
        self.iterations = np.zeros(rows, int)
        self.residual, self.out_best, self.denominator = np.full((3, rows), np.nan)

    def gap_tolerance(self) -> np.ndarray:
        """``GAP_RTOL max|z|`` per live row (mm)."""
        if self.gtol is None:
            self.gtol = GAP_RTOL * np.abs(self.z).max(axis=1, initial=0.0)
        return self.gtol

    def product(self, v: np.ndarray, fast: bool = False) -> np.ndarray:
        """``A v`` on a stack of rows: the ``fast`` product when asked for and given."""
        apply = self.ops.fast if fast and self.ops.fast is not None else self.ops.exact
        return apply(v.reshape(len(v), *self.shape)).reshape(len(v), -1)

    def refresh(self, rows: np.ndarray, fast: bool = False) -> None:
        """``u = A p`` from scratch on ``rows`` (a bool mask); by the ``fast`` product when
        asked for (the rows then stay marked stale: confirmed on an exact one)."""
        fast = fast and self.ops.fast is not None
        if self.cheap is not None and self.cheap.refresh(self, rows, fast):
            return
        if np.count_nonzero(rows) == len(rows):
            np.copyto(self.u, self.product(self.p, fast))  # (a product may return a buffer it keeps)
            self.stale[:] = int(fast)
        else:
            self.u[rows] = self.product(self.p[rows], fast)
            self.stale[rows] = int(fast)
        if self.scale is not None:
            self.scale[rows] = _largest(self.u if np.count_nonzero(rows) == len(rows) else self.u[rows])
        self.products += int(rows.sum())

    def gap(self):
        """Projected gap ``g``, multipliers ``m``, loaded cells ``on`` and ``g`` on them."""
        g, m, on, g_on, count, self.weight = self.buffers.gap(
            self.p, self.u, self.z, self.k, self.basis, self.basis_t, self.plane
        )
        self.count = count if self.k == 1 else self.count
        return g, m, on, g_on

    def residuals(self, g, g_on, on) -> np.ndarray | None:
        if self.tol.residual is None:
            return None
        free = self.buffers.free(self.mask) if self.masked else None  # (~mask: by index where few)
        res = kkt_residual(g, g_on, on, free, self.scale, self.buffers.scratch(g) if self.masked else None)
        if self.basis_scale is not None:
            res = np.maximum(res, constraint_residual(self.p, self.basis, self.target, self.basis_scale, self.plane))
        return res

    def converged(self, g, on, res) -> np.ndarray | None:
        """The stopping rule: which rows meet their test (None: none)."""
        done = None if res is None else res <= self.tol.residual
        if self.change2 is not None and np.count_nonzero(self.small):
            pen = ~on & (g < -self.gap_tolerance()[:, None])
            if self.masked:
                pen &= self.mask
            pen = pen.any(axis=1)
            small = self.small & ~pen
            done = small if done is None else done | small
        return done if done is not None and np.count_nonzero(done) else None

    def check(self, it: int, monitor):
        """Before step ``it + 1``: stop the rows that are done (stopping rule, cap, stall),
        drop them, and return the live rows' ``(it, g, m, on, g_on, gg, res)`` for
        :meth:`step`, or None when no row is left."""
        if not self.left:
            return None
        g, m, on, g_on = self.gap()
        res = self.residuals(g, g_on, on)
        want = self.converged(g, on, res)
        exact = None if want is None else want & (self.stale > 0)
        if res is not None and np.count_nonzero(self.fast & (res <= FAST_RESIDUAL)):
            leave = self.fast & (res <= FAST_RESIDUAL)  # from here on the exact product
            self.fast &= ~leave
            exact = leave if exact is None else exact | leave
        if exact is not None and np.count_nonzero(exact):
            if self.ops.fast is not None:  # the gradient jumps by the fast products' drift: restart
                self.conj &= ~exact
            # the cheap update drifted by rounding: confirm on an exact product
            self.refresh(exact)
            g, m, on, g_on = self.gap()
            res = self.residuals(g, g_on, on)
            want = self.converged(g, on, res)
        if res is not None:
            self.history.append(float(res.max()))
            if monitor is not None and it % MONITOR_EVERY == 0:
                monitor(it, float(res.max()))
        if want is not None:
            self.finish(want, StopReason.CONVERGED, it, m, res)
        if self.tol.caller_stops(it, res, self.p, self.done):
            self.finish(np.ones(1, bool), StopReason.STOPPED, it, m, res)
        if res is not None:
            better = res < 0.5 * self.best
            self.best, self.it_best = np.where(better, res, self.best), np.where(better, it, self.it_best)
            stalled = it - self.it_best > self.tol.stall
            if it < self.tol.max_iter and np.count_nonzero(stalled):
                self.finish(stalled, StopReason.STAGNATED, it, m, res)
        if it == self.tol.max_iter:
            self.finish(np.ones(len(g), bool), StopReason.MAX_ITER, it, m, res)
        g, m, on, g_on, res = self.drop(g, m, on, g_on, res)
        if not self.left:
            return None
        return self.contact_sets(it, g, m, on, g_on, res)

    def contact_sets(self, it, g, m, on, g_on, res):
        """Rows without pressure start from their penetrating cells (without constraint);
        rows whose gap vanishes on the contact take in the cells that penetrate (a
        conjugacy reset), and are solved when there are none."""
        gg = row_dot(g_on, g_on)
        if np.count_nonzero(gg) == len(gg):
            return it, g, m, on, g_on, gg, res
        if not self.k:
            empty = ~on.any(axis=1)
            if np.count_nonzero(empty):
                on[empty] = g[empty] < 0.0
                if self.masked:
                    on[empty] &= self.mask[empty]
                self.weight = self.buffers.weigh(on)
                g_on = np.where(on, g, 0.0)
                gg = row_dot(g_on, g_on)
                if np.count_nonzero(gg) == len(gg):
                    return it, g, m, on, g_on, gg, res
        flat = gg == 0.0
        entering = ~on & (g < -self.gap_tolerance()[:, None]) & flat[:, None]
        if self.masked:
            entering &= self.mask
        self.finish(flat & ~entering.any(axis=1), StopReason.CONVERGED, it, m, res)
        on |= entering
        self.weight = self.buffers.weigh(on)
        self.conj &= ~flat
        if self.k == 1:
            self.count = np.maximum(row_count(on), 1)
        if self.k:
            m = m + project(
                g, self.basis, on, self.count, self.basis_t, self.plane
            )  # the projection over the new contact
        g_on = np.where(on, g, 0.0)
        gg = row_dot(g_on, g_on)
        g, m, on, g_on, gg, res = self.drop(g, m, on, g_on, gg, res)
        return (it, g, m, on, g_on, gg, res) if self.left else None

    def finish(self, rows: np.ndarray, reason: StopReason, it: int, m, res, copy: bool = False) -> None:
        """Record the outcome of ``rows`` (a bool mask over the live rows; rows already
        finished keep their first outcome). ``copy``: the live arrays change afterwards."""
        rows = rows & ~self.done
        count = np.count_nonzero(rows)
        if not count:
            return
        at = np.flatnonzero(rows) if self.index is None else self.index[rows]
        if self.out_p is None and count == len(rows) and not copy:
            self.out_p, self.out_u = self.p, self.u  # every row at once: the arrays themselves
        else:
            if self.out_p is None:
                self.out_p, self.out_u = (
                    np.zeros((len(self.reasons), self.p.shape[1])),
                    np.zeros((len(self.reasons), self.p.shape[1])),
                )
            self.out_p[at], self.out_u[at] = self.p[rows], self.u[rows]
        self.left -= count
        self.done |= rows
        self.pending = True
        if m is not None:
            self.out_m[at] = m[rows]
        self.iterations[at] = it
        if res is not None:
            self.residual[at], self.out_best[at] = res[rows], self.best[rows]
        for i in at.tolist():
            self.reasons[i] = reason

    def direction(self, g_on, on, gg):
        """Steepest-descent direction on the loaded cells and ``G`` (its inner product with
        the gradient): the projected gap, or the preconditioner applied to it and projected
        in turn (rows where rounding makes that product non-positive keep the gap)."""
        if self.pc is None:
            return g_on, gg
        d = self.pc(g_on.reshape(len(g_on), *self.shape), on.reshape(len(on), *self.shape)).reshape(len(on), -1)
        restart = getattr(self.pc, "restart", None)
        if restart is not None and restart():  # a new preconditioner: the old directions are not conjugate in it
            self.conj[:] = False
        d *= self.weight
        if self.k:  # (without a constraint nothing is subtracted: d stays 0 off the loaded cells)
            project(d, self.basis, on, self.count if self.k == 1 else None, self.basis_t, self.plane, loaded_only=True)
            d *= self.weight
        G = row_dot(g_on, d)
        good = G > 0.0
        if not good.all():
            d[~good], G = g_on[~good], np.where(good, G, gg)
        return d, G

    def step(self, it, g, m, on, g_on, gg, res) -> None:
        """One Polonsky-Keer step on every live row (see :mod:`.kernel`)."""
        rows = len(g)
        d, G = self.direction(g_on, on, gg)
        beta = (G / self.G_old) * self.conj
        beta[self.kept & (G > KEPT_GROWTH * self.G_old)] = 0.0  # kept over an entry that made the gradient jump
        t = self.t
        if np.count_nonzero(beta):
            t *= column(beta)
            t += d
            t *= self.weight
        else:  # restarted: d itself (0 off the loaded cells already; the same values, one pass for three)
            np.copyto(t, d)
        self.G_old = G
        r = None if self.cheap is None else self.cheap.product(self, t, res)
        r = halved(self.ops, t, self.k, beta, self.stale) or self.product(t, fast=True) if r is None else r
        self.products += rows if self.pc is None else 2 * rows
        if isinstance(r, Halves):
            denom = r.energy()
        else:
            w = self.weight if self.k == 1 else on  # (a fit of the moments takes the bools)
            scratch = self.buffers.scratch(r) if self.k == 1 and w is not on else None  # (no fresh row-sized product)
            denom = denominator(r, t, w, self.count, self.basis, self.basis_t, self.plane, scratch)
        bad = ~(denom > 0.0)
        if np.count_nonzero(bad):
            self.denominator[np.flatnonzero(bad) if self.index is None else self.index[bad]] = denom[bad]
            self.finish(bad, StopReason.BREAKDOWN, it, m, res, copy=True)
            denom[bad] = np.inf  # tau = 0: the row keeps its pressure until it is dropped
        tau = row_dot(g_on, t) / denom
        p_old = self.p.copy() if self.change2 is not None else None
        p = self.p
        tau_c = column(tau)
        p -= np.multiply(t, tau_c, out=d if d is not g_on else None)
        clipped, reenter, change = clip_and_enter(p, g, tau, self.mask, self.ops.columns is not None)
        entered = reenter.any(axis=1)
        # few cells entered: the directions stay conjugate enough to keep (counted only then)
        few = row_count(reenter) <= self.ops.keep_conjugacy * row_count(on) if entered.any() else True
        self.kept = entered & few
        self.conj = ~entered | self.kept
        factor = restore(p, self.basis, self.target, basis_t=self.basis_t, plane=self.plane) if self.k else 1.0
        self.update_displacement(r, tau_c, factor, clipped | entered, change)
        if p_old is not None:
            p_old -= p
            d2, n2 = row_dot(p_old, p_old), row_dot(p, p)
            self.small = d2 <= self.change2 * n2
            if np.count_nonzero(n2) < len(n2):
                self.small |= n2 == 0.0
        self.drop()

    def update_displacement(self, r, tau_c, factor, changed, change: CellChange | None = None) -> None:
        """``u = A p`` after a step: from ``A t`` where ``p`` changed by ``-tau t`` and a
        constant factor only, plus the kernel's columns where at most
        :data:`~.products.COLUMN_CELLS` cells were clipped or entered (``change``), from
        scratch elsewhere (by the fast product while the row is on it) and every
        :data:`REFRESH_EVERY` steps."""
        summed = None
        if change is not None and factor is not None and np.count_nonzero(changed):
            summed = changed & (change.per_row(len(changed)) <= COLUMN_CELLS) & (self.stale < REFRESH_EVERY)
            changed = changed & ~summed
        redo = changed | (self.stale >= REFRESH_EVERY) | (False if self.cheap is None else self.cheap.due(self))
        count = np.count_nonzero(redo)
        if factor is None or count == len(redo):
            # every row from scratch: fast only if all still are (``redo`` may be empty)
            self.refresh(np.ones(len(changed), bool), bool(self.fast.all()))
            return
        fast = bool(self.fast[redo].all())
        r = r.finish() if isinstance(r, Halves) else r
        r *= tau_c
        self.u -= r
        if self.k:
            self.u *= column(factor)
        if summed is not None and np.count_nonzero(summed):
            change.apply(self.u, summed, factor, self.ops.columns)
        self.stale += 1
        if count:
            self.refresh(redo, fast)

    def drop(self, *arrays):
        """Remove the finished rows from the working arrays (and from ``arrays``)."""
        if not self.pending:
            return arrays
        self.pending = False
        if not self.left:
            return arrays  # all done: nothing to compact
        keep = ~self.done
        if self.index is None:
            self.index = np.arange(len(keep))
        for name in self.PER_ROW:
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, value[keep])
        return tuple(None if a is None else a[keep] for a in arrays)

    def result(self, shape) -> PKResult:
        rows = len(self.out_p)
        return PKResult(
            self.out_p.reshape(rows, *shape),
            self.out_u.reshape(rows, *shape),
            self.out_m,
            tuple(self.reasons),
            self.iterations,
            self.residual,
            self.out_best,
            self.denominator,
            self.products,
            tuple(self.history),
            self.tol,
        )
