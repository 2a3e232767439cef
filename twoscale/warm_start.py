"""A warm start of a whole two-scale solve from a neighbouring one.

:class:`WarmStart` joins the macro step's start (tip forces, approach, tilt:
:class:`~twoscale.macro.start.MacroStart`) and the micro step's (the pressure around each
tip: :class:`~twoscale.micro.start.MicroStart`). :func:`warm_start` builds one from a
previous result, the tips it was solved for and the tips of the new solve, matched by index
(the same tips in the same order by default; ``index[m] = -1`` for a tip the previous solve
did not have). The answer does not depend on the start, only the work does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .macro.start import MacroStart
from .micro.start import MicroStart, PressureStart


@dataclass(frozen=True)
class WarmStart:
    """Starts of the macro and the micro step (either may be None: cold)."""

    macro: MacroStart | None = None
    micro: MicroStart | None = None


def warm_start(
    result, previous_tips: np.ndarray, n_tips: int, h: float, *, index: np.ndarray | None = None, pressure: bool = True
) -> WarmStart:
    """The start a previous two-scale ``result`` gives a solve of ``n_tips`` tips at cell size ``h``.

    Parameters
    ----------
    result : ContactResult
        The previous solve.
    previous_tips : (N_prev, 2) array, mm
        The tips it was solved for, in its order.
    n_tips : int
        Tips of the new solve.
    h : float
        Cell size of the new solve, mm: the pressure start needs the previous solve's.
    index : (n_tips,) int array, optional
        For each new tip its position among the previous ones, -1 for a new tip; default
        the identity (same tips, same order; then ``n_tips`` must equal ``N_prev``).
    pressure : bool, default True
        Also start the micro step from the previous pressure (else the macro step only).
    """
    previous_tips = np.asarray(previous_tips, dtype=float).reshape(-1, 2)
    if index is None:
        if n_tips != len(previous_tips):
            raise ValueError(
                f"the previous solve had {len(previous_tips)} tips, this one {n_tips}: "
                f"give index (each new tip's previous position, -1 for a new one)"
            )
        index = np.arange(n_tips)
    index = np.asarray(index, dtype=np.int64)
    if index.shape != (n_tips,) or np.any(index >= len(previous_tips)) or np.any(index < -1):
        raise ValueError(f"index must hold {n_tips} positions in [-1, {len(previous_tips) - 1}]")
    macro = MacroStart.from_result(result, None if np.array_equal(index, np.arange(len(previous_tips))) else index)
    micro = None
    grids = [f.grid.h for f in getattr(result, "fields", ())]
    if pressure and grids and all(abs(g - h) <= 1e-12 * h for g in grids):
        macro_forces = getattr(getattr(getattr(result, "details", None), "macro", None), "forces", None)
        forces = result.asperities.forces if macro_forces is None else macro_forces
        micro = MicroStart(
            PressureStart.from_fields(result.fields, previous_tips, h, forces), index, _theta_offset(result)
        )
    return WarmStart(macro, micro)


def _theta_offset(result) -> tuple:
    """The previous micro step's approach and tilt minus its macro step's (zeros when unknown)."""
    macro = getattr(getattr(result, "details", None), "macro", None)
    if macro is None or getattr(macro, "penetration", None) is None:
        return (0.0, 0.0, 0.0)
    off = [float(result.penetration) - float(macro.penetration), 0.0, 0.0]
    if result.tilt is not None and macro.tilt is not None:
        off[1:] = [float(result.tilt[0]) - float(macro.tilt[0]), float(result.tilt[1]) - float(macro.tilt[1])]
    return tuple(off)


__all__ = ["WarmStart", "warm_start"]
