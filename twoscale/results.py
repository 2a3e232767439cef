"""Frozen result objects shared by every solver.

A solver's pressure lives on one or more aligned rectangular grids ("patches"):
the reference solver has one grid covering the scene, the two-scale solver one
patch per asperity. Per-asperity figures are integrals over the cells each
asperity owns (the indenter nearest the body).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .grid import Grid


def _frozen(a, dtype=float) -> np.ndarray:
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class PressureField:
    """Pressure and related fields on one grid.

    Attributes
    ----------
    grid : Grid
    pressure : (ny, nx) array, MPa (>= 0).
    owner : (ny, nx) int array: owning asperity, -1 where no indenter has material.
    gap : (ny, nx) array, mm: ``z + u - d`` (indenter height + displacement - approach);
        0 in contact, > 0 outside; ``inf`` where no indenter has material.
    """

    grid: Grid
    pressure: np.ndarray
    owner: np.ndarray
    gap: np.ndarray

    def __post_init__(self) -> None:
        for name in ("pressure", "gap"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "owner", _frozen(self.owner, np.int64))
        for name in ("pressure", "owner", "gap"):
            if getattr(self, name).shape != self.grid.shape:
                raise ValueError(f"{name} has shape {getattr(self, name).shape}, grid is {self.grid.shape}")


@dataclass(frozen=True)
class AsperitySummary:
    """Per-asperity integrals of the final pressure (arrays in scene order).

    forces (N), contact_areas (mm^2), max_pressures (MPa).
    """

    forces: np.ndarray
    contact_areas: np.ndarray
    max_pressures: np.ndarray


def summarise(fields: Sequence[PressureField], n_asperities: int) -> AsperitySummary:
    """Force, contact area and peak pressure of each asperity from its owned cells."""
    forces = np.zeros(n_asperities)
    areas = np.zeros(n_asperities)
    pmax = np.zeros(n_asperities)
    for f in fields:
        own = f.owner.ravel()
        p = f.pressure.ravel()
        ok = own >= 0
        h2 = f.grid.h ** 2
        forces += h2 * np.bincount(own[ok], weights=p[ok], minlength=n_asperities)
        areas += h2 * np.bincount(own[ok], weights=(p[ok] > 0).astype(float), minlength=n_asperities)
        if np.any(ok):
            np.maximum.at(pmax, own[ok], p[ok])
    return AsperitySummary(_frozen(forces), _frozen(areas), _frozen(pmax))


@dataclass(frozen=True)
class ContactResult:
    """What every solver returns.

    Attributes
    ----------
    method : str
        "dense", "cg" (reference solvers) or "twoscale".
    fields : tuple of PressureField
        Pressure on the grid(s) the solver used.
    penetration : float
        Rigid approach d, mm (given or solved).
    tilt : (alpha, beta) or None
        Tilt angles, radians, when the load was applied through a ball-and-socket joint.
    total_load : float
        Integral of the pressure, N.
    asperities : AsperitySummary
        Per-asperity forces, areas, peak pressures, in scene order.
    converged : bool
        Whether every stopping criterion was met. A solver that hits its iteration
        limit returns ``converged=False`` with ``message`` saying why.
    message : str
    iterations : dict
        Iteration counts by stage, e.g. {"outer": 12} or {"macro": 5, "micro": 7}.
    residuals : dict
        Residual histories by stage (tuples of floats).
    timings_s : dict
        Wall-clock seconds by stage.
    extra : dict
        Method-specific figures (e.g. "macro_forces", "p0_change_percent").
    """

    method: str
    fields: tuple
    penetration: float
    tilt: tuple | None
    total_load: float
    asperities: AsperitySummary
    converged: bool
    message: str = ""
    iterations: dict = field(default_factory=dict)
    residuals: dict = field(default_factory=dict)
    timings_s: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    @property
    def n_cells(self) -> int:
        """Number of cells the solver carried (its problem size)."""
        return sum(f.grid.size for f in self.fields)

    def pressure_on(self, grid: Grid) -> np.ndarray:
        """The pressure assembled onto an aligned ``grid`` (zero where no field covers it)."""
        out = np.zeros(grid.shape)
        for f in self.fields:
            di, dj = f.grid.offset_in(grid)
            i0, j0 = max(di, 0), max(dj, 0)
            i1, j1 = min(di + f.grid.nx, grid.nx), min(dj + f.grid.ny, grid.ny)
            if i1 <= i0 or j1 <= j0:
                continue
            out[j0:j1, i0:i1] += f.pressure[j0 - dj:j1 - dj, i0 - di:i1 - di]
        return out
