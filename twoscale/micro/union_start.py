"""The union CG's start from the macro step (:func:`interference_start`).

On the cells each tip owns, its interference cap at a fraction ``START_FRACTION`` of its
macro local approach: a cap a little wider than the Hertz contact, so that the CG's active
set shrinks onto the contact in a few large steps (where it grows cell by cell). Where the
macro step came near a solution each tip's cap is scaled to carry that tip's macro force:
the CG rescales its start by one factor (to the load, or by a line search on the energy),
and the caps' depths alone weigh a tip's start by its approach, not by its force. Thousands
of separated tips under penetration control (the union CG's iterations / products, the cap
alone against the caps scaled): 1,684 paraboloids 22 / 56 against 20 / 49, 5,782 spheres 31
/ 81 against 27 / 68. On the height-map roads the macro forces are poor stone by stone and
the scaling changed nothing beyond the noise (18-21 iterations either way).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..indenters import Asperity

#: The start's cap around tip k reaches the level ``z_k + START_FRACTION delta_k``
#: (``delta_k`` its macro local approach): radius sqrt(2 x 0.6) = 1.1 times Hertz's contact
#: radius. 300 merged tips: 64 CG iterations against 70 from the CG's own start (0.5: 66,
#: 0.8: 63).
START_FRACTION = 0.6


def interference_start(
    surface, asperities: Sequence[Asperity], approaches: np.ndarray, forces: np.ndarray | None = None
) -> np.ndarray | None:
    """A start for the CG on ``surface`` (MPa up to a factor: the CG rescales it): on each
    cell owned by tip k, ``max(z_k + START_FRACTION delta_k - z, 0)``, ``delta_k`` the
    macro local approach (mm). With ``forces`` (N, the macro step's, one a tip) each tip's
    cap is scaled to carry its force (MPa; a cap whose tip has no force is dropped), unless
    a force is not finite or no cap would keep pressure. None when no cell gets pressure."""
    tips = np.array([a.z for a in asperities], dtype=float)
    level = tips + START_FRACTION * np.maximum(np.asarray(approaches, dtype=float), 0.0)
    # whole-grid passes through the owners shifted by one, a cell no tip owns (owner -1) at a
    # level of -inf put first: no masked gathers and scatters, three fresh grid-sized arrays
    # where there were nine (each page-faulting in a fresh process)
    at = surface.owner + 1
    start = np.concatenate(([-np.inf], level))[at]
    np.subtract(start, surface.height, out=start)
    np.maximum(start, 0.0, out=start)
    if forces is not None:
        start = _scaled(start, at, np.asarray(forces, dtype=float), surface.grid.h)
    return start if np.any(start > 0) else None


def _scaled(cap: np.ndarray, at: np.ndarray, forces: np.ndarray, h: float) -> np.ndarray:
    """The caps (mm, ``at`` each cell's owner plus one, 0 for none: cap 0 there) scaled tip
    by tip to carry ``forces`` (N) on cells of side ``h`` (mm): pressures, MPa, in place;
    the caps unchanged where that is not possible (a force not finite, or no tip with both
    a cap and a force)."""
    if len(forces) == 0 or not np.all(np.isfinite(forces)):
        return cap
    n = len(forces)
    volume = np.bincount(at.ravel(), weights=cap.ravel(), minlength=n + 1)[1:] * (h * h)  # mm^3 a tip
    carried = (volume > 0.0) & (forces > 0.0)
    if not np.any(carried):
        return cap
    factor = np.zeros(n + 1)
    factor[1:][carried] = forces[carried] / volume[carried]
    cap *= factor[at]
    return cap
