"""Far-field sources of a patch: nine point forces that carry its load's moments.

A patch's pressure ``p`` on cells of side ``h`` is replaced, for points far from it, by
nine point forces on a 3 x 3 lattice over the patch: its centre and ``+-delta`` along each
axis, ``delta = (sqrt 3 / 2) a`` with ``a`` the half-width from the centre to the outer
cell centres (the zeros of the third Chebyshev polynomial, which minimise the largest
three-point interpolation error over the patch). The force at node ``(i, j)`` is
``h^2 sum_c p_c L_i(x_c) L_j(y_c)``, ``L`` the quadratic Lagrange functions of the nodes, so
the nine reproduce every moment ``sum_c h^2 p_c x_c^a y_c^b`` with ``a, b <= 2``: the
resultant, the centre of pressure and the second moments, whatever the load's shape or
place in the patch. The displacement they cause at a distance ``d`` then differs from the
patch's by a relative ``O((a / d)^3)``. Units: mm, N, MPa.
"""

from __future__ import annotations

import math

import numpy as np


def lagrange3(xi: np.ndarray) -> np.ndarray:
    """Quadratic Lagrange weights at nodes -1, 0, 1 for points ``xi`` (n,) -> (n, 3)."""
    return np.column_stack([0.5 * xi * (xi - 1.0), 1.0 - xi * xi, 0.5 * xi * (xi + 1.0)])


def grid_interpolation(ny: int, nx: int) -> np.ndarray:
    """The (ny nx, 9) weights taking values at the nine nodes over a patch grid of ``ny x nx``
    cells (outer nodes on the outer cell centres) to the cells, row-major like the stencils:
    they depend on the grid's shape only."""
    xi = (np.arange(nx) - 0.5 * (nx - 1)) / max(0.5 * (nx - 1), 1e-300)
    eta = (np.arange(ny) - 0.5 * (ny - 1)) / max(0.5 * (ny - 1), 1e-300)
    return np.einsum("ja,ib->jiab", lagrange3(eta), lagrange3(xi)).reshape(ny * nx, 9)


#: Position of the outer source nodes, in half-widths of the patch: the zeros of the
#: third Chebyshev polynomial, which minimise the largest interpolation error over it.
SOURCE_NODE = math.sqrt(3.0) / 2.0

#: Bytes a far field keeps for every owned cell of a patch of fewer than
#: :data:`SEPARABLE_CELLS` owned cells while the patch stays: the cell's column of
#: :func:`source_weights` (9 float64) and its row of :func:`grid_interpolation` (9 float64)
#: with the row's block index (an int64), as a sweep's level lays them end to end
#: (:class:`.level_far.LevelWeights`); 152-156 bytes an owned cell held at the most in
#: the sweep's two-level solves measured (seed 8's #31, #51, #150, #166). Where a block's
#: right-hand side is asked alone (:meth:`.farfield.FarFieldCoupling._interpolation`: the
#: rounds' gaps on some scenes) its rows are kept once more, 72 bytes a cell not counted.
#: The cells' centres are not kept: the weights are made from the grids'
#: (:func:`patch_source_weights`). One engine's at a time: an engine a merge replaces is
#: released with it.
KEPT_BYTES_PER_OWNED_CELL = np.dtype(np.float64).itemsize * (9 + 9) + np.dtype(np.int64).itemsize
#: Bytes a patch of at least :data:`SEPARABLE_CELLS` owned cells holds per row and per column
#: of its grid while its far field or sources are taken by the tensor-product forms
#: (:func:`separable_strengths`, :func:`.level_far.separable_far`): the three quadratic
#: Lagrange weights (float64) of each; made at each call, nothing per cell kept.
SEPARABLE_BYTES_PER_ROW_OR_COLUMN = np.dtype(np.float64).itemsize * 3


def source_frame(grid) -> tuple[np.ndarray, np.ndarray]:
    """Centre (2,) mm of a patch on ``grid`` and the offset (2,) mm of its outer source
    nodes along x and y (at least ``h / 2``)."""
    xmin, xmax, ymin, ymax = grid.bounds
    centre = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)])
    half = 0.5 * grid.h * np.array([grid.nx - 1, grid.ny - 1], dtype=float)
    return centre, np.maximum(SOURCE_NODE * half, 0.5 * grid.h)


