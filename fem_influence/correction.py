"""The smooth correction of the block's compliance (finite block minus half-space).

For a unit normal point force at the top-face point ``s`` the block's displacement
is ``u_B + u_c``: Boussinesq's half-space field ``u_B``
(:mod:`fem_influence.boussinesq`) plus a correction ``u_c`` that solves
elasticity in the block with

* top face: traction-free (``u_B`` already carries the point force);
* side faces: traction ``-sigma_B n`` (cancels the half-space traction, sides free);
* base, ``"bonded"``: ``u_c = -u_B`` (total u = 0);
* base, ``"sliding"``: ``u_c,z = -u_B,z`` and tangential traction
  ``-(sigma_B n)_tangential`` (total: no normal motion, no shear).  The three
  in-plane rigid motions left free are pinned at base nodes; they do not change
  the vertical displacement the provider reports.

All data of ``u_c`` lie far (>= the thickness or the distance to the sides) from
the load, so ``u_c`` is smooth and a graded 5-12 mm Q2-Q1 mesh resolves it. The
system matrix depends on mesh, nu and base only; it is factorised once (sparse LU,
SuperLU with a minimum-degree ordering on ``A + A^T``) and every source point is
one more right-hand side. The field is computed for ``E = 1`` MPa and scales as ``1/E``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse.linalg as spla

from twoscale.material import Material

from .assembly import INTORDER, assemble_mixed
from .boussinesq import point_displacement, point_stress
from .layer import BASES


#: Largest relative residual accepted from the factorised solve.
RESIDUAL_TOL = 1e-8


@dataclass(frozen=True)
class BlockGeometry:
    """Boundary parts of a block mesh in the block frame ``(x, y, depth)``.

    Attributes
    ----------
    thickness : float
        Depth of the base below the top face, mm.
    top, base, sides : int arrays
        Boundary facet indices of each part.
    """

    thickness: float
    top: np.ndarray
    base: np.ndarray
    sides: np.ndarray


def block_geometry(mesh, *, tol: float = 1e-8) -> BlockGeometry:
    """Split the boundary of a block mesh into top (depth 0), base (max depth) and sides."""
    z = mesh.p[2]
    if abs(z.min()) > tol * max(1.0, np.ptp(z)):
        raise ValueError(f"block mesh top face must be at depth 0, smallest depth is {z.min()!r}")
    t = float(z.max())
    bf = mesh.boundary_facets()
    fz = mesh.p[2, mesh.facets[:, bf]]  # (4, nbf)
    top = bf[np.all(np.abs(fz) <= tol * t, axis=0)]
    base = bf[np.all(np.abs(fz - t) <= tol * t, axis=0)]
    sides = np.setdiff1d(bf, np.concatenate([top, base]))
    return BlockGeometry(thickness=t, top=top, base=base, sides=sides)


@dataclass
class CorrectionSolver:
    """Factorised correction problem for one mesh, Poisson ratio and base.

    Not a result: an explicit, reusable factorisation (lifetime = this object).
    Build with :meth:`build`; :meth:`top_displacement` returns the correction's
    vertical displacement on the top-face Q2 nodes for any set of sources.

    Attributes
    ----------
    nu : float
    base : str
    top_xy : (n_top, 2) array
        Top-face node positions, mm (block frame).
    timings_s : dict
        ``assembly``, ``factorisation`` seconds.
    """

    mesh: object
    nu: float
    base: str
    top_xy: np.ndarray
    timings_s: dict
    _lu: object = field(repr=False)
    _free: np.ndarray = field(repr=False)
    _fixed: np.ndarray = field(repr=False)
    _A_fd: object = field(repr=False)
    _n: int = field(repr=False)
    _ns: int = field(repr=False)
    _top_dofs: np.ndarray = field(repr=False)
    _fixed_base_dofs: np.ndarray = field(repr=False)
    _base_xyz: np.ndarray = field(repr=False)
    _loads: list = field(repr=False)
    _matrix: object = field(repr=False)
    residuals: list = field(default_factory=list)

    @classmethod
    def build(cls, mesh, nu: float, base: str = "bonded") -> "CorrectionSolver":
        """Assemble (E = 1 MPa) and factorise the correction problem.

        Parameters
        ----------
        mesh : skfem.MeshHex
            Block mesh in the block frame (top face at depth 0).
        nu : float
            Poisson's ratio, 0 < nu <= 0.5.
        base : {"bonded", "sliding"}, default "bonded"
        """
        from skfem import ElementHex2, FacetBasis

        if base not in BASES:
            raise ValueError(f"base must be one of {BASES}, got {base!r}")
        t0 = time.perf_counter()
        geo = block_geometry(mesh)
        system = assemble_mixed(mesh, Material(1.0, nu))
        ns, n = system.n_scalar, system.size
        from skfem import CellBasis

        ub = CellBasis(mesh, ElementHex2(), intorder=INTORDER)
        top_dofs = np.unique(ub.get_dofs(geo.top).all())
        base_dofs = np.unique(ub.get_dofs(geo.base).all())
        loads = [("sides", FacetBasis(mesh, ElementHex2(), facets=geo.sides, intorder=INTORDER))]
        if base == "bonded":
            fixed = np.concatenate([base_dofs + a * ns for a in range(3)])
        else:
            loads.append(("base", FacetBasis(mesh, ElementHex2(), facets=geo.base, intorder=INTORDER)))
            fixed = np.concatenate([base_dofs + 2 * ns, _rigid_pins(system.doflocs, base_dofs, ns)])
        fixed = np.unique(fixed)
        free = np.setdiff1d(np.arange(n), fixed)
        A = system.matrix
        t1 = time.perf_counter()
        A_ff = A[free][:, free].tocsc()
        lu = spla.splu(A_ff, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
        t2 = time.perf_counter()
        fixed_base = fixed[fixed < 3 * ns]
        return cls(
            mesh=mesh,
            nu=nu,
            base=base,
            top_xy=system.doflocs[:2, top_dofs].T.copy(),
            timings_s={"assembly": t1 - t0, "factorisation": t2 - t1},
            _lu=lu,
            _free=free,
            _fixed=fixed,
            _A_fd=A[free][:, fixed].tocsc(),
            _n=n,
            _ns=ns,
            _top_dofs=top_dofs,
            _fixed_base_dofs=fixed_base,
            _base_xyz=system.doflocs[:, fixed_base % ns].T.copy(),
            _loads=loads,
            _matrix=A_ff,
        )

    def _rhs(self, source: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mat = Material(1.0, self.nu)
        f = np.zeros(self._n)
        for part, fb in self._loads:
            X = np.asarray(fb.global_coordinates())  # (3, nf, nq)
            nrm = np.asarray(fb.normals)  # (3, nf, nq)
            sig = point_stress(np.moveaxis(X, 0, -1), mat, source=source)  # (nf, nq, 3, 3)
            trac = -np.einsum("fqab,bfq->afq", sig, nrm)
            if part == "base":
                trac[2] = 0.0  # only the shear is a load there
            phi = np.stack([np.asarray(fb.basis[i][0]) for i in range(fb.Nbfun)])  # (27, nf, nq)
            fe = np.einsum("ifq,afq,fq->aif", phi, trac, fb.dx)
            dofs = fb.element_dofs  # (27, nf)
            for a in range(3):
                f += np.bincount((dofs + a * self._ns).ravel(), fe[a].ravel(), minlength=self._n)
        ud = np.zeros(len(self._fixed))
        comp = self._fixed_base_dofs // self._ns
        uB = point_displacement(self._base_xyz, mat, source=source)
        vals = -uB[np.arange(len(comp)), comp]
        if self.base == "sliding":
            vals = np.where(comp == 2, vals, 0.0)  # rigid-motion pins stay at 0
        ud[: len(vals)] = vals
        return f, ud

    def top_displacement(self, sources: np.ndarray) -> np.ndarray:
        """Vertical correction displacement on the top-face nodes, mm per N (E = 1 MPa).

        Parameters
        ----------
        sources : (K, 2) array
            Force positions on the top face, block frame, mm.

        Returns
        -------
        (K, n_top) array, ordered like :attr:`top_xy`.
        """
        full = self._solve_full(np.asarray(sources, dtype=float).reshape(-1, 2))
        return full[2 * self._ns + self._top_dofs].T

    def vertex_displacement(self, sources: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
        """Correction displacement at the mesh vertices for a combination of sources, mm (E = 1 MPa).

        The problem is linear in the load, so the field of the forces ``coefficients[k]``
        (N) at ``sources[k]`` is one solve with the summed right-hand side.

        Parameters
        ----------
        sources : (K, 2) array
            Force positions on the top face, block frame, mm.
        coefficients : (K,) array
            Forces, N.

        Returns
        -------
        (n_vertices, 3) array ``(u_x, u_y, u_depth)`` at ``mesh.p`` (depth positive into the block).
        """
        sources = np.asarray(sources, dtype=float).reshape(-1, 2)
        c = np.asarray(coefficients, dtype=float).reshape(-1)
        if len(c) != len(sources):
            raise ValueError(f"coefficients has {len(c)} entries, sources {len(sources)}")
        full = self._solve_full(sources, c)[:, 0]
        nv = self.mesh.p.shape[1]
        # ElementHex2 numbers the vertex dofs first, in mesh.p order
        return np.column_stack([full[a * self._ns : a * self._ns + nv] for a in range(3)])

    def _solve_full(self, sources: np.ndarray, combine: np.ndarray | None = None) -> np.ndarray:
        """All displacement/pressure dofs, one column per source (or one column for ``combine``)."""
        F = np.empty((len(self._free), len(sources)))
        U = np.empty((len(self._fixed), len(sources)))
        for k, s in enumerate(sources):
            f, ud = self._rhs(s)
            F[:, k] = f[self._free]
            U[:, k] = ud
        if combine is not None:
            F, U = F @ combine[:, None], U @ combine[:, None]
        b = F - self._A_fd @ U
        x = self._lu.solve(b)
        bn = np.maximum(np.linalg.norm(b, axis=0), 1e-300)
        res = np.linalg.norm(self._matrix @ x - b, axis=0) / bn
        # the LU uses no diagonal pivoting (symmetric mode keeps the fill low); guard it
        # with iterative refinement and refuse to return an inaccurate field
        for _ in range(3):
            if res.max() <= RESIDUAL_TOL:
                break
            x += self._lu.solve(b - self._matrix @ x)
            res = np.linalg.norm(self._matrix @ x - b, axis=0) / bn
        self.residuals.extend(res.tolist())
        if res.max() > RESIDUAL_TOL:
            raise RuntimeError(
                f"correction solve inaccurate: relative residual {res.max():.2e} > "
                f"{RESIDUAL_TOL:.0e} after 3 refinement steps (mesh, nu={self.nu}, base={self.base})"
            )
        full = np.zeros((self._n, U.shape[1]))
        full[self._free] = x
        full[self._fixed] = U
        return full


def _rigid_pins(doflocs: np.ndarray, base_dofs: np.ndarray, ns: int) -> np.ndarray:
    # in-plane rigid motions of the sliding block: fix u_x at the two base nodes
    # nearest (0, -y) and (0, +y) ends of the centre line, u_y at the first
    xy = doflocs[:2, base_dofs].T
    c = base_dofs[np.argmin(np.hypot(xy[:, 0], xy[:, 1]))]
    far = base_dofs[np.argmax(np.abs(xy[:, 1]) - np.abs(xy[:, 0]))]
    return np.array([c, far, c + ns])
