"""Evaluation of top-face nodal fields at arbitrary top-face points.

Two ways, chosen from the node layout:

* the top-face Q2 nodes form a full rectilinear grid (every mesh from
  :func:`meshes.block_mesh`): the exact finite-element interpolant, tensor
  quadratic Lagrange on each element, as a sparse matrix (9 entries per point);
* otherwise (user meshes): Clough-Tocher (C1, cubic) on the Delaunay
  triangulation of the nodes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def _quadratic_weights(x: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    edges = nodes[::2]
    e = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    from .operators import lagrange_weights

    idx = 2 * e[:, None] + np.arange(3)[None, :]
    return idx, lagrange_weights(np.asarray(x, dtype=float), nodes[idx])


class TopInterpolator:
    """Linear map from values on the top-face nodes ``top_xy`` (n, 2) to points (mm)."""

    def __init__(self, top_xy: np.ndarray):
        self.top_xy = np.asarray(top_xy, dtype=float)
        xs = np.unique(np.round(self.top_xy[:, 0], 9))
        ys = np.unique(np.round(self.top_xy[:, 1], 9))
        self.rectilinear = len(xs) * len(ys) == len(self.top_xy) and len(xs) % 2 == 1 and len(ys) % 2 == 1
        if self.rectilinear:
            ix = np.searchsorted(xs, np.round(self.top_xy[:, 0], 9))
            iy = np.searchsorted(ys, np.round(self.top_xy[:, 1], 9))
            self._node = np.full((len(ys), len(xs)), -1, dtype=np.int64)
            self._node[iy, ix] = np.arange(len(self.top_xy))
            self.rectilinear = bool((self._node >= 0).all())
        self._xs, self._ys = xs, ys
        self._tri = None
        self.bounds = (xs[0], xs[-1], ys[0], ys[-1])

    def _check(self, P: np.ndarray) -> None:
        x0, x1, y0, y1 = self.bounds
        tol = 1e-9 * max(1.0, x1 - x0)
        bad = (P[:, 0] < x0 - tol) | (P[:, 0] > x1 + tol) | (P[:, 1] < y0 - tol) | (P[:, 1] > y1 + tol)
        if bad.any():
            raise ValueError(f"point {P[bad][0].tolist()} lies outside the block's top face")

    def matrix(self, points: np.ndarray) -> sp.csr_matrix:
        """Sparse (M, n) evaluation matrix (rectilinear layouts only)."""
        P = np.asarray(points, dtype=float).reshape(-1, 2)
        self._check(P)
        ix, wx = _quadratic_weights(P[:, 0], self._xs)
        iy, wy = _quadratic_weights(P[:, 1], self._ys)
        cols = self._node[iy[:, :, None], ix[:, None, :]].reshape(len(P), 9)
        vals = (wy[:, :, None] * wx[:, None, :]).reshape(len(P), 9)
        # each row's nine nodes are distinct: the CSR arrays directly, each row's columns
        # sorted as the coordinate format's conversion leaves them (no sums, the same matrix)
        order = np.argsort(cols, axis=1, kind="stable")
        indptr = np.arange(0, 9 * len(P) + 1, 9)
        data, indices = np.take_along_axis(vals, order, 1).ravel(), np.take_along_axis(cols, order, 1).ravel()
        return sp.csr_matrix((data, indices, indptr), shape=(len(P), len(self.top_xy)))

    def compressed(self, points: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
        """:meth:`matrix` on the nodes it uses only: ``(M', nodes)`` with ``M' @ values[nodes]``
        equal to ``matrix(points) @ values`` (each row's entries in the same order), so a
        product reads the rows of those nodes, not every top-face node's."""
        M = self.matrix(points)
        nodes = np.unique(M.indices)
        indices = np.searchsorted(nodes, M.indices)
        return sp.csr_matrix((M.data, indices, M.indptr), shape=(M.shape[0], len(nodes))), nodes

    def __call__(self, points: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Values (n, K) at ``points`` (M, 2) -> (M, K)."""
        P = np.asarray(points, dtype=float).reshape(-1, 2)
        if self.rectilinear:
            return self.matrix(P) @ values
        from scipy.interpolate import CloughTocher2DInterpolator
        from scipy.spatial import Delaunay

        self._check(P)
        if self._tri is None:
            self._tri = Delaunay(self.top_xy)
        out = CloughTocher2DInterpolator(self._tri, values)(P)
        if np.isnan(out).any():
            raise ValueError("a target point lies outside the block's top face")
        return out
