"""Direct FEM mode: the block loaded by uniform pressure on one square cell, no correction.

Used to validate the correction (``Love + h^2 C``) and the method itself: with
``boundary="halfspace"`` the sides and base carry the half-space displacement of
the same cell load (Boussinesq integrated over the cell), so the top-face answer
must reproduce Love's closed form; with ``"bonded"`` / ``"sliding"`` it is the
block itself. The cell sits at the centre of the top face, so a quarter of the
block is meshed (symmetry planes x = 0 and y = 0), graded from ``h_cell / per_cell``
elements under the cell (``per_cell`` per side) to ``h_coarse``, with Taylor-Hood Q2-Q1
elements.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as spla

from twoscale.material import Material

from .assembly import INTORDER, assemble_mixed
from .boussinesq import point_displacement
from .interpolate import TopInterpolator

BOUNDARIES = ("halfspace", "bonded", "sliding")


@dataclass(frozen=True)
class DirectResult:
    """Top-face vertical displacement of the direct cell-load solve.

    Attributes
    ----------
    r : (M,) array
        Distances from the cell centre along the x axis, mm.
    u : (M,) array
        Vertical displacement per unit pressure on the cell, mm/MPa.
    n_elements, n_unknowns : int
    residual : float
        Relative residual of the linear solve.
    converged : bool
        ``residual < 1e-8``.
    timings_s : dict
    """

    r: np.ndarray
    u: np.ndarray
    n_elements: int
    n_unknowns: int
    residual: float
    converged: bool
    timings_s: dict


def _axis(
    end: float, h_cell: float, h_coarse: float, growth: float, fine: float = 1.5, per_cell: int = 4
) -> np.ndarray:
    # 0 .. fine * h_cell at h_cell/per_cell (the pressure edge at h_cell/2 is a node), then
    # geometric growth to h_coarse up to ``end``
    x = list(np.arange(0.0, fine * h_cell + 1e-9, h_cell / per_cell))
    h = h_cell / per_cell
    while x[-1] < end - 1e-9:
        h = min(h * growth, h_coarse)
        x.append(end if end - x[-1] < 1.5 * h else x[-1] + h)
    return np.array(x)


def _depth_axis(
    t: float, h_cell: float, h_coarse: float, growth: float, fine: float = 1.0, per_cell: int = 4
) -> np.ndarray:
    z = list(np.arange(0.0, min(fine * h_cell, t) + 1e-9, h_cell / per_cell))
    h = h_cell / per_cell
    while z[-1] < t - 1e-9:
        z.append(t if t - z[-1] < 1.5 * h else z[-1] + h)
        h = min(h * growth, h_coarse)
    return np.array(z)


def _cell_halfspace_displacement(points: np.ndarray, material: Material, h_cell: float, n: int = 8) -> np.ndarray:
    # half-space field of unit pressure on the cell |x|,|y| <= h/2: Gauss quadrature of
    # Boussinesq's point field; the boundary points are >= 2 h away, where n = 8 is exact to ~1e-12
    g, w = np.polynomial.legendre.leggauss(n)
    g, w = 0.5 * h_cell * g, 0.5 * h_cell * w
    u = np.zeros(points.shape[:-1] + (3,))
    for gi, wi in zip(g, w):
        for gj, wj in zip(g, w):
            u += wi * wj * point_displacement(points, material, source=(gi, gj))
    return u


def _fixed_dofs(X: np.ndarray, ns: int, boundary: str, material: Material, size, h_cell: float, tol: float):
    """The quarter block's prescribed unknowns and their values: zero normal displacement on
    the two symmetry planes, then the base and sides by ``boundary`` (the half-space's own
    displacement under the cell on base and sides, a bonded base, or a base sliding on its
    plane); where two conditions meet on an edge the symmetry zero wins."""
    Lx, Ly, t = size
    on = lambda cond: np.flatnonzero(cond)
    fixed_list = [on(np.abs(X[0]) < tol) + 0 * ns, on(np.abs(X[1]) < tol) + 1 * ns]  # symmetry planes
    values = [np.zeros(len(fixed_list[0])), np.zeros(len(fixed_list[1]))]
    base = on(np.abs(X[2] - t) < tol)
    sides = on((np.abs(X[0] - Lx / 2) < tol) | (np.abs(X[1] - Ly / 2) < tol))
    if boundary == "halfspace":
        outer = np.unique(np.concatenate([base, sides]))
        uh = _cell_halfspace_displacement(X[:, outer].T, material, h_cell)
        for a in range(3):
            fixed_list.append(outer + a * ns)
            values.append(uh[:, a])
    elif boundary == "bonded":
        for a in range(3):
            fixed_list.append(base + a * ns)
            values.append(np.zeros(len(base)))
    else:
        fixed_list.append(base + 2 * ns)
        values.append(np.zeros(len(base)))
    dofs, first = np.unique(np.concatenate(fixed_list), return_index=True)
    return dofs, np.concatenate(values)[first]


def _cell_load(mesh, ns: int, n: int, h_cell: float, tol: float) -> np.ndarray:
    """The load vector of unit pressure (+1 MPa along depth) on the loaded quarter cell."""
    from skfem import ElementHex2, FacetBasis

    loaded = mesh.facets_satisfying(
        lambda x: (np.abs(x[2]) < tol) & (x[0] < h_cell / 2) & (x[1] < h_cell / 2), boundaries_only=True
    )
    fb = FacetBasis(mesh, ElementHex2(), facets=loaded, intorder=INTORDER)
    phi = np.stack([np.asarray(fb.basis[i][0]) for i in range(fb.Nbfun)])
    fz = np.einsum("ifq,fq->if", phi, fb.dx)
    return np.bincount((fb.element_dofs + 2 * ns).ravel(), fz.ravel(), minlength=n).astype(float)


def solve_cell_load(
    material: Material,
    *,
    size=(140.0, 140.0, 20.0),
    h_cell: float = 2.0,
    boundary: str = "bonded",
    r=None,
    h_coarse: float = 10.0,
    growth: float = 1.5,
    per_cell: int = 6,
) -> DirectResult:
    """Solve the block under unit pressure on the central cell of side ``h_cell``.

    Parameters
    ----------
    material : Material
        E (MPa), 0 < nu <= 0.5.
    size : (3,) floats, default (140, 140, 20)
        Block dimensions, mm.
    h_cell : float, default 2
        Side of the loaded square cell, mm.
    boundary : {"halfspace", "bonded", "sliding"}, default "bonded"
        Sides and base: half-space displacement imposed, or the block's own
        conditions (free sides; base bonded or sliding).
    r : array_like, optional
        Distances along x where the displacement is reported, mm; default 0-40 mm.
    h_coarse : float, default 10
        Largest element size, mm.
    growth : float, default 1.5
        Ratio of neighbouring element sizes.
    per_cell : int, default 6
        Elements along the loaded cell's side (even, so the cell edge is a node). With
        half-space data, Love is reproduced within 0.32 % at r = 0-40 mm at 6 (the 140 mm
        block: 116k unknowns, ~9 min, 5.5 GB), within 1.4 % at 4 (65k unknowns).

    Returns
    -------
    DirectResult
    """
    from skfem import MeshHex

    if boundary not in BOUNDARIES:
        raise ValueError(f"boundary must be one of {BOUNDARIES}, got {boundary!r}")
    Lx, Ly, t = (float(v) for v in size)
    t0 = time.perf_counter()
    if per_cell < 2 or per_cell % 2:
        raise ValueError(f"per_cell must be an even integer >= 2, got {per_cell!r}")
    mesh = MeshHex.init_tensor(
        _axis(Lx / 2, h_cell, h_coarse, growth, per_cell=per_cell),
        _axis(Ly / 2, h_cell, h_coarse, growth, per_cell=per_cell),
        _depth_axis(t, h_cell, h_coarse, growth, per_cell=per_cell),
    )
    system = assemble_mixed(mesh, material)
    ns, n = system.n_scalar, system.size
    X = system.doflocs
    tol = 1e-9 * max(Lx, Ly, t)
    dofs, vals = _fixed_dofs(X, ns, boundary, material, (Lx, Ly, t), h_cell, tol)
    f = _cell_load(mesh, ns, n, h_cell, tol)
    free = np.setdiff1d(np.arange(n), dofs)
    A = system.matrix
    t1 = time.perf_counter()
    A_ff = A[free][:, free].tocsc()
    b = f[free] - A[free][:, dofs] @ vals
    lu = spla.splu(A_ff, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    x = lu.solve(b)
    res = float(np.linalg.norm(A_ff @ x - b) / np.linalg.norm(b))
    t2 = time.perf_counter()
    u = np.zeros(n)
    u[free], u[dofs] = x, vals
    top = np.flatnonzero(np.abs(X[2]) < tol)
    r = np.linspace(0.0, 40.0, 9) if r is None else np.asarray(r, dtype=float)
    interp = TopInterpolator(X[:2, top].T)
    uz = interp(np.column_stack([r, np.zeros_like(r)]), u[2 * ns + top][:, None])[:, 0]
    return DirectResult(
        r=r,
        u=uz,
        n_elements=mesh.nelements,
        n_unknowns=len(free),
        residual=res,
        converged=res < 1e-8,
        timings_s={"assembly": t1 - t0, "solve": t2 - t1},
    )
