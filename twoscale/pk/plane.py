"""The load-and-moments constraint algebra by sums along the grid's rows (:class:`PlaneBasis`).

With a free tilt the constraint basis is ``[1, x - px, y - py]`` on a rectangular grid.
The kernel's general algebra (:mod:`.projection`) handles any (n, k) basis: each fit
multiplies the whole (k, n) basis by the loaded cells (a 3 x n temporary), and each
restoring sweep again by the pressure. Here the basis is separable: every weighted sum
``sum_w b_a b_b`` and ``sum_w v b_a`` follows from one matrix product of the (ny, nx)
weights with the columns ``[1, x, x^2]`` (ny rows of three sums), then the rows' sums
against ``y``. The coordinates are centred on the grid (the normal equations stay well
conditioned, no refinement step needed) and the coefficients mapped back to the basis.
A box of 5.26 M cells: a fit 0.24 s by :func:`.projection.fit` against two passes here.
On grids of more than ``SHORT_ROW`` cells the rows' sums are passes of their own, not a
matrix product: OpenBLAS threads the product on such grids, and its idle thread then spins
beside the FFTs (5,162 tilted spheres on 4.5 M cells: 7.6 s of that thread's CPU against
36 s of the solve's, the same time per pass single-threaded).
"""

from __future__ import annotations

import numpy as np

from .projection import FIT_MAX_CONDITION, SHORT_ROW


class PlaneBasis:
    """The basis ``[1, x - px, y - py]`` on a (ny, nx) grid, for :class:`~.kernel.Constraint`.

    Parameters
    ----------
    x : (nx,) array
        ``x - px`` of the grid's columns, mm.
    y : (ny,) array
        ``y - py`` of the grid's rows, mm.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        self.shape = (len(y), len(x))
        self.x0, self.y0 = float(x.mean()), float(y.mean())
        self.xc, self.yc = x - self.x0, y - self.y0
        # [1, xc, xc^2] per column: the per-row sums of a weight in one product
        self.columns = np.ascontiguousarray(np.stack([np.ones_like(x), self.xc, self.xc**2], axis=1))
        self.xc2 = self.xc**2
        # b = bc @ L (bc the centred basis [1, xc, yc]): the map of coefficients c = L^-1 cc
        self.L = np.array([[1.0, self.x0, self.y0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        self._buffer: np.ndarray | None = None
        # the loaded cells of the last fit and their Gram matrix: an iteration fits the gap,
        # the preconditioned direction and its product over the same cells
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    @classmethod
    def on(cls, grid, pivot) -> "PlaneBasis":
        """The basis ``[1, x - px, y - py]`` of ``grid``'s cell centres about ``pivot`` (mm)."""
        X, Y = grid.centres()
        return cls(X[0] - pivot[0], Y[:, 0] - pivot[1])

    def matches(self, basis: np.ndarray) -> bool:
        """Whether ``basis`` (n, 3) is this one (checked on the corners and the centre)."""
        ny, nx = self.shape
        if basis.shape != (ny * nx, 3):
            return False
        at = np.array([0, nx - 1, (ny - 1) * nx, ny * nx - 1, (ny // 2) * nx + nx // 2])
        j, i = np.divmod(at, nx)
        mine = np.stack([np.ones(len(at)), self.xc[i] + self.x0, self.yc[j] + self.y0], axis=1)
        return bool(np.allclose(basis[at], mine, rtol=1e-12, atol=1e-12 * (1 + np.abs(mine).max())))

    def _buf(self) -> np.ndarray:
        if self._buffer is None:
            self._buffer = np.empty(self.shape)
        return self._buffer

    def _row_sums(self, w2: np.ndarray, k: int) -> np.ndarray:
        """Per row of a (ny, nx) weight its sums against ``[1, xc, xc^2][:k]`` (ny, k): one
        matrix product on small grids, else ``k`` passes without BLAS (its threads spin)."""
        if w2.size <= SHORT_ROW:
            return w2 @ self.columns[:, :k]
        sums = [np.einsum("ij->i", w2), np.einsum("ij,j->i", w2, self.xc), np.einsum("ij,j->i", w2, self.xc2)]
        return np.stack(sums[:k], axis=1)

    def _moments(self, w2: np.ndarray) -> np.ndarray:
        """The centred weighted Gram matrix ``sum_w bc bc^T`` of a (ny, nx) weight."""
        q = self._row_sums(w2, 3)  # (ny, 3): sum w, sum w xc, sum w xc^2 per row
        s, sx, sxx = q.sum(axis=0)
        sy, syy, sxy = self.yc @ q[:, 0], (self.yc**2) @ q[:, 0], self.yc @ q[:, 1]
        return np.array([[s, sx, sy], [sx, sxx, sxy], [sy, sxy, syy]])

    def fit(self, v: np.ndarray, on: np.ndarray) -> np.ndarray | None:
        """The least-squares coefficients (3,) of one row ``v`` (n,) by the basis over the
        cells ``on`` (bool, n); None when the normal equations are ill-conditioned (the
        caller's general fit then decides)."""
        w = self._buf()
        if self._last is not None and np.array_equal(self._last[0], on):
            gram = self._last[1]
        else:
            np.copyto(w, on.reshape(self.shape))
            gram = self._moments(w)
            self._last = (on.copy(), gram)
        if not np.linalg.cond(gram) <= FIT_MAX_CONDITION:
            return None
        np.multiply(v.reshape(self.shape), on.reshape(self.shape), out=w)
        q = self._row_sums(w, 2)
        rhs = np.array([q[:, 0].sum(), q[:, 1].sum(), self.yc @ q[:, 0]])
        return np.linalg.solve(self.L, np.linalg.solve(gram, rhs))

    def moments(self, p: np.ndarray) -> np.ndarray:
        """``B^T p`` of one row ``p`` (n,): the load and both moments (one pass)."""
        q = self._row_sums(p.reshape(self.shape), 2)
        return self.L.T @ np.array([q[:, 0].sum(), q[:, 1].sum(), self.yc @ q[:, 0]])

    def subtract(self, v: np.ndarray, c: np.ndarray) -> None:
        """``v -= B c`` on one row (n,), in place (two passes, no temporary)."""
        cc = self.L @ c
        v2 = v.reshape(self.shape)
        v2 -= cc[0] + cc[1] * self.xc
        v2 -= (cc[2] * self.yc)[:, None]

    def restore(self, p: np.ndarray, target: np.ndarray, sweeps: int) -> None:
        """:func:`.projection.restore` on one row ``p`` (n,) >= 0, off the loaded cells 0: ``p
        <- p (B c)`` with ``c`` such that ``B^T p = target``, up to ``sweeps`` times while
        the plane makes cells negative (clipped in between)."""
        p2, plane = p.reshape(self.shape), self._buf()
        for _ in range(sweeps):
            gram = self.L.T @ self._moments(p2) @ self.L  # B^T diag(p) B
            cc = self.L @ np.linalg.lstsq(gram, target, rcond=1e-13)[0]
            np.add.outer(cc[2] * self.yc, cc[0] + cc[1] * self.xc, out=plane)
            p2 *= plane
            if p.min() >= 0.0:
                return
            np.maximum(p, 0.0, out=p)
