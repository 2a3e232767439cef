"""Cross-patch coupling with the far field approximated (issue 6: many asperities).

The exact coupling (:class:`~.blocks.Coupling`) applies every ``A_kl``: ``N^2`` products per
sweep. Here a pair is *near* when the distance between the patch centres is below
``(r_k + r_l) / sqrt(far_tol)`` (``r`` = half-diagonal of a patch, mm) and is applied
exactly; every other patch ``l`` acts on patch ``k`` through its resultant force placed at
its centre of pressure (``provider.point_compliance``), evaluated at the 3 x 3 corners,
edge midpoints and centre of patch ``k`` and interpolated biquadratically on its cells.

Optionally (``bins=True``, experimental) with ``BIN_MIN`` or more patches, far patches are grouped in square bins; a bin
farther than ``(r_k + b / sqrt 2) / sqrt(far_tol)`` from patch ``k`` acts through its total
force at its centre of force (side ``b`` chosen so that bins and single sources cost about
the same), which brings the far field from ``9 N^2`` to about ``N^1.5`` kernel values per sweep.

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
from .blocks import Coupling


#: Patches at which the far field starts to use bins (below: every far patch on its own).
BIN_MIN = 400


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
    bins : bool, default False
        Group distant patches in bins (experimental: at N = 1,000 it cost accuracy, 3 %
        force error at far_tol 0.2 against 0.4 % without, and sweeps; see
        docs/scaling_status.md).
    **kwargs
        Passed to :class:`~.blocks.Coupling` (``dense_max_entries``, ``cache_bytes``).

    Attributes
    ----------
    far_products, near_products : int
        Counters of far-field evaluations (one per target block) and exact pair products.
    """

    def __init__(self, provider: InfluenceProvider, patches, *, far_tol: float = 0.01, bins: bool = False,
                 **kwargs):
        if isinstance(far_tol, bool) or not isinstance(far_tol, (int, float)) or not (0.0 < far_tol < 1.0):
            raise ValueError(f"far_tol must be a number in (0, 1), got {far_tol!r}")
        super().__init__(provider, patches, **kwargs)
        self.far_tol = float(far_tol)
        self.use_bins = bool(bins)
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
        self._bins(n)

    def _bins(self, n: int) -> None:
        """Square bins grouping the patches for the distant far field (``n >= BIN_MIN``).

        Side ``b = (2 far_tol A / (pi rho))^(1/4)`` (A the scene's area, rho = n / A)
        balances the number of bins against the sources within the bin cut; never below
        four patch radii."""
        self._bin = None
        self._bin_far: dict = {}
        if not self.use_bins or n < BIN_MIN:
            return
        lo = self._centres.min(axis=0)
        span = np.maximum(self._centres.max(axis=0) - lo, 1e-12)
        area = float(span[0] * span[1]) or float(max(span) ** 2)
        b = max((2.0 * self.far_tol * area * area / (math.pi * n)) ** 0.25, 4.0 * float(self._radii.max()))
        ij = np.floor((self._centres - lo) / b).astype(np.int64)
        keys, self._bin = np.unique(ij[:, 0] * (1 << 32) + ij[:, 1], return_inverse=True)
        self._bin = self._bin.ravel()
        self._bin_size = b
        self._bin_centres = lo + b * (np.column_stack([keys >> 32, keys & ((1 << 32) - 1)]) + 0.5)

    def _far_bins(self, k: int) -> np.ndarray:
        """Bins far enough from patch ``k`` to act through their total force (bool per bin)."""
        out = self._bin_far.get(k)
        if out is None:
            half = self._bin_size / math.sqrt(2.0)
            dist = np.hypot(*(self._bin_centres - self._centres[k]).T)
            out = dist * math.sqrt(self.far_tol) >= self._radii[k] + half
            out[self._bin[self.near(k)]] = False
            out[self._bin[k]] = False
            self._bin_far[k] = out
        return out

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
        # the sweeps replace a block's vector when it changes (never modify it): a block is
        # stale when its vector is not the very object seen last time
        stale = [l for l, (v, seen) in enumerate(zip(values, self._seen)) if v is not seen and v is not None]
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
        bins = None if self._bin is None else self._far_bins(k)
        if bins is not None:
            far &= ~bins[self._bin]          # sources in far bins act through the bin totals
        far &= np.any(F != 0.0, axis=1)
        W = self._interpolation(k, whole)
        self.far_products += 1
        stencil = self._stencil(k)
        cols = []
        for j in range(F.shape[1]):
            pts, forces = C[far, j], F[far, j]
            if bins is not None:
                bp, bf = self._bin_sources(F[:, j], C[:, j], bins)
                pts, forces = np.concatenate([pts, bp]), np.concatenate([forces, bf])
            cols.append(self.provider.point_compliance(stencil, pts) @ forces if len(forces) else np.zeros(9))
        return W @ np.column_stack(cols)

    def _bin_sources(self, F: np.ndarray, C: np.ndarray, bins: np.ndarray):
        """Total force of each far bin at its centre of force (bin centre when that is
        outside the bin, e.g. forces of both signs); returns (points (M, 2), forces (M,))."""
        nb = len(self._bin_centres)
        Fb = np.bincount(self._bin, F, minlength=nb)
        Mb = np.column_stack([np.bincount(self._bin, F * C[:, 0], minlength=nb),
                              np.bincount(self._bin, F * C[:, 1], minlength=nb)])
        use = bins & (Fb != 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            cp = Mb[use] / Fb[use, None]
        centre = self._bin_centres[use]
        bad = ~np.isfinite(cp).all(axis=1) | (np.abs(cp - centre).max(axis=1) > 0.5 * self._bin_size)
        cp[bad] = centre[bad]
        return cp, Fb[use]

    # ------------------------------------------------------------------ products
    def rhs(self, k: int, values: list, rhs: np.ndarray) -> np.ndarray:
        """``rhs - sum_{l != k} A_kl v_l``: near pairs exact, far ones by resultants (mm)."""
        out = rhs.copy()
        near = [int(l) for l in self.near(k)]
        self.near_products += sum(1 for l in near if values[l] is not None and np.any(values[l]))
        self._subtract(k, near, values, out)
        far = self._far(k, values, whole=False)
        out -= far[:, 0] if rhs.ndim == 1 else far
        return out

    def patch_displacement(self, k: int, values: list) -> np.ndarray:
        """Displacement (mm) on the whole patch ``k`` from the other blocks (near exact)."""
        shape = self.patches[k].grid.shape
        u = self._sum(k, [int(l) for l in self.near(k)], values, whole=True)
        u = np.zeros(shape) if u is None else u
        return u + self._far(k, values, whole=True)[:, 0].reshape(shape)


class LaggedFarField(FarFieldCoupling):
    """:class:`FarFieldCoupling` whose far field is computed for every block at once and
    held until :meth:`refresh` (a Jacobi far field inside a Gauss-Seidel sweep).

    Each far patch acts through **nine point forces** on a 3 x 3 lattice over its patch
    (nodes at the centre and ``+-(sqrt 3 / 2) a`` along each axis, ``a`` the half-width
    from the centre to the outer cell centres), whose strengths are the patch's pressure
    integrated against the biquadratic Lagrange functions of those nodes
    (:func:`source_strengths`). They reproduce every moment ``x^i y^j`` (``i, j <= 2``)
    of the patch's load: its resultant, centre of pressure and second moments, so the
    error a far patch makes falls as ``(r / dist)^3`` instead of the ``(r / dist)^2`` of a
    resultant at the centre of pressure (or ``r / dist`` of a resultant at the tip when
    the load is off-centre, as on a measured stone's basin). The displacement at the
    3 x 3 stencils of all blocks is one ``provider.point_operator`` product (an FFT for
    the half-space, exact chunks otherwise) with the near pairs and the block itself
    excluded. Per sweep this costs ``O(N)`` (fast operator) instead of the ``9 N^2``
    kernel values of :class:`FarFieldCoupling`. Held values are stale for the blocks
    updated since the last refresh: the two-level iteration (:mod:`.twolevel`) refreshes
    once per sweep and corrects the smooth error that this leaves by its coarse step.
    Near lists come from a k-d tree (``O(N log N)``), and a patch that grows updates only
    its own geometry.

    Parameters
    ----------
    provider, patches, far_tol : as :class:`FarFieldCoupling`
    rtol : float, default 1e-6
        Accuracy asked of the provider's point operator.
    """

    def __init__(self, provider: InfluenceProvider, patches, *, far_tol: float = 0.2,
                 rtol: float = 1e-6, **kwargs):
        self._rtol = float(rtol)
        super().__init__(provider, patches, far_tol=far_tol, **kwargs)

    def _reset(self) -> None:
        super()._reset()
        self._op = None
        self._table = None

    def _moved(self, k: int) -> None:
        """Patch ``k`` changed: its geometry, and every cache that depends on it."""
        xmin, xmax, ymin, ymax = self.patches[k].grid.bounds
        self._centres[k] = 0.5 * (xmin + xmax), 0.5 * (ymin + ymax)
        self._radii[k] = 0.5 * math.hypot(xmax - xmin, ymax - ymin)
        self._near = {}
        for key in [(k, False), (k, True)]:
            self._weights.pop(key, None)
        self._cells.pop(k, None)
        self._op = None
        self._table = None
        self._F = None

    def append(self, patch) -> None:
        Coupling.append(self, patch)
        self._centres = np.vstack([self._centres, np.zeros((1, 2))])
        self._radii = np.append(self._radii, 0.0)
        self._seen.append(None)
        self._moved(len(self.patches) - 1)

    def replace(self, k: int, patch) -> None:
        Coupling.replace(self, k, patch)
        self._moved(k)

    def near(self, k: int) -> np.ndarray:
        if not self._near:
            self._near_all()
        return self._near[k]

    def _near_all(self) -> None:
        # pairs with dist < (r_k + r_l) / sqrt(far_tol): candidates within (r_k + r_max) / sqrt(far_tol)
        from scipy.spatial import cKDTree
        n = len(self.patches)
        scale = 1.0 / math.sqrt(self.far_tol)
        tree = cKDTree(self._centres)
        rmax = float(self._radii.max()) if n else 0.0
        cands = tree.query_ball_point(self._centres, (self._radii + rmax) * scale)
        for k, cand in enumerate(cands):
            cand = np.asarray(cand, dtype=np.int64)
            dist = np.hypot(*(self._centres[cand] - self._centres[k]).T)
            keep = (dist * math.sqrt(self.far_tol) < self._radii[cand] + self._radii[k]) & (cand != k)
            self._near[k] = np.sort(cand[keep])

    def near_pattern(self):
        """Sparse (N, N) pattern of the near pairs (patch indices, ``k`` excluded)."""
        import scipy.sparse as sp
        n = len(self.patches)
        cols = [self.near(k) for k in range(n)]
        rows = np.repeat(np.arange(n), [len(c) for c in cols])
        cols = np.concatenate(cols) if n else np.zeros(0, np.int64)
        return sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))

    def _point_operator(self):
        if self._op is None:
            import scipy.sparse as sp
            n = len(self.patches)
            sources = np.concatenate([source_nodes(pt.grid)[0] for pt in self.patches])
            targets = np.concatenate([self._stencil(k) for k in range(n)])
            near = self.near_pattern() + sp.identity(n, format="csr")
            # stencil row 9k + i excludes the nine sources of the patches near k and of k
            exclude = sp.kron(near, np.ones((9, 9)), format="csr")
            self._op = self.provider.point_operator(targets, sources, exclude=exclude, rtol=self._rtol)
        return self._op

    def refresh(self, values: list) -> None:
        """Recompute the far field on every stencil from the block vectors ``values``."""
        n = len(self.patches)
        first = next((v for v in values if v is not None and v.size), None)
        m = 1 if first is None or first.ndim == 1 else first.shape[1]
        S = np.zeros((n, 9, m))
        for l, v in enumerate(values):
            if v is not None and v.size:   # a block can own no cell (a neighbour owns its patch)
                g = self.patches[l].grid
                _, centre, delta = source_nodes(g)
                S[l] = source_strengths(self._owned_points(l), v.reshape(len(v), -1), centre, delta, g.h)
        self._table = self._point_operator().apply(S.reshape(9 * n, m)).reshape(n, 9, m)
        self.far_products += 1

    def _far(self, k: int, values: list, whole: bool) -> np.ndarray:
        first = next((v for v in values if v is not None and v.size), None)
        m = 1 if first is None or first.ndim == 1 else first.shape[1]
        if self._table is None or self._table.shape[2] != m:
            self.refresh(values)
        return self._interpolation(k, whole) @ self._table[k]


