"""Cross-patch coupling with the far field approximated (issue 6: many asperities).

The exact coupling (:class:`~.blocks.Coupling`) applies every ``A_kl``: ``N^2`` products per
sweep. Here a pair is *near* when the distance between the patch centres is below
``(r_k + r_l) / sqrt(far_tol)`` (``r`` = half-diagonal of a patch, mm) and is applied
exactly; every other patch ``l`` acts on patch ``k`` through its resultant force placed at
its centre of pressure (``provider.point_compliance``), evaluated at the 3 x 3 corners,
edge midpoints and centre of patch ``k`` and interpolated biquadratically on its cells.

Error of one far pair, relative to that pair's displacement: the resultant at the centre of
pressure drops the quadrupole, of order ``(r_l / dist)^2 <= far_tol``; the interpolation
error is of order ``(r_k / dist)^3``. Memory: the near operators plus O(N) numbers for the
resultants and O(cells) for the interpolation weights; no ``N^2`` table.
The provider is only asked for ``point_compliance``, so any body works (the finite-block
provider's correction is smooth, so its far field is as well represented as the half-space's).
"""
from __future__ import annotations

import math

import numpy as np

from ..influence.base import InfluenceProvider
from .blocks import Coupling, scatter


def _lagrange3(xi: np.ndarray) -> np.ndarray:
    """Quadratic Lagrange weights at nodes -1, 0, 1 for points ``xi`` (n,) -> (n, 3)."""
    return np.column_stack([0.5 * xi * (xi - 1.0), 1.0 - xi * xi, 0.5 * xi * (xi + 1.0)])


