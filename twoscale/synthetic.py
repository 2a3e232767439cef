"""Seeded random scenes of many asperities, as users have them (tyre/road texture).

:func:`random_scene` returns a plain :class:`twoscale.scene.Scene`; the same arguments
(seed included) always give the same scene. Two kinds:

``"dense"``
    Every tip touches: R uniform in 3-6 mm, tip recesses z uniform in [0, 0.1] mm, about
    200 tips on 60 x 60 mm (side ``L = 60 sqrt(n / 200)`` mm), E = 6 MPa, nu = 0.5,
    2.5 N per tip (the middle of the 2-3 N of a tyre tread on a road; the first dense user
    scene had 1.5 N: ``load_per_tip``).
``"sparse"``
    The many-asperity layout (``benchmarks/many_asperities.py``): R uniform in
    2-6 mm, side ``3 sqrt(n)`` mm, E = 10 MPa, nu = 0.5, h = 0.04 mm (mean R / 100),
    0.05 N per tip, and the recesses spread so that a fraction ``touching`` (30 %) of
    the tips are reached at the approach where independent Hertz asperities carry the
    load.

Tips are uniform on the square ``[-L/2, L/2]^2`` centred on the origin (the centre of
the block's top face with ``body="block"``), none closer than ``MIN_SPACING`` to
another. Under penetration control the approach is the one at which independent Hertz
paraboloids (no interaction) carry ``n * load_per_tip``; interaction lowers the load
actually carried. Units: mm, N, MPa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from .analytic import hertz
from .indenters import SHAPES, Asperity
from .material import Material
from .options import settings_from
from .scene import BLOCK_DEFAULT_SIZE, Scene, _hertz_level

FAMILY_KINDS = ("dense", "sparse")
CONTROLS = ("load", "penetration")
BODY_KINDS = ("halfspace", "block")
#: Smallest distance between two tips, mm.
MIN_SPACING = 1.5
#: Largest side of the square of tips on the default block, mm (its top face is 140 mm).
BLOCK_MAX_SIDE = 120.0
#: Default load per tip by kind, N.
LOAD_PER_TIP = {"dense": 2.5, "sparse": 0.05}
#: Material by kind: (E MPa, nu).
MATERIALS = {"dense": (6.0, 0.5), "sparse": (10.0, 0.5)}
#: Tip radii by kind: uniform in (low, high), mm.
RADII = {"dense": (3.0, 6.0), "sparse": (2.0, 6.0)}
#: Dense kind: tip recesses uniform in [0, DENSE_SPREAD] mm.
DENSE_SPREAD = 0.1
#: Sparse kind: cell size, mm (mean R / 100, as the many-asperity benchmark).
SPARSE_H = 0.04


def square_side(n_tips: int, kind: str) -> float:
    """Side of the square of tips, mm: ``60 sqrt(n / 200)`` (dense), ``3 sqrt(n)`` (sparse)."""
    return 60.0 * math.sqrt(n_tips / 200.0) if kind == "dense" else 3.0 * math.sqrt(n_tips)


@dataclass(frozen=True)
class Variation:
    """The rarer settings of :func:`random_scene` (its keywords ``load_per_tip``,
    ``touching`` and ``side``, documented there)."""

    load_per_tip: float | None = None
    touching: float = 0.3
    side: float | None = None


def random_scene(
    n_tips: int,
    *,
    kind: str = "dense",
    control: str = "load",
    shape: str = "sphere",
    body: str = "halfspace",
    seed: int = 0,
    h: float | None = None,
    **variation,
) -> Scene:
    """A seeded random scene of ``n_tips`` rigid asperities.

    Parameters
    ----------
    n_tips : int
        Number of asperities (>= 1).
    kind : {"dense", "sparse"}, default "dense"
        The family member (module docstring): every tip touches, or about ``touching``
        of them.
    control : {"load", "penetration"}, default "load"
        Load control, total ``n_tips * load_per_tip`` N; or penetration control at the
        approach (mm) where independent Hertz asperities carry that load.
    shape : {"sphere", "paraboloid"}, default "sphere"
        Shape of every tip.
    body : {"halfspace", "block"}, default "halfspace"
        The elastic half-space, or the default 140 x 140 x 20 mm bonded block (needs
        ``fem_influence`` to solve); the square of tips must fit in ``BLOCK_MAX_SIDE``.
    seed : int, default 0
        Seed of :func:`numpy.random.default_rng`.
    h : float, optional
        Cell size, mm (> 0). None: the kind's default (dense: chosen by
        :func:`twoscale.scene.default_h`; sparse: ``SPARSE_H``).
    **variation
        ``load_per_tip``, ``side``, ``touching`` (below; :class:`Variation`); another
        keyword is refused by name.
    load_per_tip : float, optional
        Load per tip, N (> 0); None: 2.5 (dense) or 0.05 (sparse).
    side : float, optional
        Side of the square of tips, mm (> 0); default :func:`square_side` (the kind's
        density).
    touching : float, default 0.3
        Sparse kind: fraction of the tips reached (0 < touching <= 1); the lowest
        ``round(touching * n_tips)`` tips (at least one) touch by independent Hertz.

    Returns
    -------
    Scene

    Raises
    ------
    ValueError
        Naming the bad argument and its value (also when the tips do not fit on the block
        or cannot be placed ``MIN_SPACING`` apart).
    """
    v = settings_from(Variation, variation, "random_scene")
    load_per_tip, touching, side = v.load_per_tip, v.touching, v.side
    if isinstance(n_tips, bool) or not isinstance(n_tips, (int, np.integer)) or n_tips < 1:
        raise ValueError(f"n_tips must be an integer >= 1, got {n_tips!r}")
    for name, value, allowed in (
        ("kind", kind, FAMILY_KINDS),
        ("control", control, CONTROLS),
        ("shape", shape, SHAPES),
        ("body", body, BODY_KINDS),
    ):
        if value not in allowed:
            raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    h = _check_positive("h", h, allow_none=True)
    load_per_tip = LOAD_PER_TIP[kind] if load_per_tip is None else _check_positive("load_per_tip", load_per_tip)
    if (
        isinstance(touching, bool)
        or not isinstance(touching, (int, float, np.integer, np.floating))
        or not 0 < touching <= 1
    ):
        raise ValueError(f"touching must be a number in (0, 1], got {touching!r}")
    n = int(n_tips)
    side = square_side(n, kind) if side is None else _check_positive("side", side)
    if body == "block" and side > BLOCK_MAX_SIDE:
        most = _most_tips(kind)
        raise ValueError(
            f"n_tips = {n} needs a square of side {side:.1f} mm, larger than the "
            f"{BLOCK_MAX_SIDE:g} mm that fit on the default block's top face "
            f"({BLOCK_DEFAULT_SIZE[0]:g} mm); at most {most} tips for kind = {kind!r}"
        )
    rng = np.random.default_rng(int(seed))
    tips = spaced_points(rng, n, side)
    R = rng.uniform(*RADII[kind], size=n)
    total = n * load_per_tip
    E, nu = MATERIALS[kind]
    material = Material(E, nu)
    if kind == "dense":
        z = rng.uniform(0.0, DENSE_SPREAD, size=n)
    else:
        z = sparse_recesses(rng.uniform(0.0, 1.0, size=n), R, total, material.E_star, touching)
        h = SPARSE_H if h is None else h
    asperities = tuple(Asperity(float(x), float(y), float(zk), float(rk), shape) for (x, y), zk, rk in zip(tips, z, R))
    influence = {"kind": "block"} if body == "block" else {"kind": "halfspace"}
    loaded = Scene(material, asperities, total_load=total, h=h, influence=influence)
    if control == "load":
        return loaded
    return Scene(material, asperities, penetration=_hertz_level(loaded), h=h, influence=influence)


def _check_positive(name: str, value, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not math.isfinite(value)
        or not value > 0
    ):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _most_tips(kind: str) -> int:
    """Largest n whose square fits on the default block."""
    n = 1
    while square_side(n + 1, kind) <= BLOCK_MAX_SIDE:
        n += 1
    return n


def spaced_points(
    rng: np.random.Generator, n: int, side: float, *, min_spacing: float = MIN_SPACING, max_tries: int = 100
) -> np.ndarray:
    """``n`` points uniform on ``[-side/2, side/2]^2`` (mm), none closer than
    ``min_spacing`` to another (rejection; candidates drawn ``n`` at a time).

    Raises
    ------
    ValueError
        When ``max_tries * n`` candidates did not give ``n`` points (the square is too
        small for the spacing).
    """
    pts = np.empty((n, 2))
    cell = min_spacing  # bucket grid: a point's neighbours within min_spacing are in 3 x 3 buckets
    buckets: dict[tuple[int, int], list[int]] = {}
    count = 0
    for _ in range(max_tries):
        for c in rng.uniform(-side / 2, side / 2, size=(n, 2)):
            i, j = int(math.floor(c[0] / cell)), int(math.floor(c[1] / cell))
            near = [k for di in (-1, 0, 1) for dj in (-1, 0, 1) for k in buckets.get((i + di, j + dj), ())]
            if near and np.min(np.hypot(*(pts[near] - c).T)) < min_spacing:
                continue
            pts[count] = c
            buckets.setdefault((i, j), []).append(count)
            count += 1
            if count == n:
                return pts
    raise ValueError(
        f"min_spacing = {min_spacing!r} mm: could not place {n} tips on a square of "
        f"side {side:.3g} mm in {max_tries * n} tries"
    )


def sparse_recesses(u: np.ndarray, R: np.ndarray, total_load: float, E_star: float, touching: float) -> np.ndarray:
    """Tip recesses z = s u (mm) such that independent Hertz paraboloids carry
    ``total_load`` (N) at an approach d = s u* reaching exactly ``m = round(touching n)``
    tips (at least one): u* is halfway between the m-th and (m+1)-th smallest u.

    The Hertz load at d = s u* is ``s^1.5 sum_k P_H(R_k, u* - u_k)`` (homogeneous in
    s), so ``s`` follows in closed form.
    """
    n = len(u)
    m = min(max(int(round(touching * n)), 1), n)
    order = np.sort(u)
    u_star = 0.5 * (order[m - 1] + order[m]) if m < n else 1.0  # u < 1: every tip reached
    unit = float(np.sum(hertz.load(R, u_star - u, E_star)))
    s = (total_load / unit) ** (2.0 / 3.0)
    return s * u


def scene_family(
    sizes: Sequence[int] = (50, 200, 1000),
    *,
    kinds: Sequence[str] = FAMILY_KINDS,
    controls: Sequence[str] = CONTROLS,
    shapes: Sequence[str] = SHAPES,
    bodies: Sequence[str] = ("halfspace",),
    seed: int = 0,
) -> Iterator[tuple[str, Scene]]:
    """Yield ``(name, scene)`` for every combination of the arguments, sizes outermost.

    Names read ``"{kind}-{control}-{shape}-{body}-n{size}"``; the scenes are
    :func:`random_scene` with the given ``seed``. Built one at a time (a generator).
    """
    for n in sizes:
        for body in bodies:
            for kind in kinds:
                for control in controls:
                    for shape in shapes:
                        yield (
                            f"{kind}-{control}-{shape}-{body}-n{n}",
                            random_scene(n, kind=kind, control=control, shape=shape, body=body, seed=seed),
                        )
