"""A law given by a table, e.g. from single-asperity micro-scale solves.

Inside the table the force is the monotone piecewise-cubic Hermite interpolant
(PCHIP, Fritsch-Carlson): C1, monotone, no overshoot. Beyond the last point
``(delta_n, P_n)`` it continues as the power law ``P = P_n (delta / delta_n)^m``
with ``m = delta_n P'(delta_n) / P_n`` the local exponent of the interpolant there:
value and slope match (C1), it stays monotone, and it is exact for power laws such as
Hertz (``m = 3/2``) up to the accuracy of the end slope.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PchipInterpolator

from .base import AsperityLaw, as_force, as_penetration

_BISECTIONS = 60  # halves a table interval down to 2^-60 of its width: below double rounding


class TabulatedLaw(AsperityLaw):
    """Monotone tabulated load-penetration law; see the module docstring.

    Parameters
    ----------
    delta : (n,) array, mm
        Penetrations, strictly increasing, starting at 0, n >= 2.
    P : (n,) array, N
        Forces, strictly increasing, starting at 0.

    Raises
    ------
    ValueError
        If the table is not finite, not 1-D of equal lengths >= 2, does not start at
        (0, 0), is not strictly increasing, or its interpolant ends with zero slope
        (then no power-law continuation exists: extend the table).
    """

    def __init__(self, delta, P):
        d = np.array(delta, dtype=float)
        p = np.array(P, dtype=float)
        _validate_table(d, p)
        d.setflags(write=False)
        p.setflags(write=False)
        self.delta_table, self.P_table = d, p
        self._interp = PchipInterpolator(d, p, extrapolate=False)
        self._dinterp = self._interp.derivative()
        self._integral = self._interp.antiderivative()
        slope = float(self._dinterp(d[-1]))
        self.exponent = d[-1] * slope / p[-1]
        if not self.exponent > 0:
            raise ValueError(
                f"tabulated law ends with slope {slope!r} N/mm at delta={d[-1]!r}: "
                "no monotone continuation; extend the table"
            )

    def force(self, delta):
        d = as_penetration(delta)
        dn, pn, m = self.delta_table[-1], self.P_table[-1], self.exponent
        inside = np.clip(d, 0.0, dn)
        out = np.where(d > dn, pn * (np.maximum(d, dn) / dn) ** m, self._interp(inside))
        return np.where(d > 0, out, 0.0)

    def stiffness(self, delta):
        d = as_penetration(delta)
        dn, pn, m = self.delta_table[-1], self.P_table[-1], self.exponent
        inside = np.clip(d, 0.0, dn)
        beyond = m * pn / dn * (np.maximum(d, dn) / dn) ** (m - 1.0)
        out = np.where(d > dn, beyond, self._dinterp(inside))
        return np.where(d > 0, out, 0.0)

    def penetration(self, P):
        p = as_force(P)
        dn, pn, m = self.delta_table[-1], self.P_table[-1], self.exponent
        beyond = dn * (np.maximum(p, pn) / pn) ** (1.0 / m)
        return np.where(p > pn, beyond, self._invert_inside(np.minimum(p, pn)))

    def work(self, delta) -> np.ndarray:
        """``int_0^delta P`` (N mm), exact for the interpolant and its continuation."""
        d = np.maximum(as_penetration(delta), 0.0)
        dn, pn, m = self.delta_table[-1], self.P_table[-1], self.exponent
        inside = self._integral(np.minimum(d, dn))
        tail = pn * dn / (m + 1.0) * ((np.maximum(d, dn) / dn) ** (m + 1.0) - 1.0)
        return inside + tail

    def complementary_energy(self, P):
        """``P delta(P) - int_0^delta(P) P`` (N mm) (Legendre transform of :meth:`work`)."""
        P = as_force(P)
        d = self.penetration(P)
        return P * d - self.work(d)

    def _invert_inside(self, p: np.ndarray) -> np.ndarray:
        # The interpolant is monotone on each table interval: locate the interval,
        # then bisect there (vectorised).
        d, P = self.delta_table, self.P_table
        i = np.clip(np.searchsorted(P, p, side="right") - 1, 0, len(P) - 2)
        lo, hi = d[i], d[i + 1]
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            below = self._interp(mid) < p
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        return np.where(p > 0, 0.5 * (lo + hi), 0.0)


def _validate_table(d: np.ndarray, p: np.ndarray) -> None:
    if d.ndim != 1 or p.ndim != 1 or d.shape != p.shape or d.size < 2:
        raise ValueError(
            f"tabulated law needs 1-D delta and P of equal length >= 2, got shapes {d.shape} and {p.shape}"
        )
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(p))):
        raise ValueError(f"tabulated law has non-finite entries: delta={d!r}, P={p!r}")
    if d[0] != 0.0 or p[0] != 0.0:
        raise ValueError(f"tabulated law must start at (0, 0), got ({d[0]!r}, {p[0]!r})")
    bad = np.flatnonzero(np.diff(d) <= 0)
    if bad.size:
        raise ValueError(
            f"tabulated delta must be strictly increasing, fails at index {bad[0] + 1}: "
            f"{d[bad[0]]!r} -> {d[bad[0] + 1]!r}"
        )
    bad = np.flatnonzero(np.diff(p) <= 0)
    if bad.size:
        raise ValueError(
            f"tabulated P must be strictly increasing, fails at index {bad[0] + 1}: {p[bad[0]]!r} -> {p[bad[0] + 1]!r}"
        )
