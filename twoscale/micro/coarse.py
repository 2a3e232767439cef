"""Coarse correction of block Gauss-Seidel: the macro equations solved on the sweep's error.

Block Gauss-Seidel removes the error inside each patch in a sweep or two, but the error
shared by many patches (the bulk deflection of thousands of asperities, which can exceed
their local approaches) decays by a factor that tends to one as the scene grows, and with
a lagged far field (:class:`~.farfield.LaggedFarField`) it need not decay at all. The
coarse step removes it at the tip level, like a two-grid method whose coarse space is one
function per patch:

* ``s_k = A_SS^{-1} 1``: pressure on patch ``k``'s contact cells per mm of rigid
  approach of that patch alone; ``kappa_k = h^2 sum s_k`` (N/mm) its contact stiffness;
* the sweep leaves patch ``k`` with an approach error ``rho_k``: the displacement that the
  resultant changes ``dF_l`` of the sweep caused at tip ``k`` and that block ``k`` did not
  see when it was solved (later near blocks and every far block),
  ``rho_k = -sum_{l not seen} T_kl dF_l`` (``T`` the point compliance);
* forces ``dP_k = kappa_k c_k`` (patch ``k`` shifted by ``c_k`` mm) and corrections
  ``dtheta`` of (d, alpha, beta) under load control solve the linearised macro equations
  (docs/method.md section 2, paper eqs. 4-5, 11-12)::

      dP_k / kappa_k + sum_l T_kl dP_l - G_k dtheta = rho_k      (patches in contact)
      sum_k E_k dP_k = e - sum_k E_k F_k                         (load, moments)

  with ``G_k = (1, -Y_k, -X_k)``, ``E_k = (1, Y_k, X_k)``, ``(X_k, Y_k)`` the centroid of
  ``s_k`` about the pivot. The load and moment rows hold exactly after the step (up to
  pressures clipped at zero): ``h^2 sum`` of the added pressure is exactly ``dP``.

At the solution of the micro problem ``dF = 0``, so ``rho = 0`` and the step is zero: it
changes the speed of the iteration, not its answer.

``T`` between two patches whose tips are closer than their contacts' size (merged or nearly
merged contacts) is not the point compliance ``1 / (pi E* r)``: that grows without bound as
the tips meet, past the patches' own ``1 / kappa``, and the system above becomes indefinite
(two tips at ``r < 2a / pi`` already make it so), so the step throws force between the two
patches and the sweeps undo it (859 light clustered spheres: the change went 0.16, 0.67,
0.70 over the first sweeps). Near pairs take instead the compliance of two smeared loads,
``T_kl r / sqrt(r^2 + sigma_k^2 + sigma_l^2)`` with ``sigma_k = kappa_k / (sqrt 2 pi E*)``
(the self term of that kernel is ``1 / kappa_k``, the diagonal), which is the point
compliance where the pair is far compared with its contacts and stays below the diagonal
where the tips meet. The system is solved densely up to ``dense_max`` patches in contact,
and by conjugate gradients with the provider's ``point_operator`` beyond.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..influence.base import InfluenceProvider
from ..krylov import block_cg
from ..mixed_precision import refined_solve
from .constraints import Control, block_coordinates
from .coarse_shapes import SHAPE_REUSE, SHAPE_RTOL, block_shapes, shape, solve_shapes, stale  # noqa: F401
from .segments import laid_end_to_end, segment_sums, starts_of


#: The tips' point operator (approach errors, conjugate-gradient products) is asked for this
#: fraction of the conjugate gradients' ``rtol``: the step only accelerates the sweeps.
OPERATOR_RTOL_FACTOR = 0.1


@dataclass(frozen=True)
class CoarseStep:
    """Outcome of one coarse correction: ``pressures`` per block (MPa, clipped at zero),
    ``theta`` (approach d mm, alpha, beta radians), ``forces`` the change ``dP`` given to
    each patch (N), ``iterations`` of the conjugate gradients (0 for a dense solve),
    ``converged`` False when they did not reach their tolerance (the step is still applied:
    it only accelerates)."""

    pressures: list
    theta: np.ndarray
    forces: np.ndarray
    iterations: int
    converged: bool


class CoarseSpace:
    """Tip-level interaction of the patches and the coarse step; see the module docstring.

    Parameters
    ----------
    provider : InfluenceProvider
    tips : (N, 2) array, mm
        The tip of each patch's asperity, in patch order.
    lower : sparse (N, N)
        Pattern of the pairs ``(k, l)`` whose coupling block ``k`` saw exactly and up to
        date during the sweep (near pairs with ``l`` before ``k``).
    dense_max : int, default 2000
        Largest number of patches in contact solved with a dense matrix.
    rtol : float, default 1e-3
        Relative residual of the conjugate gradients (the step only accelerates).
    max_iter : int, default 200
        Conjugate-gradient iterations allowed.
    """

    def __init__(
        self,
        provider: InfluenceProvider,
        tips: np.ndarray,
        lower,
        *,
        dense_max: int = 2000,
        rtol: float = 1e-3,
        max_iter: int = 200,
    ):
        self.provider = provider
        self.tips = np.asarray(tips, dtype=float)
        self.dense_max, self.rtol, self.max_iter = int(dense_max), float(rtol), int(max_iter)
        lower = sp.csr_matrix(lower)
        self._E_star = float(provider.material.E_star)
        self._op = None
        self._compliance = self._smooth = None
        self._frames: dict = {}
        self._flat = None  # the frames laid end to end (:meth:`_flat_frames`)
        # the pairs' values from the tips' compliance on a translation-invariant body, or the
        # pairs alone (the finite block's), not a point_compliance call a row (5,930 tips: 16 s)
        T = self.compliance() if getattr(provider, "translation_invariant", False) else None
        rows = np.repeat(np.arange(lower.shape[0]), np.diff(lower.indptr))
        pairs = getattr(provider, "pair_compliance", None)
        if T is not None or pairs is not None:
            vals = T[rows, lower.indices] if T is not None else pairs(self.tips, rows, lower.indices)
        else:
            vals = np.zeros(lower.nnz)
            for i in range(lower.shape[0]):
                a, b = lower.indptr[i], lower.indptr[i + 1]
                if b > a:
                    vals[a:b] = provider.point_compliance(self.tips[i : i + 1], self.tips[lower.indices[a:b]])[0]
        self.lower = sp.csr_matrix((vals, lower.indices, lower.indptr), shape=lower.shape)
        coo = self.lower.tocoo()
        self._pairs = (coo.row, coo.col, coo.data)
        self._dist = np.hypot(*(self.tips[coo.row] - self.tips[coo.col]).T)

    def _shape(self, blk, active: np.ndarray) -> np.ndarray:
        """:func:`.coarse_shapes.shape` of block ``blk``."""
        return shape(self.provider, blk, active)

    def _solve_shapes(self, stacks, blocks, todo: list, active: list) -> None:
        """:func:`.coarse_shapes.solve_shapes` of the FFT blocks ``todo``."""
        solve_shapes(self.provider, stacks, blocks, todo, active)

    def smooth_self(self) -> np.ndarray:
        """Each tip's smooth compliance on itself ``c_k`` (mm/N), made once. ``A_SS = B_SS +
        C_SS``, ``C`` nearly ``c_k`` on a patch: ``A_SS^{-1} 1`` is ``B_SS^{-1} 1`` scaled, ``1 /
        kappa_k = 1 / kappa_k(B) + c_k``, and the step uses ``s_k / kappa_k`` only."""
        self._smooth = self._smooth if self._smooth is not None else self.provider.smooth_self_compliance(self.tips)
        return self._smooth

    def _operator(self):
        if self._op is None:
            # a tenth of the step's own tolerance, not the provider's default 1e-6: on 7,567
            # tips the coarse steps took 1.13 s instead of 1.83 (forces within 1.4e-12)
            rtol = OPERATOR_RTOL_FACTOR * self.rtol
            self._op = self.provider.point_operator(self.tips, self.tips, rtol=rtol)
        return self._op

    def compliance(self) -> np.ndarray | None:
        """The tips' point compliance (N, N) mm/N, made once for the coarse space's steps
        where ``N <= dense_max`` (else None: the steps use the point operator); coincident
        tips, the diagonal included, contribute nothing (0), as in the point operator. Made again at
        every step, with the point operator built for the approach errors, it was half of
        the coarse step on 1,485 clustered spheres (0.35 of 0.86 s of CPU in 4 steps)."""
        if self._compliance is None and len(self.tips) <= self.dense_max:
            T = np.array(self.provider.point_compliance(self.tips, self.tips), dtype=float)
            T[~np.isfinite(T)] = 0.0
            self._compliance = T
        return self._compliance

    def near_correction(self, kappa: np.ndarray) -> sp.csr_matrix:
        """The smeared compliance minus the point compliance on the near pairs ``(k, l)``,
        ``l < k`` (sparse lower triangle, mm/N), for patch stiffnesses ``kappa`` (N/mm, 0 for
        patches out of contact); see the module docstring."""
        rows, cols, t = self._pairs
        n = len(self.tips)
        sigma2 = (np.asarray(kappa, dtype=float) / (math.sqrt(2.0) * math.pi * self._E_star)) ** 2
        r = self._dist
        smear2 = sigma2[rows] + sigma2[cols]
        with np.errstate(invalid="ignore", divide="ignore"):
            smeared = np.where(
                r > 0.0, t * r / np.sqrt(r * r + smear2), 1.0 / (math.pi * self._E_star * np.sqrt(smear2))
            )
        return sp.csr_matrix((np.nan_to_num(smeared - t), (rows, cols)), shape=(n, n))

    def approach_errors(self, dF: np.ndarray, near=None) -> np.ndarray:
        """``rho`` (mm): approach error of each patch after a sweep that changed the
        resultants by ``dF`` (N); ``near``: :meth:`near_correction` (the pairs not seen
        during the sweep, ``l > k``, then act through the smeared compliance)."""
        T = self.compliance()
        far = self._operator().apply(dF) if T is None else T @ dF
        rho = -(far - self.lower @ dF)
        if near is not None:
            rho -= near.T @ dF
        return rho

    def correct(
        self,
        blocks,
        patches,
        pressures: list,
        active: list,
        dF: np.ndarray,
        theta: np.ndarray,
        control: Control,
        stacks=None,
    ) -> CoarseStep:
        """One coarse step after a sweep; see the module docstring.

        Parameters
        ----------
        blocks, patches : the local blocks and their patches.
        pressures, active : per block, after the sweep.
        dF : (N,) array, N
            Change of each block's resultant during the sweep.
        theta : (3,) array
            (d, alpha, beta) used by the sweep.
        control : Control
            Pivot (mm), rigid-body unknowns corrected (0 penetration control, 1 load, 3 load
            and tilt) and their target: total load (N) and moments (0).
        stacks : BlockStacks, optional
            The FFT blocks' ``s_k`` solved together on its canvases (:meth:`_solve_shapes`).
        """
        pivot, n_unknowns, target = control.pivot, control.n_unknowns, control.target
        n = len(patches)
        if stacks is not None:
            todo = [k for k, blk in enumerate(blocks) if stale(blk, active[k])]
            if todo:
                self._solve_shapes(stacks, blocks, todo, active)
        # FFT blocks' s_k on a base kernel (the finite block's): the tip's own correction added
        smooth = None if stacks is None or stacks.whole_kernel else self.smooth_self()
        h2 = patches[0].grid.h ** 2 if n else 1.0
        # the blocks' sums over their cells laid end to end (:mod:`.segments`)
        starts = starts_of(active)
        shapes = block_shapes(self.provider, blocks, active, starts)
        flat = laid_end_to_end([np.zeros(blk.n) if v is None else v for blk, v in zip(blocks, shapes)])
        kappa = h2 * segment_sums(flat, starts)
        if smooth is not None:
            with np.errstate(divide="ignore"):
                soft = np.array([not blk.dense for blk in blocks], bool) & (kappa > 0.0) & (1.0 / kappa + smooth > 0.0)
                kappa[soft] = 1.0 / (1.0 / kappa[soft] + smooth[soft])
        kappa = np.where(kappa > 0.0, kappa, 0.0)
        A = np.flatnonzero(kappa > 0.0)
        xr, yr = self._flat_frames(patches, blocks, pivot)
        cent = np.zeros((n, 2))
        cent[A, 0] = h2 * segment_sums(xr * flat, starts)[A] / kappa[A]
        cent[A, 1] = h2 * segment_sums(yr * flat, starts)[A] / kappa[A]
        theta = np.array(theta, dtype=float)
        if A.size == 0:
            return CoarseStep(list(pressures), theta, np.zeros(n), 0, True)
        near = self.near_correction(kappa)
        rho = self.approach_errors(dF, near)[A]
        m = n_unknowns
        X, Y = cent[A, 0], cent[A, 1]
        G = np.column_stack([np.ones(A.size), -Y, -X])[:, :m]
        E = np.vstack([np.ones(A.size), Y, X])[:m]
        rhs = np.column_stack([rho, G])
        near = (near + near.T).tocsr()[A][:, A]
        sol, iters, ok = self._solve(A, 1.0 / kappa[A], rhs, near)
        dtheta = np.zeros(3)
        dP_A = sol[:, 0]
        if m:
            now = np.atleast_1d(self._resultants(patches, pressures, pivot, m))
            S = E @ sol[:, 1:]
            q = np.asarray(target, float) - now - E @ sol[:, 0]
            # singular when the active patches cannot carry a moment (one patch at the
            # pivot): the least-squares step leaves the tilt where it is
            dtheta[:m] = np.linalg.lstsq(S, q, rcond=1e-12)[0]
            dP_A = sol[:, 0] + sol[:, 1:] @ dtheta[:m]
        dP = np.zeros(n)
        dP[A] = dP_A
        scale = np.zeros(n)
        scale[A] = dP_A / kappa[A]
        moved = np.maximum(laid_end_to_end(pressures) + np.repeat(scale, np.diff(starts)) * flat, 0.0)
        out = list(pressures)  # the others' the very objects (unchanged)
        for k in A.tolist():
            out[k] = moved[starts[k] : starts[k + 1]]
        return CoarseStep(out, theta + dtheta, dP, iters, ok)

    def _flat_frames(self, patches, blocks, pivot) -> tuple:
        """The blocks' :meth:`_frame` coordinates ``(xr, yr)`` laid end to end, kept while the
        patches are the same objects."""
        hit = self._flat
        if (
            hit is None
            or hit[0] != tuple(pivot)
            or len(hit[1]) != len(patches)
            or any(map(operator.is_not, hit[1], patches))
        ):
            frames = [self._frame(k, pt, pivot, blk) for k, (pt, blk) in enumerate(zip(patches, blocks))]
            hit = (tuple(pivot), list(patches), *(laid_end_to_end([f[i] for f in frames]) for i in (0, 1)))
            self._flat = hit
        return hit[2], hit[3]

    def _frame(self, k: int, pt, pivot, blk=None) -> tuple:
        """Block ``k``'s :func:`block_coordinates` and the columns ``(1, y, x)`` of
        :func:`resultants`, kept while its patch is the same object (4,548 blocks: made
        again at every step, 0.7 s of a 3 s step), also with the block ``blk`` for the
        next round's coarse space (1,485 clustered spheres: 1,375 frames made again after
        a merge)."""
        hit = self._frames.get(k)
        if hit is None or hit[0] is not pt or hit[1] != tuple(pivot):
            hit = getattr(blk, "coarse_frame", None)
            if hit is None or hit[0] is not pt or hit[1] != tuple(pivot):
                xr, yr = block_coordinates(pt, pivot)
                hit = (pt, tuple(pivot), (xr, yr, np.column_stack([np.ones_like(xr), yr, xr])))
            self._frames[k] = hit
            if blk is not None:
                blk.coarse_frame = hit
        return hit[2]

    def _resultants(self, patches, pressures: list, pivot, m: int) -> np.ndarray:
        """:func:`resultants` by the kept frames (the same arithmetic)."""
        out = 0.0
        for k, (pt, p) in enumerate(zip(patches, pressures)):
            G = self._frame(k, pt, pivot)[2]
            out = out + pt.grid.h**2 * (G[:, :m].T @ p)
        return np.asarray(out)

    def _solve(self, A: np.ndarray, kinv: np.ndarray, rhs: np.ndarray, near):
        """Solve ``(diag(kinv) + T_AA + near) x = rhs`` for the columns of ``rhs`` (``near``:
        the near pairs' correction on ``A``, sparse symmetric)."""
        if A.size <= self.dense_max:
            T, tA = self.compliance(), self.tips[A]
            if T is not None:  # every patch in contact: a copy of T, not a gather (1 against 7 ms)
                M = T.copy() if A.size == len(T) else T[np.ix_(A, A)]
            else:
                M = np.array(self.provider.point_compliance(tA, tA), dtype=float)
            M[np.arange(A.size), np.arange(A.size)] = kinv
            pairs = near.tocoo()  # its few entries added where they are, not a dense copy of it
            M[pairs.row, pairs.col] += pairs.data
            # a compliance plus the patches' own: positive definite, so Cholesky (1,383
            # tips: LDL's pivoting cost 1.5-2x), in single precision refined in double
            # (half the factor's cost); LDL where rounding or an odd near correction leave
            # it indefinite
            x = refined_solve(M, rhs, definite=True)
            if x is not None:
                return x, 0, True
            for kind in ("pos", "sym"):
                try:
                    return sla.solve(M, rhs, assume_a=kind, check_finite=False), 0, True
                except (sla.LinAlgError, ValueError):
                    continue
            return np.linalg.lstsq(M, rhs, rcond=None)[0], 0, True
        op = self._operator()
        n = len(self.tips)

        def matvec(x):
            full = np.zeros((n, x.shape[1]))
            full[A] = x
            return op.apply(full)[A] + kinv[:, None] * x + near @ x

        out = block_cg(matvec, 1.0 / kinv, rhs, rtol=self.rtol, max_iter=self.max_iter)
        return out.x, out.iterations, out.converged
