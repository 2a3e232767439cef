"""Displacement field inside the block for a set of surface point forces.

``u = u_B + u_C``: the half-space part ``u_B`` is Boussinesq's interior point-force field
(:func:`fem_influence.boussinesq.point_displacement`) summed over the forces, the
correction ``u_C`` is the FEM correction field for the same loading: the forces are
spread onto the provider's source lattice with the provider's own cubic interpolation
weights and the correction problem is solved once for that combined load.

Approximation (half-space part). The contact pressure is replaced by point forces:
each loaded micro cell carries ``h^2 p`` (N), and cells are first merged into square
aggregates of side ``aggregate`` (mm) acting at their centre of force. At a distance
``r`` from an aggregate the error is of relative order ``(aggregate / r)^2``, so the
field is accurate away from the loaded surface and poor at nodes within a few
aggregate sizes (and a few micro cells) of the contact, where the true field is that of
a distributed pressure, not of point forces. A node closer than ``aggregate / 2`` to a
force horizontally and shallower than ``aggregate / 2`` is evaluated at depth
``aggregate / 2`` under that force (finite instead of singular). The correction part is
smooth and carries no such error beyond the lattice interpolation (docs/records/fem_status.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twoscale.material import Material

from .boussinesq import point_displacement


@dataclass(frozen=True)
class BlockField:
    """Displacement at the block mesh vertices.

    Attributes
    ----------
    points : (n, 3) array
        Vertices ``(x, y, depth)``, mm: x, y in the scene frame, depth >= 0 into the block.
    displacement : (n, 3) array
        ``(u_x, u_y, u_depth)``, mm (u_depth > 0 into the block).
    halfspace : (n, 3) array
        The Boussinesq part of ``displacement``, mm.
    cells : (n_cells, 8) int array
        Hexahedra as vertex indices, scikit-fem order (``mesh.t.T``).
    n_forces : int
        Point forces after aggregation.
    total_force : float
        Sum of the forces, N.
    aggregate : float
        Aggregate side, mm (0: no aggregation).
    """

    points: np.ndarray
    displacement: np.ndarray
    halfspace: np.ndarray
    cells: np.ndarray
    n_forces: int
    total_force: float
    aggregate: float


def aggregate_forces(points, forces, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge point forces into square bins of side ``size`` (mm) at their centre of force.

    Zero forces are dropped; ``size = 0`` only drops them. Returns positions (M, 2), mm,
    and forces (M,), N.
    """
    P = np.asarray(points, dtype=float).reshape(-1, 2)
    f = np.asarray(forces, dtype=float).reshape(-1)
    if len(f) != len(P):
        raise ValueError(f"forces has {len(f)} entries, points {len(P)}")
    if not (np.isfinite(size) and size >= 0):
        raise ValueError(f"aggregate must be a finite length >= 0 (mm), got {size!r}")
    keep = f != 0
    P, f = P[keep], f[keep]
    if size == 0 or len(f) == 0:
        return P, f
    keys = np.floor(P / size).astype(np.int64)
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    F = np.bincount(inv, weights=f)
    X = np.bincount(inv, weights=f * P[:, 0]) / F
    Y = np.bincount(inv, weights=f * P[:, 1]) / F
    return np.column_stack([X, Y]), F


def halfspace_field(
    nodes: np.ndarray, sources: np.ndarray, forces: np.ndarray, material: Material, *, lift: float
) -> np.ndarray:
    """Sum of Boussinesq point-force fields at ``nodes`` (n, 3: x, y, depth), mm.

    A node within ``lift / 2`` of a force horizontally and shallower than ``lift / 2``
    is evaluated at depth ``lift / 2`` for that force (``lift`` > 0, mm).
    """
    u = np.zeros((len(nodes), 3))
    half = 0.5 * lift
    for s, P in zip(sources, forces):
        pts = nodes
        near = (np.hypot(nodes[:, 0] - s[0], nodes[:, 1] - s[1]) < half) & (nodes[:, 2] < half)
        if near.any():
            pts = nodes.copy()
            pts[near, 2] = half
        u += point_displacement(pts, material, source=s, P=P)
    return u
