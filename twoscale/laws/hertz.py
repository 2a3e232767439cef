"""Closed-form laws: Hertz paraboloid and exact rigid sphere (Segedin) on a half-space.

Both wrap :mod:`twoscale.analytic.hertz`. Parameters may be arrays (one entry per
asperity) for elementwise evaluation; :class:`~twoscale.laws.stack.LawStack` uses
this to evaluate many asperities in one call.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..analytic import hertz
from .base import AsperityLaw, as_force, as_penetration, check_positive


@dataclass(frozen=True, eq=False)
class HertzLaw(AsperityLaw):
    """Hertz law of a rigid paraboloid ``z = r^2 / (2R)``: ``P = 4/3 E* sqrt(R) delta^(3/2)``.

    Parameters
    ----------
    R : float or array
        Tip radius of curvature, mm (> 0).
    E_star : float or array
        Plane-strain modulus of the body, MPa (> 0).
    """

    R: float
    E_star: float

    def __post_init__(self) -> None:
        check_positive("R (mm)", self.R)
        check_positive("E_star (MPa)", self.E_star)

    def force(self, delta):
        return hertz.load(self.R, as_penetration(delta), self.E_star)

    def stiffness(self, delta):
        return hertz.load_derivative(self.R, as_penetration(delta), self.E_star)

    def penetration(self, P):
        return hertz.penetration(self.R, as_force(P), self.E_star)

    @classmethod
    def stacked(cls, laws: Sequence["HertzLaw"]) -> "HertzLaw":
        """One law with array parameters evaluating ``laws`` elementwise."""
        return cls(np.array([l.R for l in laws], float), np.array([l.E_star for l in laws], float))


@dataclass(frozen=True, eq=False)
class SphereLaw(AsperityLaw):
    """Exact rigid sphere of radius ``R`` (Segedin 1957), in contact radius ``a < R``:
    ``delta = (a/2) ln((R+a)/(R-a))``, ``P = E*/2 [(a^2+R^2) ln((R+a)/(R-a)) - 2aR]``,
    ``dP/ddelta = 2 E* a``. Tends to :class:`HertzLaw` for ``delta << R``.

    Parameters
    ----------
    R : float or array
        Sphere radius, mm (> 0).
    E_star : float or array
        Plane-strain modulus of the body, MPa (> 0).
    """

    R: float
    E_star: float

    def __post_init__(self) -> None:
        check_positive("R (mm)", self.R)
        check_positive("E_star (MPa)", self.E_star)

    def force(self, delta):
        return hertz.sphere_load(self.R, as_penetration(delta), self.E_star)

    def stiffness(self, delta):
        return hertz.sphere_load_derivative(self.R, as_penetration(delta), self.E_star)

    def penetration(self, P):
        P = as_force(P)
        return hertz.sphere_penetration_from_radius(self.R, self._radius_from_load(P))

    def _radius_from_load(self, P: np.ndarray) -> np.ndarray:
        # Newton on P(a) - P = 0; P(a) is convex in a (P'' = 2 E* d'(a) > 0), so from the
        # Hertz start, clipped below R, the iterates approach from above after one step.
        R = np.broadcast_to(np.asarray(self.R, float), P.shape) if np.ndim(self.R) else self.R
        E = self.E_star
        a = np.minimum(np.sqrt(R * hertz.penetration(R, P, E)), 0.999 * np.asarray(R))
        for _ in range(100):
            f = hertz.sphere_load_from_radius(R, a, E) - P
            # dP/da = dP/ddelta * ddelta/da = 2 E* a d'(a)
            dprime = 0.5 * np.log((R + a) / (R - a)) + a * R / (R * R - a * a)
            fp = 2.0 * E * a * dprime
            step = np.where(fp > 0, f / np.where(fp > 0, fp, 1.0), 0.0)
            a_new = np.clip(a - step, 0.0, np.asarray(R) * (1 - 1e-12))
            done = np.all(np.abs(a_new - a) <= 1e-15 * np.asarray(R))
            a = a_new
            if done:
                break
        return np.where(P > 0, a, 0.0)

    @classmethod
    def stacked(cls, laws: Sequence["SphereLaw"]) -> "SphereLaw":
        """One law with array parameters evaluating ``laws`` elementwise."""
        return cls(np.array([l.R for l in laws], float), np.array([l.E_star for l in laws], float))
