"""Grid-level pieces of the finite-block provider (:mod:`fem_influence.provider`).

* :func:`lagrange_1d`: the cubic Lagrange stencil that interpolates the correction in
  the source point from its lattice;
* :class:`BlockCorrection`: the correction in factored form (forces on the lattice
  nodes), for solvers that keep it apart from the half-space part;
* :class:`BlockGridOperator`: a grid product, half-space FFT convolution plus the
  low-rank correction ``h^2 U (W p)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from twoscale.grid import Grid
from twoscale.influence.base import GridOperator, LowRankCorrection

if TYPE_CHECKING:
    from .provider import BlockProvider


def lagrange_1d(x: np.ndarray, d: float, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Lagrange stencil on the lattice ``d * [lo..hi]``: indices and weights, (N, 4) each."""
    n = min(4, hi - lo + 1)
    i0 = np.floor(x / d).astype(int) - (n // 2 - 1)
    i0 = np.clip(i0, lo, hi - n + 1)
    idx = i0[:, None] + np.arange(n)[None, :]
    nodes = idx * d
    w = np.ones_like(nodes, dtype=float)
    for m in range(n):
        for k in range(n):
            if k != m:
                w[:, m] *= (x - nodes[:, k]) / (nodes[:, m] - nodes[:, k])
    return idx, w


class BlockCorrection(LowRankCorrection):
    """The block's correction in factored form (:meth:`BlockProvider.split`): coefficients are
    forces (N, for E = 1 fields scaled by 1/E at evaluation) on the correction lattice
    nodes, indexed like the provider's field table."""

    def __init__(self, provider: "BlockProvider"):
        self._p = provider

    def coefficients(self, source: Grid, p: np.ndarray) -> np.ndarray:
        cols, W = self._p._source_weights(source)
        c = np.zeros(self._p._state.table.shape[1])
        c[cols] = source.h**2 * (W @ np.asarray(p, dtype=float).ravel())  # columns are distinct nodes
        return c

    def evaluate(self, target: Grid, c: np.ndarray) -> np.ndarray:
        n = self._p._state.table.shape[1]
        c = np.asarray(c, dtype=float)
        if len(c) < n:
            c = np.concatenate([c, np.zeros(n - len(c))])
        if self._p._state.interpolator.rectilinear:
            return (self._p._target_values(target) @ c).reshape(target.shape)
        nz = np.flatnonzero(c)
        return (self._p._target_values(target, nz) @ c[nz]).reshape(target.shape)


class BlockGridOperator(GridOperator):
    """Half-space FFT convolution plus the low-rank correction ``h^2 U (W p)``."""

    def __init__(self, halfspace_op: GridOperator, U: np.ndarray, W, area: float):
        self.target, self.source = halfspace_op.target, halfspace_op.source
        self._hs, self._U, self._W, self._area = halfspace_op, U, W, area

    def apply(self, p: np.ndarray) -> np.ndarray:
        u = self._hs.apply(p)
        corr = self._U @ (self._W @ np.asarray(p, dtype=float).ravel())
        return u + self._area * corr.reshape(self.target.shape)

    def preconditioner(self):
        """The half-space part's preconditioner: the correction is smooth and of low rank,
        so the half-space kernel's inverse is as close to this operator's inverse as the
        CG needs (the preconditioned CG stays exact: only its iteration count changes)."""
        return self._hs.preconditioner()

    @property
    def nbytes(self) -> int:
        w = self._W.data.nbytes if sp.issparse(self._W) else self._W.nbytes
        return int(self._hs.nbytes) + self._U.nbytes + w

    @property
    def flops_estimate(self) -> float:
        nnz = self._W.nnz if sp.issparse(self._W) else self._W.size
        return self._hs.flops_estimate + 2.0 * self._U.size + 2.0 * nnz