class FarFieldCoupling(Coupling):
    """:class:`~.blocks.Coupling` with near pairs exact and far pairs by resultants.

    Parameters
    ----------
    provider : InfluenceProvider
    patches : sequence of Patch
    far_tol : float, default 0.01
        Relative error accepted on the displacement due to one far patch, 0 < far_tol < 1;
        pairs with ``dist < (r_k + r_l) / sqrt(far_tol)`` are exact.
    **kwargs
        Passed to :class:`~.blocks.Coupling` (``dense_max_entries``, ``cache_bytes``).

    Attributes
    ----------
    far_products, near_products : int
        Counters of far-field evaluations (one per target block) and exact pair products.
    """

    def __init__(self, provider: InfluenceProvider, patches, *, far_tol: float = 0.01, **kwargs):
        if isinstance(far_tol, bool) or not isinstance(far_tol, (int, float)) or not (0.0 < far_tol < 1.0):
            raise ValueError(f"far_tol must be a number in (0, 1), got {far_tol!r}")
        super().__init__(provider, patches, **kwargs)
        self.far_tol = float(far_tol)
        self.far_products = 0
        self.near_products = 0
        self._reset()

    # ------------------------------------------------------------------ geometry
    def _reset(self) -> None:
        n = len(self.patches)
        self._centres = np.zeros((n, 2))
        self._radii = np.zeros(n)
        for k, pt in enumerate(self.patches):
            xmin, xmax, ymin, ymax = pt.grid.bounds
            self._centres[k] = 0.5 * (xmin + xmax), 0.5 * (ymin + ymax)
            self._radii[k] = 0.5 * math.hypot(xmax - xmin, ymax - ymin)
        self._near: dict = {}
        self._weights: dict = {}
        self._cells: dict = {}
        self._seen: list = [None] * n
        self._F = None

    def append(self, patch) -> None:
        super().append(patch)
        self._reset()

    def replace(self, k: int, patch) -> None:
        super().replace(k, patch)
        self._reset()

    def near(self, k: int) -> np.ndarray:
        """Indices ``l != k`` of the patches coupled exactly to patch ``k``."""
        out = self._near.get(k)
        if out is None:
            dist = np.hypot(*(self._centres - self._centres[k]).T)
            mask = dist * math.sqrt(self.far_tol) < self._radii + self._radii[k]
            mask[k] = False
            out = np.flatnonzero(mask)
            self._near[k] = out
        return out

    def _stencil(self, k: int) -> np.ndarray:
        g = self.patches[k].grid
        xs = g.x0 + 0.5 * (g.nx - 1) * g.h * np.array([0.0, 1.0, 2.0])
        ys = g.y0 + 0.5 * (g.ny - 1) * g.h * np.array([0.0, 1.0, 2.0])
        X, Y = np.meshgrid(xs, ys)          # (3 y, 3 x)
        return np.column_stack([X.ravel(), Y.ravel()])

    def _interpolation(self, k: int, whole: bool) -> np.ndarray:
        """Weights (n_cells, 9) from the stencil values to the cells (owned or whole patch)."""
        key = (k, whole)
        w = self._weights.get(key)
        if w is None:
            g = self.patches[k].grid
            xi = (np.arange(g.nx) - 0.5 * (g.nx - 1)) / max(0.5 * (g.nx - 1), 1e-300)
            eta = (np.arange(g.ny) - 0.5 * (g.ny - 1)) / max(0.5 * (g.ny - 1), 1e-300)
            W = np.einsum("ja,ib->jiab", _lagrange3(eta), _lagrange3(xi)).reshape(g.ny * g.nx, 9)
            w = W if whole else W[self.patches[k].owned.ravel()]
            self._weights[key] = w
        return w

    def _owned_points(self, l: int) -> np.ndarray:
        pts = self._cells.get(l)
        if pts is None:
            pt = self.patches[l]
            X, Y = pt.grid.centres()
            pts = np.column_stack([X[pt.owned], Y[pt.owned]])
            self._cells[l] = pts
        return pts

    # ------------------------------------------------------------------ resultants
    def _resultants(self, values: list) -> tuple[np.ndarray, np.ndarray]:
        """Force (N, m) in N and its point of application (N, m, 2) in mm of every block;
        only blocks whose vector object changed since the last call are recomputed."""
        first = next((v for v in values if v is not None), None)
        m = 1 if first is None or first.ndim == 1 else first.shape[1]
        n = len(values)
        if self._F is None or self._F.shape != (n, m):
            self._F = np.zeros((n, m))
            self._C = np.repeat(self._centres[:, None, :], m, axis=1)
            self._seen = [None] * n
            self._ids = np.zeros(n, dtype=np.int64)
        # identity test by id(): the vectors seen are kept alive in _seen, so an id
        # cannot be reused by a new vector while it is cached
        ids = np.fromiter(map(id, values), dtype=np.int64, count=n)
        stale = np.flatnonzero(ids != self._ids)
        self._ids = ids
        for l in stale:
            v = values[l].reshape(len(values[l]), -1)
            h2 = self.patches[l].grid.h ** 2
            pts = self._owned_points(l)
            F = h2 * v.sum(axis=0)
            first_moment = h2 * (pts.T @ v)            # (2, m)
            C = np.repeat(self._centres[l][:, None], m, axis=1)
            # the centre of pressure when it is meaningful (inside the patch), else the centre
            with np.errstate(divide="ignore", invalid="ignore"):
                cp = first_moment / F
            ok = np.isfinite(cp).all(axis=0) & (np.hypot(*(cp - C)) <= self._radii[l])
            C[:, ok] = cp[:, ok]
            self._F[l], self._C[l] = F, C.T
            self._seen[l] = values[l]
        return self._F, self._C

    def _far(self, k: int, values: list, whole: bool) -> np.ndarray:
        """Far-field displacement on block ``k`` (owned cells, or whole patch), (n, m) mm."""
        F, C = self._resultants(values)
        far = np.ones(len(values), bool)
        far[self.near(k)] = False
        far[k] = False
        far &= np.any(F != 0.0, axis=1)
        W = self._interpolation(k, whole)
        if not far.any():
            return np.zeros((W.shape[0], F.shape[1]))
        self.far_products += 1
        stencil = self._stencil(k)
        u9 = np.column_stack([self.provider.point_compliance(stencil, C[far, j]) @ F[far, j]
                              for j in range(F.shape[1])])
        return W @ u9

    # ------------------------------------------------------------------ products
    def rhs(self, k: int, values: list, rhs: np.ndarray) -> np.ndarray:
        """``rhs - sum_{l != k} A_kl v_l``: near pairs exact, far ones by resultants (mm)."""
        out = rhs.copy()
        for l in self.near(k):
            v = values[l]
            if np.any(v):
                out -= self.apply(k, int(l), v)
                self.near_products += 1
        far = self._far(k, values, whole=False)
        out -= far[:, 0] if rhs.ndim == 1 else far
        return out

    def patch_displacement(self, k: int, values: list) -> np.ndarray:
        """Displacement (mm) on the whole patch ``k`` from the other blocks (near exact)."""
        u = np.zeros(self.patches[k].grid.shape)
        for l in self.near(k):
            v = values[l]
            if np.any(v):
                u += self.full_operator(k, int(l)).apply(scatter(self.patches[l], v))
        return u + self._far(k, values, whole=True)[:, 0].reshape(u.shape)
