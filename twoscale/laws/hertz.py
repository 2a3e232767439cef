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
from .base import GAUSS_NODES, GAUSS_WEIGHTS, AsperityLaw, as_force, as_penetration, check_positive


@dataclass(frozen=True, eq=False)
class _ClosedFormLaw(AsperityLaw):
    """A law fixed by a tip radius ``R`` (mm) and the body's ``E_star`` (MPa), scalars
    or arrays (elementwise)."""

    R: float
    E_star: float

    def __post_init__(self) -> None:
        check_positive("R (mm)", self.R)
        check_positive("E_star (MPa)", self.E_star)

    @classmethod
    def stacked(cls, laws: Sequence["_ClosedFormLaw"]) -> "_ClosedFormLaw":
        """One law with array parameters evaluating ``laws`` elementwise."""
        return cls(np.array([l.R for l in laws], float), np.array([l.E_star for l in laws], float))


@dataclass(frozen=True, eq=False)
class HertzLaw(_ClosedFormLaw):
    """Hertz law of a rigid paraboloid ``z = r^2 / (2R)``: ``P = 4/3 E* sqrt(R) delta^(3/2)``.

    Parameters
    ----------
    R : float or array
        Tip radius of curvature, mm (> 0).
    E_star : float or array
        Plane-strain modulus of the body, MPa (> 0).
    """

    def force(self, delta):
        return hertz.load(self.R, as_penetration(delta), self.E_star)

    def stiffness(self, delta):
        return hertz.load_derivative(self.R, as_penetration(delta), self.E_star)

    def penetration(self, P):
        return hertz.penetration(self.R, as_force(P), self.E_star)

    def complementary_energy(self, P):
        """``int_0^P delta = 3/5 P delta(P)`` (N mm)."""
        P = as_force(P)
        return 0.6 * P * hertz.penetration(self.R, P, self.E_star)


