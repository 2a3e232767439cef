"""Constrained conjugate gradients on one block (Polonsky & Keer 1999), FFT products.

Used for large blocks instead of the dense active-set method:

* :func:`pk_fixed_approach` — ``p >= 0``, gap ``A p - b >= 0``, ``p . gap = 0``
  (the local step of a Gauss-Seidel sweep, eq. 8);
* :func:`pk_fixed_force` — the same with ``b = s - z`` and the shift ``s`` unknown so that
  ``h^2 sum p = P`` (paper eq. 7), the original load-controlled algorithm.

Both start from any ``p >= 0`` (warm starts make a sweep cheap) and stop when the relative
change of the pressure in one step is below ``rtol`` and no cell penetrates.
"""
from __future__ import annotations

import numpy as np


def _direction(g, S, t, delta, G_old):
    """Conjugate direction on the contact cells S (zero elsewhere) and ``|g_S|^2``."""
    G = float(g[S] @ g[S])
    t = np.where(S, g + (delta * G / G_old if G_old > 0 else 0.0) * t, 0.0)
    return t, G


def pk_fixed_approach(matvec, b: np.ndarray, p_start: np.ndarray, *, rtol: float = 1e-10,
                      max_iter: int = 1000) -> tuple[np.ndarray, bool, int]:
    """Contact with a given right-hand side ``b`` (mm) on one block.

    Parameters
    ----------
    matvec : callable
        ``A v`` (mm) for a block vector ``v`` (MPa).
    b : (n,) array, mm
    p_start : (n,) array, MPa
        Warm start (negative entries are clipped).
    rtol : float, default 1e-10
        Relative change of the pressure at which to stop.
    max_iter : int, default 1000

    Returns
    -------
    pressure (n,), converged, iterations
    """
    p = np.maximum(np.asarray(p_start, dtype=float), 0.0)
    t = np.zeros_like(p)
    delta, G_old = 0.0, 0.0
    gtol = 1e-12 * float(np.max(np.abs(b), initial=0.0))
    u = matvec(p)
    for it in range(1, max_iter + 1):
        g = u - b
        S = p > 0.0
        if not np.any(S):
            S = g < 0.0
            if not np.any(S):
                return p, True, it
        if not np.any(g[S]):   # exact on the contact cells (a contact of a cell or two can be)
            entering = ~S & (g < -gtol)
            if not np.any(entering):
                return p, True, it
            S, delta = S | entering, 0.0
        t, G_old = _direction(g, S, t, delta, G_old)
        r = matvec(t)
        denom = float(t[S] @ r[S])
        if denom <= 0.0:
            return p, False, it
        tau = float(g[S] @ t[S]) / denom
        p_old = p
        trial = np.where(S, p - tau * t, p)
        p = np.maximum(trial, 0.0)
        overlap = (p == 0.0) & (g < 0.0) & ~S
        delta = 0.0 if np.any(overlap) else 1.0
        p[overlap] -= tau * g[overlap]
        # the product is linear: without clipping or new cells, A p follows from A t
        # (re-evaluated every 25 steps against drift)
        exact_step = not np.any(overlap) and not np.any(trial < 0.0)
        u = u - tau * r if exact_step and it % 25 else matvec(p)
        change = float(np.linalg.norm(p - p_old))
        norm = float(np.linalg.norm(p))
        if norm == 0.0 or change <= rtol * norm:
            u = matvec(p)
            gap = u - b
            if not np.any((p == 0.0) & (gap < -gtol)):
                return p, True, it
    return p, False, max_iter


def pk_fixed_force(matvec, z: np.ndarray, force: float, h: float, p_start: np.ndarray, *,
                   rtol: float = 1e-10, max_iter: int = 1000) -> tuple[np.ndarray, float, bool, int]:
    """Pressure carrying ``force`` (N) on one block, rigid shift unknown (eq. 7).

    Parameters
    ----------
    matvec : callable
        ``A v`` (mm) for a block vector ``v`` (MPa).
    z : (n,) array, mm
        Indenter height on the block's cells.
    force : float, N (> 0)
    h : float, mm
    p_start : (n,) array, MPa
        Initial pressure (> 0 somewhere).

    Returns
    -------
    pressure (n,), shift s (mm, ``A p = s - z`` on the contact), converged, iterations
    """
    target = force / (h * h)
    p = np.maximum(np.asarray(p_start, dtype=float), 0.0)
    p *= target / p.sum()
    t = np.zeros_like(p)
    delta, G_old = 0.0, 0.0
    s = float("nan")
    u = matvec(p)
    for it in range(1, max_iter + 1):
        S = p > 0.0
        g = u + z
        s = float(g[S].mean())
        g = g - s
        t, G_old = _direction(g, S, t, delta, G_old)
        At = matvec(t)
        r = At - At[S].mean()
        denom = float(t[S] @ r[S])
        if denom <= 0.0:
            return p, s, False, it
        tau = float(g[S] @ t[S]) / denom
        p_old = p
        trial = np.where(S, p - tau * t, p)
        p = np.maximum(trial, 0.0)
        overlap = (p == 0.0) & (g < 0.0)
        delta = 0.0 if np.any(overlap) else 1.0
        p[overlap] -= tau * g[overlap]
        scale = target / p.sum()
        p *= scale
        # A p follows from A t when nothing was clipped or added (every 25 steps: recomputed)
        exact_step = not np.any(overlap) and not np.any(trial < 0.0) and it % 25
        u = scale * (u - tau * At) if exact_step else matvec(p)
        if float(np.linalg.norm(p - p_old)) <= rtol * float(np.linalg.norm(p)):
            return p, s, True, it
    return p, s, False, max_iter
