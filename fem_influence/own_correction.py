"""A grid's correction of itself, from separable factors kept per grid.

The lagged part of a local solve on the block (:mod:`twoscale.micro.pk_stack`) is the
correction that a patch's own pressure ``p`` makes on its own cells, at every local solve
of every sweep: ``evaluate(grid, coefficients(grid, p))`` of
:class:`~fem_influence.operators.BlockCorrection`, which scatters the lattice-node forces
into a vector over every solved node, finds its non-zeros again and cuts the table's rows
and columns each time (5,930 spheres: 62,782 calls, a tenth of the solve profiled).

On a rectilinear top face every factor is a tensor product, so per grid this keeps

* the source weights onto the lattice nodes, one axis at a time (``wy``, ``wx``:
  :class:`~fem_influence.grid_factors.GridWeights`');
* the table's rows of the top-face nodes around the grid on the columns of those lattice
  nodes (over E), ``T`` (``ry rx`` x ``ly lx``);
* the top-face interpolation at the cells, one axis at a time (``my``, ``mx``).

and the correction is ``h^2 My (T (Wy P Wx^T)) Mx^T``: four small products, the same
numbers up to the order of the sums. The factors hold ~2 KB a grid.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twoscale.grid import Grid

if TYPE_CHECKING:
    from .provider import BlockProvider


class OwnCorrection:
    """``C p`` on a grid's cells for pressure ``p`` on the same grid (module docstring)."""

    def __init__(self, grid: Grid, wy, wx, T: np.ndarray, my: np.ndarray, mx: np.ndarray):
        self._wy, self._wxT, self._T, self._my, self._mxT = wy, wx.T.copy(), T, my, mx.T.copy()
        self._area, self._shape = grid.h**2, grid.shape
        self._nodes = (my.shape[1], mx.shape[1])

    def __call__(self, p: np.ndarray) -> np.ndarray:
        """The correction (mm) on the grid's cells, ``grid.shape``, from ``p`` (MPa) on them."""
        C = (self._wy @ np.asarray(p, dtype=float).reshape(self._shape)) @ self._wxT
        V = (self._T @ C.ravel()).reshape(self._nodes)
        return self._area * ((self._my @ V) @ self._mxT)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self._wy, self._wxT, self._T, self._my, self._mxT))


def own_correction(provider: "BlockProvider", grid: Grid) -> OwnCorrection | None:
    """The :class:`OwnCorrection` of ``grid`` (scene frame), or None where the top face is
    not rectilinear."""
    from .grid_factors import _axis_weights, grid_weights
    from .interpolate import _quadratic_weights

    nodes, W = grid_weights(provider, grid)
    cols = provider._ensure(nodes)  # the first fields solved also make the interpolator
    top = provider._state.interpolator
    if not top.rectilinear:
        return None
    ox, oy = provider.origin
    x_nodes, mx = _axis_weights(grid.x, *_quadratic_weights(grid.x + ox, top._xs))
    y_nodes, my = _axis_weights(grid.y, *_quadratic_weights(grid.y + oy, top._ys))
    rows = top._node[np.ix_(y_nodes, x_nodes)].ravel()
    T = provider._state.table[np.ix_(rows, cols)] / provider.material.E
    return OwnCorrection(grid, W.wy, W.wx, T, my.T.copy(), mx.T.copy())
