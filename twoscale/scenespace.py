"""The scene space users live in: seeded random scenes over every axis a user varies.

A scene family samples a few corners; users meet everything in between. This module draws
plausible scenes at random (with a seed, so every draw can be rebuilt) over:

* the number of tips (1 to 10,000, log-uniform) and their layout: uniform at random (close
  pairs allowed: merged contacts), clustered, or a jittered square lattice;
* the density, from isolated tips to touching contacts (mean spacing over the expected
  contact diameter, log-uniform);
* the load per tip (1e-4 to 10 N, log-uniform; capped where a contact would pass 0.4 R),
  under load or penetration control, with the ball-and-socket tilt and a pivot off the
  centroid under load control;
* radii (0.5 to 20 mm, log-uniform median, uniform spread up to +-60 %), tip height
  spread (none to three times the expected approach), spheres or paraboloids;
* height maps instead of tips: synthetic roads, roads with a hole of missing samples, maps
  in um that say so;
* the body (half-space or the default finite block) and a cell size given or not.

:func:`draw` returns a :class:`SceneSpec`, plain data that prints as one line and
round-trips through JSON; :func:`build` makes the :class:`~twoscale.scene.Scene` (a height
map is written as ``.npz`` beside a scene table in a folder the caller gives, and read
back through the scene-file route a user takes). Units: mm, N, MPa.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass

import numpy as np

from .analytic import hertz
from .indenters import Asperity
from .material import Material
from .scene import BLOCK_DEFAULT_SIZE, Scene, _hertz_level

POSITION_LAYOUTS = ("uniform", "clustered", "lattice")
SCENE_KINDS = ("tips", "road", "road-hole", "road-um")
#: Largest contact radius over R a drawn load may reach (larger loads are capped).
MAX_A_OVER_R = 0.4
#: Side of the square the tips may occupy on the default block (its top face is 140 mm,
#: one 5 mm correction spacing inside each side, and room for the patches).
BLOCK_SIDE = 110.0
#: Largest square of tips drawn on the half-space, mm.
HALFSPACE_SIDE = 400.0


@dataclass(frozen=True)
class SceneSpec:
    """One drawn scene, as plain data (every field a number, string or bool).

    Attributes
    ----------
    index : int
        Its number in the draw (its own generator is seeded by the pair ``(seed, index)``).
    seed : int
        The sweep's seed.
    kind : {"tips", "road", "road-hole", "road-um"}
    n : int
        Tips (kind ``"tips"``); 0 for maps.
    layout : {"uniform", "clustered", "lattice"}
    spacing : float
        Mean distance between neighbouring tips over the expected contact diameter (< 1:
        contacts merge; > 10: isolated).
    load_per_tip : float
        Mean load per tip, N (maps: nominal pressure, MPa).
    control : {"load", "penetration"}
    tilt : bool
        Ball-and-socket joint, with a pivot off the centroid.
    radius : float
        Median tip radius, mm.
    radius_spread : float
        Radii uniform in ``radius * (1 +- radius_spread)``.
    height_spread : float
        Tip recesses uniform in ``[0, height_spread * expected approach]``.
    shape : {"sphere", "paraboloid"}
    body : {"halfspace", "block"}
    E : float
        Young's modulus, MPa.
    nu : float
    h_factor : float
        0: no ``h`` given (the default rule); else ``h`` = this times the default.
    size : float
        Side of the square of tips or of the map, mm.
    """

    index: int
    seed: int
    kind: str
    n: int
    layout: str
    spacing: float
    load_per_tip: float
    control: str
    tilt: bool
    radius: float
    radius_spread: float
    height_spread: float
    shape: str
    body: str
    E: float
    nu: float
    h_factor: float
    size: float

    @property
    def label(self) -> str:
        """One line naming the scene's axes."""
        if self.kind != "tips":
            return (
                f"#{self.index} {self.kind} {self.size:.0f} mm {self.load_per_tip:.3g} MPa {self.control}"
                f"{' h x' + format(self.h_factor, '.2g') if self.h_factor else ''} {self.body}"
            )
        return (
            f"#{self.index} {self.n} {self.shape}s {self.layout} s/2a {self.spacing:.3g} "
            f"{self.load_per_tip:.2g} N R {self.radius:.2g}+-{100 * self.radius_spread:.0f}% "
            f"dz {self.height_spread:.2g} {self.control}{' tilt' if self.tilt else ''}"
            f"{' h x' + format(self.h_factor, '.2g') if self.h_factor else ''} {self.body}"
        )

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _capped_load(load: float, R: float, E_star: float) -> float:
    """``load`` capped so that a lone tip's Hertz contact radius stays below MAX_A_OVER_R R."""
    a_max = MAX_A_OVER_R * R
    return min(load, 4.0 * E_star * a_max**3 / (3.0 * R))


