"""Each tip's approach under penetration control with its neighbours' push, estimated
before solving: a mean field of the macro step's point forces (no grid, no solve).

Under a given penetration ``d`` a tip alone would sink ``d - z_k``; its neighbours' forces
lift the surface around it by ``u_k = sum_l F_l / (pi E* r_kl)`` (Boussinesq), so it sinks
``d - z_k - u_k`` and its contact is smaller: 300-9,000 tips on the sweep's scenes carried
0.2-0.4 of the cells counted without it. Here every neighbour is taken to carry the mean
force ``F`` (so ``u_k = g_k F`` with ``g_k = sum_l 1 / (pi E* max(r_kl, a_k + a_l))``, the
contact radii ``a`` those of the tips alone), and ``F`` solves
``F = mean_l P_H(R_l, d - z_l - g_l F)`` (Hertz). The sums ``g_k`` take at most
:data:`SOURCES` sources, each weighted by the tips it stands for. Under load control the
total is given and the approach found without interaction already spreads it
(:func:`twoscale.resolution.expected_approaches`). Units: mm, N, MPa.
"""

from __future__ import annotations

import numpy as np

from .analytic import hertz
from .resolution import _contact_radii, expected_approaches, expected_contact_radii
from .scene import Scene

#: Largest number of tips summed over as sources of the push (a random subset beyond it,
#: each weighted by the tips it stands for): 8,880 tips cost 0.06 s of CPU (0.48 s with
#: 1,000 sources, the cells counted the same within 1 % on the sweep's seed 7).
SOURCES = 256


def pushed_approaches(scene: Scene) -> np.ndarray:
    """Each tip's approach with the mean push of its neighbours, mm (N,): under load
    control, or on one tip, the approaches without interaction
    (:func:`~twoscale.resolution.expected_approaches`). Kept with the scene (a pure function
    of it, asked for at every cell size an advice tries)."""
    kept = scene.__dict__.get("_pushed_approaches")
    if kept is None:
        kept = _solve(scene)
        scene.__dict__["_pushed_approaches"] = kept  # not a field: equality and hash ignore it
    return kept


def pushed_contact_radii(scene: Scene, pushed: bool = True) -> np.ndarray:
    """Contact radius (mm) of each asperity at its :func:`pushed_approaches` (``pushed=False``:
    alone, :func:`~twoscale.resolution.expected_contact_radii`)."""
    if not pushed:
        return expected_contact_radii(scene)
    return _contact_radii(scene.asperities, pushed_approaches(scene))


def _solve(scene: Scene) -> np.ndarray:
    alone = expected_approaches(scene)
    if scene.penetration is None or len(alone) < 2 or scene.surface is not None:
        return alone
    from scipy.optimize import brentq

    g = _push_per_newton(scene)
    R = np.array([a.R for a in scene.asperities], dtype=float)
    E_star = scene.material.E_star

    def excess(F: float) -> float:
        return float(np.mean(hertz.load(R, alone - g * F, E_star))) - F

    top = float(np.mean(hertz.load(R, alone, E_star)))
    if not top > 0 or not np.all(np.isfinite(g)):
        return alone
    F = brentq(excess, 0.0, top, xtol=1e-12 * top)
    return np.maximum(alone - g * F, 0.0)


def _push_per_newton(scene: Scene) -> np.ndarray:
    """``g_k``, mm/N: the lift at tip ``k`` from a unit force at every other tip."""
    tips = np.array([[a.x, a.y] for a in scene.asperities], dtype=float)
    a = expected_contact_radii(scene)
    n = len(tips)
    pick = np.arange(n) if n <= SOURCES else np.sort(np.random.default_rng(0).choice(n, SOURCES, replace=False))
    g = np.zeros(n)
    for start in range(0, n, 4096):  # 4,096 targets at a time: 8 MB of distances
        k = np.arange(start, min(start + 4096, n))
        r = np.hypot(np.subtract.outer(tips[k, 0], tips[pick, 0]), np.subtract.outer(tips[k, 1], tips[pick, 1]))
        np.maximum(r, a[k, None] + a[None, pick], out=r)
        with np.errstate(divide="ignore"):
            inv = np.reciprocal(r, out=r)
        inv[~np.isfinite(inv)] = 0.0  # two tips at one point without contact
        mine = np.flatnonzero((pick >= start) & (pick < start + len(k)))
        inv[pick[mine] - start, mine] = 0.0  # not a tip's own force
        g[k] = inv.sum(axis=1)
    return g * (n / len(pick)) / (np.pi * scene.material.E_star)
