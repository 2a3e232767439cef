"""The far field's point operator kept while a few patches change.

:class:`~.farfield.LaggedFarField` sums the far patches' nine point forces on the 3 x 3
stencils of every patch with one ``provider.point_operator`` over all patches, the near
pairs and each patch itself left out. When a patch grows or a few patches merge, the
other patches' source nodes, stencils and near pairs stay what they were: only the rows
and columns of the changed patches differ. :class:`KeptPointOperator` applies the
operator built for the earlier patches on the pairs of unchanged patches, and the changed
patches' rows and columns exactly from ``provider.point_compliance`` (dense, ``9 c x 9 N``
numbers twice for ``c`` changed patches among ``N``), so a merge after the first sweep
does not build the operator again (1,383 patches: the Ewald build of 12,000 points,
0.35-0.6 s of CPU, against 9 x 12,000 kernel values).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..influence.points import PointOperator

#: Most kernel values the changed patches' rows and columns may hold (8 bytes each, 48 MB);
#: beyond it the far field builds its operator again. 4,548 paraboloids: seven patches
#: changed among 4,377 hold 5.0M values, made in well under the 1.4 s of CPU a build took.
KEPT_MAX_ENTRIES = 6_000_000


def _rows(patches: np.ndarray) -> np.ndarray:
    """The nine stencil (or source) rows ``9 k + i`` of each patch ``k``."""
    return (9 * np.asarray(patches, dtype=np.int64)[:, None] + np.arange(9)).ravel()


class KeptPointOperator(PointOperator):
    """Point operator over the patches' source nodes and stencils made from ``base``, the
    operator of earlier patches, and exact rows and columns for the changed ones.

    Parameters
    ----------
    provider : InfluenceProvider
        Gives ``point_compliance`` for the changed patches' rows and columns.
    base : PointOperator
        The operator built for the earlier patches (their ``9 N_b`` stencils and sources).
    index : (N,) int array
        Index of each patch among the earlier patches where it is the same patch, -1 where
        it changed (or is new).
    targets, sources : (9 N, 2) arrays, mm
        Stencils and source nodes of the patches now.
    near : sparse (N, N)
        The near pairs now, each patch with itself included: their nine by nine pairs are
        left out, as in the operator built anew.
    """

    def __init__(self, provider, base: PointOperator, index: np.ndarray, targets, sources, near):
        self.targets, self.sources = np.asarray(targets, dtype=float), np.asarray(sources, dtype=float)
        self.base = base
        index = np.asarray(index, dtype=np.int64)
        kept, changed = np.flatnonzero(index >= 0), np.flatnonzero(index < 0)
        self._kept_rows, self._base_rows = _rows(kept), _rows(index[kept])
        self._changed_rows = _rows(changed)
        near = sp.csr_matrix(near, dtype=bool)
        # every source on the changed patches' stencils; the changed sources on the others'
        self._to_changed = self._block(provider, self._changed_rows, np.arange(len(self.sources)), near[changed])
        self._from_changed = self._block(provider, self._kept_rows, self._changed_rows, near[kept][:, changed])

    def _block(self, provider, rows: np.ndarray, cols: np.ndarray, near) -> np.ndarray:
        """Kernel values ``G(targets[rows], sources[cols])`` with the near patches' pairs
        and coincident points zero; ``near`` (len(rows) / 9, len(cols) / 9) by patch."""
        G = np.asarray(provider.point_compliance(self.targets[rows], self.sources[cols]), dtype=float)
        G[~np.isfinite(G)] = 0.0
        mask = np.kron(near.toarray(), np.ones((9, 9), dtype=bool))
        G[mask] = 0.0
        return G

    @staticmethod
    def entries(changed: int, patches: int) -> int:
        """Kernel values held for ``changed`` of ``patches`` patches (at most)."""
        return 2 * 81 * changed * patches

    def apply(self, forces):
        F = self._check_forces(forces)
        F2 = F.reshape(len(F), -1)
        Fb = np.zeros((self.base.shape[1], F2.shape[1]))
        Fb[self._base_rows] = F2[self._kept_rows]
        u = np.zeros((len(self.targets), F2.shape[1]))
        u[self._kept_rows] = self.base.apply(Fb).reshape(len(Fb), -1)[self._base_rows]
        u[self._kept_rows] += self._from_changed @ F2[self._changed_rows]
        u[self._changed_rows] = self._to_changed @ F2
        return u.reshape((len(self.targets),) + F.shape[1:])


def kept_operator(provider, kept: tuple | None, patches: list, targets, sources, near) -> PointOperator | None:
    """The far field's operator for ``patches`` from ``kept`` = ``(operator, the patches it
    was built for)`` where few of them changed (the same patch objects stay), else None
    (no operator kept, or the changed patches' rows and columns would hold more than
    :data:`KEPT_MAX_ENTRIES` kernel values)."""
    if kept is None:
        return None
    base, earlier = kept
    where = {id(pt): j for j, pt in enumerate(earlier)}
    index = np.array([where.get(id(pt), -1) for pt in patches], dtype=np.int64)
    if len(patches) == len(earlier) and np.array_equal(index, np.arange(len(earlier))):
        return base
    if KeptPointOperator.entries(int(np.sum(index < 0)), len(patches)) > KEPT_MAX_ENTRIES:
        return None
    return KeptPointOperator(provider, base, index, targets, sources, near)
