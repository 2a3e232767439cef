"""Dense solves by a single-precision factor refined in double precision.

As LAPACK's ``dsgesv`` (LU) and ``dsposv`` (Cholesky): ``K`` is factorised in single
precision, at about half the cost of the double-precision factor (1,485 unknowns: LU 0.05
against 0.10 s), and the solution is refined by ``x += K32^-1 (rhs - K x)`` with the
residual in double precision until it is below ``sqrt(n) eps |K|_inf |x|_inf`` (per
column), the backward error of a double-precision solve. The answer is then the
double-precision solve's to rounding. Where the single-precision factor fails (singular,
or not positive definite) or the refinement does not converge (``K`` too ill-conditioned
for single precision), :func:`refined_solve` returns None and the caller solves in double
precision.

Neither the factor nor its tolerance holds a second matrix of ``K``'s size: the
single-precision copy is made in LAPACK's (column) order and factorised in place, and the
row sums of ``|K|`` are taken by blocks of rows. Each such temporary is memory a fresh
process pays in pages at every Newton step (662 tips: 10 steps, 17,000 page faults).
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

#: Entries of ``|K|`` held at a time for its largest row sum (:func:`inf_norm`).
NORM_BLOCK_ENTRIES = 1 << 16


def refined_solve(
    K: np.ndarray, rhs: np.ndarray, *, definite: bool = False, max_refinements: int = 10
) -> np.ndarray | None:
    """``K x = rhs`` (``rhs`` (n,) or (n, m)) as the module docstring says; ``definite``:
    ``K`` is symmetric positive definite (Cholesky), else LU. None where it does not apply."""
    n = K.shape[0]
    if n == 0:
        return rhs.copy()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", sla.LinAlgWarning)
            K32 = K.astype(np.float32, order="F")  # LAPACK's order: factorised in place, not copied
            if definite:
                chol = sla.cho_factor(K32, lower=True, overwrite_a=True, check_finite=False)
                solve = lambda b: sla.cho_solve(chol, b, check_finite=False)  # noqa: E731
            else:
                lu = sla.lu_factor(K32, overwrite_a=True, check_finite=False)
                solve = lambda b: sla.lu_solve(lu, b, check_finite=False)  # noqa: E731
    except (sla.LinAlgError, sla.LinAlgWarning, ValueError):
        return None

    def correction(r: np.ndarray) -> np.ndarray:
        # each column scaled to 1 first: a small residual does not underflow in single precision
        scale = np.max(np.abs(r), axis=0)
        scale = np.where(np.isfinite(scale) & (scale > 0.0), scale, 0.0)
        return scale * solve((r / np.where(scale > 0.0, scale, 1.0)).astype(np.float32)).astype(float)

    tol = np.sqrt(n) * np.finfo(float).eps * inf_norm(K)
    x = correction(rhs)
    for _ in range(max_refinements):
        r = rhs - K @ x
        if not np.all(np.isfinite(r)):
            return None
        if np.all(np.max(np.abs(r), axis=0) <= tol * np.max(np.abs(x), axis=0)):
            return x
        x = x + correction(r)
    return None


def inf_norm(K: np.ndarray) -> float:
    """``max_i sum_j |K_ij|``, the same number as ``np.max(np.sum(np.abs(K), axis=1))``: on a
    C-ordered ``K`` by blocks of rows (each row summed as numpy sums it whole), without
    ``|K|`` in one array."""
    if K.ndim != 2 or not K.flags.c_contiguous or K.shape[1] == 0:
        return float(np.max(np.sum(np.abs(K), axis=1)))
    step = max(1, NORM_BLOCK_ENTRIES // K.shape[1])
    return max(float(np.max(np.sum(np.abs(K[a : a + step]), axis=1))) for a in range(0, K.shape[0], step))
