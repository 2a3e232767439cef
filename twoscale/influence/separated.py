"""Products between well-separated grids by Chebyshev interpolation (a low-rank block).

When the source grid lies far from the target grid compared with their sizes, the block
``A_ts`` (displacement at target cells from pressure on source cells) is a smooth function
of both positions. It is then represented as

    A_ts ~= S_t K S_s^T,

``S_t`` and ``S_s`` tensor Lagrange interpolation on ``q x q`` Chebyshev nodes of each grid's
cell-centre box, and ``K`` the cell kernel between those nodes. A product costs
``O(q^4 + q n)`` instead of the zero-padded FFT's ``O(n log n)`` with its fixed overheads,
which is what many patches a few patch-widths apart need (the micro step applies every
pair on every sweep).

Accuracy (relative to the largest displacement of one-signed pressure):

* interpolation: the kernel, as a function of one coordinate, is analytic except at complex
  points at distance >= ``G`` (the gap between the two boxes) from the interval of
  half-width ``w``, i.e. outside the Bernstein ellipse ``rho = g + sqrt(g^2 + 1)``,
  ``g = G / w``; the error falls like ``rho^-q``, and ``q`` is chosen per coordinate for
  ``rtol`` (a dimension with fewer cells than nodes is represented exactly by its cells);
* cell averaging: the kernel of a cell load is the provider's multipole expansion of the
  cell (for the half-space :func:`~twoscale.analytic.halfspace.love_far_field`) to the
  order whose remainder bound ``FAR_FIELD_BOUND[order] (h / G)^(order + 2)`` is within
  ``rtol / 4``.

``tests/test_separated.py`` checks the bound against the exact (Love, FFT) product over a
range of separations, sizes and tolerances.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from ..grid import Grid
from .base import GridOperator
from .cache import BoundedCache

#: Largest number of Chebyshev nodes per coordinate; pairs needing more are not separated.
Q_MAX = 20
#: Safety factor on the interpolation bound (calibrated in tests/test_separated.py).
_SAFETY = 10.0
#: Relative remainder of the cell's far-field expansion of order 0, 2, 4 (terms in (h/r)^order):
#: ``bound (h / r)^(order + 2)``; checked against quadrature of the point kernel in tests/test_separated.py.
FAR_FIELD_BOUND = {0: 0.1, 2: 0.03, 4: 0.01}


def chebyshev_points(lo: float, hi: float, q: int) -> np.ndarray:
    """``q`` Chebyshev points of the first kind on ``[lo, hi]``, increasing."""
    k = np.arange(q)
    t = -np.cos((2 * k + 1) * np.pi / (2 * q))
    return 0.5 * (lo + hi) + 0.5 * (hi - lo) * t


def lagrange_matrix(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Lagrange interpolation matrix ``(len(x), len(nodes))`` (barycentric form)."""
    nodes = np.asarray(nodes, dtype=float)
    x = np.asarray(x, dtype=float)
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    w = 1.0 / diff.prod(axis=1)
    d = x[:, None] - nodes[None, :]
    hit = d == 0.0
    d[hit] = 1.0
    L = w[None, :] / d
    L /= L.sum(axis=1, keepdims=True)
    rows = hit.any(axis=1)
    L[rows] = hit[rows].astype(float)
    return L


def _box(grid: Grid) -> tuple[float, float, float, float]:
    return grid.x0, grid.x0 + (grid.nx - 1) * grid.h, grid.y0, grid.y0 + (grid.ny - 1) * grid.h


def box_gap(target: Grid, source: Grid) -> float:
    """Euclidean distance between the cell-centre boxes of two grids, mm."""
    tx0, tx1, ty0, ty1 = _box(target)
    sx0, sx1, sy0, sy1 = _box(source)
    gx = max(sx0 - tx1, tx0 - sx1, 0.0)
    gy = max(sy0 - ty1, ty0 - sy1, 0.0)
    return math.hypot(gx, gy)


def relative_frames(target: Grid, source: Grid) -> tuple[Grid, Grid]:
    """The pair in the frame of the source's lattice: the source's first cell at the origin,
    the target at its integer cell offset (so that what is built from them depends only on
    the pair's relative position, to the last bit); grids off each other's lattice stay
    as they are."""
    try:
        ti, tj = target.offset_in(source)
    except ValueError:
        return target, source
    h = float(source.h)
    return Grid(ti * h, tj * h, h, target.nx, target.ny), Grid(0.0, 0.0, h, source.nx, source.ny)


