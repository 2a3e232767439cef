"""The asperities that can own a cell of each of many one-asperity patches, found together.

:func:`~.patches.patch_candidates` answers for one patch: the highest its asperity's surface
is over the patch (:func:`~.patches.highest_over`, one cell sampled), then the tips a k-d
tree finds within reach of the patch (:meth:`~.patches.TipTable.reaching`). Asked patch by
patch, the calls cost more than their arithmetic: 1,572 patches of 1,485 clustered spheres
took 0.5 s, a third of a millisecond each. :func:`candidates_of` does the same for every
patch at once, with one query of the tree and the same arithmetic on arrays, so each
patch's candidates are the ones :func:`~.patches.patch_candidates` gives.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..grid import Grid
from ..indenters import sampled_in_batches
from .patches import TREE_MIN, TipTable


def candidates_of(table: TipTable, wanted: Sequence[tuple[int, Grid]]) -> list | None:
    """The sorted candidates (int arrays) of the one-asperity patches ``wanted`` (pairs
    ``(k, grid)``), as :func:`~.patches.patch_candidates` gives them; None where that
    function would not take the one-cell and k-d tree routes for all of them (an asperity
    other than a plain sphere or paraboloid, a grid not sampled in batches, few tips).
    A patch whose reach is unbounded (a paraboloid among the tips and the patch's sphere
    short of its farthest cell) tests every tip, as that function does."""
    if not wanted or not table.plain or len(table) <= TREE_MIN:
        return None
    if not all(sampled_in_batches(grid) for _, grid in wanted):
        return None
    ks = np.array([k for k, _ in wanted], dtype=np.int64)
    b = np.array([grid.bounds for _, grid in wanted])
    below = _highest(table, ks, [grid for _, grid in wanted])
    radius = [
        table._candidate_radius(float(lo)) + 0.5 * math.hypot(xmax - xmin, ymax - ymin)
        for lo, (xmin, xmax, ymin, ymax) in zip(below, b.tolist())
    ]
    if table._tree is None:
        from scipy.spatial import cKDTree

        table._tree = cKDTree(np.column_stack([table.x, table.y]))
    centres = np.column_stack([0.5 * (b[:, 0] + b[:, 1]), 0.5 * (b[:, 2] + b[:, 3])])
    bounded = np.flatnonzero(np.isfinite(radius))
    found = [np.arange(len(table))] * len(wanted)  # an unbounded reach: every tip
    for i, f in zip(bounded, table._tree.query_ball_point(centres[bounded], np.array(radius)[bounded])):
        found[i] = np.sort(np.asarray(f, dtype=np.int64))
    counts = np.array([len(f) for f in found], dtype=np.int64)
    cand = np.concatenate(found)
    which = np.repeat(np.arange(len(wanted)), counts)
    keep = _reaching(table, cand, b[which], below[which])
    kept = np.bincount(which[keep], minlength=len(wanted))
    return np.split(cand[keep], np.cumsum(kept)[:-1])


def _highest(table: TipTable, ks: np.ndarray, grids: list) -> np.ndarray:
    """:func:`~.patches.highest_over` of each patch's own plain asperity: its height at
    the cell centre farthest from its tip, by :func:`~twoscale.indenters.sample_tips`'s
    arithmetic (``inf`` where a sphere's material does not reach that cell)."""
    x0 = np.array([g.x0 for g in grids])
    y0 = np.array([g.y0 for g in grids])
    h = np.array([g.h for g in grids])
    x1 = x0 + h * np.array([g.nx - 1 for g in grids], dtype=float)
    y1 = y0 + h * np.array([g.ny - 1 for g in grids], dtype=float)
    x, y, z, R = table.x[ks], table.y[ks], table.z[ks], table.curvature[ks]
    # the first of the two edges' centres on a tie, as np.argmax takes it
    far_x = np.where((x1 - x) ** 2 > (x0 - x) ** 2, x1, x0)
    far_y = np.where((y1 - y) ** 2 > (y0 - y) ** 2, y1, y0)
    r2 = (far_y - y) ** 2 + (far_x - x) ** 2
    sphere = table.spherical[ks]
    R2 = R * R
    outside = r2 >= R2
    hk = R2 - r2
    hk[outside] = 0.0
    hk = r2 / (np.sqrt(hk) + R) + z
    hk[outside] = np.inf
    return np.where(sphere, hk, r2 / (2.0 * R) + z)


def _reaching(table: TipTable, cand: np.ndarray, bounds: np.ndarray, below: np.ndarray) -> np.ndarray:
    """:meth:`~.patches.TipTable.reaching`'s test of its tree's candidates ``cand`` (each
    with its patch's ``bounds`` and ``below``, rows): which are kept."""
    xmin, xmax, ymin, ymax = bounds.T
    x, y, R = table.x[cand], table.y[cand], table.R[cand]
    dx = np.maximum(np.maximum(xmin - x, x - xmax), 0.0)
    dy = np.maximum(np.maximum(ymin - y, y - ymax), 0.0)
    r2 = dx * dx + dy * dy
    keep = table.unbounded[cand] | (r2 < R * R)
    finite = np.isfinite(below)
    curv = table.curvature[cand]
    low = np.full(len(cand), -np.inf)
    par, sph = table.parabolic[cand] & finite, table.spherical[cand] & keep & finite
    low[par] = r2[par] / (2.0 * curv[par])
    low[sph] = r2[sph] / (curv[sph] + np.sqrt(np.maximum(curv[sph] ** 2 - r2[sph], 0.0)))
    keep &= ~((par | sph) & (table.z[cand] + low >= below))
    return keep
