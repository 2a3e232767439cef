"""Closed forms for a rigid paraboloid (radius R) on a viscoelastic half-space of constant
Poisson's ratio, the references of the tests.

* Step load ``W`` at t = 0 (contact growing, Lee and Radok 1960):
  ``a(t)^3 = 3 R W (1 - nu^2) J(t) / 4``, approach ``d = a^2 / R``.
* Step approach ``d`` at t = 0: ``W(t) = 4 sqrt(R) d^1.5 E(t) / (3 (1 - nu^2))``.
* Any history while the contact grows (Lee and Radok): with ``A = a^3``,
  ``W(t) = 4 / (3 R (1 - nu^2)) int_0^t E(t - s) dA(s)``, or inverted,
  ``A(t) = 3 R (1 - nu^2) / 4 int_0^t J(t - s) dW(s)``.
* Contact shrinking after its largest radius at ``t_m`` (Ting 1966, J. Appl. Mech. 33,
  845; Greenwood 2010, Int. J. Mech. Sci. 52, 829): the load depends on the growing
  phase only up to the time ``t_1(t) <= t_m`` at which the radius was what it is now,
  ``W(t) = 4 / (3 R (1 - nu^2)) int_0^{t_1} E(t - s) dA(s)``, ``a(t) = a(t_1)``.
  Under a given load this fixes ``t_1`` and so ``a(t)`` (:func:`ting_radius`).

* A paraboloid moved at a low speed ``v`` (every ``v tau_k`` far below the contact radius)
  at a held approach or load: the branches act as a viscosity ``eta = sum_k E_k tau_k``
  (``E(t) -> E_inf + eta delta(t)``), the first-order pressure is that of a flat circular
  punch tilted by ``eta v / (E_inf R)`` (moment ``4 E* a^3 theta / 3``), so the horizontal
  force over the load is ``v eta / (E_inf R)``, whatever the contact radius
  (:func:`low_speed_friction`). The energy route gives the same: the dashpots dissipate
  ``(eta / E_inf^2) <dp/dt, K dp/dt>`` with ``dp/dt = v dp/dx`` and ``K p = E_inf u``, which
  integrates by parts to ``eta v^2 W / (E_inf R)``, the drag times ``v``.

Integrals against a Prony kernel ``k0 + sum_k w_k exp(-t / theta_k)`` of a
piecewise-linear function are exact per segment (:func:`hereditary`).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..material import Material
from .prony import creep_compliance, relaxation_modulus


def creep_radius(material: Material, R: float, W: float, t) -> np.ndarray:
    """Contact radius (mm) under a step load ``W`` (N) held from t = 0, at times ``t`` (s)."""
    J = creep_compliance(material)
    return (3.0 * R * W * (1.0 - material.nu**2) * J(t) / 4.0) ** (1.0 / 3.0)


def creep_approach(material: Material, R: float, W: float, t) -> np.ndarray:
    """Rigid approach (mm) under a step load ``W`` (N): ``a(t)^2 / R``."""
    return creep_radius(material, R, W, t) ** 2 / R


def relaxation_load(material: Material, R: float, d: float, t) -> np.ndarray:
    """Load (N) under a step approach ``d`` (mm) held from t = 0."""
    return 4.0 * np.sqrt(R) * d**1.5 * relaxation_modulus(material, t) / (3.0 * (1.0 - material.nu**2))


def low_speed_friction(material: Material, R: float, speed: float) -> float:
    """Drag over load of a paraboloid of radius ``R`` (mm) moved at a low ``speed`` (mm/s)
    over the body: ``speed sum_k E_k tau_k / (E_inf R)`` (module docstring); 0 when elastic."""
    eta = sum(e * t for e, t in material.prony)
    return float(speed * eta / (material.E * R))


def hereditary(k0: float, w, theta, s, x, t) -> np.ndarray:
    """``int_0^t k(t - u) dX(u)`` for ``k(t) = k0 + sum_k w_k exp(-t / theta_k)`` and X
    piecewise linear through ``(s_i, x_i)`` (``s`` increasing, ``s_0 >= 0``; X = 0
    before ``s_0``, so ``x_0 != 0`` is a jump there; X held after the last point)."""
    s, x = np.asarray(s, dtype=float), np.asarray(x, dtype=float)
    w, theta = np.asarray(w, dtype=float), np.asarray(theta, dtype=float)
    out = []
    for tt in np.atleast_1d(np.asarray(t, dtype=float)):
        if tt < s[0]:
            out.append(0.0)
            continue
        total = k0 * float(np.interp(tt, s, x)) + float(np.sum(w * np.exp(-(tt - s[0]) / theta))) * x[0]
        lo, hi = s[:-1], np.minimum(s[1:], tt)
        ok = hi > lo
        slope = np.diff(x)[ok] / np.diff(s)[ok]
        lo, hi = lo[ok], hi[ok]
        # int_lo^hi exp(-(t - u) / theta) m du = m theta (exp(-(t - hi)/theta) - exp(-(t - lo)/theta))
        e = np.exp(-(tt - hi[:, None]) / theta) - np.exp(-(tt - lo[:, None]) / theta)
        total += float(np.sum(slope[:, None] * theta * w * e))
        out.append(total)
    return np.array(out)


def _kernels(material: Material):
    J = creep_compliance(material)
    Ek = np.array([e for e, _ in material.prony])
    tau = np.array([t for _, t in material.prony])
    return (material.E, Ek, tau), (J.J_inf, -J.c, J.lambdas)


def ting_radius(material: Material, R: float, load_points, t, *, n: int = 4000) -> np.ndarray:
    """Contact radius (mm) at times ``t`` (s) under the piecewise-linear load history
    ``load_points`` ([(t, W)], s and N): Lee-Radok while the radius grows, Ting's
    ``t_1`` once it shrinks (module docstring). ``n``: points of the table of the growing
    phase (geometric in time from its first instant, linear near its end)."""
    (E0, Ek, tau), (J0, Jw, lam) = _kernels(material)
    s_w = np.array([p[0] for p in load_points], dtype=float)
    W = np.array([p[1] for p in load_points], dtype=float)
    c = 3.0 * R * (1.0 - material.nu**2) / 4.0
    end = max(float(np.max(t)), s_w[-1])
    grid = np.unique(
        np.concatenate([s_w, np.geomspace(max(s_w[0], 1e-12 * end) + 1e-12 * end, end, n), np.linspace(s_w[0], end, n)])
    )
    A = c * hereditary(J0, Jw, lam, s_w, W, grid)  # a^3 if the contact only grew
    grows = np.diff(A) >= -1e-12 * A.max()
    m = int(np.argmin(grows)) if not grows.all() else grows.size  # last index of the growing phase
    s_g, A_g = grid[: m + 1], A[: m + 1]
    out = []
    for tt in np.atleast_1d(np.asarray(t, dtype=float)):
        if tt <= s_g[-1]:
            out.append(float(np.interp(tt, grid, A)) ** (1.0 / 3.0))
            continue
        target = c * float(np.interp(tt, s_w, W))

        def F(t1, tt=tt, target=target):  # int_0^t1 E(t - s) dA(s) - c W(t), increasing in t1
            k = np.searchsorted(s_g, t1, side="right")
            ss = np.append(s_g[:k], t1)
            AA = np.append(A_g[:k], np.interp(t1, s_g, A_g))
            return float(hereditary(E0, Ek, tau, ss, AA, tt)[0]) - target

        lo, hi = s_g[0], s_g[-1]
        if F(lo) >= 0:  # even the first instant's radius carries more: the smallest radius there
            out.append(float(A_g[0]) ** (1.0 / 3.0))
            continue
        if F(hi) <= 0:
            out.append(float(A_g[-1]) ** (1.0 / 3.0))
            continue
        t1 = brentq(F, lo, hi, xtol=1e-14 * max(hi, 1e-300))
        out.append(float(np.interp(t1, s_g, A_g)) ** (1.0 / 3.0))
    return np.array(out)
