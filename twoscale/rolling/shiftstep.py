"""The start of a run's second position: the first answer moved with the road and advanced
by its derivative with the shift (a linearised step).

From the third position on, the window path starts from the last answer moved with the
road and extrapolated linearly from the two last ones (:meth:`.window.WindowState.start`):
a stone's pressure changes smoothly as it rolls through the footprint. The second position
has one answer only, and the first answer moved with the road leaves the change the
footprint makes over a step to the CG (20 iterations on the 1 m benchmark's tyre against
9-10 for an extrapolated start). That change is known to first order: in the road's frame
the stones do not move, the body's face does (by the step: its height under a road cell
changes by ``dface = face(x) - face(x - step)``, smooth), so on the first answer's contact
``C`` the pressure changes by ``q`` with

    ``A_CC q = -dface + c``  (``c``: the approach's change; load control: ``sum q = 0``),

and off the contact the gap by ``A q + dface - c``. :class:`ShiftStep` solves this for
``q`` by a few conjugate-gradient iterations on ``C`` (float32 products of the position's
own operator, preconditioned by the position's stone blocks, :mod:`.blocks`, where the body
has them: :data:`SHIFT_STEP_ITERATIONS`, :data:`SHIFT_STEP_RTOL`; its vectors on the rows
of ``C`` alone, ~12,000 of the tyre's cut of 200,000 cells, the products through one kept
grid field), and returns the change
of the start's signed field (pressure on the contact; minus the gap, scaled to a pressure,
off it), i.e. what the extrapolation adds from the third position on. Its products and its
blocks (the stones' inverses on ``C``, kept and updated by the CG's own blocks after it)
are the second position's work, and counted there. It only changes the start: the answer
is the CG's to its tolerance. A flat face (no tyre) changes nothing (``dface = 0``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..grid import Grid

#: Most CG iterations of the linearised step (float32 products of the position's cut, ~5 ms
#: each on the 1 m benchmark's tyre, whose second position took 20 CG iterations, ~10 ms
#: each, from the moved start: without a preconditioner 15, 14, 11, 10, 8 and 7 after 2,
#: 3, 4, 6, 8 and 16 of them; with the stone blocks 10, 7 and 7 after 1, 2 and 3).
SHIFT_STEP_ITERATIONS = 10
#: The linearised step stops when its projected residual has fallen below this fraction of
#: its first (the tyre's: 0.28, 0.16, 0.12, 0.066, 0.044, 0.031, 0.023, 0.013 after 1-8
#: iterations without a preconditioner, 0.028 and 0.0021 after 1 and 2 with the blocks).
SHIFT_STEP_RTOL = 0.02


@dataclass(frozen=True)
class ShiftStep:
    """The linearised change of a position's answer over one step of the road.

    Attributes
    ----------
    body : KeptBody
        The body (:class:`.window.KeptBody`), its operators kept by grid.
    face : callable
        ``face(x)``: the body's face height at body x, mm (:meth:`.spec.RollingSpec.face`).
    load_control : bool
        The total load is held (the change sums to 0; else the approach is held).
    gap_stiffness : float
        The factor turning a gap into the signed field's negative entries, MPa/mm
        (:data:`.window.GAP_STIFFNESS` over a cell's self-compliance).
    """

    body: Any
    face: Callable[[np.ndarray], np.ndarray]
    load_control: bool
    gap_stiffness: float

    def __call__(self, one: np.ndarray, grid: Grid, step: float, precondition: Any = None) -> np.ndarray:
        """The change of the signed field ``one`` (the last answer moved by ``step`` mm with
        the road onto ``grid``: pressure where positive, minus the scaled gap elsewhere, 0
        where unknown) over that step; 0 where ``one`` is 0. ``precondition``: an approximate
        inverse on the loaded cells, ``precondition(gap, on)`` on the grid (e.g. the position's
        stone blocks, whose ``on_part(cells)`` takes the loaded cells' rows alone), or None."""
        on = one > 0.0
        if step == 0.0 or not np.count_nonzero(on):
            return np.zeros_like(one)
        x = grid.x0 + grid.h * (np.arange(grid.nx) + 0.5)  # (the face varies along x only)
        with np.errstate(invalid="ignore"):
            dface = self.face(x) - self.face(x - step)
        dface = np.where(np.isfinite(dface), dface, 0.0)
        if not np.any(dface):
            return np.zeros_like(one)
        cells = np.flatnonzero(on)
        q, aq = self._solve(grid, cells, np.broadcast_to(dface, grid.shape).ravel()[cells], precondition)
        dgap = aq + dface
        if self.load_control:
            dgap -= dgap.ravel()[cells].mean()  # the approach's change
        out = np.where(one != 0.0, -self.gap_stiffness * dgap, 0.0)
        out.ravel()[cells] = q
        return out

    def _solve(self, grid: Grid, cells: np.ndarray, dface: np.ndarray, precondition: Any) -> tuple:
        """``q`` on the loaded ``cells`` (flat, increasing; ``dface`` there) minimising ``q.A q
        / 2 + dface.q`` (load control: ``sum q = 0``) by (preconditioned) CG on their rows,
        and ``A q`` on the grid (float32 products)."""
        single = self.body.grid_operator(grid).single_precision()
        pc = _on_rows(precondition, grid, cells)
        q, aq, field = np.zeros(cells.size), np.zeros(grid.shape), np.zeros(grid.size)
        r = self._projected(dface)  # the gradient at q = 0
        z = r if pc is None else self._projected(pc(r))
        d, rz, rr0 = -z, float(np.vdot(r, z)), float(np.vdot(r, r))
        for _ in range(SHIFT_STEP_ITERATIONS):
            if float(np.vdot(r, r)) <= SHIFT_STEP_RTOL**2 * rr0 or not rz > 0.0:
                break  # (rz: the preconditioner's rounding, float32, may end it)
            field[cells] = d
            ad = single.apply(field.reshape(grid.shape))
            pad = self._projected(ad.ravel()[cells])
            curvature = float(np.vdot(d, pad))
            if not curvature > 0.0:
                break
            alpha = rz / curvature
            q += alpha * d
            aq += alpha * ad
            r += alpha * pad
            z = r if pc is None else self._projected(pc(r))
            rz, rz_old = float(np.vdot(r, z)), rz
            d = (rz / rz_old) * d - z
        return q, aq

    def _projected(self, v: np.ndarray) -> np.ndarray:
        """``v`` (the loaded cells' rows) less its mean under load control."""
        return v - v.mean() if self.load_control else v


def _on_rows(precondition: Any, grid: Grid, cells: np.ndarray) -> Callable | None:
    """``precondition`` on the rows of the loaded ``cells`` (all loaded): its ``on_part``
    when it has one, else through the grid."""
    if precondition is None:
        return None
    on = np.ones(cells.size, dtype=bool)
    if hasattr(precondition, "on_part"):
        part = precondition.on_part(cells)
        return lambda r: part(r, on)
    mask = np.zeros(grid.size, dtype=bool)
    mask[cells] = True
    mask = mask.reshape(grid.shape)

    def through_grid(r: np.ndarray) -> np.ndarray:
        full = np.zeros(grid.size)
        full[cells] = r
        return precondition(full.reshape(grid.shape), mask).ravel()[cells]

    return through_grid