@dataclass(frozen=True)
class SeparationPlan:
    """Nodes per coordinate (target x, y; source x, y) and the order of the cell expansion."""

    q: tuple[int, int, int, int]
    order: int


def check_rtol(rtol, name: str = "rtol", *, allow_none: bool = False) -> None:
    """Raise ValueError naming ``name`` unless ``rtol`` is a number in (0, 1) (or None when allowed)."""
    if rtol is None and allow_none:
        return
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0.0 < rtol < 1.0:
        raise ValueError(f"{name} must be a number in (0, 1){' or None' if allow_none else ''}, got {rtol!r}")


def plan(target: Grid, source: Grid, rtol: float, *, q_max: int = Q_MAX) -> SeparationPlan | None:
    """How to represent the pair within ``rtol``, or ``None`` when it is not separated enough
    (or the low-rank form would cost more than the dense block or the FFT product)."""
    check_rtol(rtol)
    h = float(source.h)
    gap = box_gap(target, source) - h / math.sqrt(2.0)  # the source cell's extent
    if gap <= 2.0 * h:
        return None
    order = next((o for o, c in FAR_FIELD_BOUND.items() if c * (h / gap) ** (o + 2) <= 0.25 * rtol), None)
    if order is None:
        return None
    qs = []
    for g, lo, hi, n in (
        (target, *_box(target)[:2], target.nx),
        (target, *_box(target)[2:], target.ny),
        (source, *_box(source)[:2], source.nx),
        (source, *_box(source)[2:], source.ny),
    ):
        w = 0.5 * (hi - lo)
        if w == 0.0:
            qs.append(1)
            continue
        ratio = gap / w
        rho = ratio + math.sqrt(ratio * ratio + 1.0)
        q = math.ceil(math.log(_SAFETY / rtol) / math.log(rho))
        qs.append(min(max(q, 2), n))
    if max(qs) > q_max:
        return None
    qtx, qty, qsx, qsy = qs
    # the kernel between nodes must cost less than the products it replaces: the dense
    # block, and the zero-padded FFT (~ 8 flops per padded cell and log factor)
    entries = (qtx * qty) * (qsx * qsy)
    if entries >= 0.25 * target.size * source.size or entries > 8 * (target.nx + source.nx) * (target.ny + source.ny):
        return None
    return SeparationPlan(q=(qtx, qty, qsx, qsy), order=order)


