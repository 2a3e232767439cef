"""The cases of a rolling study, their keys, and the rolling scene each one rolls.

A case is one road section under one body of one material at one load and one speed. Its
key hashes its inputs (the strip's content and segmentation keys, the offset, the body and
its face, the material, the load, the run's start, end and step, the speed, the solver
options), never the names. An elastic body has no time: its positions do not depend on the
speed, so the cases that differ only by the speed share one *solve* (:func:`solve_key`),
rolled once and written at every speed (times and third-octave bands follow the speed).
A viscoelastic material's speeds are solves of their own.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from ..influence.cache import BoundedCache
from .keys import digest
from .rolling_spec import RollingStudy, Section

#: Bumped when a change of the rolling driver or of the stored record makes old results invalid.
ROLLING_KEY_VERSION = 1
#: Built strips a process keeps (each a segmented height map).
MAX_STRIPS = 4


@dataclass(frozen=True)
class RollingCase:
    """One case: ``ref`` = (section, body, material, load, speed) indices, what a task is sent."""

    section: Section
    body: Any
    material: Any
    load: tuple
    speed: float
    ref: tuple

    @property
    def label(self) -> str:
        kind, v = self.load
        load = f"W={v:g}N" if kind == "total" else f"d={v:g}mm"
        return f"{self.section.name} {self.body.name} {self.material.name} {load} {self.speed:g}km/h"

    @property
    def viscoelastic(self) -> bool:
        return bool(self.material.material.viscoelastic)


def case_at(study: RollingStudy, section: int, body: int, material: int, load: int, speed: int) -> RollingCase:
    """The case of ``study`` at these indices."""
    return RollingCase(
        study.sections[section],
        study.bodies[body],
        study.materials[material],
        study.loads[load],
        study.speeds[speed],
        (section, body, material, load, speed),
    )


def expand(study: RollingStudy) -> list[RollingCase]:
    """Every case: sections outermost, then bodies, materials, loads, speeds."""
    return [
        case_at(study, i, j, m, k, s)
        for i in range(len(study.sections))
        for j in range(len(study.bodies))
        for m in range(len(study.materials))
        for k in range(len(study.loads))
        for s in range(len(study.speeds))
    ]


def case_inputs(case: RollingCase, study: RollingStudy) -> dict:
    """Everything the case's files depend on, as JSON-ready data."""
    mat = case.material.material
    return {
        "key_version": ROLLING_KEY_VERSION,
        "kind": "rolling",
        "strip": case.section.strip_key,
        "offset_mm": case.section.offset,
        "influence": {k: (list(v) if isinstance(v, tuple) else v) for k, v in case.body.influence.items()},
        "face": {k: (list(v) if isinstance(v, (tuple, list)) else v) for k, v in case.body.face.items()},
        "material": {"E": mat.E, "nu": mat.nu, "prony": [list(b) for b in mat.prony]},
        "load": {case.load[0]: case.load[1]},
        "track": dict(study.track),
        "speed_kmh": case.speed,
        "solver": dict(sorted(study.solver.items())),
    }


def case_key(case: RollingCase, study: RollingStudy) -> str:
    return digest(case_inputs(case, study))


def solve_key(case: RollingCase, study: RollingStudy) -> str:
    """The key of the solve behind the case: the case's, less the speed on an elastic body."""
    inputs = case_inputs(case, study)
    if not case.viscoelastic:
        inputs.pop("speed_kmh")
    return digest(inputs)


def rolling_spec(case: RollingCase, study: RollingStudy, speed: float | None = None):
    """The case's ``[rolling]`` table: the study's run less the section's offset, the body's
    face, the case's speed (or ``speed``)."""
    from ..rolling.spec import RollingSpec

    t, o = study.track, case.section.offset
    return RollingSpec(
        start=t["start"] - o,
        end=t["end"] - o,
        step=t["step"],
        speed=case.speed if speed is None else speed,
        **case.body.face,
    )


class StripCache:
    """The strips (segmented height maps) one process has built, by section strip key."""

    def __init__(self, max_strips: int = MAX_STRIPS):
        self._cache = BoundedCache(max_strips, name="study strips")

    def get(self, section: Section):
        surface = self._cache.get(section.strip_key)
        if surface is None:
            surface = self._cache.put(section.strip_key, build_strip(section), 1)
        return surface


def build_strip(section: Section):
    """Read (or generate) and segment the section's strip: a
    :class:`~twoscale.surface.measured.MeasuredSurface`."""
    if section.generate is None:
        from ..surface.scene_table import surface_from_table

        return surface_from_table(section.surface, base_dir=section.base)
    from ..rolling.strip import road_strip
    from ..surface.measured import SurfaceOptions, build_surface
    from ..surface.reading import RawMap

    g = section.generate
    heights = road_strip(g["length"], g["width"], g["h"], seed=g["seed"])
    options = SurfaceOptions(**{k: v for k, v in section.surface.items() if k != "law_cache"})
    return build_surface(RawMap(heights, spacing=g["h"], units="mm"), options)


def case_scene(case: RollingCase, study: RollingStudy, strips: StripCache):
    """The rolling scene of ``case`` (the strip from ``strips``)."""
    from ..scene import Scene

    kind, value = case.load
    load = {"total_load": value} if kind == "total" else {"penetration": value}
    return Scene(
        material=case.material.material,
        surface=strips.get(case.section),
        rolling=rolling_spec(case, study),
        influence=dict(case.body.influence),
        **load,
    )


def with_speed(scene, speed: float):
    """``scene`` rolled at ``speed`` km/h instead."""
    return dataclasses.replace(scene, rolling=dataclasses.replace(scene.rolling, speed=speed))
