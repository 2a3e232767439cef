"""Hertz contact of a rigid paraboloid (and the exact sphere, Segedin 1957) on a half-space.

Units: R, d, a, r in mm; E* in MPa; P in N; p in MPa. The paraboloid
``z = r^2 / (2R)`` is Hertz's exact setting; a spherical cap ``R - sqrt(R^2 - r^2)``
rises faster (higher by about ``r^4 / 8R^3``), so at the same penetration it has a smaller
contact and carries less load (0.5 % less at d = R/20): :func:`sphere_load` gives the
exact-sphere law (Segedin).
"""

from __future__ import annotations

import numpy as np


def contact_radius(R: float | np.ndarray, d, E_star: float | None = None):
    """Hertz contact radius ``a = sqrt(R d)`` (mm) for penetration ``d >= 0`` (mm)."""
    return np.sqrt(R * np.maximum(d, 0.0))


def load(R: float | np.ndarray, d, E_star: float):
    """Hertz load ``P = 4/3 E* sqrt(R) d^(3/2)`` (N) at penetration ``d`` (mm); 0 for d <= 0."""
    dp = np.maximum(np.asarray(d, dtype=float), 0.0)
    return 4.0 / 3.0 * E_star * np.sqrt(R) * dp**1.5


def load_derivative(R: float, d, E_star: float):
    """``dP/dd = 2 E* sqrt(R d) = 2 E* a`` (N/mm); 0 for d <= 0."""
    return 2.0 * E_star * np.sqrt(R * np.maximum(np.asarray(d, dtype=float), 0.0))


def penetration(R: float, P, E_star: float):
    """Inverse of :func:`load`: ``d = (3 P / (4 E* sqrt(R)))^(2/3)`` (mm) for P >= 0 (N)."""
    Pp = np.maximum(np.asarray(P, dtype=float), 0.0)
    return (3.0 * Pp / (4.0 * E_star * np.sqrt(R))) ** (2.0 / 3.0)


def max_pressure(R: float, d, E_star: float):
    """Peak pressure ``p0 = 2 E* a / (pi R)`` (MPa)."""
    return 2.0 * E_star * contact_radius(R, d) / (np.pi * R)


def pressure(r, R: float, d, E_star: float):
    """Hertz pressure ``p0 sqrt(1 - r^2/a^2)`` inside the contact, 0 outside (MPa)."""
    a = contact_radius(R, d)
    r = np.asarray(r, dtype=float)
    if a == 0:
        return np.zeros_like(r)
    return max_pressure(R, d, E_star) * np.sqrt(np.clip(1.0 - (r / a) ** 2, 0.0, None))


def contact_area(R: float, d):
    """Hertz contact area ``pi a^2 = pi R d`` (mm^2)."""
    return np.pi * R * np.maximum(d, 0.0)


# ---------------------------------------------------------------- exact sphere (Segedin)
def _atanh_minus_identity(e):
    # atanh(e) - e, summed as a series for small e, where the direct difference cancels
    e = np.asarray(e, dtype=float)
    e2 = e * e
    series = np.zeros_like(e)
    term = e * e2
    for n in range(1, 14):  # e < 0.1: the first omitted term is below 1e-16 of the sum
        series = series + term / (2 * n + 1)
        term = term * e2
    return np.where(e < 0.1, series, np.arctanh(np.minimum(e, 1.0 - 1e-16)) - e)


def sphere_penetration_from_radius(R: float, a):
    """Exact rigid sphere: ``d = (a/2) ln((R+a)/(R-a)) = a atanh(a/R)`` (mm), 0 <= a < R."""
    a = np.asarray(a, dtype=float)
    return a * np.arctanh(np.minimum(a / R, 1.0 - 1e-16))


def sphere_load_from_radius(R: float, a, E_star: float):
    """Exact rigid sphere: ``P = E*/2 [(a^2 + R^2) ln((R+a)/(R-a)) - 2 a R]`` (N).

    Evaluated as ``E* [a^2 atanh(a/R) + R^2 (atanh(a/R) - a/R)]`` with the last bracket
    summed as a series for small ``a/R``: the textbook form loses ``(R/a)^3`` digits
    to cancellation (1e-6 relative at d/R = 2e-7)."""
    a = np.asarray(a, dtype=float)
    e = a / R
    return E_star * (a * a * np.arctanh(np.minimum(e, 1.0 - 1e-16)) + R * R * _atanh_minus_identity(e))


def sphere_contact_radius(R: float | np.ndarray, d):
    """Contact radius (mm) of the exact sphere at penetration ``d`` (mm), by Newton on
    ``d(a)``; starts from Hertz's ``sqrt(R d)``, which it approaches for d << R."""
    d = np.maximum(np.asarray(d, dtype=float), 0.0)
    a = np.minimum(np.sqrt(R * d), 0.999 * R)
    for _ in range(60):
        f = sphere_penetration_from_radius(R, a) - d
        # d'(a) = 0.5 ln((R+a)/(R-a)) + a R / (R^2 - a^2)
        fp = 0.5 * np.log((R + a) / (R - a)) + a * R / (R * R - a * a)
        step = np.where(fp > 0, f / np.where(fp > 0, fp, 1.0), 0.0)
        a = np.clip(a - step, 0.0, R * (1 - 1e-12))
        if np.all(np.abs(step) <= 1e-15 * R):
            break
    return a


def sphere_load(R: float, d, E_star: float):
    """Exact rigid sphere load (N) at penetration ``d`` (mm); ``~ Hertz`` for d << R."""
    return sphere_load_from_radius(R, sphere_contact_radius(R, d), E_star)


def sphere_load_derivative(R: float, d, E_star: float):
    """``dP/dd = 2 E* a`` holds for any axisymmetric punch (Sneddon), so also here (N/mm)."""
    return 2.0 * E_star * sphere_contact_radius(R, d)
