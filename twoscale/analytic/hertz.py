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
#: ``2n + 1`` for the series' terms ``n = 1..13`` (e < 0.1: the first omitted term is below
#: 1e-16 of the sum)
_SERIES_ODD = 2.0 * np.arange(1, 14) + 1.0


def _atanh_minus_identity(e, atanh=None):
    """``atanh(e) - e``, summed as a series for small ``e``, where the direct difference
    cancels; ``atanh``: ``atanh(e)`` if the caller has it. The series' terms are made by
    one running product and summed by one running sum, in the order of the plain loop over
    them (the same bits): the macro step's safe path evaluates the sphere law thousands of
    times on a few tips, where each array operation's fixed cost is the time (39 of them
    for the loop, 8 tips: 64 us a call)."""
    e = np.asarray(e, dtype=float)
    direct = (np.arctanh(np.minimum(e, 1.0 - 1e-16)) if atanh is None else atanh) - e
    small = e < 0.1
    if not np.any(small):
        return direct
    e2 = e * e
    terms = np.empty(e.shape + (len(_SERIES_ODD),))
    terms[..., 0] = e * e2
    terms[..., 1:] = e2[..., None]
    np.cumprod(terms, axis=-1, out=terms)  # e^3, e^5, ... as term = term * e2
    terms /= _SERIES_ODD
    return np.where(small, np.cumsum(terms, axis=-1)[..., -1], direct)


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
    atanh = np.arctanh(np.minimum(e, 1.0 - 1e-16))
    return E_star * (a * a * atanh + R * R * _atanh_minus_identity(e, atanh))


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
