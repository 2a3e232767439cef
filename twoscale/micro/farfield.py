"""Cross-patch coupling with the far field approximated (many asperities).

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

import itertools
import math
import operator

import numpy as np
import scipy.sparse as sp

from ..influence.base import InfluenceProvider
from .blocks import Coupling
from .kept_points import kept_operator
from .level_far import LevelWeights, separable_far
from .localblock import whole_patch, whole_patch_is_large
from .near_window import FIRST_GATHER_ENTRIES
from .sources import SEPARABLE_CELLS, all_source_nodes, all_stencils, all_strengths, grid_interpolation
from .spectral_pairs import level_near


def patch_frames(patches) -> tuple[np.ndarray, np.ndarray]:
    """Centre (N, 2) mm and half-diagonal (N,) mm of each patch's grid."""
    b = np.array([pt.grid.bounds for pt in patches], dtype=float).reshape(-1, 4)
    centres = np.column_stack([0.5 * (b[:, 0] + b[:, 1]), 0.5 * (b[:, 2] + b[:, 3])])
    return centres, 0.5 * np.hypot(b[:, 1] - b[:, 0], b[:, 3] - b[:, 2])


def near_lists(centres: np.ndarray, radii: np.ndarray, far_tol: float) -> list:
    """For each patch, the sorted indices of the others coupled exactly: centres closer
    than ``(r_k + r_l) / sqrt(far_tol)`` (candidates from a k-d tree within
    ``(r_k + r_max) / sqrt(far_tol)``, all patches' in one array)."""
    from scipy.spatial import cKDTree

    n = len(centres)
    if n == 0:
        return []
    cands = cKDTree(centres).query_ball_point(centres, (radii + float(radii.max())) / math.sqrt(far_tol))
    counts = np.fromiter(map(len, cands), dtype=np.int64, count=n)
    cand = np.fromiter(itertools.chain.from_iterable(cands), dtype=np.int64, count=int(counts.sum()))
    k = np.repeat(np.arange(n, dtype=np.int64), counts)
    dist = np.hypot(*(centres[cand] - centres[k]).T)
    keep = (dist * math.sqrt(far_tol) < radii[cand] + radii[k]) & (cand != k)
    cand, k = cand[keep], k[keep]
    return np.split(cand[np.lexsort((cand, k))], np.cumsum(np.bincount(k, minlength=n))[:-1])