@dataclass(frozen=True, eq=False)
class SphereLaw(_ClosedFormLaw):
    """Exact rigid sphere of radius ``R`` (Segedin 1957), in contact radius ``a < R``:
    ``delta = (a/2) ln((R+a)/(R-a))``, ``P = E*/2 [(a^2+R^2) ln((R+a)/(R-a)) - 2aR]``,
    ``dP/ddelta = 2 E* a``. Tends to :class:`HertzLaw` for ``delta << R``.

    Uses the cancellation-free closed forms of :mod:`twoscale.analytic.hertz`
    (``sphere_*_from_radius``), so that the law and its inverse agree to ~1e-15
    relative even for ``delta/R ~ 1e-7``.

    Parameters
    ----------
    R : float or array
        Sphere radius, mm (> 0).
    E_star : float or array
        Plane-strain modulus of the body, MPa (> 0).
    """

    def force(self, delta):
        return _sphere_load(self.R, self._radius_from_penetration(as_penetration(delta)), self.E_star)

    def stiffness(self, delta):
        return 2.0 * self.E_star * self._radius_from_penetration(as_penetration(delta))

    def penetration(self, P):
        return _sphere_penetration(self.R, self._radius_from_load(as_force(P)))

    def complementary_energy(self, P):
        """``int_0^P delta = E* [a delta^2 - R^3 int_0^(a/R) u^2 atanh(u)^2 du]`` (N mm), by
        parts over the contact radius ``a`` (``dP/da = 2 E* a delta'(a)``): one inversion of
        the law instead of one per quadrature node of the generic rule (the macro step's
        safe path asks for it a thousand times: 1.7 s of a 3.3 s solve of four spheres).
        The integral by Gauss-Legendre on ``[0, a/R]``, smooth for ``a/R`` up to
        ``SPHERE_ENERGY_EDGE``; closer to the cap's edge (``delta`` near ``R``) the generic
        rule."""
        P = as_force(P)
        P, R, E = np.broadcast_arrays(P, np.asarray(self.R, dtype=float), np.asarray(self.E_star, dtype=float))
        a = self._radius_from_load(P)
        e = a / R
        u = 0.5 * np.multiply.outer(GAUSS_NODES + 1.0, e)
        tail = 0.5 * e * np.tensordot(GAUSS_WEIGHTS, u * u * np.arctanh(u) ** 2, axes=1)
        delta = a * np.arctanh(e)
        out = np.asarray(E * (a * delta * delta - R**3 * tail))
        edge = e > SPHERE_ENERGY_EDGE
        if np.any(edge):
            out[edge] = AsperityLaw.complementary_energy(SphereLaw(R[edge], E[edge]), P[edge])
        return out

    def _radius_from_penetration(self, delta: np.ndarray) -> np.ndarray:
        # Newton's method asks for the force and then the stiffness at the same penetrations:
        # the last inversion is kept (one entry; the law is otherwise immutable)
        return self._kept("_last_radius", np.maximum(delta, 0.0), self._invert_penetration)

    def _kept(self, name: str, x: np.ndarray, invert) -> np.ndarray:
        """``invert(x)``, kept for the next call with the same ``x`` (one entry under ``name``)."""
        last = self.__dict__.get(name)
        if last is not None and np.array_equal(last[0], x):
            return last[1].copy()
        a = invert(x)
        object.__setattr__(self, name, (np.array(x, copy=True), np.array(a, copy=True)))
        return a

    def _invert_penetration(self, d: np.ndarray) -> np.ndarray:
        # delta(a) is convex and above Hertz's a^2/R: Newton from sqrt(R delta) descends monotonically
        # (near the cap's edge from a = R tanh(1 + delta / R), above the root, as in
        # _radius_from_load)
        R = self.R
        a_max = (1.0 - 1e-15) * np.asarray(R)
        a = np.minimum(np.minimum(np.sqrt(R * d), a_max), R * np.tanh(1.0 + d / R))
        for _ in range(100):
            eps = a / R
            slope = np.arctanh(eps) + eps / (1.0 - eps * eps)
            step = np.where(a > 0, (_sphere_penetration(R, a) - d) / np.where(a > 0, slope, 1.0), 0.0)
            a = np.clip(a - step, 0.0, a_max)
            # quadratic convergence: the next step is ~1e-24 a; or held at the sphere's edge
            if np.all((np.abs(step) <= 1e-12 * a) | ((a >= a_max) & (step < 0))):
                break
        return a

    def _radius_from_load(self, P: np.ndarray) -> np.ndarray:
        # the macro step's safe path asks for the energy and then its gradient (the
        # penetration) at the same forces: the last inversion is kept, as by penetration
        return self._kept("_last_load_radius", P, self._invert_load)

    def _invert_load(self, P: np.ndarray) -> np.ndarray:
        # P(a) is convex and above Hertz's 4 E* a^3 / (3R): Newton from Hertz's radius
        # descends monotonically. Near the cap's edge (Hertz's radius about R) it starts
        # instead from a = R tanh(1 + P / (E* R^2)), also above the root, where P(a)'s slope
        # is finite (from the edge itself its first step was ~1e-14 a and read as converged,
        # leaving the radius at the edge for loads a cap of a/R ~ 0.95 carries)
        R, E = self.R, self.E_star
        a_max = (1.0 - 1e-15) * np.asarray(R)
        a = np.minimum((3.0 * P * R / (4.0 * E)) ** (1.0 / 3.0), a_max)
        a = np.minimum(a, R * np.tanh(1.0 + P / (E * R * R)))
        for _ in range(100):
            eps = a / R
            slope = 2.0 * E * a * (np.arctanh(eps) + eps / (1.0 - eps * eps))
            step = np.where(a > 0, (_sphere_load(R, a, E) - P) / np.where(a > 0, slope, 1.0), 0.0)
            a = np.clip(a - step, 0.0, a_max)
            # quadratic convergence: the next step is ~1e-24 a; or held at the sphere's edge
            # (a load past what the cap can carry, met by the macro step's safe path: 100
            # steps each time, 68 of a 70 s solve of four spheres)
            if np.all((np.abs(step) <= 1e-12 * a) | ((a >= a_max) & (step < 0))):
                break
        return a


# the contact radius over R up to which the sphere's energy is summed over the radius: the
# quadrature's error there is below 1e-10 (atanh's singularity at 1 is a tenth of the
# interval away)
SPHERE_ENERGY_EDGE = 0.9

# Segedin's closed forms, cancellation-free (twoscale.analytic.hertz)
_sphere_penetration = hertz.sphere_penetration_from_radius
_sphere_load = hertz.sphere_load_from_radius