def _nodes(
    lo: float, hi: float, q: int, n: int, h: float, cache: BoundedCache | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Nodes of one coordinate and the interpolation matrix from them to the ``n`` cells
    (read-only; every patch recurs in many pairs, so they are kept in ``cache`` when given)."""
    key = ("chebyshev", lo, hi, q, n, h)
    if cache is not None:
        hit = cache.get(key)
        if hit is not None:
            return hit
    cells = lo + h * np.arange(n)
    if q >= n:
        nodes, S = cells, np.eye(n)
    else:
        nodes = chebyshev_points(lo, hi, q)
        S = lagrange_matrix(nodes, cells)
    nodes.setflags(write=False)
    S.setflags(write=False)
    if cache is not None:
        cache.put(key, (nodes, S), nodes.nbytes + S.nbytes)
    return nodes, S


class SeparatedOperator(GridOperator):
    """``A_ts ~= S_t K S_s^T`` for a well-separated pair (see the module docstring).

    Parameters
    ----------
    target, source : Grid
    kernel : callable ``(dx, dy) -> K``
        Displacement per unit pressure on a source cell (mm/MPa) at offsets
        ``target - source`` (arrays of equal shape), accurate to ``sep``'s tolerance.
    sep : SeparationPlan
    cache : BoundedCache, optional
        Where the interpolation matrices of each grid are kept (the provider's: every patch
        recurs in many pairs); none by default.

    The three stages of :meth:`apply` are the contract's :meth:`spectrum` (source node values
    ``S_s^T p``), :meth:`multiply` (``K m``) and :meth:`finish` (``S_t phi``); keys identify the
    node sets by value (grid and node counts).
    """

    def __init__(self, target: Grid, source: Grid, kernel, sep: SeparationPlan, *, cache: BoundedCache | None = None):
        self.target, self.source = target, source
        self.plan = sep
        qtx, qty, qsx, qsy = sep.q
        tx0, tx1, ty0, ty1 = _box(target)
        sx0, sx1, sy0, sy1 = _box(source)
        ntx, self._Stx = _nodes(tx0, tx1, qtx, target.nx, target.h, cache)
        nty, self._Sty = _nodes(ty0, ty1, qty, target.ny, target.h, cache)
        nsx, self._Ssx = _nodes(sx0, sx1, qsx, source.nx, source.h, cache)
        nsy, self._Ssy = _nodes(sy0, sy1, qsy, source.ny, source.h, cache)
        # K[(ty, tx), (sy, sx)] = kernel(tx - sx, ty - sy)
        dx = ntx[:, None] - nsx[None, :]  # (qtx, qsx)
        dy = nty[:, None] - nsy[None, :]  # (qty, qsy)
        DX, DY = np.broadcast_arrays(dx[None, :, None, :], dy[:, None, :, None])
        self._K = kernel(DX, DY).reshape(len(nty) * len(ntx), len(nsy) * len(nsx))

    def transposed(self) -> "SeparatedOperator":
        """The operator from ``target`` to ``source`` for a symmetric kernel
        (``K(d) = K(-d)``, as for any cell kernel of a homogeneous body): the same arrays,
        ``K`` transposed, no new kernel values."""
        qtx, qty, qsx, qsy = self.plan.q
        out = SeparatedOperator.__new__(SeparatedOperator)
        out.target, out.source = self.source, self.target
        out.plan = SeparationPlan(q=(qsx, qsy, qtx, qty), order=self.plan.order)
        out._Stx, out._Sty, out._Ssx, out._Ssy = self._Ssx, self._Ssy, self._Stx, self._Sty
        out._K = self._K.T
        return out

    def moved(self, target: Grid, source: Grid) -> "SeparatedOperator":
        """This operator for ``target`` and ``source`` translated together from its own pair
        (the arrays depend only on the cells' positions within each box and on the nodes'
        differences: shared, not copied)."""
        out = copy.copy(self)
        out.target, out.source = target, source
        return out

    @property
    def nbytes(self) -> int:
        return self._K.nbytes + sum(a.nbytes for a in (self._Stx, self._Sty, self._Ssx, self._Ssy))

    @property
    def source_key(self) -> tuple:
        """Identifies the source-side nodes (the grid and its node counts, which fix them):
        operators with equal keys share :meth:`moments`."""
        return ("chebyshev", self.source, self.plan.q[2], self.plan.q[3])

    @property
    def target_key(self) -> tuple:
        """Identifies the target-side nodes: node displacements of operators with equal keys
        add up before one :meth:`expand`."""
        return ("chebyshev", self.target, self.plan.q[0], self.plan.q[1])

    def moments(self, p: np.ndarray) -> np.ndarray:
        """Pressure on the source grid (ny, nx[, m]) -> node values ``S_s^T p``, (q_s[, m])."""
        if p.ndim == 2:
            return (self._Ssy.T @ p @ self._Ssx).ravel()
        return np.einsum("ya,yxm,xb->abm", self._Ssy, p, self._Ssx).reshape(-1, p.shape[2])

    def node_product(self, m: np.ndarray) -> np.ndarray:
        """Displacement at the target nodes from source node values ``m``: ``K m``."""
        return self._K @ m

    def expand(self, phi: np.ndarray) -> np.ndarray:
        """Node displacements ``phi`` (q_t[, m]) -> displacement on the target grid (ny, nx[, m])."""
        qy, qx = self._Sty.shape[1], self._Stx.shape[1]
        if phi.ndim == 1:
            return self._Sty @ phi.reshape(qy, qx) @ self._Stx.T
        return np.einsum("ya,abm,xb->yxm", self._Sty, phi.reshape(qy, qx, -1), self._Stx)

    # the contract's stages (GridOperator): moments, node product, expansion
    def spectrum(self, p: np.ndarray) -> np.ndarray:
        return self.moments(p)

    def multiply(self, s: np.ndarray) -> np.ndarray:
        return self.node_product(s)

    def finish(self, a: np.ndarray) -> np.ndarray:
        return self.expand(a)

    def apply(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        if p.shape != self.source.shape:
            raise ValueError(f"pressure has shape {p.shape}, expected {self.source.shape}")
        return self.expand(self._K @ self.moments(p))

    @property
    def flops_estimate(self) -> float:
        qt, qs = self._K.shape
        return 2.0 * (qt * qs + self.target.size * self._Stx.shape[1] + self.source.size * self._Ssx.shape[1])
