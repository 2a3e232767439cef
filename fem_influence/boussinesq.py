"""Boussinesq's point force on an elastic half-space: displacement and stress inside.

Frame: ``x, y`` on the surface, ``z`` = depth (positive into the body); a unit
normal force ``P`` (N) acts at the surface origin pointing into the body (+z).
Stresses are tension-positive (MPa), displacements in mm. Closed forms from
Boussinesq (1885), as written in Johnson, *Contact Mechanics* (1985), eq. 3.20,
rotated from cylindrical ``(r, theta, z)`` to Cartesian components.

The combinations ``(1 - z/rho)/r^2`` and ``r/(rho (rho + z))`` are written as
``1/(rho (rho + z))`` and ``r/(rho (rho + z))``, which are regular on the axis
``r = 0`` for ``z > 0``.
"""

from __future__ import annotations

import numpy as np

from twoscale.material import Material


def _split(points: np.ndarray, source: np.ndarray):
    p = np.asarray(points, dtype=float)
    if p.shape[-1] != 3:
        raise ValueError(f"points must have shape (..., 3) (x, y, depth in mm), got {p.shape}")
    s = np.asarray(source, dtype=float).reshape(2)
    x, y, z = p[..., 0] - s[0], p[..., 1] - s[1], p[..., 2]
    if np.any(z < 0):
        raise ValueError("points must have depth z >= 0 (inside the half-space)")
    r = np.hypot(x, y)
    rho = np.sqrt(r * r + z * z)
    if np.any(rho == 0):
        raise ValueError("a point coincides with the point force (singular)")
    return x, y, z, r, rho


def _lame(material: Material):
    G = material.E / (2.0 * (1.0 + material.nu))
    return G, material.nu


def point_displacement(points, material: Material, *, source=(0.0, 0.0), P: float = 1.0) -> np.ndarray:
    """Displacement field of a normal point force on the half-space.

    Parameters
    ----------
    points : (..., 3) array
        Field points ``(x, y, depth)``, mm, depth >= 0.
    material : Material
        E (MPa) and nu of the half-space (nu = 0.5 allowed).
    source : (2,) array, default (0, 0)
        Surface position of the force, mm.
    P : float, default 1
        Force, N, pointing into the body.

    Returns
    -------
    (..., 3) array, mm: ``(u_x, u_y, u_z)`` with ``u_z`` positive into the body.
    """
    x, y, z, r, rho = _split(points, source)
    G, nu = _lame(material)
    k = P / (4.0 * np.pi * G)
    # u_r / r, regular on the axis
    ur_r = k * (z / rho**3 - (1.0 - 2.0 * nu) / (rho * (rho + z)))
    uz = k * (z * z / rho**3 + 2.0 * (1.0 - nu) / rho)
    return np.stack([ur_r * x, ur_r * y, uz], axis=-1)


def point_stress(points, material: Material, *, source=(0.0, 0.0), P: float = 1.0) -> np.ndarray:
    """Cauchy stress of a normal point force on the half-space (tension positive).

    Parameters
    ----------
    points : (..., 3) array
        Field points ``(x, y, depth)``, mm, depth >= 0, not at the force.
    material : Material
        Only nu enters the stress.
    source : (2,) array, default (0, 0)
        Surface position of the force, mm.
    P : float, default 1
        Force, N, pointing into the body.

    Returns
    -------
    (..., 3, 3) array, MPa, symmetric, components in the ``(x, y, depth)`` frame.
    """
    x, y, z, r, rho = _split(points, source)
    nu = material.nu
    c = P / (2.0 * np.pi)
    inv = 1.0 / (rho * (rho + z))  # (1 - z/rho)/r^2
    s_rr = c * ((1.0 - 2.0 * nu) * inv - 3.0 * z * r * r / rho**5)
    s_tt = -c * (1.0 - 2.0 * nu) * (inv - z / rho**3)
    s_zz = -3.0 * c * z**3 / rho**5
    t_rz_r = -3.0 * c * z * z / rho**5  # tau_rz / r
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.where(r > 0, x / np.where(r > 0, r, 1.0), 1.0)
        sin = np.where(r > 0, y / np.where(r > 0, r, 1.0), 0.0)
    out = np.empty(x.shape + (3, 3))
    out[..., 0, 0] = s_rr * cos * cos + s_tt * sin * sin
    out[..., 1, 1] = s_rr * sin * sin + s_tt * cos * cos
    out[..., 0, 1] = out[..., 1, 0] = (s_rr - s_tt) * sin * cos
    out[..., 0, 2] = out[..., 2, 0] = t_rz_r * x
    out[..., 1, 2] = out[..., 2, 1] = t_rz_r * y
    out[..., 2, 2] = s_zz
    return out