def _columns(values: list) -> int:
    """Right-hand sides per block vector: 1 for (n,) vectors, m for (n, m)."""
    first = next((v for v in values if v is not None and v.size), None)
    return 1 if first is None or first.ndim == 1 else first.shape[1]


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
        self._centres, self._radii = patch_frames(self.patches)
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
        """Indices ``l != k`` of the patches coupled exactly to patch ``k`` (all patches'
        lists at once, by :func:`near_lists`, on first use after a change)."""
        if not self._near:
            self._near = dict(enumerate(near_lists(self._centres, self._radii, self.far_tol)))
        return self._near[k]

    def _stencil(self, k: int) -> np.ndarray:
        return all_stencils([self.patches[k]])  # (9, 2): 3 y by 3 x

    def _interpolation(self, k: int, whole: bool) -> np.ndarray:
        """Weights (n_cells, 9) from the stencil values to the cells (owned or whole patch)."""
        key = (k, whole)
        w = self._weights.get(key)
        if w is None:
            W = self._shape_weights(self.patches[k].grid)
            w = W if whole else W[self.patches[k].owned.ravel()]
            self._weights[key] = w
        return w

    def _shape_weights(self, g) -> np.ndarray:
        """The whole patch's weights (ny nx, 9) of grid ``g``: its shape's only."""
        W = self._weights.get(("shape", g.nx, g.ny))
        if W is None:
            W = self._weights[("shape", g.nx, g.ny)] = grid_interpolation(g.ny, g.nx)
        return W

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
        m = _columns(values)
        n = len(values)
        if self._F is None or self._F.shape != (n, m):
            self._F = np.zeros((n, m))
            self._C = np.repeat(self._centres[:, None, :], m, axis=1)
            self._seen = [None] * n
        # the sweeps replace a block's vector when it changes (never modify it): a block is
        # stale when its vector is not the very object seen last time
        stale = [l for l, (v, seen) in enumerate(zip(values, self._seen)) if v is not seen and v is not None]
        for l in stale:
            v = values[l].reshape(len(values[l]), m)  # m columns also for a block owning no cell
            h2 = self.patches[l].grid.h ** 2
            pts = self._owned_points(l)
            F = h2 * v.sum(axis=0)
            first_moment = h2 * (pts.T @ v)  # (2, m)
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
        self.far_products += 1
        stencil = self._stencil(k)
        cols = []
        for j in range(F.shape[1]):
            pts, forces = C[far, j], F[far, j]
            cols.append(self.provider.point_compliance(stencil, pts) @ forces if len(forces) else np.zeros(9))
        return W @ np.column_stack(cols)

    # ------------------------------------------------------------------ products
    def rhs(self, k: int, values: list, rhs: np.ndarray) -> np.ndarray:
        """``rhs - sum_{l != k} A_kl v_l``: near pairs exact, far ones by resultants (mm)."""
        if rhs.ndim == 1:
            return self._rhs_1d(k, values, rhs)
        out = rhs.copy()
        near = [int(l) for l in self.near(k)]
        self.near_products += sum(1 for l in near if values[l] is not None and np.any(values[l]))
        self._subtract(k, near, values, out)
        out -= self._far(k, values, whole=False)
        return out

    def _rhs_1d(self, k: int, values: list, rhs: np.ndarray) -> np.ndarray:
        """:meth:`rhs` for one right-hand side: the near pairs whose dense block is kept
        multiplied here, the others by their routes. A sweep's blocks call it thousands of
        times (939 blocks of 41-266 cells with 2.5 near pairs each: 0.19 ms a call through
        the routes, 40 % of the sweeps' CPU), so the common case skips their bookkeeping."""
        out = rhs - self._far(k, values, whole=False)[:, 0]
        self._subtract(k, self._near_kept(k, values, out), values, out)
        return out

    def _near_kept(self, k: int, values: list, out: np.ndarray) -> list:
        """``out -= sum_{l near k} A_kl v_l`` (1-D, in place): kept dense blocks, else one gather of the loaded
        columns from the kernel's window; returns the pairs left to their routes (past the dense size)."""
        rest, gathered, n = [], [], max(len(out), 1)
        wide, few = self.dense_max_entries / n, FIRST_GATHER_ENTRIES / n  # smaller pairs: dense blocks
        for l in self.near(k):
            v = values[l]
            if v is None or not (loaded := np.count_nonzero(v)):  # 0.6 us against any()'s 4 (#181)
                continue
            self.near_products += 1
            M = self._ops.get((k, int(l)))  # kept only for a pair whose route is the dense block
            if M is not None:
                out -= M @ v
            elif self._window is not None and ((k, l) in self._window.pairs or (len(v) > wide and loaded <= few)):
                gathered.append(int(l))
            else:
                rest.append(int(l))
        if gathered and self._window is not None:
            u = self._window.total(k, self.patches[k], [(l, self.patches[l], values[l]) for l in gathered])
            if u is None:
                rest += gathered
            else:
                out -= u
        return rest

    def patch_displacement(self, k: int, values: list) -> np.ndarray:
        """Displacement (mm) on the whole patch ``k`` from the other blocks (near exact):
        a near pair whose dense block is kept by it on the patch's own cells and by
        :func:`~.localblock.whole_patch` on the cells neighbours own, not by an FFT operator
        made for this one product (2,370 of them on 939 scattered patches, the growth
        check's 0.4 s); the other pairs (and kept ones too large for it) by their routes."""
        pt = self.patches[k]
        shape = pt.grid.shape
        u, rest = np.zeros(shape), []
        for l in self.near(k):
            v = values[int(l)]
            if v is None or not np.count_nonzero(v):
                continue
            M = self._ops.get((k, int(l)))
            if M is None or whole_patch_is_large(pt, v):
                rest.append(int(l))
            else:
                u += whole_patch(self.provider, pt, M @ v, self.patches[int(l)], v)
        routed = self._sum(k, rest, values, whole=True) if rest else None
        if routed is not None:
            u += routed
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

    def __init__(self, provider: InfluenceProvider, patches, *, far_tol: float = 0.2, rtol: float = 1e-6, **kwargs):
        self._rtol = float(rtol)
        super().__init__(provider, patches, far_tol=far_tol, **kwargs)

    def _reset(self) -> None:
        super()._reset()
        self._op = None
        self._kept: tuple | None = None  # (an operator built, the patches it was built for)
        self._table = None
        self._held: list = []  # the block vectors of the last refresh
        self._sources: dict = {}
        self._levels = LevelWeights()

    def _moved(self, k: int) -> None:
        """Patch ``k`` changed: its geometry, and every cache that depends on it."""
        centre, radius = patch_frames([self.patches[k]])
        self._centres[k], self._radii[k] = centre[0], radius[0]
        self._near = {}
        for key in [(k, False), (k, True)]:
            self._weights.pop(key, None)
        self._cells.pop(k, None)
        self._sources.pop(k, None)
        self._levels.forget(k)  # the other levels' weights stay
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

    def near_pattern(self):
        """Sparse (N, N) pattern of the near pairs (patch indices, ``k`` excluded)."""
        n = len(self.patches)
        cols = [self.near(k) for k in range(n)]
        rows = np.repeat(np.arange(n), [len(c) for c in cols])
        cols = np.concatenate(cols) if n else np.zeros(0, np.int64)
        return sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))

    def keep_pairs(self, old, index: dict) -> None:
        """As :meth:`~.blocks.Coupling.keep_pairs`, and ``old``'s point operator kept for
        the patches both hold (:func:`~.kept_points.kept_operator`)."""
        super().keep_pairs(old, index)
        if isinstance(old, LaggedFarField) and old.provider is self.provider and old.far_tol == self.far_tol:
            self._kept = old._kept if old._rtol == self._rtol else None

    def _point_operator(self):
        if self._op is None:
            n = len(self.patches)
            sources, targets = all_source_nodes(self.patches), all_stencils(self.patches)
            near = self.near_pattern() + sp.identity(n, format="csr")
            self._op = kept_operator(self.provider, self._kept, self.patches, targets, sources, near)
            if self._op is None:
                # built anew: the earlier operator is let go first, not held through the
                # build (8,355 patches: 260 MB held, and the build's own 400 MB on top)
                self._kept = None
                # stencil row 9k + i excludes the nine sources of the patches near k and of k
                exclude = sp.kron(near, np.ones((9, 9)), format="csr")
                self._op = self.provider.point_operator(targets, sources, exclude=exclude, rtol=self._rtol)
                self._kept = (self._op, tuple(self.patches))
        return self._op

    def refresh(self, values: list) -> None:
        """Recompute the far field on every stencil from the block vectors ``values``; kept
        when they are the very vectors of the last refresh (replaced, never modified)."""
        held, self._held = self._held, list(values)
        if self._table is not None and len(held) == len(values) and all(map(operator.is_, held, values)):
            return
        n, m = len(self.patches), _columns(values)
        # the source weights kept until a patch changes (4,548 patches: made again at every
        # refresh, half of the refresh's CPU), none for a large patch (:mod:`.level_far`)
        S = all_strengths(self.patches, values, self._sources)
        self._table = self._point_operator().apply(S.reshape(9 * n, m)).reshape(n, 9, m)
        self.far_products += 1

    def _weighted(self, k: int) -> bool:
        """Patch ``k`` keeps (9, n) source and (n, 9) interpolation weights (else their tensor-product forms)."""
        return int(self.patches[k].owned.sum()) < SEPARABLE_CELLS

    def _far(self, k: int, values: list, whole: bool) -> np.ndarray:
        m = _columns(values)
        if self._table is None or self._table.shape[2] != m:
            self.refresh(values)
        if self._weighted(k):
            return self._interpolation(k, whole) @ self._table[k]
        return separable_far(self.patches[k].grid, None if whole else self.patches[k].owned, self._table[k])

    def rhs_level(self, level: list, values: list, rhs: list) -> dict:
        """:meth:`rhs` ``{k: ...}`` of a sweep's blocks ``level`` (1-D ``rhs[k]``): the held far
        field on all their cells by one product (:mod:`.level_far`), then the near pairs."""
        if self._table is None or self._table.shape[2] != 1:
            self.refresh(values)
        far = self._levels.far(self.patches, level, self._table, self._shape_weights)
        return level_near(self, values, {k: rhs[k] - f for k, f in zip(level, far)})
