"""What the output writers read from a result, gathered in one place.

The field files, the per-asperity CSV and the figures read a solver's result only
through :func:`result_view`, so a change of the result type is adapted here once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ResultView:
    """The figures of a result that the output files show (arrays in scene order).

    Attributes
    ----------
    method : str
    converged : bool
    message : str
    penetration : float
        Rigid approach, mm.
    tilt : (alpha, beta) or None
        Radians.
    total_load : float
        N.
    forces, contact_areas, max_pressures : (N,) arrays
        Per asperity: N, mm^2, MPa.
    macro_forces : (N,) array or None
        The macro step's tip forces, N, when the method has a macro step.
    fields : tuple of PressureField
        The pressure patches (owner 0-based in memory, -1 for none).
    """

    method: str
    converged: bool
    message: str
    penetration: float
    tilt: tuple | None
    total_load: float
    forces: np.ndarray
    contact_areas: np.ndarray
    max_pressures: np.ndarray
    macro_forces: np.ndarray | None
    fields: tuple


def result_view(result) -> ResultView:
    """The :class:`ResultView` of a :class:`~twoscale.results.ContactResult`."""
    s = result.asperities
    macro = result.macro_forces
    return ResultView(
        method=str(result.method), converged=bool(result.converged), message=str(result.message),
        penetration=float(result.penetration),
        tilt=None if result.tilt is None else (float(result.tilt[0]), float(result.tilt[1])),
        total_load=float(result.total_load),
        forces=np.asarray(s.forces, float), contact_areas=np.asarray(s.contact_areas, float),
        max_pressures=np.asarray(s.max_pressures, float),
        macro_forces=None if macro is None else np.asarray(macro, float).ravel(),
        fields=tuple(result.fields))
