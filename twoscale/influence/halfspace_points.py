"""Fast sums of Boussinesq point-force displacements on the half-space (Ewald split).

``u_i = sum_j F_j / (pi E* r_ij)`` for ``M`` targets and ``N`` sources in
``O((N + M) p^2 + P log P + n_near)`` per product instead of ``O(M N)``, with the split
(Ewald 1921; in 2-D point form as in particle-mesh Ewald, Darden et al. 1993)

    1/r = erf(r/sigma)/r + erfc(r/sigma)/r.

* Long range, ``erf(r/sigma)/r`` (smooth, ``2/(sigma sqrt(pi))`` at ``r = 0``): source
  forces are spread onto a uniform mesh of spacing ``H`` with local Lagrange weights
  (``p`` nodes per axis), convolved with the kernel sampled at the mesh offsets by one
  zero-padded (non-periodic) FFT, and interpolated back to the targets with the same
  weights. The two interpolations are the only error: a two-sided ``p``-point Lagrange
  interpolant of ``erf(r/sigma)/r`` with ``H/sigma = h`` has ``max_r r |error| <= delta(p, h)``
  (table :data:`_LAGRANGE_DELTA`, measured by sampling), so for forces of one sign the
  long-range error at a target is at most ``delta`` times its displacement.
* Short range, ``erfc(r/sigma)/r``, summed exactly over the pairs with
  ``r < r_cut = alpha sigma`` (k-d tree, once); the tail left out is at most
  ``erfc(alpha)`` times the displacement, since ``erfc`` decreases.
* Excluded and coincident pairs: their exact long-range value ``erf(r/sigma)/r`` is
  subtracted (and they are left out of the short range), folded into the same sparse
  matrix. What stays of such a pair is its interpolation error, ``<= delta / r``.

``sigma``, ``H``, ``p`` and ``alpha`` are chosen from ``rtol`` so that
``erfc(alpha) <= rtol/4`` and ``delta(p, H/sigma) <= rtol/2``; among those, the
(``p``, ``sigma``) with the least modelled cost (:func:`choose_parameters`: spreading
weights, FFT size and near pairs, the latter counted on a subsample of the targets), with
the padded mesh capped at :data:`MESH_CAP` nodes (a binding cap pushes ``sigma`` up).
Memory is ``O((N + M) p^2 + P + n_near + nnz(exclude))``: no ``M x N`` array.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
import scipy.sparse as sp
from scipy.special import erf, erfc, erfcinv

from .points import PointOperator, check_exclude, check_points

#: Above this many pairs ``M N`` the half-space returns the fast operator.
FAST_ENTRIES = 4_000_000
#: Largest padded FFT mesh, nodes (2048^2: 32 MB per real right-hand side).
MESH_CAP = 2048 * 2048
#: Lagrange orders tried (nodes per axis; even, so a point's stencil is centred on it).
ORDERS = (4, 6, 8, 10, 12)

# log10 of delta(p, h) = max over r, and over the positions of both points relative to
# the mesh, of r |error| for the two-sided p-point Lagrange interpolant of erf(r)/r on a
# mesh of spacing h (sigma = 1). Measured by sampling 9e4 pairs with r < 4 (the maximum
# sits at r ~ 1-1.6), three seeds, largest value kept.
_H_TABLE = np.array([0.7, 0.6, 0.5, 0.4, 0.3, 0.25, 0.2, 0.15, 0.12, 0.1])
_LAGRANGE_DELTA = {
    4: [-1.84, -2.07, -2.38, -2.72, -3.20, -3.51, -3.89, -4.39, -4.76, -5.09],
    6: [-2.17, -2.42, -2.78, -3.35, -4.00, -4.46, -5.03, -5.75, -6.33, -6.81],
    8: [-2.38, -2.72, -3.14, -3.78, -4.69, -5.30, -6.03, -7.01, -7.77, -8.40],
    10: [-2.49, -2.92, -3.46, -4.18, -5.33, -6.01, -6.94, -8.13, -9.10, -9.88],
    12: [-2.58, -3.05, -3.70, -4.53, -5.83, -6.66, -7.77, -9.19, -10.31, -11.25],
}

# Cost model, seconds per unit on one core (measured with scipy 1.17: CSR products,
# scipy.fft, cKDTree and erfc). Builds are weighted as one per _APPLIES_PER_BUILD
# products: the micro step rebuilds its operator whenever a patch moves.
_W_APPLY, _W_BUILD = 5e-9, 4e-8  # per spreading / interpolation weight
_FFT_APPLY, _FFT_BUILD = 1.7e-9, 1.7e-9  # per P log2 P of the padded mesh
_PAIR_APPLY, _PAIR_BUILD = 5e-9, 1.5e-7  # per near pair
_APPLIES_PER_BUILD = 10
#: Targets used to count near pairs when choosing sigma.
_SAMPLE = 2000


def lagrange_delta(order: int, h: float) -> float:
    """``max_r r |error|`` of ``order``-point two-sided Lagrange interpolation of
    ``erf(r)/r`` at spacing ``h`` (``sigma = 1``): :data:`_LAGRANGE_DELTA`, log-log
    interpolated, extrapolated with the last slope below the finest spacing."""
    logd, logh = np.asarray(_LAGRANGE_DELTA[order]), np.log10(_H_TABLE)
    x = math.log10(h)
    if x < logh[-1]:
        slope = (logd[-1] - logd[-2]) / (logh[-1] - logh[-2])
        return float(10 ** (logd[-1] + (x - logh[-1]) * slope))
    return float(10 ** np.interp(x, logh[::-1], logd[::-1]))


def lagrange_spacing(order: int, delta: float) -> float:
    """Largest ``H/sigma`` at which ``order``-point Lagrange interpolation keeps
    ``max_r r |error| <= delta`` (inverse of :func:`lagrange_delta`; at most the
    coarsest tabulated spacing)."""
    logd, logh = np.asarray(_LAGRANGE_DELTA[order]), np.log10(_H_TABLE)
    y = math.log10(delta)
    if y >= logd[0]:
        return float(_H_TABLE[0])
    if y < logd[-1]:
        slope = (logd[-1] - logd[-2]) / (logh[-1] - logh[-2])
        return float(10 ** (logh[-1] + (y - logd[-1]) / slope))
    return float(10 ** np.interp(y, logd[::-1], logh[::-1]))


@dataclass(frozen=True)
class EwaldParameters:
    """Split and mesh of an :class:`EwaldPointOperator`.

    Attributes
    ----------
    sigma : float, mm
        Ewald splitting length.
    spacing : float, mm
        Mesh spacing ``H``.
    order : int
        Lagrange nodes per axis ``p``.
    r_cut : float, mm
        Short-range cut-off ``alpha sigma``.
    error_bound : float
        ``erfc(alpha) + delta(p, H/sigma)``: bound on the error relative to the
        displacement at each target for forces of one sign (excluded pairs add at most
        ``delta / r`` each).
    """

    sigma: float
    spacing: float
    order: int
    r_cut: float
    error_bound: float


def _mesh_range(xmin: float, xmax: float, x0: float, H: float, p: int) -> tuple[int, int]:
    """First lattice index and node count of a mesh carrying the stencils of points
    in ``[xmin, xmax]`` (lattice ``x0 + k H``)."""
    lo = math.floor((xmin - x0) / H) - p // 2 + 1
    hi = math.floor((xmax - x0) / H) + p // 2
    return lo, hi - lo + 1


def _boxes(targets: np.ndarray, sources: np.ndarray):
    """Bounding boxes ``(lo, hi)`` of the targets and of the sources, mm."""
    return [(pts.min(axis=0), pts.max(axis=0)) for pts in (targets, sources)]


def _meshes(boxes, x0: np.ndarray, H: float, p: int):
    """``((tx, ty), (nyt, nxt)), ((sx, sy), (nys, nxs))``: first lattice index and shape
    of the target and the source mesh, for the bounding ``boxes`` of :func:`_boxes`."""
    out = []
    for lo, hi in boxes:
        (ix, nx), (iy, ny) = (_mesh_range(lo[d], hi[d], x0[d], H, p) for d in (0, 1))
        out.append(((ix, iy), (ny, nx)))
    return out


def _fft_shape(tshape, sshape) -> tuple[int, int]:
    """Padded FFT mesh (y, x) for the linear convolution of the two meshes."""
    return (
        sfft.next_fast_len(tshape[0] + sshape[0] - 1, real=False),
        sfft.next_fast_len(tshape[1] + sshape[1] - 1, real=True),
    )


def choose_parameters(targets: np.ndarray, sources: np.ndarray, rtol: float) -> EwaldParameters:
    """Split length, mesh and order for :class:`EwaldPointOperator` (module docstring).

    The cost model (``_*_APPLY``, ``_*_BUILD``) adds the spreading weights
    ``p^2 (N + M)``, the FFT work ``P log2 P`` and the near pairs within ``r_cut``
    (counted with a k-d tree on at most ``_SAMPLE`` targets), over ``sigma`` on a
    geometric grid from the bounding-box diagonal down to where the mesh cap binds.
    The pairs are counted first within the cut-offs under a tenth of the diagonal; the
    larger ones (three quarters of the counting's time: 0.10 of 0.14 s on 8,451 points)
    only when a bound on their cost does not rule them out: a cut-off's pairs are at least
    the largest counted one's, so the choice is the one all counts give.
    """
    from scipy.spatial import cKDTree

    m, n = len(targets), len(sources)
    alpha = float(erfcinv(0.25 * rtol))
    boxes = _boxes(targets, sources)
    x0 = np.minimum(boxes[0][0], boxes[1][0])
    diag = float(np.hypot(*(np.maximum(boxes[0][1], boxes[1][1]) - x0))) or 1.0
    sigmas = diag / alpha * 2.0 ** (-np.arange(0, 60) / 3.0)
    # near pairs counted once for every candidate cut-off (sigmas descend, radii ascend)
    step = max(1, m // _SAMPLE)
    sample = targets[::step]
    radii = alpha * sigmas[::-1]
    trees = cKDTree(sample), cKDTree(sources)
    small = max(1, int(np.searchsorted(radii, 0.1 * diag)))
    counts = np.full(len(sigmas), np.nan)
    counts[len(sigmas) - small :] = trees[0].count_neighbors(trees[1], radii[:small])[::-1] * (m / len(sample))
    best, bound = _cheapest(boxes, x0, sigmas, counts, m + n, rtol, alpha, floor=counts[len(sigmas) - small])
    if best is None or bound <= best[0]:  # a larger cut-off might be cheaper: count all
        counts = trees[0].count_neighbors(trees[1], radii)[::-1] * (m / len(sample))
        best, _ = _cheapest(boxes, x0, sigmas, counts, m + n, rtol, alpha, floor=0.0)
    if best is None:  # cannot happen: the largest sigma gives a mesh of a few nodes
        raise RuntimeError("no Ewald mesh fits under MESH_CAP")
    return best[1]


def _cheapest(boxes, x0, sigmas, counts, points: int, rtol: float, alpha: float, *, floor: float):
    """``((cost, parameters) or None, bound)``: the first cheapest candidate whose near
    pairs are counted (``counts``; NaN where not), and the least cost the others can have
    (their pairs at least ``floor``; ``inf`` if none)."""
    best, bound = None, math.inf
    for p in ORDERS:
        h = lagrange_spacing(p, 0.5 * rtol)
        weights = p * p * points
        for sigma, npair in zip(sigmas, counts):
            (_, tshape), (_, sshape) = _meshes(boxes, x0, h * sigma, p)
            shape = _fft_shape(tshape, sshape)
            P = float(shape[0] * shape[1])
            if P > MESH_CAP:
                break  # sigmas decrease: every later mesh is larger
            pairs = floor if np.isnan(npair) else npair
            apply = _W_APPLY * weights + _FFT_APPLY * P * math.log2(P) + _PAIR_APPLY * pairs
            build = _W_BUILD * weights + _FFT_BUILD * P * math.log2(P) + _PAIR_BUILD * pairs
            cost = apply + build / _APPLIES_PER_BUILD
            if np.isnan(npair):
                bound = min(bound, cost)
            elif best is None or cost < best[0]:
                error = float(erfc(alpha)) + lagrange_delta(p, h)
                params = EwaldParameters(float(sigma), float(h * sigma), p, float(alpha * sigma), error)
                best = (cost, params)
    return best, bound


def _long(r: np.ndarray, sigma: float) -> np.ndarray:
    """``erf(r/sigma)/r``, 1/mm, with its limit ``2/(sigma sqrt(pi))`` at ``r = 0``."""
    out = np.full(r.shape, 2.0 / (sigma * math.sqrt(math.pi)))
    nz = r > 0
    out[nz] = erf(r[nz] / sigma) / r[nz]
    return out


def _short(r: np.ndarray, sigma: float) -> np.ndarray:
    """Near-pair entries: ``erfc(r/sigma)/r``; at coincident points (no contribution)
    minus the long-range value the mesh adds there."""
    out = np.full(r.shape, -2.0 / (sigma * math.sqrt(math.pi)))
    nz = r > 0
    out[nz] = erfc(r[nz] / sigma) / r[nz]
    return out


def _lagrange_weights(x: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """First node index (lattice units) and the ``p`` Lagrange weights of each ``x``."""
    k = np.floor(x)
    f = x - k
    nodes = np.arange(-p // 2 + 1, p // 2 + 1, dtype=float)
    W = np.ones((len(x), p))
    for a in range(p):
        for b in range(p):
            if a != b:
                W[:, a] *= (f - nodes[b]) / (nodes[a] - nodes[b])
    return k.astype(np.int64) + int(nodes[0]), W


def _interpolation_matrix(
    points: np.ndarray, x0: np.ndarray, H: float, p: int, lo: tuple[int, int], shape: tuple[int, int]
) -> sp.csr_matrix:
    """(len(points), ny * nx) CSR of tensor Lagrange weights on the mesh whose node
    ``(0, 0)`` is lattice index ``lo = (ix, iy)``; nodes in row-major order (x fastest)."""
    ny, nx = shape
    kx, wx = _lagrange_weights((points[:, 0] - x0[0]) / H, p)
    ky, wy = _lagrange_weights((points[:, 1] - x0[1]) / H, p)
    ix = kx[:, None] - lo[0] + np.arange(p)  # (n, p)
    iy = ky[:, None] - lo[1] + np.arange(p)
    cols = (iy[:, :, None] * nx + ix[:, None, :]).reshape(len(points), -1)
    vals = (wy[:, :, None] * wx[:, None, :]).reshape(len(points), -1)
    indptr = np.arange(0, cols.size + 1, p * p, dtype=np.int64)
    return sp.csr_matrix((vals.ravel(), cols.ravel(), indptr), shape=(len(points), ny * nx))


class EwaldPointOperator(PointOperator):
    """Half-space point-force sums by Ewald splitting (module docstring).

    Parameters
    ----------
    E_star : float, MPa
        Plane-strain modulus; ``G = 1 / (pi E* r)``.
    targets, sources : (M, 2), (N, 2) arrays, mm
    exclude : sparse (M, N), optional
        Pairs left out (stored entries); coincident points always contribute nothing.
    rtol : float, default 1e-6
        Error allowed relative to ``max |u|`` for forces of one sign.
    params : EwaldParameters, optional
        Use these instead of :func:`choose_parameters` (tests, studies).

    Attributes
    ----------
    params : EwaldParameters
    mesh_shape : (int, int)
        Padded FFT mesh (ny, nx).
    """

    def __init__(
        self,
        E_star: float,
        targets,
        sources,
        *,
        exclude=None,
        rtol: float = 1e-6,
        params: EwaldParameters | None = None,
    ):
        if not (np.isfinite(rtol) and 0.0 < rtol < 1.0):
            raise ValueError(f"rtol must be in (0, 1), got {rtol!r}")
        if not (np.isfinite(E_star) and E_star > 0):
            raise ValueError(f"E_star must be finite and > 0 (MPa), got {E_star!r}")
        self.targets = check_points(targets, "targets")
        self.sources = check_points(sources, "sources")
        m, n = self.shape
        ex = check_exclude(exclude, m, n)
        self.rtol = float(rtol)
        self.params = choose_parameters(self.targets, self.sources, rtol) if params is None else params
        scale = 1.0 / (math.pi * E_star)
        self._near = scale * self._near_matrix(ex)
        self._build_mesh(scale)

    # -- short range, exclusions and coincident pairs ------------------------------
    def _near_matrix(self, ex) -> sp.csr_matrix:
        from scipy.spatial import cKDTree

        m, n = self.shape
        sigma, rc = self.params.sigma, self.params.r_cut
        t, s = self.targets, self.sources
        pairs = cKDTree(t).sparse_distance_matrix(cKDTree(s), rc, output_type="ndarray")
        # the tree's distances (within 2 ulp of point_compliance's hypot): gathering the
        # pairs' points again took 0.26-0.29 s of a 1.9 s build (82,611 points, 7.2 M pairs)
        i, j, r = pairs["i"], pairs["j"], pairs["v"]
        near = sp.csr_matrix((_short(r, sigma), (i, j)), shape=(m, n))
        if ex is None or ex.nnz == 0:
            return near
        # excluded pairs: no short range (ex's pattern times near is near on those
        # pairs, so the difference is exactly 0 there), and their long range taken back
        ex_coo = ex.tocoo()
        ei, ej = ex_coo.row, ex_coo.col
        r_ex = np.hypot(t[ei, 0] - s[ej, 0], t[ei, 1] - s[ej, 1])
        back = sp.csr_matrix((-_long(r_ex, sigma), (ei, ej)), shape=(m, n))
        out = near - ex.multiply(near) + back
        out.eliminate_zeros()
        return sp.csr_matrix(out)

    # -- long range on the mesh -----------------------------------------------------
    def _build_mesh(self, scale: float) -> None:
        p, H, sigma = self.params.order, self.params.spacing, self.params.sigma
        t, s = self.targets, self.sources
        boxes = _boxes(t, s)
        x0 = np.minimum(boxes[0][0], boxes[1][0])
        ((tx, ty), self._tmesh), ((sx, sy), self._smesh) = _meshes(boxes, x0, H, p)
        (nyt, nxt), (nys, nxs) = self._tmesh, self._smesh
        self._gather = _interpolation_matrix(t, x0, H, p, (tx, ty), self._tmesh)
        self._spread = _interpolation_matrix(s, x0, H, p, (sx, sy), self._smesh).T.tocsr()
        # kernel at every offset (target node - source node), like ConvolutionOperator
        ox = (tx - sx - (nxs - 1) + np.arange(nxt + nxs - 1)) * H
        oy = (ty - sy - (nys - 1) + np.arange(nyt + nys - 1)) * H
        table = _long(np.hypot(ox[None, :], oy[:, None]), sigma)
        self.mesh_shape = _fft_shape(self._tmesh, self._smesh)
        self._khat = sfft.rfft2(scale * table, s=self.mesh_shape)[:, :, None]

    def _long_range(self, F: np.ndarray) -> np.ndarray:
        (nyt, nxt), (nys, nxs) = self._tmesh, self._smesh
        my, mx = self.mesh_shape
        k = F.shape[1]
        q = (self._spread @ F).reshape(nys, nxs, k)
        # axis by axis: padding rows are never transformed, only target rows come back
        a = sfft.rfft(q, n=mx, axis=1)
        a = sfft.fft(a, n=my, axis=0, overwrite_x=True)
        a *= self._khat
        a = sfft.ifft(a, axis=0, overwrite_x=True)[nys - 1 : nys - 1 + nyt]
        v = sfft.irfft(a, n=mx, axis=1)[:, nxs - 1 : nxs - 1 + nxt]
        return self._gather @ np.ascontiguousarray(v).reshape(nyt * nxt, k)

    def apply(self, forces):
        F = self._check_forces(forces)
        F2 = F.reshape(len(F), -1)
        u = self._long_range(F2) + self._near @ F2
        return u.reshape((len(self.targets),) + F.shape[1:])

    @property
    def nnz(self) -> int:
        """Stored numbers of the sparse parts (near pairs, spreading, interpolation)."""
        return int(self._near.nnz + self._spread.nnz + self._gather.nnz)
