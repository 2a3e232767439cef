"""The block's correction in factored form, for solvers that keep it apart from the
half-space part (:meth:`~fem_influence.provider.BlockProvider.split`).

Coefficients are forces on the correction lattice's nodes; a grid's are its source
weights times its pressure, and their displacement on a grid the top-face interpolation
of the field table's columns. Three forms: the contract's (a vector over every lattice
node), a grid on itself (:meth:`BlockCorrection.on_itself`, :meth:`BlockCorrection.own_stack`
for a stack of canvases), and the near pairs' compact one (:meth:`BlockCorrection.compact`,
:meth:`BlockCorrection.near_sum`: a source's own nodes only, the table's cut kept per pair).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twoscale.grid import Grid
from twoscale.influence.base import LowRankCorrection

if TYPE_CHECKING:
    from .provider import BlockProvider

#: Pairs whose cut of the field table :meth:`BlockCorrection.near_sum` keeps (9 x 16 values
#: each on a patch; beyond, all are dropped and made again on use).
PAIR_CUTS = 50_000


class BlockCorrection(LowRankCorrection):
    """The block's correction in factored form (:meth:`BlockProvider.split`): coefficients are
    forces (N, for E = 1 fields scaled by 1/E at evaluation) on the correction lattice
    nodes, indexed like the provider's field table."""

    def __init__(self, provider: "BlockProvider"):
        self._p = provider
        self._own: dict = {}  # per grid: the table's rows and columns of its own correction
        self._pairs: dict = {}  # per (target, source) grid: the table's cut of the pair

    def on_itself(self, grid: Grid, p: np.ndarray) -> np.ndarray:
        """``evaluate(grid, coefficients(grid, p))`` (``grid.shape``, mm): a local solve's
        lagged correction of its own box at every solve of every sweep (5,930 spheres: 62,782
        calls, a tenth of the solve profiled), as ``h^2 M (T_g (W p))`` with the grid's kept
        source weights ``W`` and interpolation ``M`` and the table's rows and columns they
        use ``T_g``, kept here per grid (a few hundred bytes): no vector over every lattice
        node scattered, searched and cut again at each call."""
        st, (cols, W) = self._p._state, self._p._source_weights(grid)  # the fields solved first
        if not st.interpolator.rectilinear:
            return self.evaluate(grid, self.coefficients(grid, p))
        M, rows = st.interpolation(grid, self._p.origin)
        T = self._own.get(grid)
        if T is None:
            T = self._own[grid] = st.scaled_table(self._p.material.E)[np.ix_(rows, cols)]
        c = grid.h**2 * (W @ np.asarray(p, dtype=float).ravel())
        return (M @ (T @ c)).reshape(grid.shape)

    def own_stack(self, grids: list, shape: tuple[int, int]):
        """:meth:`on_itself` of every grid of ``grids`` at once, for pressures on canvases of
        ``shape`` whose corner is each grid's (:class:`~.stacked_correction.StackedCorrection`),
        or None where a grid's factors are not separable (a top face not rectilinear, a
        grid across many elements)."""
        from .grid_factors import GridWeights, KronMatrix
        from .stacked_correction import StackedCorrection

        st, factors = self._p._state, []
        for grid in grids:
            cols, W = self._p._source_weights(grid)
            if not (st.interpolator.rectilinear and isinstance(W, GridWeights)):
                return None
            M, rows = st.interpolation(grid, self._p.origin)
            if not isinstance(M, KronMatrix):
                return None
            T = self._own.get(grid)
            if T is None:
                T = self._own[grid] = st.scaled_table(self._p.material.E)[np.ix_(rows, cols)]
            factors.append((W.wy, W.wx, T, M.my, M.mx, grid.h**2))
        return StackedCorrection(factors, shape) if factors else None

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
            nz = np.flatnonzero(c)
            if 2 * len(nz) < len(c):
                # a few near sources' nodes: the table's rows around the grid on their
                # columns only (the same sums as the factor's own sparse product)
                st = self._p._state
                M, rows = st.interpolation(target, self._p.origin)
                T = st.scaled_table(self._p.material.E)
                return (M @ (T[rows[:, None], nz] @ c[nz])).reshape(target.shape)
            return (self._p._target_factor(target) @ c).reshape(target.shape)
        nz = np.flatnonzero(c)
        return (self._p._target_factor(target, nz) @ c[nz]).reshape(target.shape)

    def at_points(self, targets: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The correction at ``targets`` (scene frame, (M, 2), mm) from the coefficients ``c``:
        the top-face interpolation of the field table's columns of the nodes ``c`` loads."""
        nz = np.flatnonzero(np.asarray(c, dtype=float))
        if nz.size == 0:
            return np.zeros(len(targets))
        nodes = self._p._state.nodes_of(nz)
        return self._p._top_values(targets, nodes) @ np.asarray(c, dtype=float)[nz]

    def compact(self, source: Grid, p: np.ndarray) -> tuple:
        """:meth:`coefficients` on the source grid's own lattice nodes: ``(columns, values)``,
        not a vector over every node (a near pair's source: 16 of ~620)."""
        cols, W = self._p._source_weights(source)
        return cols, source.h**2 * (W @ np.asarray(p, dtype=float).ravel())

    def near_sum(self, target: Grid, terms: list) -> np.ndarray:
        """``evaluate(target, sum of coefficients)`` for ``terms`` = [(source grid, its
        :meth:`compact` coefficients)]: the table's rows around the target on each source's
        columns, kept per pair, the terms summed on those rows and interpolated once (the
        near sums of 5,930 spheres: 47,410 targets a solve, each of a few sources)."""
        st = self._p._state
        if not st.interpolator.rectilinear:
            c = np.zeros(st.table.shape[1])
            for _, (cols, vals) in terms:
                c[cols] += vals
            return self.evaluate(target, c)
        M, rows = st.interpolation(target, self._p.origin)
        cuts, V = self._pairs, None
        if len(cuts) > PAIR_CUTS:
            cuts.clear()
        for source, (cols, vals) in terms:
            G = cuts.get((target, source))
            if G is None:
                G = cuts[(target, source)] = st.scaled_table(self._p.material.E)[np.ix_(rows, cols)]
            V = G @ vals if V is None else V + G @ vals
        return np.zeros(target.shape) if V is None else (M @ V).reshape(target.shape)
