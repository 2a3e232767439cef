"""The rolling path (the half-space; a block's face under a strip): one constrained CG per
position over a window fixed in the body, its operator built once for the run.

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
* the **start** is the previous pressure moved with the road by exactly the step (a
  whole number of cells on a height map), extrapolated linearly from the two previous
  positions (a stone's pressure changes smoothly in the footprint; the second position's
  by the face's motion: :mod:`.shiftstep`), the pressure and, off the contact, minus the
  gap as one signed field (:meth:`WindowState.keep`): a cell whose gap closes starts loaded;
* the **solve** is :func:`twoscale.reference.cg.solve_cg` on the surface of the
  position's stones (:func:`twoscale.indenters.surface_on`, the heights every static
  solve sees), preconditioned by the stones' blocks and their coupling (:mod:`.blocks`;
  a body without them: the circulant inverse), to the KKT residual the union CG stops
  at (``tol x`` :data:`~twoscale.micro.strategies.UNION_TOL_FACTOR`), in one stage
  (``precision="single-directions"``): the search directions' products in float32, the
  pressure, displacement and residual in double precision, the few cells a step clips
  or lets in corrected by the kernel's columns instead of a fresh product, and the
  conjugate directions kept while at most :data:`KEEP_CONJUGACY` of the loaded cells
  enter (the start's contact settles at the stones' edges a few cells at a time), and
  its array passes on the cells within :data:`NEAR_GAP` of the road at the last position
  (:meth:`WindowState.near`; the others checked on the answer, by ``solve_cg``).
* the **cut**: the CG runs on a part of the window, the box of the last position's
  contact (fixed in the body: the footprint) with :data:`CUT_MARGIN_CELLS` to spare along
  the rolling direction and what the transform's length leaves beside it (:func:`cut_grid`;
  on the tyre's footprint 320 of the window's 384 cells along x and 608 of its 625 rows:
  the footprint's rim lies below the approach bound but the tyre's elastic lift keeps it
  off; the first position's: the columns over the tyre's estimated footprint,
  :attr:`WindowState.footprint`, and the rows of the cells that can touch), and its answer is
  checked a posteriori on the whole window (:func:`.lift.touching_outside`: on a half-space a
  lower bound of the lift its pressure makes there, :mod:`.lift`; else the displacement, one
  float32 product, exact only near contact); cells outside the cut that would touch make
  it grow to take them in, solved again from its answer.

The answer is the static contact of the road at that shift to the solver's tolerance: the
cells left out of the window cannot touch (their height is above the bound), those out of
the cut were checked not to, the start only changes the work; a position that does not
converge is solved again by the two-scale solver from cold.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..grid import Grid
from ..indenters import Surface
from .blocks import StoneBlocks
from .boxes import CUT_MARGIN_CELLS, clipped, covers, cut_grid, fast_grid, grown, loaded_box, moved, union
from .lift import touching_outside
from .reach import contact_box, covers_extents, low_box, reference_grid
from .stones import stones_surface

#: Cells added on every side when the window is built or grows.
MARGIN_CELLS = 8
#: Most CG iterations of a position (17-30 measured over a 1 m run), then the two-scale
#: solver from cold (a safety net: :data:`twoscale.pk.products.KEPT_GROWTH`).
WINDOW_MAX_ITER = 100
#: The kept cut is rebuilt around the last contact when that would leave at most this
#: fraction of its cells (a new operator costs a few products; a cut grown for one
#: position, or to the whole window, would otherwise stay).
CUT_SHRINK = 0.9
#: The start extrapolates ``-GAP_STIFFNESS gap / a00`` off the contact (``a00``: a cell's
#: self-compliance; the tyre's positions replayed: 18.8 CG iterations at 0, 16.7 at 0.3;
#: with the stone blocks, 60 mm of the 1 m benchmark's run: 9.19 a position at 0.3, 8.92 at
#: 0.45, 8.83 at 0.6, 8.98 at 0.8; 20 mm: 9.37 at 1, 10.1 at 2 and 5). It scales the pressure
#: the start gives the ~300 cells a position that enter the contact (all of them foreseen
#: by the extrapolated gap, with ~60-120 more that stay out).
GAP_STIFFNESS = 0.6
#: The CG runs on the cells of the cut that were within this gap (mm) of the road at the
#: last position, moved with the road, or are loaded at the start
#: (``solve_cg(reach=...)``): 14 % of the tyre's cut instead of its 96 % with material, the
#: others checked on the answer (over a 20 mm section the cells within 0.1 mm of the last
#: contact held all but one loaded cell of the next; twice that for a margin).
NEAR_GAP = 0.2
#: Operators :class:`KeptBody` keeps (the window's, the cut window's, one cut before).
KEPT_OPERATORS = 3
#: The CG keeps its conjugate directions when at most this fraction of the loaded cells
#: enters in a step (a warm start's contact settles at the stones' edges a few cells at a
#: time: 23 -> 18 iterations a position on the tyre's footprint; 0.2 % and 1 % took more).
KEEP_CONJUGACY = 0.005


class KeptOperator:
    """A grid operator with its single-precision twin and preconditioner built once
    (``solve_cg`` asks for them at every solve), and the wrapped operator's own routes
    where it has them: ``exact`` (the float32 operator's float64 product, the CG's anchor)
    and ``on_cells`` (on the CG's part of the grid, also in two halves), else None."""

    def __init__(self, op, single: bool = False, parent=None):
        self.op, self.single, self.parent = op, single, parent
        self.target, self.source = op.target, op.source
        self._twin = self._pc = None
        exact = getattr(op, "exact", None)  # (its float64 buffers kept: every position's anchor)
        self.exact = None if exact is None else (lambda p: exact(p, keep=True))
        self.on_cells = getattr(op, "on_cells", None)

    def apply(self, p):
        return self.op.apply(p)

    def columns(self, targets=None):
        return self.op.columns(targets) if hasattr(self.op, "columns") else None

    def single_precision(self) -> "KeptOperator":
        if self._twin is None:
            self._twin = KeptOperator(self.op.single_precision(), single=True, parent=self)
        return self._twin

    def preconditioner(self):
        """The float32 circulant inverse for both stages (it shapes the directions only)."""
        if self.parent is not None:
            return self.parent.preconditioner()
        if self._pc is None:
            single = self.single_precision().op
            self._pc = getattr(single, "preconditioner", lambda: None)() or self.op.preconditioner()
        return self._pc


class KeptBody:
    """The body as :func:`~twoscale.reference.cg.solve_cg` asks for it, with the operator of
    each square grid kept: a translation-invariant body (``split()`` has no correction) by
    the grid's shape (a smaller grid's from a kept offset table), any other by the grid."""

    def __init__(self, provider):
        self.provider, self.material = provider, provider.material
        self.invariant = provider.split()[1] is None  # no correction: translation-invariant
        self._ops: dict = {}
        self._self: dict = {}  # cell size -> a cell's self-compliance

    def self_compliance(self, h: float) -> float:
        """The provider's self-compliance of a cell of ``h`` mm, kept (~0.3 ms a call)."""
        if h not in self._self:
            self._self[h] = self.provider.self_compliance(h)
        return self._self[h]

    def grid_operator(self, target: Grid, source: Grid | None = None):
        if source is not None and source != target:
            return self.provider.grid_operator(target, source)
        key = target.shape if self.invariant else target
        op = self._ops.pop(key, None)
        if op is None:
            kept = [k.op for k in self._ops.values() if self.invariant and hasattr(k.op, "restricted")]
            cut = (k.restricted(target) for k in kept)  # a kept table cut to a smaller grid
            op = KeptOperator(next(filter(None, cut), None) or self.provider.grid_operator(target))
            largest = max(self._ops, key=lambda k: self._ops[k].target.size, default=None)
            while len(self._ops) >= KEPT_OPERATORS:  # the least recently used goes, not the cuts' table
                self._ops.pop(next(k for k in self._ops if k != largest))
        self._ops[key] = op
        return op


@dataclass
class WindowState:
    """What the positions of one run share on this path: the body with its kept operator,
    the window, and the last two answers (grid, signed field, shift) for the start: the
    pressure where it is positive, minus the gap scaled to a pressure elsewhere
    (:meth:`keep`; a field without negative entries is a plain pressure)."""

    body: KeptBody
    grid: Grid | None = None
    past: list = field(default_factory=list)
    cut: Grid | None = None
    blocks: StoneBlocks | None = None
    ahead: Callable | None = None  # the second position's linearised step (:mod:`.shiftstep`)
    footprint: tuple | None = None  # body x-interval of the expected contact, mm (the first cut)

    def window(self, need: Grid) -> Grid:
        """The kept window if it covers ``need`` (same lattice), else one that covers both
        with :data:`MARGIN_CELLS` more on every side, within the body's domain (a block's)."""
        g, m, (lo_x, hi_x, lo_y, hi_y) = self.grid, MARGIN_CELLS * need.h, need.bounds
        if g is not None and covers(g, need):
            return g
        if g is not None:
            b = g.bounds
            lo_x, hi_x, lo_y, hi_y = min(lo_x, b[0]), max(hi_x, b[1]), min(lo_y, b[2]), max(hi_y, b[3])
        grid = fast_grid(Grid.covering(lo_x - m, hi_x + m, lo_y - m, hi_y + m, need.h, anchor=(need.x0, need.y0)))
        self.grid = clipped(grid, self.body.provider.domain())
        return self.grid

    def cut_in(self, window: Grid, low: Callable[[], Grid | None] | None = None) -> Grid:
        """The grid the position is solved on: the kept cut if it lies in ``window`` and
        covers the last contact's box (fixed in the body) with a cell to spare, else one
        built around that box (:func:`cut_grid`); with no last contact, the window's columns
        over :attr:`footprint` with :data:`CUT_MARGIN_CELLS` to spare and the rows of ``low()``
        (the box of the cells that can touch) with the side's margin (the first position
        solved on a cut too: its operator is the second's); ``window`` itself when there is
        neither or the cut would not be smaller."""
        box = self._last_contact()
        if box is None:
            return window if self.footprint is None else self._first_cut(window, None if low is None else low())
        kept = self.cut
        if kept is not None and covers(window, kept) and covers(kept, grown(box, 1)):
            fresh = cut_grid(box)
            if fresh.size >= CUT_SHRINK * kept.size or not covers(window, fresh):
                return kept  # (a cut grown for one position shrinks back when the contact allows)
        return self.grow_cut(window, box)

    def grow_cut(self, window: Grid, need: Grid) -> Grid:
        """A cut covering ``need`` with margins to spare (:func:`cut_grid`), kept; ``window``
        itself when that is not inside it."""
        cut = cut_grid(need)
        if not covers(window, cut) or cut.size >= window.size:
            cut = window
        self.cut = cut
        return cut

    def _first_cut(self, window: Grid, low: Grid | None) -> Grid:
        """The window's columns over :attr:`footprint` and the rows of ``low`` with margins to
        spare (:func:`cut_grid`), or where that does not fit in the window, or without
        ``low``, its columns with :data:`CUT_MARGIN_CELLS` more on each side (5-smooth) and
        all its rows; kept; the window itself when that is not smaller."""
        lo, hi = (round((x - window.x0) / window.h) for x in self.footprint)
        cut = None
        if low is not None:
            j0 = low.offset_in(window)[1]
            cut = cut_grid(window.subgrid(lo, j0, max(hi - lo, 1), low.ny))
        if cut is None or not covers(window, cut):
            i0, i1 = max(lo - CUT_MARGIN_CELLS, 0), min(hi + CUT_MARGIN_CELLS, window.nx)
            cut = fast_grid(window.subgrid(i0, 0, max(i1 - i0, 1), window.ny))
        if not covers(window, cut) or cut.size >= window.size:
            return window  # (no cut kept: the next is built around the contact)
        self.cut = cut
        table = getattr(self.body.grid_operator(window).op, "offset_table", None)
        if self.body.invariant and table is not None:
            table()  # the window's operator and table first: the cut's is a window of it
        return cut

    def _last_contact(self) -> Grid | None:
        """The box of the last position's loaded cells (a sub-grid of its grid)."""
        return loaded_box(*self.past[-1][:2]) if self.past else None

    def start(self, grid: Grid, shift: float, pc=None, one=None) -> np.ndarray | None:
        """The last pressure moved with the road to ``shift`` on ``grid``, extrapolated
        linearly from the two last positions when both are there, else advanced by
        ``ahead`` if given (preconditioned by ``pc``; the signed fields of :meth:`keep`,
        clipped at 0; 0 where the last one is not known or has no material). ``one``: the
        last signed field already moved to ``grid`` (:meth:`last_moved`)."""
        if not self.past:
            return None
        one = self.last_moved(grid, shift) if one is None else one
        if len(self.past) < 2:
            ahead = 0.0 if self.ahead is None else self.ahead(one, grid, shift - self.past[-1][2], pc)
            return np.maximum(one + ahead, 0.0)
        out = np.multiply(one, 2.0)  # (in place: 2 one - two, clipped, 0 where one is: four passes less)
        out -= moved(*self.past[-2], grid, shift)
        np.maximum(out, 0.0, out=out)
        out[one == 0.0] = 0.0
        return out

    def last_moved(self, grid: Grid, shift: float) -> np.ndarray | None:
        """The last signed field (:meth:`keep`) moved with the road to ``shift`` on ``grid``."""
        return moved(*self.past[-1], grid, shift) if self.past else None

    def near(self, grid: Grid, one: np.ndarray | None) -> np.ndarray | None:
        """The cells of ``grid`` within :data:`NEAR_GAP` of the road at the last position
        (``one``: :meth:`last_moved`; the cells it did not cover too), None without a gap."""
        if one is None or not np.any(one < 0.0):
            return None  # no last position, or a plain pressure: the gap is not known
        return one > -NEAR_GAP * GAP_STIFFNESS / self.body.self_compliance(grid.h)

    def keep(self, result, shift: float) -> None:
        """Keep ``result``'s pressure, and off the contact minus its gap times
        :data:`GAP_STIFFNESS` over a cell's self-compliance, for the next starts."""
        f = result.fields[0] if result.fields else None
        if f is None or abs(f.grid.h - (self.grid.h if self.grid else f.grid.h)) > 1e-12:
            self.past.clear()
            return
        stiffness = GAP_STIFFNESS / self.body.self_compliance(f.grid.h)
        signed = np.maximum(f.gap, 0.0)  # (in place: -stiffness max(gap, 0), -0 off material)
        signed *= -stiffness
        signed[~np.isfinite(signed)] = -0.0
        np.copyto(signed, f.pressure, where=f.pressure > 0.0)
        self.past = (self.past + [(f.grid, signed, shift)])[-2:]


def _window_surface(track, selection, bound: float, state: WindowState):
    """The kept window (grown if need be) and the stones' surface on it, or None when no
    cell can touch: the surface is sampled once, on the kept window, when the stones'
    reach lies inside it (the box of their low cells then does too)."""
    g = state.grid
    if g is not None and (covers_extents(g, track, selection) or covers(g, reference_grid(track, selection, bound))):
        surface = stones_surface(g, selection.stones, selection.group)
        return None if low_box(surface, bound) is None else (g, surface)
    box = contact_box(track, selection, bound)
    if box is None:
        return None
    grid = state.window(box)
    return grid, stones_surface(grid, selection.stones, selection.group)


def solve_window(track, selection, bound: float, state: WindowState, tol: float):
    """The static solve of the road at ``selection.shift`` (its stones) by one constrained
    CG over the cut of the kept window (module docstring), checked on the whole window;
    None when no cell can touch."""
    from ..micro.strategies import UNION_TOL_FACTOR
    from ..reference.cg import solve_cg

    found = _window_surface(track, selection, bound, state)
    if found is None:
        return None
    grid, surface = found
    scene = track.scene
    cut = state.cut_in(grid, lambda: low_box(surface, bound))
    if not np.isfinite(_restricted(surface, cut).height).any():
        cut = grid  # no stone's material in the cut (cannot carry a load): the whole window
    blocks = None if state.blocks is None else state.blocks.at(selection.numbers, selection.shift, grid.h)
    # the second position's linearised step by its stone blocks, let go before the CG builds
    # its own (held through it, the heap grew by their ~6 MB: 2,100 more page faults)
    step_pc = None if blocks is None or len(state.past) != 1 else blocks(_restricted(surface, cut))
    one = state.last_moved(cut, selection.shift)  # moved once, for the start and the CG's cells
    start, step_pc = state.start(cut, selection.shift, step_pc, one), None
    near = state.near(cut, one)
    reach = None if near is None or start is None else near | (start > 0.0)
    while True:
        result = solve_cg(
            state.body,
            _restricted(surface, cut),
            penetration=scene.penetration,
            total_load=scene.total_load,
            tol=tol * UNION_TOL_FACTOR,
            start=start,
            precision="single-directions",
            precondition=True,
            preconditioner=blocks,
            keep_conjugacy=KEEP_CONJUGACY,
            max_iter=WINDOW_MAX_ITER,
            reach=reach,
            half_products=True,
        )
        if cut == grid or not result.converged:
            break
        if not result.fields:  # nothing reached the approach in the cut: solve the whole window
            cut, start, reach = grid, None, None
            continue
        wrong = touching_outside(state.body, surface, result, tol * UNION_TOL_FACTOR)
        if wrong is None:
            break
        # cells around the cut would touch: solve again on a cut that takes them in
        f = result.fields[0]
        cut = state.grow_cut(grid, union(f.grid, wrong))
        start, reach = moved(f.grid, f.pressure, 0.0, cut, 0.0), None
    return dataclasses.replace(result, message="") if result.converged else result


def _restricted(surface, cut: Grid):
    """``surface`` on the aligned sub-grid ``cut``."""
    if cut == surface.grid:
        return surface
    rows, cols = cut.window_in(surface.grid)
    return Surface(cut, surface.height[rows, cols], surface.owner[rows, cols], surface.n_asperities)
