"""Polonsky & Keer's constrained conjugate gradient (1999), written once for every caller.

Minimises ``1/2 p.A p + z.p`` over ``p >= 0`` subject to ``B^T p = target`` on a stack of
independent problems (leading axis: one row for the full-grid reference or one block, many
rows for the blocks of one size class). Per row and per iteration:

* gap ``g = A p + z``, projected orthogonally to the constraint basis ``B`` on the loaded
  cells ``S = {p > 0}`` (load control: minus its mean over ``S``; load and moments: minus
  the least-squares plane); the projection coefficients are the rigid-motion multipliers;
* search direction ``t = g_S + beta t`` (optionally preconditioned), ``beta = G / G_old``
  while the contact set only shrank, 0 after cells re-entered (the conjugacy reset);
* step ``p <- max(p - tau t, 0)`` with ``tau = g_S.t / t.A t``; cells with ``p = 0`` and
  ``g < 0`` re-enter with ``-tau g``; the constraints are restored by a factor (a
  constant: load control; a plane: load and moments);
* ``A p`` follows from ``A t`` while nothing was clipped or entered and the factor was a
  constant, and is recomputed otherwise and every :data:`REFRESH_EVERY` iterations.

The stopping rule (:class:`Tolerance`) tests, before each step: the KKT residual
(largest gap on ``S`` and interpenetration elsewhere over the largest displacement)
against ``residual``, and/or the relative change of ``p`` in the last step against
``change`` with no cell penetrating; either is confirmed on an exact product. A row also
stops on the iteration cap, when its residual has not halved for ``stall`` iterations, or
on a breakdown ``t.A t <= 0``; the reason is a :class:`~twoscale.stopping.StopReason`.
A row leaves the working stack when it stops (the others go on), so the stacked form
costs what the live rows cost, one operator call per iteration for all of them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .plane import PlaneBasis
from .iteration import GAP_RTOL, MONITOR_EVERY, REFRESH_EVERY, Iteration
from .products import Products
from .result import STALL_ITERATIONS, PKResult, Tolerance

Operator = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Constraint:
    """What the rows' pressures must carry: ``basis^T p = target`` per row.

    Attributes
    ----------
    basis : (n, k) array
        Constraint basis over the flattened field, shared by the rows: one constant
        column (load), or more (load and moments).
    target : (B, k) array
        ``basis^T p`` to hold, per row (the load over ``h^2``).
    plane : PlaneBasis, optional
        The basis ``[1, x - px, y - py]`` in its separable form on the rows' grid
        (:class:`~.plane.PlaneBasis`): the fits and the restoring by sums along the
        grid's rows instead of passes over the (n, 3) basis. None: the general algebra.
    """

    basis: np.ndarray
    target: np.ndarray
    plane: PlaneBasis | None = None


@dataclass(frozen=True)
class Start:
    """Initial pressures with their product ``A pressure``, when the caller made it (e.g. for
    the start's own line search): the kernel's first product saved. The product is the fast
    one where the rows start on it (else exact), for pressures the kernel keeps as they are
    (non-negative, 0 off the mask, no constraint to restore).

    Attributes
    ----------
    pressure : (B, ...) array, MPa
    product : (B, ...) array, mm
    """

    pressure: np.ndarray
    product: np.ndarray


def pk_solve(
    apply: Operator | Products,
    z: np.ndarray,
    start: "np.ndarray | Start",
    mask: np.ndarray | None,
    tolerance: Tolerance,
    *,
    constraint: Constraint | None = None,
    precondition: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    monitor=None,
) -> PKResult:
    """Polonsky & Keer's constrained CG on a stack of independent contact problems.

    Parameters
    ----------
    apply : callable or Products
        ``apply(v)`` returns ``A v`` (mm) for a stack ``v`` (b, ...) of pressures (MPa) in
        the field shape of ``z``, for any number b of rows (the live ones); or a
        :class:`~.products.Products` with a cheaper approximate product and the kernel's
        columns besides.
    z : (B, ...) array, mm
        Gap at zero pressure without the unknown rigid motion: height minus approach
        (penetration control), height (load control), ``-b`` for a block's right-hand side.
    start : (B, ...) array, MPa, or Start
        Initial pressures (negative entries and cells off ``mask`` are set to zero; with a
        constraint each row must be positive somewhere), or with their product
        (:class:`Start`).
    mask : (B, ...) bool array or None
        Cells that may carry pressure (others are neither loaded nor checked); None: all.
    tolerance : Tolerance
        The stopping rule and the iteration cap.
    constraint : Constraint, optional
        Load (and moments) to carry, the rigid shifts unknown; None: the gap is given.
    precondition : callable, optional
        ``precondition(v, on)``: an approximate inverse of ``A`` on a stack, applied to the
        projected gap ``v`` to make the search direction (``on``: the rows' loaded cells,
        bool, in the field shape; the result is taken on them, and may be a buffer it
        keeps: the step uses it before the next call).
    monitor : callable, optional
        ``monitor(iteration, residual)`` every :data:`MONITOR_EVERY` iterations.

    Returns
    -------
    PKResult
    """
    shape = z.shape[1:]
    rows = len(z)
    start, u0 = (start.pressure, start.product.reshape(rows, -1)) if isinstance(start, Start) else (start, None)
    plane = None
    if constraint is None:
        basis, target = np.zeros((z[0].size, 0)), np.zeros((rows, 0))
    else:
        basis, target = constraint.basis, np.asarray(constraint.target, dtype=float).reshape(rows, -1)
        plane = constraint.plane
    stack = Iteration(
        apply if isinstance(apply, Products) else Products(apply),
        precondition,
        shape,
        z.reshape(rows, -1),
        start.reshape(rows, -1),
        None if mask is None else mask.reshape(rows, -1),
        basis,
        target,
        tolerance,
        plane,
        u0,
    )
    for it in range(tolerance.max_iter + 1):
        live = stack.check(it, monitor)
        if live is None:
            break
        stack.step(*live)
    return stack.result(shape)


__all__ = [
    "Constraint",
    "GAP_RTOL",
    "MONITOR_EVERY",
    "PKResult",
    "Products",
    "REFRESH_EVERY",
    "STALL_ITERATIONS",
    "Start",
    "Tolerance",
    "pk_solve",
]