def draw(index: int, seed: int = 0, *, max_tips: int = 10_000, maps: float = 0.12, block: float = 0.06) -> SceneSpec:
    """The ``index``-th scene of the sweep with ``seed`` (the same pair, the same scene).

    ``maps``: probability of a height map; ``block``: of the finite block body.
    """
    rng = np.random.default_rng([int(seed), int(index)])
    E = _loguniform(rng, 1.0, 100.0)
    nu = float(rng.choice([0.5, 0.5, 0.45, 0.3]))
    body = "block" if rng.uniform() < block else "halfspace"
    h_factor = 0.0 if rng.uniform() < 0.7 else float(rng.choice([0.5, 1.5, 3.0]))
    common = dict(index=index, seed=seed, h_factor=h_factor)
    if rng.uniform() < maps:
        return _map_spec(rng, body, **common)
    return _tips_spec(rng, body, E, nu, max_tips, **common)


def _map_spec(rng: np.random.Generator, body: str, **common) -> SceneSpec:
    """A height map's scene (a synthetic road, with a hole or in um) under a nominal pressure."""
    kind = str(rng.choice(SCENE_KINDS[1:]))
    size = float(rng.choice([30.0, 50.0, 70.0]))
    pressure = _loguniform(rng, 0.05, 0.5)
    return SceneSpec(
        kind=kind,
        n=0,
        layout="uniform",
        spacing=0.0,
        load_per_tip=pressure,
        control="load",
        tilt=False,
        radius=0.0,
        radius_spread=0.0,
        height_spread=0.0,
        shape="sphere",
        body=body if size <= BLOCK_SIDE else "halfspace",
        E=10.0,
        nu=0.5,
        size=size,
        **common,
    )


def _tips_spec(rng: np.random.Generator, body: str, E: float, nu: float, max_tips: int, **common) -> SceneSpec:
    """A scene of tips: their number, layout, radii, load, control, tilt and spread drawn."""
    n = int(round(_loguniform(rng, 1.0, max_tips + 0.49)))
    layout = str(rng.choice(POSITION_LAYOUTS, p=[0.6, 0.25, 0.15]))
    radius = _loguniform(rng, 0.5, 20.0)
    radius_spread = float(rng.uniform(0.0, 0.6))
    shape = str(rng.choice(["sphere", "paraboloid"]))
    E_star = E / (1.0 - nu**2)
    load = _capped_load(_loguniform(rng, 1e-4, 10.0), radius * (1.0 - radius_spread), E_star)
    control = str(rng.choice(["load", "penetration"]))
    tilt = bool(control == "load" and n >= 3 and rng.uniform() < 0.25)
    a = (3.0 * load * radius / (4.0 * E_star)) ** (1.0 / 3.0)
    spacing = _loguniform(rng, 0.7, 30.0)
    side = max(spacing * 2.0 * a * math.sqrt(n), 4.0 * a)
    if body == "block" and side > BLOCK_SIDE:
        body = "halfspace"
    delta = a * a / radius
    return SceneSpec(
        kind="tips",
        n=n,
        layout=layout,
        spacing=spacing,
        load_per_tip=load,
        control=control,
        tilt=tilt,
        radius=radius,
        radius_spread=radius_spread,
        height_spread=float(rng.choice([0.0, 0.3, 1.0, 3.0])),
        shape=shape,
        body=body,
        E=E,
        nu=nu,
        size=min(side, HALFSPACE_SIDE) if delta > 0 else side,
        **common,
    )


