"""Contact on blocks of the micro step by the Polonsky-Keer kernel (:mod:`twoscale.pk`).

* :func:`fixed_approach` — ``p >= 0``, gap ``A p - b >= 0``, ``p . gap = 0``
  (the local step of a Gauss-Seidel sweep, eq. 8);
* :func:`fixed_force` — the same with ``b = s - z`` and the shift ``s`` unknown so that
  ``h^2 sum p = P`` (paper eq. 7), the original load-controlled algorithm.

Both work on a stack of independent blocks (leading axis; one row for one block, or the
blocks of one size class on a common canvas, :mod:`.pk_stack`), start from any
``p >= 0`` (warm starts make a sweep cheap) and stop when the relative change of a
block's pressure in one step is below ``rtol`` and no cell penetrates
(:class:`~twoscale.pk.kernel.Tolerance` ``change``). :func:`pk_fixed_approach` and
:func:`pk_fixed_force` are the one-block forms, with the block's own product.
"""

from __future__ import annotations

import numpy as np

from ..pk.kernel import Constraint, Tolerance, pk_solve


def fixed_approach(
    apply,
    b: np.ndarray,
    start: np.ndarray,
    mask: np.ndarray | None,
    *,
    rtol: float,
    max_iter: int = 1000,
    precondition=None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contact with given right-hand sides on a stack of blocks.

    Parameters
    ----------
    apply : callable or Products
        ``A v`` (mm) for a stack ``v`` (b, ...) of block pressures (MPa), any number b of rows
        (or a :class:`~twoscale.pk.products.Products` with a float32 product for the search
        directions).
    b : (B, ...) array, mm
        Right-hand side of each block (zero off its mask).
    start : (B, ...) array, MPa
        Warm starts (negative entries and cells off the masks are set to zero).
    mask : (B, ...) bool array or None
        Each block's cells (None: all).
    rtol : float
        Relative change of a block's pressure at which it stops.
    max_iter : int, default 1000
    precondition : callable, optional
        ``precondition(v, on)``: an approximate inverse of ``A`` on a stack
        (:func:`~twoscale.pk.kernel.pk_solve`); None: Polonsky-Keer's plain directions.

    Returns
    -------
    pressure (B, ...), converged (B,) bool, iterations (B,) int
    """
    out = pk_solve(apply, -b, start, mask, Tolerance(change=rtol, max_iter=max_iter), precondition=precondition)
    return out.pressure, out.converged, out.iterations


def fixed_force(
    apply,
    z: np.ndarray,
    target: np.ndarray,
    start: np.ndarray,
    mask: np.ndarray | None,
    *,
    rtol: float,
    max_iter: int = 1000,
    precondition=None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pressures carrying given loads on a stack of blocks, rigid shifts unknown (eq. 7).

    ``z`` (B, ...) mm the indenter heights, ``target`` (B,) the loads over ``h^2`` (MPa
    cells), ``start`` (> 0 somewhere on each mask); ``apply``, ``mask``, ``rtol``,
    ``max_iter`` and ``precondition`` as in :func:`fixed_approach`.

    Returns pressure (B, ...), shift (B,) mm (``A p = s - z`` on the contact), converged
    (B,), iterations (B,)."""
    n = int(np.prod(z.shape[1:]))
    out = pk_solve(
        apply,
        z,
        start,
        mask,
        Tolerance(change=rtol, max_iter=max_iter),
        constraint=Constraint(np.ones((n, 1)), np.asarray(target, dtype=float)[:, None]),
        precondition=precondition,
    )
    return out.pressure, out.multipliers[:, 0], out.converged, out.iterations


def _one_row(matvec):
    return lambda v: matvec(v[0])[None]


def pk_fixed_approach(
    matvec, b: np.ndarray, p_start: np.ndarray, *, rtol: float = 1e-10, max_iter: int = 1000
) -> tuple[np.ndarray, bool, int]:
    """:func:`fixed_approach` on one block: ``matvec`` gives ``A v`` (mm) for a block
    vector ``v`` (MPa), ``b`` (n,) mm, ``p_start`` (n,) MPa. Returns pressure (n,),
    converged, iterations."""
    b = np.asarray(b, dtype=float)
    p, ok, it = fixed_approach(
        _one_row(matvec), b[None], np.asarray(p_start, dtype=float)[None], None, rtol=rtol, max_iter=max_iter
    )
    return p[0], bool(ok[0]), int(it[0])


def pk_fixed_force(
    matvec, z: np.ndarray, force: float, h: float, p_start: np.ndarray, *, rtol: float = 1e-10, max_iter: int = 1000
) -> tuple[np.ndarray, float, bool, int]:
    """:func:`fixed_force` on one block: ``force`` N on cells of side ``h`` mm, ``z``
    (n,) mm, ``p_start`` (n,) MPa (> 0 somewhere). Returns pressure (n,), shift s (mm),
    converged, iterations."""
    z = np.asarray(z, dtype=float)
    p, s, ok, it = fixed_force(
        _one_row(matvec),
        z[None],
        np.array([force / (h * h)]),
        np.asarray(p_start, dtype=float)[None],
        None,
        rtol=rtol,
        max_iter=max_iter,
    )
    return p[0], float(s[0]), bool(ok[0]), int(it[0])