#: Position of the outer source nodes, in half-widths of the patch: the zeros of the
#: third Chebyshev polynomial, which minimise the largest interpolation error over it.
SOURCE_NODE = math.sqrt(3.0) / 2.0


def source_nodes(grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nine far-field source points of a patch on ``grid``: ``(points (9, 2) mm,
    centre (2,) mm, delta (2,) mm)``, row-major over (y, x) like the stencils; ``delta``
    is the node offset along x and y (at least ``h / 2``)."""
    xmin, xmax, ymin, ymax = grid.bounds
    centre = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)])
    half = 0.5 * grid.h * np.array([grid.nx - 1, grid.ny - 1], dtype=float)
    delta = np.maximum(SOURCE_NODE * half, 0.5 * grid.h)
    X, Y = np.meshgrid(centre[0] + delta[0] * np.array([-1.0, 0.0, 1.0]),
                       centre[1] + delta[1] * np.array([-1.0, 0.0, 1.0]))
    return np.column_stack([X.ravel(), Y.ravel()]), centre, delta


def source_strengths(points: np.ndarray, values: np.ndarray, centre: np.ndarray, delta: np.ndarray,
                     h: float) -> np.ndarray:
    """Forces (9, m) N at :func:`source_nodes` with the moments ``x^i y^j`` (``i, j <= 2``)
    of the pressure ``values`` (n, m) MPa on the cells centred at ``points`` (n, 2) mm."""
    lx = _lagrange3((points[:, 0] - centre[0]) / delta[0])
    ly = _lagrange3((points[:, 1] - centre[1]) / delta[1])
    return (h * h) * np.einsum("nb,na,nm->bam", ly, lx, values).reshape(9, -1)