def _positions(spec: SceneSpec, rng: np.random.Generator) -> np.ndarray:
    n, L = spec.n, spec.size
    if spec.layout == "lattice":
        m = int(math.ceil(math.sqrt(n)))
        step = L / max(m, 1)
        g = (np.arange(m) - (m - 1) / 2.0) * step
        xy = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)[:n]
        return xy + rng.uniform(-0.1, 0.1, xy.shape) * step
    if spec.layout == "clustered":
        centres = rng.uniform(-L / 2, L / 2, (max(1, n // 20), 2))
        xy = centres[rng.integers(0, len(centres), n)] + rng.normal(0.0, L / 12.0, (n, 2))
        return np.clip(xy, -L / 2, L / 2)
    return rng.uniform(-L / 2, L / 2, (n, 2))


def _distinct(xy: np.ndarray, rng: np.random.Generator, eps: float) -> np.ndarray:
    """Nudge tips that fall on the same point (a scene refuses two tips at one (x, y))."""
    _, first = np.unique(np.round(xy / eps), axis=0, return_index=True)
    dup = np.setdiff1d(np.arange(len(xy)), first)
    xy[dup] += rng.uniform(eps, 2 * eps, (len(dup), 2))
    return xy


def _tip_scene(spec: SceneSpec) -> Scene:
    rng = np.random.default_rng([spec.seed, spec.index, 1])
    material = Material(spec.E, spec.nu)
    xy = _distinct(_positions(spec, rng), rng, 1e-3 * spec.radius)
    R = spec.radius * rng.uniform(1.0 - spec.radius_spread, 1.0 + spec.radius_spread, spec.n)
    delta = float(hertz.penetration(float(np.median(R)), spec.load_per_tip, material.E_star))
    z = rng.uniform(0.0, spec.height_spread * delta, spec.n)
    tips = tuple(Asperity(float(x), float(y), float(zk), float(rk), spec.shape) for (x, y), zk, rk in zip(xy, z, R))
    influence = {"kind": "block"} if spec.body == "block" else {"kind": "halfspace"}
    total = spec.load_per_tip * spec.n
    if spec.control == "load":
        pivot = (float(xy[:, 0].mean() + 0.1 * spec.size), float(xy[:, 1].mean() - 0.05 * spec.size))
        return Scene(
            material,
            tips,
            total_load=total,
            tilt=spec.tilt,
            pivot=pivot if spec.tilt else (0.0, 0.0),
            influence=influence,
        )
    # the approach at which independent Hertz tips would carry the total
    loaded = Scene(material, tips, total_load=total, influence=influence)
    return Scene(material, tips, penetration=float(_hertz_level(loaded)), influence=influence)


def map_table(spec: SceneSpec, folder: str) -> dict:
    """Write the height map of ``spec`` (a map kind) into ``folder`` and return the scene
    table that reads it (``[grid] h`` included where ``spec`` scales the default h): what a
    user's scene file holds. Generating the texture is the sweep's work, not the solve's;
    reading the table (:func:`twoscale.io.scene_file.scene_from_dict`) is the solve's."""
    from .io.scene_file import scene_from_dict
    from .scene import default_h
    from .surface.texture import road

    spacing = 0.1
    z = road(spec.size, spacing, seed=spec.seed * 1009 + spec.index)
    surface = {"file": f"map{spec.index}.npz", "min_distance": 2.0, "prominence": 0.1}
    if spec.kind == "road-hole":
        n = z.shape[0]
        z = z.copy()
        z[n // 3 : n // 3 + 40, n // 2 : n // 2 + 40] = np.nan  # a 4 x 4 mm hole
    if spec.kind == "road-um":
        np.savez(os.path.join(folder, surface["file"]), heights=z * 1000.0, spacing=spacing, units="um")
    else:
        np.savez(os.path.join(folder, surface["file"]), heights=z, spacing=spacing)
    table: dict = {
        "material": {"E": spec.E, "nu": spec.nu},
        "load": {"total": spec.load_per_tip * spec.size**2},
        "surface": surface,
    }
    if spec.body == "block":
        table["influence"] = {"kind": "block"}
    if spec.h_factor:
        table["grid"] = {"h": float(f"{spec.h_factor * default_h(scene_from_dict(table, base_dir=folder)):.2g}")}
    return table


def build(spec: SceneSpec, folder: str | None = None) -> Scene:
    """The scene of ``spec`` (maps are written into ``folder``, which must exist)."""
    if spec.kind != "tips":
        from .io.scene_file import scene_from_dict

        if folder is None:
            raise ValueError(f"scene {spec.label} is a height map: give a folder to write it in")
        return scene_from_dict(map_table(spec, folder), base_dir=folder)
    scene = _tip_scene(spec)
    if spec.h_factor:
        from .scene import default_h

        scene = dataclasses.replace(scene, h=float(f"{spec.h_factor * default_h(scene):.2g}"))
    return scene


def sweep(count: int, seed: int = 0, **options) -> list[SceneSpec]:
    """The first ``count`` scenes of the sweep with ``seed`` (options of :func:`draw`)."""
    return [draw(i, seed, **options) for i in range(count)]


__all__ = ["SceneSpec", "draw", "build", "map_table", "sweep", "POSITION_LAYOUTS", "SCENE_KINDS", "BLOCK_DEFAULT_SIZE"]
