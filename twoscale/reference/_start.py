"""Where the full-grid CG starts: the working grid (penetration control: the box of the
cells that can touch), the warm start checked and cut to it, and the first pressure."""

from __future__ import annotations

import numpy as np

from ..indenters import Surface
from ._problem import ContactProblem, initial_active_set


def start_on(start: np.ndarray | None, problem, work) -> np.ndarray | None:
    """The warm start checked (finite, on the problem's grid) and cut to the working grid."""
    if start is None:
        return None
    start = np.asarray(start, dtype=float)
    if start.shape != problem.grid.shape or not np.all(np.isfinite(start)):
        raise ValueError(f"start must be a finite array of shape {problem.grid.shape} (MPa), got shape {start.shape}")
    return start if work is problem else start[work.grid.window_in(problem.grid)]


def initial_pressure(
    problem: ContactProblem, op, z: np.ndarray, E_star: float, start: np.ndarray | None = None, scaled: bool = True
) -> np.ndarray:
    """Start from ``start`` (a warm start, e.g. the two-scale macro forces spread as Hertz
    pressures), else from the geometric interference ``max(level - z, 0)`` (level = d, or the
    first-guess level of load control), scaled by a line search on the energy
    (penetration control; not ``scaled``: the guess itself, :func:`line_search` later) or
    to the load. Cells without material start unloaded.
    (A Hertz-like square-root start was tried: no fewer iterations.)"""
    cand = problem.candidates.ravel()
    if start is not None and np.any(start.ravel()[cand] > 0):
        v = np.where(cand, np.maximum(start.ravel(), 0.0), 0.0)
    else:
        level = (
            problem.penetration
            if problem.mode == "penetration"
            else float(np.max(z[initial_active_set(problem, E_star).ravel()]))
        )
        v = np.where(cand, np.maximum(level - z, 0.0), 0.0)
    if not np.any(v > 0):
        v = np.where(cand & (z <= np.min(z[cand])), 1.0, 0.0)
    if problem.mode == "penetration" and scaled:
        Av = op.apply(v.reshape(problem.grid.shape)).ravel()
        num, den = line_search(v, Av, z - problem.penetration)
        return v * num / den
    return v  # the kernel scales it to the load (and moments)


def line_search(v: np.ndarray, Av: np.ndarray, gap: np.ndarray) -> tuple[float, float]:
    """The factor ``s >= 0`` minimising the energy ``1/2 s^2 v.A v + s v.gap`` of the
    pressure ``s v`` as the fraction ``(numerator, denominator)`` (``gap``: the gap at zero
    pressure, height less penetration, mm)."""
    return max(float(v @ -gap), 0.0), float(v @ Av)


def cropped(problem: ContactProblem, below: float = 1.0) -> ContactProblem:
    """Penetration control: the same problem on the bounding box of the cells with
    ``z < d`` (no other cell can touch where ``A p >= 0``: not on a body whose surface
    rises, which :func:`twoscale.reference.solve_cg` then does not crop), which makes every FFT
    smaller, when that box has fewer than ``below`` times the grid's cells (1: whenever it
    cuts a cell). Load control has no such a-priori bound: unchanged."""
    if problem.mode != "penetration":
        return problem
    reach = np.isfinite(problem.surface.height) & (problem.surface.height < problem.penetration)
    rows, cols = np.flatnonzero(reach.any(axis=1)), np.flatnonzero(reach.any(axis=0))
    j0, j1, i0, i1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    if (j1 - j0) * (i1 - i0) >= below * problem.grid.size:
        return problem
    sub = problem.grid.subgrid(int(i0), int(j0), int(i1 - i0), int(j1 - j0))
    s = problem.surface
    surface = Surface(sub, s.height[j0:j1, i0:i1], s.owner[j0:j1, i0:i1], s.n_asperities)
    return ContactProblem(surface, problem.mode, problem.penetration, problem.total_load, problem.pivot)


def scaled_start(v: np.ndarray, Av: np.ndarray, gap: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The guess ``v`` and its product ``Av`` scaled by :func:`line_search`."""
    num, den = line_search(v, Av, gap)
    return v * num / den, Av * num / den
