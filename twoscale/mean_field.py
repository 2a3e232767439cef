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
from .resolution import _hertz_level, expected_approaches
from .scene import Scene

#: Largest number of tips summed over as sources of the push (a random subset beyond it,
#: each weighted by the tips it stands for): 8,880 tips cost 0.06 s of CPU (0.48 s with
#: 1,000 sources, the cells counted the same within 1 % on the sweep's seed 7).
SOURCES = 256
#: Targets summed at a time (512 x 256 sources: 1 MB arrays, reused by the allocator; blocks
#: of 4,096 took 0.24 of 0.36 s on 8,807 tips in fresh pages' faults).
CHUNK = 512


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
        return alone_approaches(scene)
    return np.maximum(mean_field(scene).local, 0.0)


def alone_approaches(scene: Scene) -> np.ndarray:
    """:func:`~twoscale.resolution.expected_approaches`, kept with the scene (read-only), mm."""
    return _kept(scene, "_alone_approaches", lambda: expected_approaches(scene))


def _kept(scene: Scene, key: str, make) -> np.ndarray:
    """An array kept with the scene under ``key`` (not a field: equality and hash ignore
    it), made once by ``make()`` and read-only: every caller shares it."""
    kept = scene.__dict__.get(key)
    if kept is None:
        kept = np.asarray(make(), dtype=float)
        kept.flags.writeable = False
        scene.__dict__[key] = kept
    return kept


def mean_field(scene: Scene) -> MeanField:
    """The level and approaches with the neighbours' mean push, under either control (on
    one tip or a height map: without push). Kept with the scene."""
    kept = scene.__dict__.get("_mean_field")
    if kept is None:
        kept = _field(scene)
        scene.__dict__["_mean_field"] = kept  # not a field: equality and hash ignore it
    return kept


def _field(scene: Scene) -> MeanField:
    z = tip_arrays(scene).z
    pressed = scene.penetration is not None
    if len(z) < 2 or scene.surface is not None:
        d = float(scene.penetration) if pressed else _hertz_level(scene)
        return MeanField(d, d - z, d - z)
    if pressed:
        d = float(scene.penetration)
        return MeanField(d, d - z, _solve(scene))
    from scipy.optimize import brentq

    g = _push_per_newton(scene)
    R = tip_arrays(scene).R
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

    def make() -> np.ndarray:
        delta = pushed_approaches(scene) if pushed else alone_approaches(scene)
        R, kind = _radii_and_shapes(scene)  # resolution._contact_radii on the kept arrays
        return np.where(kind == 1, hertz.sphere_contact_radius(R, delta), hertz.contact_radius(R, delta))

    return _kept(scene, "_pushed_radii" if pushed else "_alone_radii", make)


def _solve(scene: Scene) -> np.ndarray:
    """Each tip's approach with the push under penetration control, mm (negative: out of
    contact; without push where there is none to take)."""
    alone = alone_approaches(scene)
    if scene.penetration is None or len(alone) < 2 or scene.surface is not None:
        return alone
    from scipy.optimize import brentq

    g = _push_per_newton(scene)
    R = tip_arrays(scene).R
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
    tips = tip_arrays(scene).tips
    a = pushed_contact_radii(scene, pushed=False)
    n = len(tips)
    pick = np.arange(n) if n <= SOURCES else np.sort(np.random.default_rng(0).choice(n, SOURCES, replace=False))
    g = np.zeros(n)
    sx, sy, sa = tips[pick, 0], tips[pick, 1], a[pick]
    r, dx = np.empty((CHUNK, len(pick))), np.empty((CHUNK, len(pick)))  # reused: no fresh pages a block
    for start in range(0, n, CHUNK):
        stop = min(start + CHUNK, n)
        m = stop - start
        rr, d = r[:m], dx[:m]
        np.subtract(tips[start:stop, 0, None], sx, out=d)
        np.subtract(tips[start:stop, 1, None], sy, out=rr)
        np.multiply(rr, rr, out=rr)
        np.multiply(d, d, out=d)
        np.add(rr, d, out=rr)
        np.add(a[start:stop, None], sa, out=d)  # the contacts' radii: no closer than their sum
        np.multiply(d, d, out=d)
        np.maximum(rr, d, out=rr)
        with np.errstate(divide="ignore"):
            np.sqrt(np.reciprocal(rr, out=rr), out=rr)
        rr[rr == np.inf] = 0.0  # two tips at one point without contact
        mine = np.flatnonzero((pick >= start) & (pick < stop))
        rr[pick[mine] - start, mine] = 0.0  # not a tip's own force
        g[start:stop] = rr.sum(axis=1)
    return g * (n / len(pick)) / (np.pi * scene.material.E_star)


def reaches(scene: Scene, depth: np.ndarray) -> np.ndarray:
    """Each asperity's :meth:`~twoscale.indenters.Asperity.reach` at ``depth`` (mm, (N,)),
    for all at once: a paraboloid's ``sqrt(2 R depth)``, a sphere's cap radius (``R`` from
    ``depth >= R``); other shapes ask their asperity. 0 where ``depth <= 0``. mm."""
    depth = np.asarray(depth, dtype=float)
    R, kind = _radii_and_shapes(scene)
    d = np.maximum(depth, 0.0)
    cap = np.minimum(d, R)
    out = np.where(kind == 1, np.sqrt(cap * (2.0 * R - cap)), np.sqrt(2.0 * R * d))
    for k in np.flatnonzero(kind == 2):  # neither: its own rule
        out[k] = scene.asperities[k].reach(float(depth[k]))
    return np.where(depth > 0, out, 0.0)


def _radii_and_shapes(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Tip radii (mm) and shapes (0 paraboloid, 1 sphere, 2 other)."""
    kept = tip_arrays(scene)
    return kept.R, kept.kind


@dataclass(frozen=True)
class TipArrays:
    """The scene's tips as arrays, kept with it (:func:`tip_arrays`): ``tips`` (N, 2)
    positions, ``z`` heights and ``R`` radii, mm; ``kind`` 0 paraboloid, 1 sphere, 2 other."""

    tips: np.ndarray
    z: np.ndarray
    R: np.ndarray
    kind: np.ndarray


def tip_arrays(scene: Scene) -> TipArrays:
    """The scene's tips as arrays, built once and kept with the scene (not a field:
    equality and hash ignore it); the estimate reads them a few times on up to 10^4 tips."""
    kept = scene.__dict__.get("_tip_arrays")
    if kept is None:
        asp = scene.asperities
        get = lambda f: np.fromiter((getattr(a, f) for a in asp), dtype=float, count=len(asp))  # noqa: E731
        codes = {"paraboloid": 0, "sphere": 1}
        kind = np.fromiter((codes.get(a.shape, 2) for a in asp), dtype=np.int8, count=len(asp))
        kept = TipArrays(np.column_stack([get("x"), get("y")]), get("z"), get("R"), kind)
        for a in (kept.tips, kept.z, kept.R, kept.kind):
            a.flags.writeable = False  # shared by every caller
        scene.__dict__["_tip_arrays"] = kept
    return kept