def source_nodes(grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nine far-field source points of a patch on ``grid``: ``(points (9, 2) mm,
    centre, delta)`` (:func:`source_frame`), row-major over (y, x) like the stencils."""
    centre, delta = source_frame(grid)
    X, Y = np.meshgrid(
        centre[0] + delta[0] * np.array([-1.0, 0.0, 1.0]), centre[1] + delta[1] * np.array([-1.0, 0.0, 1.0])
    )
    return np.column_stack([X.ravel(), Y.ravel()]), centre, delta


def source_strengths(
    points: np.ndarray, values: np.ndarray, centre: np.ndarray, delta: np.ndarray, h: float
) -> np.ndarray:
    """Forces (9, m) N at :func:`source_nodes` with the moments ``x^i y^j`` (``i, j <= 2``)
    of the pressure ``values`` (n, m) MPa on the cells centred at ``points`` (n, 2) mm."""
    return source_weights(points, centre, delta, h) @ values


def source_weights(points: np.ndarray, centre: np.ndarray, delta: np.ndarray, h: float) -> np.ndarray:
    """The (9, n) matrix taking a pressure (n,) MPa on the cells centred at ``points``
    (n, 2) mm to the forces N at :func:`source_nodes` (:func:`source_strengths`): it depends
    on the patch only, so a far field refreshed every sweep keeps it."""
    n = len(points)
    # lagrange3's numbers as rows (x and y, node, cell) with each pass contiguous over the
    # cells and no temporaries: a broadcast product over (n, 3, 3) runs its inner loop three
    # elements at a time, and each temporary of a large patch is fresh memory (4,548 patches
    # of ~1,000 cells: 3 s a solve, now a tenth of it)
    L = np.empty((2, 3, n))
    xi = L[:, 1]
    np.subtract(points.T, np.asarray(centre, dtype=float)[:, None], out=xi)
    xi /= np.asarray(delta, dtype=float)[:, None]
    np.subtract(xi, 1.0, out=L[:, 0])
    L[:, 0] *= xi
    L[:, 0] *= 0.5  # (0.5 xi)(xi - 1) exactly: a product by 0.5 does not round
    np.add(xi, 1.0, out=L[:, 2])
    L[:, 2] *= xi
    L[:, 2] *= 0.5
    np.multiply(xi, xi, out=L[:, 1])
    np.subtract(1.0, L[:, 1], out=L[:, 1])
    # the transpose of a (n, 9) array, as it was made before: the far field's products with
    # it are the same BLAS calls, summed in the same order
    out = np.empty((n, 9)).T
    for a in range(3):
        for b in range(3):
            np.multiply(L[1, a], L[0, b], out=out[3 * a + b])
    out *= h * h
    return out


#: A patch of at least this many owned cells keeps no weights: its sources and its far field
#: are taken by the weights' tensor-product forms (:func:`separable_strengths`,
#: :func:`.level_far.separable_far`: three numbers a cell, not a (9, n) matrix; the smaller
#: blocks' weights are worth keeping, a block's own call costing ~15 us).
SEPARABLE_CELLS = 1024


def all_strengths(patches, values: list, kept: dict) -> np.ndarray:
    """The source strengths (N, 9, m) N of every block vector ``values[l]`` ((n_l,) or
    (n_l, m) MPa, or None): by :func:`source_weights` kept in ``kept`` (by block, the missing
    ones made in passes over many, :func:`patch_source_weights`) below
    :data:`SEPARABLE_CELLS` owned cells, by :func:`separable_strengths` from there."""
    first = next((v for v in values if v is not None and v.size), None)
    S = np.zeros((len(patches), 9, 1 if first is None or first.ndim == 1 else first.shape[1]))
    for l, v in enumerate(values):
        if v is None or not v.size:  # a block can own no cell (a neighbour owns its patch)
            continue
        v = v.reshape(len(v), -1)
        if len(v) >= SEPARABLE_CELLS:
            S[l] = separable_strengths(patches[l].grid, patches[l].owned, v)
            continue
        if l not in kept:
            todo = [k for k in range(len(patches)) if k not in kept and patches[k].owned.sum() < SEPARABLE_CELLS]
            kept.update(zip(todo, patch_source_weights([patches[k] for k in todo])))
        S[l] = kept[l] @ v
    return S


def separable_strengths(grid, owned: np.ndarray, values: np.ndarray) -> np.ndarray:
    """:func:`source_weights` of the cells ``owned`` (ny, nx bool) of ``grid`` times the
    pressure ``values`` (n, m) MPa on them, (9, m) N, by the weights' tensor-product form
    ``h^2 L_y^T P L_x`` (``P`` the pressure on the grid): no (9, n) matrix kept, the same
    sums in another order."""
    centre, delta = source_frame(grid)
    P = np.zeros((*grid.shape, values.shape[1]))
    P[owned] = values
    Ly = lagrange3((grid.y - centre[1]) / delta[1])
    Lx = lagrange3((grid.x - centre[0]) / delta[0])
    S = np.tensordot(np.tensordot(Ly, P, axes=(0, 0)), Lx, axes=(1, 0))  # (3 y, m, 3 x)
    return (grid.h * grid.h) * S.transpose(0, 2, 1).reshape(9, -1)


#: Owned cells :func:`patch_source_weights` takes in one pass (its temporaries: ~100 bytes a cell).
WEIGHTS_CHUNK_CELLS = 1 << 18


def patch_source_weights(patches) -> list:
    """:func:`source_weights` of every patch's owned cells in its own frame
    (:func:`source_frame`), the same numbers in the same (9, n) layout, computed over many
    patches a pass: per patch its ~25 array operations cost ~80 us whatever its size
    (4,548 patches, each far field made twice: 1.9 s of #162's CPU)."""
    out: list = []
    counts = [int(pt.owned.sum()) for pt in patches]
    start = 0
    while start < len(patches):
        stop, cells = start + 1, counts[start]
        while stop < len(patches) and cells + counts[stop] <= WEIGHTS_CHUNK_CELLS:
            cells += counts[stop]
            stop += 1
        out.extend(_chunk(patches[start:stop], counts[start:stop]))
        start = stop
    return out


def _chunk(patches, counts: list) -> list:
    """:func:`patch_source_weights` of a few patches, one pass over their cells."""
    frames = [source_frame(pt.grid) for pt in patches]
    per_cell = lambda values: np.repeat(np.asarray(values, dtype=float), counts, axis=0)  # noqa: E731
    points = np.empty((2, sum(counts)))
    at = 0
    for pt, n in zip(patches, counts):
        X, Y = pt.grid.centres()
        points[0, at : at + n], points[1, at : at + n] = X[pt.owned], Y[pt.owned]
        at += n
    L = np.empty((2, 3, points.shape[1]))
    xi = L[:, 1]
    np.subtract(points, per_cell([c for c, _ in frames]).T, out=xi)
    xi /= per_cell([d for _, d in frames]).T
    np.subtract(xi, 1.0, out=L[:, 0])
    L[:, 0] *= xi
    L[:, 0] *= 0.5
    np.add(xi, 1.0, out=L[:, 2])
    L[:, 2] *= xi
    L[:, 2] *= 0.5
    np.multiply(xi, xi, out=L[:, 1])
    np.subtract(1.0, L[:, 1], out=L[:, 1])
    rows = np.empty((points.shape[1], 9)).T  # the transpose of a (n, 9) array, as before
    for a in range(3):
        for b in range(3):
            np.multiply(L[1, a], L[0, b], out=rows[3 * a + b])
    rows *= per_cell([pt.grid.h * pt.grid.h for pt in patches])
    bounds = np.cumsum([0] + counts)
    return [rows[:, a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def _grid_arrays(patches) -> tuple:
    """``x0, y0, nx, ny, h`` of every patch's grid, as arrays (N,)."""
    g = [pt.grid for pt in patches]
    return tuple(np.array([getattr(x, a) for x in g], dtype=float) for a in ("x0", "y0", "nx", "ny", "h"))


def _lattices(cx: np.ndarray, cy: np.ndarray, dx: np.ndarray, dy: np.ndarray, steps=(-1.0, 0.0, 1.0)) -> np.ndarray:
    """The 3 x 3 lattices ``(cx + dx i, cy + dy j)``, ``i, j`` in ``steps``, of N patches,
    (9 N, 2) mm, each row-major over (y, x)."""
    u = np.array(steps)
    X = np.broadcast_to((cx[:, None] + dx[:, None] * u)[:, None, :], (len(cx), 3, 3))
    Y = np.broadcast_to((cy[:, None] + dy[:, None] * u)[:, :, None], (len(cx), 3, 3))
    return np.column_stack([X.ravel(), Y.ravel()])


def all_stencils(patches) -> np.ndarray:
    """:meth:`.farfield.FarFieldCoupling._stencil` of every patch, (9 N, 2) mm, in one pass."""
    x0, y0, nx, ny, h = _grid_arrays(patches)
    return _lattices(x0, y0, 0.5 * (nx - 1) * h, 0.5 * (ny - 1) * h, steps=(0.0, 1.0, 2.0))


def all_source_nodes(patches) -> np.ndarray:
    """:func:`source_nodes` of every patch, (9 N, 2) mm, in one pass."""
    x0, y0, nx, ny, h = _grid_arrays(patches)
    hh = 0.5 * h
    cx = 0.5 * ((x0 - hh) + (x0 + (nx - 1) * h + hh))
    cy = 0.5 * ((y0 - hh) + (y0 + (ny - 1) * h + hh))
    dx = np.maximum(SOURCE_NODE * (0.5 * h * (nx - 1)), 0.5 * h)
    dy = np.maximum(SOURCE_NODE * (0.5 * h * (ny - 1)), 0.5 * h)
    return _lattices(cx, cy, dx, dy)
