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
(:func:`twoscale.resolution.expected_approaches`); the level a macro step reaches there,
which sizes the patches when it stalls (:mod:`twoscale.memory_stall`), is found with the
same push: each tip carries ``F = W / N`` on average and the level solves
``sum_k P_H(R_k, d - z_k - g_k F) = W`` (:func:`mean_field`). Units: mm, N, MPa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .analytic import hertz
from .resolution import _contact_radii, _hertz_level, expected_approaches, expected_contact_radii
from .scene import Scene

#: Largest number of tips summed over as sources of the push (a random subset beyond it,
#: each weighted by the tips it stands for): 8,880 tips cost 0.06 s of CPU (0.48 s with
#: 1,000 sources, the cells counted the same within 1 % on the sweep's seed 7).
SOURCES = 256


@dataclass(frozen=True)
class MeanField:
    """The rigid level and each tip's approaches under its neighbours' mean push.

    Attributes
    ----------
    level : float
        Rigid approach d, mm: the given penetration, or under load control the level at
        which the pushed tips carry the load.
    geometric : (N,) array
        ``d - z_k``, mm (negative: the tip is above the level).
    local : (N,) array
        ``d - z_k - u_k``, mm, the push ``u_k`` taken off (negative: out of contact).
    """

    level: float
    geometric: np.ndarray
    local: np.ndarray


def pushed_approaches(scene: Scene) -> np.ndarray:
    """Each tip's approach with the mean push of its neighbours, mm (N,): under penetration
    control the :func:`mean_field`'s local approaches (kept with the scene), under load
    control the approaches without interaction
    (:func:`~twoscale.resolution.expected_approaches`)."""
    if scene.penetration is None:
        return expected_approaches(scene)
    return np.maximum(mean_field(scene).local, 0.0)


def mean_field(scene: Scene) -> MeanField:
    """The level and approaches with the neighbours' mean push, under either control (on
    one tip or a height map: without push). Kept with the scene."""
    kept = scene.__dict__.get("_mean_field")
    if kept is None:
        kept = _field(scene)
        scene.__dict__["_mean_field"] = kept  # not a field: equality and hash ignore it
    return kept


def _field(scene: Scene) -> MeanField:
    z = np.array([a.z for a in scene.asperities], dtype=float)
    pressed = scene.penetration is not None
    if len(z) < 2 or scene.surface is not None:
        d = float(scene.penetration) if pressed else _hertz_level(scene)
        return MeanField(d, d - z, d - z)
    if pressed:
        d = float(scene.penetration)
        return MeanField(d, d - z, _solve(scene))
    from scipy.optimize import brentq

    g = _push_per_newton(scene)
    R = np.array([a.R for a in scene.asperities], dtype=float)
    E_star, W = scene.material.E_star, float(scene.total_load)
    lift = g * (W / len(z)) if np.all(np.isfinite(g)) else np.zeros_like(z)
    alone = _hertz_level(scene)  # the push only lowers the approaches: the level rises from here

    def excess(d: float) -> float:
        return float(np.sum(hertz.load(R, d - z - lift, E_star))) - W

    top = alone + float(lift.max()) * (1.0 + 1e-9) + 1e-300  # every tip at least as deep as alone
    d = alone if not excess(alone) < 0 else brentq(excess, alone, top, xtol=1e-12 * max(abs(top), 1e-300))
    return MeanField(float(d), d - z, d - z - lift)


def pushed_contact_radii(scene: Scene, pushed: bool = True) -> np.ndarray:
    """Contact radius (mm) of each asperity at its :func:`pushed_approaches` (``pushed=False``:
    alone, :func:`~twoscale.resolution.expected_contact_radii`)."""
    if not pushed:
        return expected_contact_radii(scene)
    return _contact_radii(scene.asperities, pushed_approaches(scene))


def _solve(scene: Scene) -> np.ndarray:
    """Each tip's approach with the push under penetration control, mm (negative: out of
    contact; without push where there is none to take)."""
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
    return alone - g * F


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
