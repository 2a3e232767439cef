"""Union iteration: one constrained conjugate-gradient solve over the box of the patches.

Where contacts crowd (hundreds of tips under real loads, merged contacts) the patches
cover much of their bounding box and the cross-patch products cost more than one FFT
product on the box itself. Then the micro step is best solved as one problem: the
Polonsky-Keer constrained conjugate gradient (:func:`twoscale.reference.cg.solve_cg`) on
the box of all patches (the macro forces say where contact is, so the box is much tighter
than the reference solver's a-priori reach), warm-started from the macro forces spread as
Hertz pressures (or from the paper's eq. 7 pressures when they were computed). The load,
the approach and the tilt are solved by the same iteration, so no sensitivity sweeps are
needed. If pressure reaches the box's edge, the box grows by half and the solve resumes
from its pressure.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..grid import Grid
from ..indenters import Asperity, surface_on
from ..influence.base import InfluenceProvider
from ..results import ContactResult
from .patches import Patch

#: Enlargements of the box (by half each time) when pressure reaches its edge.
MAX_ENLARGEMENTS = 3


@dataclass(frozen=True)
class UnionOutcome:
    """What the union iteration produced.

    Attributes
    ----------
    result : ContactResult
        The CG result on the final box (one field).
    patch : Patch
        The box as one patch whose members are every asperity owning a cell of it.
    start : (ny, nx) array, MPa
        The warm start on the final box.
    enlargements : int
        How often the box grew because pressure reached its edge.
    on_edge : bool
        Pressure still reaches the final box's edge (the answer may be clipped).
    iterations : int
        CG iterations, all boxes together.
    products : int
        FFT products, all boxes together.
    """

    result: ContactResult
    patch: Patch
    start: np.ndarray
    enlargements: int
    on_edge: bool
    iterations: int
    products: int


def box_of(patches: Sequence[Patch], h: float, anchor: tuple[float, float], *, grow: float = 1.0) -> Grid:
    """The grid covering every patch, its half-sizes scaled by ``grow`` about its centre."""
    b = np.array([pt.grid.bounds for pt in patches])
    xmin, xmax, ymin, ymax = b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max()
    cx, cy, rx, ry = (xmin + xmax) / 2, (ymin + ymax) / 2, (xmax - xmin) / 2, (ymax - ymin) / 2
    return Grid.covering(cx - grow * rx, cx + grow * rx, cy - grow * ry, cy + grow * ry, h, anchor=anchor)


def box_cells(patches: Sequence[Patch], h: float, anchor: tuple[float, float]) -> int:
    """Cells of :func:`box_of` (without building its arrays)."""
    g = box_of(patches, h, anchor)
    return g.size


def hertz_start(grid: Grid, asperities: Sequence[Asperity], forces: np.ndarray, E_star: float) -> np.ndarray:
    """The macro forces spread as Hertz pressures ``p_max sqrt(1 - r^2/a^2)`` around each tip
    (``a = (3 P R / 4 E*)^(1/3)``), summed, on ``grid`` (MPa)."""
    out = np.zeros(grid.shape)
    h = grid.h
    for a, P in zip(asperities, np.asarray(forces, dtype=float)):
        if not (math.isfinite(P) and P > 0):
            continue
        r = (3.0 * P * a.R / (4.0 * E_star)) ** (1.0 / 3.0)
        i0 = max(int(math.floor((a.x - r - grid.x0) / h)), 0)
        i1 = min(int(math.ceil((a.x + r - grid.x0) / h)) + 1, grid.nx)
        j0 = max(int(math.floor((a.y - r - grid.y0) / h)), 0)
        j1 = min(int(math.ceil((a.y + r - grid.y0) / h)) + 1, grid.ny)
        if i0 >= i1 or j0 >= j1:
            continue
        x = grid.x0 + h * np.arange(i0, i1)
        y = grid.y0 + h * np.arange(j0, j1)
        s = 1.0 - ((x[None, :] - a.x) ** 2 + (y[:, None] - a.y) ** 2) / (r * r)
        out[j0:j1, i0:i1] += 1.5 * P / (math.pi * r * r) * np.sqrt(np.maximum(s, 0.0))
    return out


def _embed(p: np.ndarray, sub: Grid, grid: Grid) -> np.ndarray:
    """``p`` on ``sub`` placed on ``grid`` (both on one lattice; ``sub`` inside ``grid``)."""
    out = np.zeros(grid.shape)
    di, dj = sub.offset_in(grid)
    out[dj:dj + sub.ny, di:di + sub.nx] = p
    return out


def _on_edge(p: np.ndarray) -> bool:
    return bool(np.any(p[0, :] > 0) or np.any(p[-1, :] > 0) or np.any(p[:, 0] > 0) or np.any(p[:, -1] > 0))


def solve_union(provider: InfluenceProvider, asperities: Sequence[Asperity], patches: Sequence[Patch], *,
                h: float, anchor: tuple[float, float], forces: np.ndarray, penetration: float | None,
                total_load: float | None, free_tilt: bool, pivot: tuple[float, float], tol: float,
                start: np.ndarray | None = None, start_grid: Grid | None = None,
                max_iter: int = 20_000, max_enlargements: int = MAX_ENLARGEMENTS,
                precision: str = "mixed") -> UnionOutcome:
    """Solve the micro step as one problem on the box of ``patches``.

    Parameters
    ----------
    provider, asperities
        The body and the indenters.
    patches : sequence of Patch
        The macro step's patches (only their extent is used).
    h : float
        Cell side, mm.
    anchor : (float, float)
        A cell centre of the lattice, mm.
    forces : (N,) array
        Macro forces, N (the warm start when ``start`` is None).
    penetration, total_load : float or None
        Exactly one: the approach d (mm) or the total load (N).
    free_tilt : bool
        Ball-and-socket joint (with ``total_load``), about ``pivot`` (mm).
    tol : float
        KKT residual of the CG relative to the largest displacement.
    start : (ny, nx) array or None
        Warm start on ``start_grid`` (e.g. eq. 7 pressures), MPa; default the macro forces
        as Hertz pressures.
    max_iter : int, default 20000
        CG iterations per box.
    max_enlargements : int, default 3
        Box enlargements when pressure reaches its edge.
    precision : {"mixed", "double"}, default "mixed"
        Of the CG's products (:func:`twoscale.reference.cg.solve_cg`): single-precision
        iterations to 1e-6 first, then double precision to ``tol``.
    """
    from ..reference.cg import solve_cg

    grow, iterations, products = 1.0, 0, 0
    previous = None
    for enlargement in range(max_enlargements + 1):
        grid = box_of(patches, h, anchor, grow=grow)
        surface = surface_on(grid, asperities)
        if previous is not None:
            warm = _embed(previous.fields[0].pressure, previous.fields[0].grid, grid)
        elif start is not None:
            warm = _embed(start, start_grid, grid)
        else:
            warm = hertz_start(grid, asperities, forces, provider.material.E_star)
        result = solve_cg(provider, surface, penetration=penetration, total_load=total_load, tilt=free_tilt,
                          pivot=pivot, tol=tol, max_iter=max_iter, start=warm, precision=precision)
        iterations += int(result.iterations.get("cg", 0))
        products += int(result.iterations.get("products", 0))
        if not result.converged or not _on_edge(result.fields[0].pressure):
            break
        previous, grow = result, grow * 1.5
    members = tuple(int(k) for k in np.unique(surface.owner[surface.owner >= 0]))
    first = members[0] if members else 0
    patch = Patch(first, grid, surface.height, surface.owner, members or (first,))
    return UnionOutcome(result, patch, warm, enlargement, _on_edge(result.fields[0].pressure), iterations,
                        products)
