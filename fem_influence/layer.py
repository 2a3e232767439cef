"""Elastic layer on a rigid base: Fourier compliance and point-force surface displacement.

A layer of thickness ``t`` (mm) lies on a rigid base, either bonded (u = 0) or
frictionless ("sliding": u_z = 0, no shear). Its surface compliance in Fourier
space (docs/method.md section 6; Carbone & Mangialardi 2008) is written as the
half-space compliance ``2/(E* q)`` times a dimensionless factor ``g(qt)`` that
tends to 1 for ``qt -> infinity``:

* bonded: ``g(s) = [(3-4nu) sinh 2s - 2s] / [(3-4nu) cosh 2s + 2 s^2 + 5 - 12 nu + 8 nu^2]``
* sliding: ``g(s) = (cosh 2s - 1) / (sinh 2s + 2s)``

The axisymmetric point-force displacement is the Hankel transform
``u(r) = (1/2pi) int_0^inf G(q) J0(qr) q dq``; relative to Boussinesq it reads
``u / u_B = 1 + (r/t) int_0^inf (g(s) - 1) J0(s r/t) ds``, whose integrand decays
like ``exp(-2s)``, so Gauss-Legendre quadrature on ``[0, s_max]`` converges fast.
"""

from __future__ import annotations

import numpy as np
from scipy.special import j0

from twoscale.material import Material

BASES = ("bonded", "sliding")
#: Beyond this s = q t the factor g differs from 1 by < 1e-30 (exp(-2 s) s^2).
_S_MAX = 40.0


def _check_base(base: str) -> None:
    if base not in BASES:
        raise ValueError(f"base must be one of {BASES}, got {base!r}")


def layer_factor(s, nu: float, base: str = "bonded") -> np.ndarray:
    """Layer compliance over half-space compliance, ``g(qt)``, dimensionless.

    Parameters
    ----------
    s : array_like
        ``q t`` (wavenumber, rad/mm, times thickness, mm), >= 0.
    nu : float
        Poisson's ratio (used by the bonded base only).
    base : {"bonded", "sliding"}, default "bonded"

    Returns
    -------
    array of ``g``; ``g -> 1`` as ``s -> inf``, ``g -> 0`` as ``s -> 0``.
    """
    _check_base(base)
    s = np.minimum(np.asarray(s, dtype=float), _S_MAX)
    if base == "bonded":
        k = 3.0 - 4.0 * nu
        return (k * np.sinh(2 * s) - 2 * s) / (k * np.cosh(2 * s) + 2 * s * s + 5 - 12 * nu + 8 * nu * nu)
    return (np.cosh(2 * s) - 1.0) / (np.sinh(2 * s) + 2 * s)


def layer_fourier_compliance(q, t: float, material: Material, base: str = "bonded") -> np.ndarray:
    """Surface displacement per unit pressure amplitude, ``u_hat / p_hat`` (mm/MPa).

    Parameters
    ----------
    q : array_like
        Wavenumber, rad/mm (> 0).
    t : float
        Layer thickness, mm.
    material : Material
    base : {"bonded", "sliding"}, default "bonded"
    """
    q = np.asarray(q, dtype=float)
    return 2.0 / (material.E_star * q) * layer_factor(q * t, material.nu, base)


def point_ratio(r, t: float, nu: float, base: str = "bonded", *, n_quad: int = 800) -> np.ndarray:
    """Surface displacement of a point force on the layer over Boussinesq's, at distance ``r``.

    Parameters
    ----------
    r : array_like
        Distance from the force, mm (> 0).
    t : float
        Layer thickness, mm (> 0).
    nu : float
        Poisson's ratio.
    base : {"bonded", "sliding"}, default "bonded"
    n_quad : int, default 800
        Gauss-Legendre points on ``[0, 40]`` in ``s = qt``; 800 resolves the
        Bessel oscillation for ``r/t <= 20`` to ~1e-10.

    Returns
    -------
    array, ``u_layer(r) / (1 / (pi E* r))``.
    """
    if not t > 0:
        raise ValueError(f"layer thickness t must be > 0 (mm), got {t!r}")
    r = np.asarray(r, dtype=float)
    if np.any(r <= 0):
        raise ValueError("distances r must be > 0 (mm)")
    x, w = np.polynomial.legendre.leggauss(n_quad)
    s = 0.5 * _S_MAX * (x + 1.0)
    w = 0.5 * _S_MAX * w
    gm1 = layer_factor(s, nu, base) - 1.0
    a = (r / t)[..., None]
    return 1.0 + a[..., 0] * np.sum(w * gm1 * j0(s * a), axis=-1)


def point_displacement(r, t: float, material: Material, base: str = "bonded") -> np.ndarray:
    """Surface displacement (mm) at distance ``r`` (mm) from a unit point force (N) on the layer."""
    r = np.asarray(r, dtype=float)
    return point_ratio(r, t, material.nu, base) / (np.pi * material.E_star * r)
