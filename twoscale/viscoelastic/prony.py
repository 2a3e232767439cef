"""Relaxation modulus and creep compliance of a Prony series (generalized Maxwell model).

The relaxation modulus (Young's, MPa) is ``E(t) = E_inf + sum_k E_k exp(-t / tau_k)``.
Its creep compliance J (1/MPa), defined by ``int_0^t E(t - s) dJ(s) = 1`` (Volterra), is
obtained exactly, without fitting: with ``F(s) = s E~(s) = E_inf + sum_k E_k s tau_k /
(1 + s tau_k)``, ``s J~(s) = 1 / F(s)``. ``F`` is a ratio of polynomials whose numerator
has n real negative roots ``-1 / lambda_j``, one below each pole ``-1 / tau_k`` (F is
decreasing between consecutive poles, positive at 0 and at -inf: Tschoegl, *The
Phenomenological Theory of Linear Viscoelastic Behavior*, 1989, ch. 4). Partial fractions
then give

    J(t) = J_inf - sum_j c_j exp(-t / lambda_j),   J_inf = 1 / E_inf,
    c_j = 1 / (x_j F'(-x_j)),   x_j = 1 / lambda_j,   F'(s) = sum_k E_k tau_k / (1 + s tau_k)^2,

the residues of ``1 / (s F(s))`` at its poles. ``J(0) = 1 / (E_inf + sum E_k)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..material import Material


@dataclass(frozen=True)
class CreepCompliance:
    """``J(t) = J_inf - sum_j c_j exp(-t / lambda_j)`` (1/MPa, t in s).

    Attributes
    ----------
    J_inf : float
        Relaxed compliance ``1 / E_inf``, 1/MPa.
    lambdas : (n,) array
        Retardation times, s (ascending).
    c : (n,) array
        Their weights, 1/MPa (> 0).
    """

    J_inf: float
    lambdas: np.ndarray
    c: np.ndarray

    @property
    def J0(self) -> float:
        """Glassy compliance ``J(0)``, 1/MPa."""
        return float(self.J_inf - self.c.sum())

    def __call__(self, t) -> np.ndarray:
        """J at times ``t`` (s, >= 0), 1/MPa."""
        t = np.asarray(t, dtype=float)
        return self.J_inf - np.sum(self.c * np.exp(-t[..., None] / self.lambdas), axis=-1)


def relaxation_modulus(material: Material, t) -> np.ndarray:
    """``E(t)`` (MPa) at times ``t`` (s, >= 0); the constant ``E`` for an elastic material."""
    t = np.asarray(t, dtype=float)
    out = np.full(t.shape, float(material.E))
    for Ek, tau in material.prony:
        out = out + Ek * np.exp(-t / tau)
    return out


def creep_compliance(material: Material) -> CreepCompliance:
    """The exact creep compliance of ``material``'s Prony series (module docstring)."""
    from scipy.optimize import brentq

    Einf = float(material.E)
    if not material.prony:
        return CreepCompliance(1.0 / Einf, np.zeros(0), np.zeros(0))
    Ek = np.array([e for e, _ in material.prony])
    tau = np.array([t for _, t in material.prony])
    order = np.argsort(-tau)  # poles x = 1 / tau ascending
    Ek, tau = Ek[order], tau[order]

    def F(x: float) -> float:  # s E~(s) at s = -x
        return Einf - float(np.sum(Ek * x * tau / (1.0 - x * tau)))

    poles = 1.0 / tau
    roots = []
    for j, hi in enumerate(poles):
        lo = 0.0 if j == 0 else poles[j - 1]
        a, b = _bracket(F, lo, hi)
        roots.append(brentq(F, a, b, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=500))
    x = np.array(roots)
    dF = np.array([np.sum(Ek * tau / (1.0 - xj * tau) ** 2) for xj in x])
    c = 1.0 / (x * dF)
    lam = 1.0 / x
    order = np.argsort(lam)
    return CreepCompliance(1.0 / Einf, lam[order], c[order])


def _bracket(F, lo: float, hi: float) -> tuple[float, float]:
    """An interval inside (lo, hi) on whose ends the decreasing F changes sign (F -> +inf
    at lo unless lo = 0, F(0) = E_inf > 0; F -> -inf at hi)."""
    a = lo if lo == 0.0 else lo * (1.0 + 1e-15)
    b = hi * (1.0 - 1e-15)
    for _ in range(60):
        if F(a) > 0:
            break
        a = lo + 0.5 * (a - lo) if lo > 0 else a
    for _ in range(60):
        if F(b) < 0:
            break
        b = hi - 2.0 * (hi - b)
    if not (F(a) > 0 > F(b)):  # pragma: no cover - only for degenerate series
        raise ValueError(f"retardation time between poles {lo!r} and {hi!r} (1/s) not bracketed")
    return a, b


def volterra_residual(material: Material, times, *, n: int = 4000) -> np.ndarray:
    """``E(t) J(0) + int_0^t E(t - s) J'(s) ds - 1`` at ``times`` (s), by quadrature on a
    grid geometric towards both ends from the shortest time scale (the identity J must satisfy; a check of
    :func:`creep_compliance` by a route that does not use its derivation)."""
    J = creep_compliance(material)
    taus = [t for _, t in material.prony] or [1.0]
    out = []
    for t in np.atleast_1d(np.asarray(times, dtype=float)):
        if t == 0:
            out.append(float(relaxation_modulus(material, 0.0) * J.J0 - 1.0))
            continue
        s0 = min(min(taus), t) * 1e-6
        g = np.geomspace(s0, t, n)  # fine near both ends: J' varies fast near 0, E(t - s) near t
        s = np.unique(np.concatenate([[0.0, t], g, t - g]).clip(0.0, t))
        # J'(s) = sum_j (c_j / lambda_j) exp(-s / lambda_j)
        dJ = np.sum(J.c / J.lambdas * np.exp(-s[:, None] / J.lambdas), axis=1)
        f = relaxation_modulus(material, t - s) * dJ
        integral = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(s)))
        out.append(float(relaxation_modulus(material, t) * J.J0 + integral - 1.0))
    return np.array(out)


def glassy_time(material: Material) -> float:
    """Shortest relaxation time, s (inf when elastic)."""
    return min((t for _, t in material.prony), default=math.inf)
