"""The block's correction of a stack of grids on themselves, in one pass of batched products.

A local solve on an FFT block of the finite block lags the correction of its own box: its
right-hand side less ``h^2 M T W p`` at its previous pressure ``p`` (the half-space part is
the canvases' operator, the correction is not). The factors of a grid are separable
(:mod:`fem_influence.grid_factors`): the source weights ``W = Wy (x) Wx`` onto the lattice
nodes around it, the top-face interpolation ``M = My (x) Mx`` from the nodes around it, and
``T`` the table's values of those nodes from those lattice nodes. For grids placed in the
corner of canvases of one shape (the stacked local solves' size classes) they are padded
with zeros to the stack's largest and applied to all canvases at once:

``C_b = Wy_b P_b Wx_b^T``, ``V_b = T_b C_b``, ``U_b = My_b V_b Mx_b^T``,

a few small batched matrix products instead of one call a block and sweep (5,930 spheres:
62,782 calls of about 60 us, mostly the calls' own Python). The sums run in another order
than the dense factors' products (rounding only).
"""

from __future__ import annotations

import numpy as np


class StackedCorrection:
    """``h^2 M T W p`` of each grid of a stack on itself, for pressures on canvases.

    Parameters
    ----------
    factors : list of (wy, wx, T, my, mx, area)
        Each grid's source weights ``wy`` (sy, ny), ``wx`` (sx, nx), table cut ``T``
        (ry * rx, sy * sx) (mm/N), interpolation ``my`` (ny, ry), ``mx`` (nx, rx) and cell
        area ``h^2`` (mm^2).
    shape : (int, int)
        The canvases' shape (at least every grid's).
    """

    def __init__(self, factors: list, shape: tuple[int, int]):
        n = len(factors)
        ny, nx = shape
        sy = max(f[0].shape[0] for f in factors)
        sx = max(f[1].shape[0] for f in factors)
        ry = max(f[3].shape[1] for f in factors)
        rx = max(f[4].shape[1] for f in factors)
        self.wy, self.wxt = np.zeros((n, sy, ny)), np.zeros((n, nx, sx))
        self.T = np.zeros((n, ry, rx, sy, sx))
        self.my, self.mxt = np.zeros((n, ny, ry)), np.zeros((n, rx, nx))
        for b, (wy, wx, T, my, mx, area) in enumerate(factors):
            (a, gy), (c, gx) = wy.shape, wx.shape
            (_, py), (_, px) = my.shape, mx.shape
            self.wy[b, :a, :gy] = area * wy
            self.wxt[b, :gx, :c] = wx.T
            self.T[b, :py, :px, :a, :c] = T.reshape(py, px, a, c)
            self.my[b, :gy, :py] = my
            self.mxt[b, :px, :gx] = mx.T
        self.T = self.T.reshape(n, ry * rx, sy * sx)

    def apply(self, P: np.ndarray) -> np.ndarray:
        """The correction (mm) on the canvases (B, ny, nx) of the pressures ``P`` (MPa) there
        (zero off each grid's cells)."""
        n, ry, rx = self.my.shape[0], self.my.shape[2], self.mxt.shape[1]
        C = (self.wy @ P) @ self.wxt  # (B, sy, sx)
        V = (self.T @ C.reshape(n, -1, 1)).reshape(n, ry, rx)
        return (self.my @ V) @ self.mxt

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.wy, self.wxt, self.T, self.my, self.mxt))
