"""Block conjugate gradients shared by the macro step and the coarse correction.

Both solve ``(diag(w) + T_AA) x = b`` with ``T`` a point compliance applied by a
:class:`~twoscale.influence.points.PointOperator` (no ``N x N`` matrix), for a few
right-hand sides at once: one product per iteration serves all columns.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class CGOutcome:
    """Solution of :func:`block_cg` and its effort.

    Attributes
    ----------
    x : (n, m) array
    iterations : int
        Products taken (each for all columns).
    converged : bool
        Every column reached ``||r|| <= rtol ||b||``.
    breakdown : bool
        A search direction with ``d.Ad <= 0`` was met: the matrix is not positive
        definite on the active set (e.g. contacts merged beyond what point forces model).
    """

    x: np.ndarray
    iterations: int
    converged: bool
    breakdown: bool = False


def block_cg(
    matvec: Callable[[np.ndarray], np.ndarray],
    precond: np.ndarray,
    rhs: np.ndarray,
    *,
    rtol: float,
    max_iter: int,
    x0: np.ndarray | None = None,
) -> CGOutcome:
    """Jacobi-preconditioned conjugate gradients on the columns of ``rhs`` at once.

    Parameters
    ----------
    matvec : callable, (n, m) -> (n, m)
        Product with a symmetric positive definite matrix.
    precond : (n,) array
        Inverse of its diagonal (or any positive diagonal preconditioner).
    rhs : (n, m) array
    rtol : float
        Stop when every column has ``||r|| <= rtol ||b||``.
    max_iter : int
    x0 : (n, m) array, optional
        Initial guess (default zero).
    """
    rhs = np.asarray(rhs, dtype=float)
    x = np.zeros_like(rhs) if x0 is None else np.array(x0, dtype=float)
    r = rhs - matvec(x) if x0 is not None else rhs.copy()
    bnorm = np.linalg.norm(rhs, axis=0)
    bnorm[bnorm == 0.0] = 1.0
    if np.all(np.linalg.norm(r, axis=0) <= rtol * bnorm):
        return CGOutcome(x, 0, True)
    z = precond[:, None] * r
    d = z.copy()
    rz = np.sum(r * z, axis=0)
    breakdown = False
    for it in range(1, max_iter + 1):
        Ad = matvec(d)
        dAd = np.sum(d * Ad, axis=0)
        breakdown |= bool(np.any((dAd <= 0.0) & (rz > 0.0)))
        step = np.divide(rz, dAd, out=np.zeros_like(rz), where=dAd > 0.0)
        x += step * d
        r -= step * Ad
        if np.all(np.linalg.norm(r, axis=0) <= rtol * bnorm):
            return CGOutcome(x, it, True, breakdown)
        if breakdown:
            return CGOutcome(x, it, False, True)
        z = precond[:, None] * r
        rz_new = np.sum(r * z, axis=0)
        d = z + np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz != 0.0) * d
        rz = rz_new
    return CGOutcome(x, max_iter, False, breakdown)


def masked_cg(apply, precondition, on: np.ndarray, x: np.ndarray, rtol: float, max_iter: int) -> np.ndarray:
    """Conjugate gradients for ``A_SS x = 1`` on a stack of fields, each row on its own
    cells ``S`` = ``on`` (B, ...): ``apply`` the product with ``A`` on a stack,
    ``precondition(v, on)`` an approximate inverse of ``A`` on a stack (taken on ``on``;
    None: none), from ``x`` (changed in place, zero off ``on``); a row leaves when its
    residual is at most ``rtol`` of its right-hand side's, or after ``max_iter``."""
    axes = tuple(range(1, on.ndim))
    b = on.astype(float)
    r = b - on * apply(x) if x.any() else b.copy()
    bnorm = np.sqrt(b.sum(axis=axes))
    live = np.arange(len(on))
    z = on * precondition(r, on) if precondition is not None else r.copy()
    d, rz = z, np.sum(r * z, axis=axes)
    for _ in range(max_iter):
        keep = np.sqrt(np.sum(r * r, axis=axes)) > rtol * bnorm[live]
        if not keep.all():
            live, r, d, rz = live[keep], r[keep], d[keep], rz[keep]
        if not live.size:
            break
        m = on[live]
        Ad = m * apply(d)
        step = (rz / np.sum(d * Ad, axis=axes)).reshape((-1,) + (1,) * len(axes))
        x[live] += step * d
        r = r - step * Ad
        z = m * precondition(r, m) if precondition is not None else r
        rz_new = np.sum(r * z, axis=axes)
        d = z + (rz_new / rz).reshape(step.shape) * d
        rz = rz_new
    return x
