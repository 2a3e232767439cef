"""The asperity-law contract: load against penetration of one asperity alone.

A law maps the local penetration ``delta`` (mm) of one asperity, pressed alone into
the body, to the force ``P`` (N) it carries (docs/method.md section 2, the ``f_k`` of
``P_k = f_k(delta_k) H(delta_k)``). Laws are monotone: ``force`` is non-decreasing,
zero with zero stiffness for ``delta <= 0``, and ``penetration`` is its inverse on
``P >= 0``. All methods are vectorised over numpy arrays.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import math

import numpy as np


class AsperityLaw(ABC):
    """Load-penetration law of one asperity; see the module docstring."""

    @abstractmethod
    def force(self, delta) -> np.ndarray:
        """Force ``P`` (N) at local penetration ``delta`` (mm); 0 for delta <= 0."""

    @abstractmethod
    def stiffness(self, delta) -> np.ndarray:
        """Tangent stiffness ``dP/ddelta`` (N/mm) at ``delta`` (mm); 0 for delta <= 0."""

    @abstractmethod
    def penetration(self, P) -> np.ndarray:
        """Inverse law: penetration ``delta`` (mm) carrying force ``P >= 0`` (N).

        Raises
        ------
        ValueError
            If any ``P`` is negative or not finite.
        """

    def complementary_energy(self, P) -> np.ndarray:
        """``Phi(P) = int_0^P delta(s) ds`` (N mm), the complementary energy of the
        asperity at force ``P >= 0``; convex, ``Phi'(P) = penetration(P)``.

        Generic rule: Gauss-Legendre in ``t`` after ``s = P t^3`` (the substitution
        removes the ``s^(2/3)`` root of Hertz-like laws; exact for Hertz). Laws with a
        closed form override it.
        """
        P = as_force(P)
        total = np.zeros_like(P)
        for node, weight in zip(GAUSS_NODES, GAUSS_WEIGHTS):  # one call per node keeps P's shape
            t = 0.5 * (node + 1.0)
            total = total + 0.5 * weight * 3.0 * t * t * self.penetration(P * t**3)
        return P * total

    def __call__(self, delta) -> np.ndarray:
        return self.force(delta)


#: Gauss-Legendre nodes and weights on [-1, 1] of the laws' energy quadratures
GAUSS_NODES, GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)


def as_penetration(delta) -> np.ndarray:
    """``delta`` as a float array; raises ValueError on NaN."""
    d = np.asarray(delta, dtype=float)
    if np.any(np.isnan(d)):
        raise ValueError(f"penetration delta contains NaN: {d!r}")
    return d


def as_force(P) -> np.ndarray:
    """``P`` as a float array checked finite and >= 0 (N)."""
    p = np.asarray(P, dtype=float)
    if not np.all(np.isfinite(p)) or np.any(p < 0):
        raise ValueError(f"force P must be finite and >= 0 (N), got {p!r}")
    return p


def check_positive(name: str, value) -> None:
    """Raise ValueError unless ``value`` (scalar or array) is finite and > 0."""
    if type(value) is float and 0.0 < value < math.inf:  # a tip's law is made per tip: no array for a float
        return
    v = np.asarray(value, dtype=float)
    if v.size == 0 or not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
