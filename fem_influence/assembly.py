"""Mixed displacement-pressure (Taylor-Hood Q2-Q1) elasticity on hexahedra.

Unknowns: displacement ``u`` (Q2, three components, component-blocked: dof
``a * n_scalar + i``) and pressure-like ``p = lambda div u`` (Q1, continuous). With
``sigma = 2 mu eps(u) + p I`` the weak form is

    int 2 mu eps(u):eps(v) + int p div v = f(v)
    int q div u - int p q / lambda       = 0,

symmetric indefinite and valid at ``nu = 0.5`` (``1/lambda = 0``) without locking.
scikit-fem supplies the meshes, elements and basis data (gradients at quadrature
points); the element matrices are formed here with vectorised ``einsum`` over all
elements at once, which is an order of magnitude faster than the generic form
assembly for Q2 hexahedra.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from twoscale.material import Material

#: Gauss order: exact for the Q2 x Q2 stiffness on affine (box) elements.
INTORDER = 4


@dataclass(frozen=True)
class MixedSystem:
    """Assembled mixed system ``[[A, B^T], [B, -M/lambda]]`` (CSC).

    Attributes
    ----------
    matrix : scipy.sparse.csc_matrix
        Square, size ``3 * n_scalar + n_pressure``.
    n_scalar : int
        Number of scalar Q2 nodes (displacement dofs per component).
    n_pressure : int
        Number of Q1 pressure dofs.
    doflocs : (3, n_scalar) array
        Coordinates of the Q2 nodes, mm.
    """

    matrix: sp.csc_matrix
    n_scalar: int
    n_pressure: int
    doflocs: np.ndarray

    @property
    def size(self) -> int:
        return 3 * self.n_scalar + self.n_pressure


def bases(mesh):
    """Q2 displacement (scalar) and Q1 pressure ``CellBasis`` on the same quadrature."""
    from skfem import CellBasis, ElementHex1, ElementHex2

    ub = CellBasis(mesh, ElementHex2(), intorder=INTORDER)
    pb = CellBasis(mesh, ElementHex1(), intorder=INTORDER)
    return ub, pb


def assemble_mixed(mesh, material: Material) -> MixedSystem:
    """Assemble the Taylor-Hood system for ``material`` on ``mesh``.

    Parameters
    ----------
    mesh : skfem.MeshHex
        Hexahedral mesh, mm.
    material : Material
        E (MPa) and nu (up to 0.5 inclusive).

    Returns
    -------
    MixedSystem
    """
    ub, pb = bases(mesh)
    E, nu = material.E, material.nu
    mu = E / (2.0 * (1.0 + nu))
    inv_lam = 0.0 if nu == 0.5 else (1.0 + nu) * (1.0 - 2.0 * nu) / (E * nu) if nu != 0 else None
    G = np.stack([ub.basis[i][0].grad for i in range(ub.Nbfun)])  # (27, 3, ne, nq)
    psi = np.stack([np.asarray(pb.basis[k][0]) for k in range(pb.Nbfun)])  # (8, ne, nq)
    dx = ub.dx  # (ne, nq)
    # batched matmul over elements: rows (a, i), columns (b, j), contraction over q
    Gr = np.ascontiguousarray(np.transpose(G, (2, 1, 0, 3))).reshape(G.shape[2], 3 * G.shape[0], -1)
    M = np.matmul(Gr * dx[:, None, :], np.transpose(Gr, (0, 2, 1)))
    M = M.reshape(G.shape[2], 3, G.shape[0], 3, G.shape[0]).transpose(0, 1, 3, 2, 4)  # (ne, 3, 3, 27, 27)
    S = np.einsum("eaaij->eij", M)
    ne, nb, npb = mesh.nelements, ub.Nbfun, pb.Nbfun
    # K[(a,i),(c,j)] = mu (delta_ac S_ij + d_a phi_j d_c phi_i) = mu (delta_ac S + M[c,a])_ij
    Ke = mu * (np.eye(3)[None, :, :, None, None] * S[:, None, None] + np.transpose(M, (0, 2, 1, 3, 4)))
    Be = np.einsum("keq,iaeq->eaik", psi * dx[None], G, optimize=True)  # (ne, 3, 27, 8)
    ns = ub.N
    udofs = ub.element_dofs.T  # (ne, 27)
    pdofs = pb.element_dofs.T + 3 * ns  # (ne, 8)
    gu = (np.arange(3)[None, :, None] * ns + udofs[:, None, :]).reshape(ne, 3 * nb)
    rows = [np.repeat(gu, 3 * nb, axis=1).ravel()]
    cols = [np.tile(gu, (1, 3 * nb)).ravel()]
    vals = [Ke.transpose(0, 1, 3, 2, 4).reshape(ne, -1).ravel()]
    Bf = Be.reshape(ne, 3 * nb, npb)
    r_b = np.repeat(gu, npb, axis=1).ravel()
    c_b = np.tile(pdofs, (1, 3 * nb)).ravel()
    rows += [r_b, c_b]
    cols += [c_b, r_b]
    vals += [Bf.ravel(), Bf.ravel()]
    if inv_lam is None:
        raise ValueError("nu = 0 is not supported by the mixed form (lambda = 0); use nu > 0")
    if inv_lam > 0:
        Mp = np.einsum("keq,leq->ekl", psi * dx[None], psi, optimize=True)
        rows.append(np.repeat(pdofs, npb, axis=1).ravel())
        cols.append(np.tile(pdofs, (1, npb)).ravel())
        vals.append(-inv_lam * Mp.ravel())
    n = 3 * ns + pb.N
    A = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsc()
    A.sum_duplicates()
    return MixedSystem(matrix=A, n_scalar=ns, n_pressure=pb.N, doflocs=ub.doflocs)
