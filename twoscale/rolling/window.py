"""The rolling path of a half-space: one constrained conjugate gradient per position over a
window fixed in the body, its FFT operator built once for the run.

Under a tyre the stones crowd the footprint (about half of those within reach touch at
once), so the two-scale solver's patches cover most of their box and its micro step runs
one constrained CG over that box anyway, rebuilding patches, the box's FFT operator and
its preconditioner at every position. Here the position is that CG directly:

* the **window** is a grid fixed in the body frame covering every cell that can touch
  (the cells of the position's stones below the approach bound); it is kept from
  position to position and only grows, by a margin, when the contact would leave it, so
  the half-space's zero-padded FFT operator, its single-precision twin and the circulant
  preconditioner are built once (:class:`KeptBody`) under load control (under penetration
  control the CG crops the window to the box of the cells below the held approach, and the
  operator is rebuilt when that box changes size);
* the **start** is the previous pressure moved with the road by exactly the step (the
  step is a whole number of cells on a height map), extrapolated linearly from the two
  previous positions (a stone's pressure changes smoothly as it rolls through the
  footprint: the start's error is about half the plain shift's);
* the **solve** is :func:`twoscale.reference.cg.solve_cg` on the surface of the
  position's stones (:func:`twoscale.indenters.surface_on`, the heights every static
  solve sees), preconditioned, to the KKT residual the two-scale solver's union CG stops
  at (``tol x`` :data:`~twoscale.micro.strategies.UNION_TOL_FACTOR`), in one stage
  (``precision="single-directions"``): the search directions' products in float32, the
  pressure, displacement and residual in double precision, the few cells a step clips
  or lets in corrected by the kernel's columns instead of a fresh product, and the
  conjugate directions kept while at most :data:`KEEP_CONJUGACY` of the loaded cells
  enter (the start's contact settles at the stones' edges a few cells at a time).

The answer is the static contact of the road at that shift to the solver's tolerance:
the cells left out of the window cannot touch (their height is above the bound), and the
start only changes the work. A position that does not converge is solved again by the
two-scale solver from cold.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..grid import Grid
from ..indenters import surface_on
from .road import Selection
from .track import Track

#: Cells added on every side when the window is built or grows.
MARGIN_CELLS = 8
#: The CG keeps its conjugate directions when at most this fraction of the loaded cells
#: enters in a step (a warm start's contact settles at the stones' edges a few cells at a
#: time: 23 -> 18 iterations a position on the tyre's footprint; 0.2 % and 1 % took more).
KEEP_CONJUGACY = 0.005


class KeptOperator:
    """A grid operator with its single-precision twin and preconditioner built once
    (``solve_cg`` asks for them at every solve)."""

    def __init__(self, op, single: bool = False, parent=None):
        self.op, self.single, self.parent = op, single, parent
        self.target, self.source = op.target, op.source
        self._twin = None
        self._pc = None

    def apply(self, p):
        return self.op.apply(p)

    def columns(self):
        return self.op.columns() if hasattr(self.op, "columns") else None

    def single_precision(self) -> "KeptOperator":
        if self._twin is None:
            self._twin = KeptOperator(self.op.single_precision(), single=True, parent=self)
        return self._twin

    def preconditioner(self):
        """The float32 circulant inverse for both stages: an approximate inverse only
        shapes the search directions (the residual is the double-precision product's), and
        float32 costs half."""
        if self.parent is not None:
            return self.parent.preconditioner()
        if self._pc is None:
            single = self.single_precision().op
            self._pc = (
                single.preconditioner() if hasattr(single, "preconditioner") else None
            ) or self.op.preconditioner()
        return self._pc


class KeptBody:
    """The body as :func:`~twoscale.reference.cg.solve_cg` asks for it, with the operator of
    each square grid kept: a translation-invariant body (the half-space: ``split()`` has no
    correction) by the grid's shape, any other by the grid itself."""

    def __init__(self, provider):
        self.provider = provider
        self.material = provider.material
        base, correction = provider.split()
        self.invariant = correction is None
        self._ops: dict = {}

    def grid_operator(self, target: Grid, source: Grid | None = None):
        if source is not None and source != target:
            return self.provider.grid_operator(target, source)
        key = target.shape if self.invariant else target
        op = self._ops.get(key)
        if op is None:
            self._ops.clear()  # one window at a time: the old one is not coming back
            op = self._ops[key] = KeptOperator(self.provider.grid_operator(target))
        return op


@dataclass
class WindowState:
    """What the positions of one run share on this path: the body with its kept operator,
    the window, and the last two pressures (grid, pressure, shift) for the start."""

    body: KeptBody
    grid: Grid | None = None
    past: list = field(default_factory=list)

    def window(self, need: Grid) -> Grid:
        """The kept window if it covers ``need`` (same lattice), else one that covers both
        with :data:`MARGIN_CELLS` more on every side."""
        g = self.grid
        if g is not None and _covers(g, need):
            return g
        m = MARGIN_CELLS * need.h
        lo_x, hi_x, lo_y, hi_y = need.bounds
        if g is not None:
            b = g.bounds
            lo_x, hi_x, lo_y, hi_y = min(lo_x, b[0]), max(hi_x, b[1]), min(lo_y, b[2]), max(hi_y, b[3])
        self.grid = fast_grid(Grid.covering(lo_x - m, hi_x + m, lo_y - m, hi_y + m, need.h, anchor=(need.x0, need.y0)))
        return self.grid

    def start(self, grid: Grid, shift: float) -> np.ndarray | None:
        """The last pressure moved with the road to ``shift`` on ``grid``, extrapolated
        linearly from the two last positions when both are there (clipped at 0)."""
        if not self.past:
            return None
        one = _moved(*self.past[-1], grid, shift)
        if len(self.past) < 2:
            return one
        two = _moved(*self.past[-2], grid, shift)
        return np.maximum(2.0 * one - two, 0.0)

    def keep(self, result, shift: float) -> None:
        f = result.fields[0] if result.fields else None
        if f is None or abs(f.grid.h - (self.grid.h if self.grid else f.grid.h)) > 1e-12:
            self.past.clear()
            return
        self.past = (self.past + [(f.grid, f.pressure, shift)])[-2:]


def fast_grid(grid: Grid) -> Grid:
    """``grid`` grown (about its centre) to sides of 5-smooth lengths: the preconditioner
    transforms the grid itself, and a prime side (Bluestein's FFT) costs as much as the
    zero-padded product."""
    from scipy.fft import next_fast_len

    nx, ny = next_fast_len(grid.nx, real=True), next_fast_len(grid.ny, real=True)
    return Grid(grid.x0 - ((nx - grid.nx) // 2) * grid.h, grid.y0 - ((ny - grid.ny) // 2) * grid.h, grid.h, nx, ny)


def _covers(outer: Grid, inner: Grid) -> bool:
    a, b = outer.bounds, inner.bounds
    eps = 1e-9 * inner.h
    return a[0] <= b[0] + eps and a[1] >= b[1] - eps and a[2] <= b[2] + eps and a[3] >= b[3] - eps


def _moved(grid: Grid, pressure: np.ndarray, shift: float, target: Grid, to: float) -> np.ndarray:
    """``pressure`` on ``grid`` at ``shift`` moved with the road to shift ``to`` (to the
    nearest cell: exact when the step is a multiple of the cell) and cut to ``target``."""
    h = target.h
    i0 = int(round((grid.x0 + (to - shift) - target.x0) / h))
    j0 = int(round((grid.y0 - target.y0) / h))
    out = np.zeros(target.shape)
    ys, yd = _overlap(j0, grid.ny, target.ny)
    xs, xd = _overlap(i0, grid.nx, target.nx)
    if ys is not None and xs is not None:
        out[yd, xd] = pressure[ys, xs]
    return out


def _overlap(offset: int, n_src: int, n_dst: int):
    lo, hi = max(0, -offset), min(n_src, n_dst - offset)
    if hi <= lo:
        return None, None
    return slice(lo, hi), slice(lo + offset, hi + offset)


def reference_grid(track: Track, selection: Selection, bound: float) -> Grid:
    """Cells of size ``track.h`` (on the lattice h Z^2) covering every place a stone of
    ``selection`` can touch when the approach is at most ``bound``, within the face window."""
    h = track.h
    boxes = []
    for s in selection.stones:
        r = s.reach(max(bound - s.z, 0.0)) * 1.05 + 3.0 * h
        boxes.append((s.x - r, s.x + r, s.y - r, s.y + r))
    b = np.array(boxes)
    x0, x1, y0, y1 = track.road.window
    lo_x, hi_x = max(b[:, 0].min(), x0 - h), min(b[:, 1].max(), x1 + h)
    lo_y, hi_y = max(b[:, 2].min(), y0 - h), min(b[:, 3].max(), y1 + h)
    return Grid.covering(lo_x, hi_x, lo_y, hi_y, h)


def contact_box(track, selection, bound: float) -> Grid | None:
    """The box of the cells of ``selection``'s stones that lie below ``bound`` (the only
    ones that can touch when the approach is at most ``bound``), on the run's lattice;
    None when no cell is that low."""
    reach = reference_grid(track, selection, bound)
    s = surface_on(reach, selection.stones)
    low = np.isfinite(s.height) & (s.height < bound)
    rows, cols = np.flatnonzero(low.any(axis=1)), np.flatnonzero(low.any(axis=0))
    if not rows.size:
        return None
    return reach.subgrid(int(cols[0]), int(rows[0]), int(cols[-1] - cols[0] + 1), int(rows[-1] - rows[0] + 1))


def solve_window(track, selection, bound: float, state: WindowState, tol: float):
    """The static solve of the road at ``selection.shift`` (its stones) by one constrained
    CG over the kept window (module docstring); None when no cell can touch."""
    from ..micro.strategies import UNION_TOL_FACTOR
    from ..reference.cg import solve_cg

    box = contact_box(track, selection, bound)
    if box is None:
        return None
    grid = state.window(box)
    surface = surface_on(grid, selection.stones)
    scene = track.scene
    result = solve_cg(
        state.body,
        surface,
        penetration=scene.penetration,
        total_load=scene.total_load,
        tol=tol * UNION_TOL_FACTOR,
        start=state.start(grid, selection.shift),
        precision="single-directions",
        precondition=True,
        keep_conjugacy=KEEP_CONJUGACY,
    )
    return dataclasses.replace(result, message="") if result.converged else result
