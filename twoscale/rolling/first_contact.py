"""The first position's contact: the approach at which the stones, each a Hertz contact,
carry the load (the start of a run under load control), and the refusal of a run in which
nothing touches at its first position (a tyre radius or a window that leaves no contact)."""

from __future__ import annotations

import numpy as np

from ..analytic import hertz
from ..errors import SceneError
from .road import Road


def hertz_level(stones, E_star: float, load: float) -> float:
    """The approach (mm) at which the stones, each alone a Hertz contact of its radius,
    carry ``load`` N: a lower estimate of the real one (interaction asks for more)."""
    from scipy.optimize import brentq

    R = np.array([s.R for s in stones], dtype=float)
    z = np.array([s.z for s in stones], dtype=float)
    lo = float(z.min())
    hi = lo + float(hertz.penetration(R[np.argmin(z)], load, E_star)) + 1e-12

    def excess(d: float) -> float:
        return float(np.sum(hertz.load(R, np.maximum(d - z, 0.0), E_star))) - load

    return float(brentq(excess, lo, hi, xtol=1e-12))


def check_contact(road: Road, bound: float, shift: float) -> None:
    """Refuse a scene under penetration control in which nothing touches at the first
    position (a tyre radius or a window that leaves no contact)."""
    sel = road.stones_at(shift, bound)
    if len(sel.stones) == 0:
        if road.spec.tyre_radius is not None:
            raise SceneError(
                f"rolling.tyre_radius = {road.spec.tyre_radius!r} mm leaves no contact at the first "
                f"position (shift {shift:g} mm, approach {bound:g} mm below the road's highest point)"
            )
        raise SceneError(f"load.penetration = {bound!r} mm: nothing touches at the first position (shift {shift:g} mm)")
