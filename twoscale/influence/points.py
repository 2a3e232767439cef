"""Sums of point-force displacements: ``u_i = sum_j G(t_i, s_j) F_j`` (many asperities).

The macro step (``T P``) and the far field of the micro step (patch resultants acting on
other patches) both need the displacement at many points due to many point forces. Formed
as a matrix this is ``M x N`` numbers: 800 MB at 10^4 asperities. A
:class:`PointOperator` applies the sum without keeping that matrix; a provider may return
a fast one (the half-space: an FFT on a mesh for the smooth long-range part) and the
default (:class:`DensePointOperator`) evaluates ``point_compliance`` in row chunks, exact
and with bounded memory.

Conventions shared by every implementation:

* coincident points (``G`` not finite, e.g. the Boussinesq ``1/r`` at ``r = 0``)
  contribute nothing: the caller adds any regular self term it wants;
* ``exclude``, a sparse ``(M, N)`` matrix, marks by its stored entries the pairs
  ``(i, j)`` left out of the sum (whatever their values);
* ``apply(F)`` takes ``(N,)`` or ``(N, m)`` forces (N) and returns ``(M,)`` or ``(M, m)``
  displacements (mm).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Callable

import numpy as np
import scipy.sparse as sp

#: Entries of ``G`` evaluated at once by :class:`DensePointOperator` (8 bytes each).
CHUNK_ENTRIES = 4_000_000
#: Below this many entries :class:`DensePointOperator` keeps its matrix between products.
KEEP_ENTRIES = 4_000_000


def check_points(points, name: str) -> np.ndarray:
    """``points`` as a finite ``(n, 2)`` float array (mm); ValueError naming ``name``."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"{name} must have shape (n, 2) (mm), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must be finite (mm)")
    return p


def check_exclude(exclude, m: int, n: int):
    """``exclude`` as a CSR matrix of shape (m, n) with its pattern only, or None."""
    if exclude is None:
        return None
    ex = sp.csr_matrix(exclude)
    if ex.shape != (m, n):
        raise ValueError(f"exclude must have shape {(m, n)}, got {ex.shape}")
    ex = sp.csr_matrix((np.ones(ex.nnz), ex.indices, ex.indptr), shape=ex.shape)
    ex.sum_duplicates()
    return ex


class PointOperator(ABC):
    """Linear map from point forces at ``sources`` to displacements at ``targets``.

    Attributes
    ----------
    targets : (M, 2) array, mm
    sources : (N, 2) array, mm
    """

    targets: np.ndarray
    sources: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.targets), len(self.sources))

    @abstractmethod
    def apply(self, forces: np.ndarray) -> np.ndarray:
        """Displacements (mm) at the targets from forces (N) at the sources."""

    def __call__(self, forces: np.ndarray) -> np.ndarray:
        return self.apply(forces)

    def _check_forces(self, forces) -> np.ndarray:
        F = np.asarray(forces, dtype=float)
        if F.shape[:1] != (len(self.sources),) or F.ndim > 2:
            raise ValueError(
                f"forces must have shape ({len(self.sources)},) or ({len(self.sources)}, m), got {F.shape}"
            )
        return F


class DensePointOperator(PointOperator):
    """Exact sum by chunks of rows of ``kernel(targets, sources)``.

    Parameters
    ----------
    kernel : callable, (targets (a, 2), sources (b, 2)) -> (a, b) mm/N
        Usually a provider's ``point_compliance``.
    targets, sources : (M, 2), (N, 2) arrays, mm
    exclude : sparse (M, N), optional
        Pairs left out (stored entries).
    """

    def __init__(self, kernel: Callable, targets, sources, exclude=None):
        self.kernel = kernel
        self.targets = check_points(targets, "targets")
        self.sources = check_points(sources, "sources")
        self.exclude = check_exclude(exclude, *self.shape)
        m, n = self.shape
        self._rows = max(1, CHUNK_ENTRIES // max(n, 1))
        self._matrix = self._block(0, m) if m * n <= KEEP_ENTRIES else None

    def _block(self, i0: int, i1: int) -> np.ndarray:
        G = np.array(self.kernel(self.targets[i0:i1], self.sources), dtype=float)
        G[~np.isfinite(G)] = 0.0
        if self.exclude is not None:
            sub = self.exclude[i0:i1].tocoo()
            G[sub.row, sub.col] = 0.0
        return G

    def apply(self, forces):
        F = self._check_forces(forces)
        if self._matrix is not None:
            return self._matrix @ F
        m = self.shape[0]
        out = np.empty((m,) + F.shape[1:])
        for i0 in range(0, m, self._rows):
            i1 = min(m, i0 + self._rows)
            out[i0:i1] = self._block(i0, i1) @ F
        return out
