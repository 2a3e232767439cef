"""Load and moment equations in the micro step (load control, ball-and-socket tilt).

With the contact sets fixed the pressure is affine in the unknowns ``theta = (d, alpha,
beta)``: ``b = d - z - beta (x - px) - alpha (y - py)``. The sensitivities
``s_j = A_SS^{-1} db/dtheta_j`` (one linear block Gauss-Seidel solve with ``m`` right-hand
sides) give the exact Jacobian ``K_ij = h^2 sum G_i s_j`` of the resultants
``G = (1, y - py, x - px)`` (total load, moment about x, moment about y), so one Newton step
``p + s dtheta`` meets the equations to round-off whenever the contact sets hold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .patches import Patch


@dataclass(frozen=True)
class Control:
    """What the rigid-body unknowns of an iteration must meet.

    Attributes
    ----------
    pivot : (px, py), mm
        Tilt pivot (moments are taken about it).
    n_unknowns : 0, 1 or 3
        Unknowns corrected: none (penetration control), the approach (load), the approach
        and the tilt (load and zero moments).
    target : (n_unknowns,) array or None
        Total load (N) and moments (0) to meet.
    """

    pivot: tuple = (0.0, 0.0)
    n_unknowns: int = 0
    target: np.ndarray | None = None


def block_coordinates(patch: Patch, pivot: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """``(x - px, y - py)`` on the block's cells, mm."""
    X, Y = patch.grid.centres()
    return X[patch.owned] - pivot[0], Y[patch.owned] - pivot[1]


def rhs_derivatives(patch: Patch, pivot: tuple[float, float], n_unknowns: int) -> np.ndarray:
    """``d b / d theta`` on the block's cells, shape (n, n_unknowns): columns d, alpha, beta."""
    xr, yr = block_coordinates(patch, pivot)
    cols = [np.ones_like(xr), -yr, -xr]
    return np.column_stack(cols[:n_unknowns])


def patch_forces(patches, pressures) -> np.ndarray:
    """Resultant force of each block's pressure (N), shape (len(patches),)."""
    return np.array([pt.grid.h**2 * float(np.sum(p)) for pt, p in zip(patches, pressures)])


def member_forces(patches, pressures) -> tuple[np.ndarray, np.ndarray]:
    """Resultant force (N) of each asperity that owns cells of a block: ``(asperities, forces)``
    (a merged patch contributes one force per member)."""
    index, forces = [], []
    for pt, p in zip(patches, pressures):
        owner = pt.owner[pt.owned]
        for m in pt.members:
            index.append(m)
            forces.append(pt.grid.h**2 * float(np.sum(p[owner == m])))
    return np.array(index, dtype=int), np.array(forces, dtype=float)


def resultants(patches, pressures, pivot: tuple[float, float], n_unknowns: int) -> np.ndarray:
    """``h^2 sum G p`` over all blocks: total load (N), then moments about x and y (N mm).

    ``pressures[k]`` is (n_k,) or (n_k, m); returns (n_unknowns,) or (n_unknowns, m).
    """
    out = 0.0
    for patch, p in zip(patches, pressures):
        xr, yr = block_coordinates(patch, pivot)
        G = np.column_stack([np.ones_like(xr), yr, xr])[:, :n_unknowns]
        out = out + patch.grid.h**2 * (G.T @ p)
    return np.asarray(out)


def newton_step(K: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """``dtheta = K^{-1} residual``; raises ValueError if ``K`` is singular (no contact)."""
    if not np.all(np.isfinite(K)) or abs(np.linalg.det(np.atleast_2d(K))) == 0.0:
        raise ValueError("load/moment Jacobian is singular: too few cells in contact to carry the load")
    return np.linalg.solve(np.atleast_2d(K), np.atleast_1d(residual))
