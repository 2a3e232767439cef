"""The union CG's test for pressure settled on its box's edge (:class:`EdgeWatch`).

When the contact reaches past the first box (the patches' box: a contact that runs a few
cells past its patch), the union CG used to solve that box to convergence before it saw
the pressure on the edge, then grew the box and solved again from that pressure. The
edge is loaded from the CG's first steps: on the sweep's boxes that grew (10 of 313 union
CGs of seeds 0-7; seed 7's #25, 36 clustered spheres on a bonded block: its contact 3
cells past the top of a 579 x 511 box) the cells on the edge carried pressure from the
first three iterations on and kept it, where the first box then took 19-30 iterations.
On boxes that did not grow, an edge cell loaded in the first steps lost its pressure
again by a KKT residual of 2e-2 (at most five steps in a row). So the CG stops on a box
that may still grow once its edge has carried pressure for ``SETTLED`` steps in a row at
a residual of at most ``EDGE_RESIDUAL``; the grown box starts from that pressure. The
final box is still solved to convergence and checked on its edge
(:func:`.union.solve_union`).
"""

from __future__ import annotations

import math

import numpy as np

from ..grid import Grid

#: The edge must have carried pressure for this many CG steps in a row.
SETTLED = 3
#: ... and the CG's KKT residual be at most this (half the largest residual, 2e-2, at which
#: an edge cell of a box that did not grow was still loaded).
EDGE_RESIDUAL = 1e-2
#: The first box stopped on its edge grows by this (:func:`.union.grown_box`: a tenth of its
#: extent on each side the pressure reached, where ``GROW`` adds a quarter): the contacts
#: that passed the patches' box reached 3-8 cells past it, 0.5-7 % of its extent (seed 7's
#: #25: 637 rows against 724 for its second box, the same 22 iterations). A box that
#: reaches its edge again grows by ``GROW``.
GROW_EARLY = 1.2


class EdgeWatch:
    """``solve_cg``'s ``stop`` for one CG on ``grid`` (the union's box cut to its material,
    inside ``box``): True once pressure has settled on the sides of ``grid`` that are
    sides of ``box`` (a side cut to the material ends in a wall, never grown).

    Attributes
    ----------
    cells : (ny, nx) bool array
        The cells on ``grid`` it reads: those on ``box``'s edge.
    fired : bool
        Whether it stopped the CG.
    """

    def __init__(self, grid: Grid, box: Grid, settled: int = SETTLED, residual: float = EDGE_RESIDUAL):
        self.cells = box_edge_cells(grid, box)
        self.settled, self.residual = settled, residual
        self.run = 0
        self.fired = False

    def __call__(self, iteration: int, residual: float, values: np.ndarray) -> bool:
        self.run = self.run + 1 if bool(np.any(values > 0.0)) else 0
        self.fired = self.run >= self.settled and residual <= self.residual
        return self.fired


def box_edge_cells(grid: Grid, box: Grid) -> np.ndarray:
    """The cells of ``grid`` (aligned, inside ``box``) on ``box``'s edge, as a bool array."""
    cells = np.zeros(grid.shape, dtype=bool)
    di, dj = grid.offset_in(box)
    if di == 0:
        cells[:, 0] = True
    if di + grid.nx == box.nx:
        cells[:, -1] = True
    if dj == 0:
        cells[0, :] = True
    if dj + grid.ny == box.ny:
        cells[-1, :] = True
    return cells


def reached_outside(box: Grid, asperities, result, provider, pivot) -> Grid | None:
    """``box`` grown to cover the tips outside it that the answer's approach and tilt bring
    into contact, or None where there is none. The first box covers the tips the macro
    step's approach and tilt reach; the CG solves its own, and a tip beyond the box that the
    final ones reach would be left out without a word (four paraboloids tilted about a pivot
    outside them: the answer's tilt reached a tip 0.3 mm past the box, the full grid gave it
    0.5 % of the load and moved the others' forces by 1 %). A tip counts as reached where
    its geometric approach at the answer's approach and tilt, less the sinking there under
    the box's tips' forces as point forces, is positive; its side of the box is moved out
    to its reach at twice that approach plus two cells."""
    from ..indenters import tip_positions
    from .workset import tip_approaches

    xmin, xmax, ymin, ymax = box.bounds
    tips = tip_positions(asperities)
    out = np.flatnonzero((tips[:, 0] < xmin) | (tips[:, 0] > xmax) | (tips[:, 1] < ymin) | (tips[:, 1] > ymax))
    theta = (result.penetration, *(result.tilt or (0.0, 0.0)))
    local = tip_approaches([asperities[k] for k in out], theta, pivot)
    out, local = out[local > 0.0], local[local > 0.0]
    if out.size == 0:
        return None
    force = result.asperities.forces
    src = np.flatnonzero(force > 0.0)
    if src.size:
        local = local - provider.point_operator(tips[out], tips[src]).apply(force[src])
    reached, local = out[local > 0.0], local[local > 0.0]
    if reached.size == 0:
        return None
    r = np.array([asperities[k].reach(2.0 * d) for k, d in zip(reached, local)]) + 2.0 * box.h
    h = box.h
    left = max(0, math.ceil((xmin - float(np.min(tips[reached, 0] - r))) / h))
    right = max(0, math.ceil((float(np.max(tips[reached, 0] + r)) - xmax) / h))
    low = max(0, math.ceil((ymin - float(np.min(tips[reached, 1] - r))) / h))
    high = max(0, math.ceil((float(np.max(tips[reached, 1] + r)) - ymax) / h))
    return Grid(box.x0 - left * h, box.y0 - low * h, h, box.nx + left + right, box.ny + low + high)
