"""An asperity law plus a smooth self-compliance of the body at the tip.

On a finite body the point compliance is ``1/(pi E* r) + C(x, x')`` with ``C`` smooth
(:meth:`~twoscale.influence.base.InfluenceProvider.smooth_self_compliance`). The
singular part is in the asperity's own (half-space) law; the regular part ``c = C(x_k,
x_k)`` adds a linear term: ``delta = delta_law(P) + c P``. ``c`` may be negative (a
bonded layer is stiffer than the half-space); the law then holds while
``1 + c dP/ddelta > 0``, i.e. up to the force where the tangent stiffness of the base
law reaches ``1/|c|``.
"""

from __future__ import annotations

import numpy as np

from .base import AsperityLaw, as_force, as_penetration

_MAX_ITER = 200


class CompliantLaw(AsperityLaw):
    """``law`` in series with a linear self-compliance ``c`` (mm/N): ``delta = delta_law(P) + c P``.

    With ``c == 0`` every method delegates to ``law`` exactly (use :func:`compliant` to
    get ``law`` itself back).

    Parameters
    ----------
    law : AsperityLaw
        The asperity's own law on the half-space.
    c : float
        Smooth self-compliance, mm/N (finite; may be negative).
    """

    def __init__(self, law: AsperityLaw, c: float):
        if not isinstance(law, AsperityLaw):
            raise ValueError(f"law must be an AsperityLaw, got {law!r}")
        if isinstance(c, bool) or not np.isfinite(c):
            raise ValueError(f"self-compliance c must be a finite number (mm/N), got {c!r}")
        self.law, self.c = law, float(c)

    def __repr__(self) -> str:
        return f"CompliantLaw({self.law!r}, c={self.c!r})"

    def force(self, delta):
        if self.c == 0.0:
            return self.law.force(delta)
        return self.law.force(self._own_penetration(as_penetration(delta)))

    def stiffness(self, delta):
        if self.c == 0.0:
            return self.law.stiffness(delta)
        k = self.law.stiffness(self._own_penetration(as_penetration(delta)))
        return k / (1.0 + self.c * k)  # springs in series: 1/k_total = 1/k + c

    def penetration(self, P):
        P = as_force(P)
        return self.law.penetration(P) + self.c * P

    def complementary_energy(self, P):
        """``Phi_law(P) + c P^2 / 2`` (N mm)."""
        P = as_force(P)
        return self.law.complementary_energy(P) + 0.5 * self.c * P * P

    def _own_penetration(self, delta: np.ndarray) -> np.ndarray:
        """Solve ``u + c f(u) = delta`` for the law's own penetration u (mm), elementwise,
        by Newton safeguarded with bisection on a bracket."""
        d = np.maximum(delta, 0.0)
        lo = np.zeros_like(d)
        if self.c > 0:
            hi = d.copy()  # h(d) = c f(d) >= 0
        else:
            hi = self._upper_bracket(d)
        u = hi.copy()
        for _ in range(_MAX_ITER):
            f = self.law.force(u)
            k = self.law.stiffness(u)
            h = u + self.c * f - d
            lo = np.where(h <= 0, u, lo)
            hi = np.where(h >= 0, u, hi)
            slope = 1.0 + self.c * k
            newton = u - h / np.where(slope > 0, slope, 1.0)
            ok = (slope > 0) & (newton > lo) & (newton < hi)
            u_new = np.where(ok, newton, 0.5 * (lo + hi))
            if np.all(np.abs(u_new - u) <= 1e-15 * np.maximum(d, 1e-300)):
                u = u_new
                break
            u = u_new
        return np.where(delta > 0, u, 0.0)

    def _upper_bracket(self, d: np.ndarray) -> np.ndarray:
        # c < 0: h(u) = u + c f(u) - d is <= 0 at u = d; double u until h >= 0, and
        # refuse if the law has stopped being monotone (h' = 1 + c f'(u) <= 0) on the way.
        hi = d.copy()
        for _ in range(200):
            h = hi + self.c * self.law.force(hi) - d
            need = h < 0
            if not np.any(need):
                return hi
            slope = 1.0 + self.c * self.law.stiffness(hi)
            if np.any(need & (slope <= 0)):
                bad = d[need & (slope <= 0)][0]
                raise ValueError(
                    f"CompliantLaw with c={self.c!r} mm/N is not monotone up to "
                    f"delta={bad!r} mm: the base law is stiffer than 1/|c| there"
                )
            hi = np.where(need, 2.0 * hi, hi)
        raise ValueError(f"CompliantLaw: no bracket found for delta up to {d.max()!r} mm")


def compliant(law: AsperityLaw, c: float) -> AsperityLaw:
    """``law`` with self-compliance ``c`` (mm/N); ``law`` itself when ``c == 0`` (half-space)."""
    if c == 0.0:
        return law
    return CompliantLaw(law, c)
