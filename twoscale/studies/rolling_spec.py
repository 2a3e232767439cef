"""A rolling study: what a study file with a ``[rolling]`` table asks for, as plain
validated data.

Cases are road sections x bodies x materials x loads x speeds (sections outermost, speeds
innermost). The format (units mm, N, MPa, km/h)::

    [study]       name (default: the file's stem); figures = true | false (each case's PNGs)
    [[section]]   name; the road: surface = {...} (a scene's [surface] table, its file relative
                  to the study file) or generate = {length, width, h, seed} (a seeded chip
                  seal, twoscale.rolling.road_strip; surface = {...} then holds only the
                  segmentation keys); offsets = [o, ...] mm (the run starts o mm further
                  along the strip: one section per offset, default [0]); seeds = [s, ...]
                  instead of generate.seed (one section per seed)
    [[body]]      name; kind = "halfspace" | "block" (size = [Lx, Ly, t], base, origin as a
                  scene's [influence]); the tyre's face: tyre_radius, tyre_shape, footprint
                  (as in a scene's [rolling] table)
    [[material]]  name; E, nu, prony = [[E_k, tau_k], ...] (as a scene's [material])
    [rolling]     start, end, step (mm; relative to each section), speeds = [v, ...] km/h
                  (or speed = v)
    [load]        total = [W, ...] (N, held) or penetration = [d, ...] (mm, held)
    [solver]      tol, iteration (each position's two-scale solve)

Every problem raises :class:`~twoscale.errors.StudyError` with one line naming the key and
the value; nothing is solved to find it (the strips are read and segmented by the cases).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from ..errors import StudyError
from ..io.scene_file import check_keys, field_path, table_of
from ..scene import BLOCK_BASES, SceneError, check_number, check_pair
from .keys import digest
from .checks import name as _name, tables as _tables

TOP_KEYS = ("study", "section", "body", "material", "rolling", "load", "solver")
BODY_KEYS = ("name", "kind", "size", "base", "origin", "tyre_radius", "tyre_shape", "footprint")
FACE_KEYS = ("tyre_radius", "tyre_shape", "footprint")
GENERATE_KEYS = ("length", "width", "h", "seed")
#: Largest number of cases a rolling study may expand to.
MAX_CASES = 100_000


@dataclass(frozen=True)
class Section:
    """A road section: the strip (a ``[surface]`` table, or a generated chip seal) and how far
    along it the run starts (``offset`` mm: the shifts are the ``[rolling]`` ones less it)."""

    name: str
    surface: dict
    generate: dict | None
    offset: float
    base: str
    digest: str

    @property
    def strip_key(self) -> str:
        """The strip's identity (content and segmentation), shared by its offsets."""
        return digest({"strip": self.digest, "surface": self.surface, "generate": self.generate})


@dataclass(frozen=True)
class RollingBody:
    """A body: a scene's ``[influence]`` table and the face of ``[rolling]`` (tyre, footprint)."""

    name: str
    influence: dict
    face: dict


@dataclass(frozen=True)
class StudyMaterial:
    name: str
    material: Any


@dataclass(frozen=True)
class RollingStudy:
    """A validated rolling study file (module docstring)."""

    name: str
    sections: tuple
    bodies: tuple
    materials: tuple
    loads: tuple
    speeds: tuple
    track: dict
    solver: dict = field(default_factory=dict)
    figures: bool = True
    source: str = ""

    @property
    def n_cases(self) -> int:
        return len(self.sections) * len(self.bodies) * len(self.materials) * len(self.loads) * len(self.speeds)


def is_rolling_study(data: Mapping) -> bool:
    """Whether parsed study TOML is a rolling study (it has a ``[rolling]`` table)."""
    return "rolling" in data


def rolling_study_from_dict(
    data: Mapping, *, base: str | os.PathLike = ".", name: str = "study", source: str = ""
) -> RollingStudy:
    """Validate a rolling study given as nested dicts (the parsed TOML)."""
    static = [k for k in ("scene", "positions", "sensor") if k in data]
    if static:
        raise StudyError(
            f"{static[0]} is a static study's table, and this study has a [rolling] table: a study "
            f"either rolls road sections ([[section]], [rolling]) or solves scenes at positions "
            f"([[scene]], [positions]); put each kind in its own study file (docs/studies.md)"
        )
    check_keys("", data, TOP_KEYS, required=("section", "body", "material", "rolling", "load"))
    head = table_of("study", data.get("study", {}))
    check_keys("study", head, ("name", "figures"))
    figures = head.get("figures", True)
    if not isinstance(figures, bool):
        raise StudyError(f"study.figures must be true or false, got {figures!r}")
    track, speeds = _rolling(table_of("rolling", data["rolling"]))
    study = RollingStudy(
        name=str(head.get("name", name)),
        sections=_sections(data["section"], Path(base)),
        bodies=_bodies(data["body"]),
        materials=_materials(data["material"], Path(base)),
        loads=_loads(table_of("load", data["load"])),
        speeds=speeds,
        track=track,
        solver=_solver(table_of("solver", data.get("solver", {}))),
        figures=figures,
        source=source,
    )
    if study.n_cases > MAX_CASES:
        raise StudyError(f"the study expands to {study.n_cases} cases, more than {MAX_CASES}; split it")
    return study


def _rolling(t: Mapping) -> tuple[dict, tuple]:
    from ..rolling.spec import RollingSpec

    check_keys("rolling", t, ("start", "end", "step", "speed", "speeds"), required=("start", "end", "step"))
    if ("speed" in t) == ("speeds" in t):
        raise StudyError(f"rolling needs one of rolling.speeds (a list, km/h) and rolling.speed, got {dict(t)!r}")
    if isinstance(t.get("speed"), list):
        raise StudyError(f"rolling.speed must be one speed (km/h); a list goes in rolling.speeds, got {t['speed']!r}")
    given = t["speeds"] if "speeds" in t else [t["speed"]]
    if not isinstance(given, list) or not given:
        raise StudyError(f"rolling.speeds must be a non-empty list of speeds (km/h), got {given!r}")
    speeds = tuple(check_number(f"rolling.speeds[{i}]", v, positive=True, unit="km/h") for i, v in enumerate(given))
    if len(set(speeds)) != len(speeds):
        raise StudyError(f"rolling.speeds has repeated values, got {given!r}")
    track = {k: t[k] for k in ("start", "end", "step")}
    RollingSpec(**track, speed=speeds[0])  # the table's own checks, one line naming the field
    return {k: float(v) for k, v in track.items()}, speeds


def _sections(v: Any, base: Path) -> tuple:
    out, seen = [], set()
    for k, t in enumerate(_tables("section", v), start=1):
        path = f"section {k}"
        check_keys(path, t, ("name", "surface", "generate", "offsets", "seeds"), required=("name",))
        _name(field_path(path, "name"), t["name"], seen)
        surface = dict(table_of(field_path(path, "surface"), t.get("surface", {})))
        offsets = _numbers(field_path(path, "offsets"), t.get("offsets", [0.0]), unit="mm")
        if ("generate" in t) == ("file" in surface):
            raise StudyError(
                f"{path}: give surface.file (a strip file) or generate (a seeded chip seal), "
                f"one of them; got {dict(t)!r}"
            )
        _check_surface(field_path(path, "surface"), surface, generated="generate" in t)
        if "generate" in t:
            gens = _generated(path, table_of(field_path(path, "generate"), t["generate"]), t.get("seeds"))
            strips = [(g, digest(g), f"-s{g['seed']}" if "seeds" in t else "") for g in gens]
        else:
            if "seeds" in t:
                raise StudyError(f"{field_path(path, 'seeds')} needs generate (a seeded strip), got {t['seeds']!r}")
            strips = [(None, _file_digest(path, base / surface["file"]), "")]
        for gen, dig, tag in strips:
            for o in offsets:
                label = t["name"] + tag + (f"@{o:g}mm" if len(offsets) > 1 or o else "")
                out.append(Section(label, surface, gen, o, os.fspath(base), dig))
    return tuple(out)


def _check_surface(path: str, surface: dict, *, generated: bool) -> None:
    """The ``[surface]`` keys, checked without reading the strip (that is the cases' work)."""
    from ..surface.measured import SurfaceOptions
    from ..surface.scene_table import SURFACE_KEYS

    check_keys(path, surface, tuple(k for k in SURFACE_KEYS if not (generated and k in ("file", "spacing", "units"))))
    options = {k: v for k, v in surface.items() if k not in ("file", "law_cache", "crop")}
    try:
        SurfaceOptions(**options)
    except (TypeError, ValueError) as exc:
        raise StudyError(f"{path}: {exc}") from None


def _generated(path: str, g: Mapping, seeds: Any) -> list[dict]:
    check_keys(field_path(path, "generate"), g, GENERATE_KEYS, required=("length", "width", "h"))
    base = {k: check_number(f"{path}: generate.{k}", g[k], positive=True, unit="mm") for k in ("length", "width", "h")}
    if seeds is not None and "seed" in g:
        raise StudyError(f"{path}: give generate.seed or seeds, not both; got seed = {g['seed']!r}, seeds = {seeds!r}")
    given = seeds if seeds is not None else [g.get("seed", 0)]
    if (
        not isinstance(given, list)
        or not given
        or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in given)
    ):
        raise StudyError(f"{field_path(path, 'seeds')} must be a non-empty list of integers >= 0, got {given!r}")
    return [dict(base, seed=int(s)) for s in given]


def _file_digest(path: str, file: Path) -> str:
    try:
        return hashlib.sha256(file.read_bytes()).hexdigest()
    except OSError as exc:
        raise StudyError(f"{path}: surface.file {os.fspath(file)!r} cannot be read: {exc.strerror}") from None


def _bodies(v: Any) -> tuple:
    from ..rolling.spec import RollingSpec

    out, seen = [], set()
    for k, t in enumerate(_tables("body", v), start=1):
        path = f"body {k}"
        kind = t.get("kind")
        if kind not in ("halfspace", "block"):
            raise StudyError(f"{field_path(path, 'kind')} must be one of ('halfspace', 'block'), got {kind!r}")
        allowed = BODY_KEYS if kind == "block" else tuple(x for x in BODY_KEYS if x not in ("size", "base", "origin"))
        check_keys(path, t, allowed, required=("name", "kind"))
        _name(field_path(path, "name"), t["name"], seen)
        influence: dict = {"kind": kind}
        if kind == "block":
            influence["size"] = check_pair(field_path(path, "size"), t.get("size"), 3, positive=True, unit="mm")
            influence["base"] = t.get("base", "bonded")
            if influence["base"] not in BLOCK_BASES:
                raise StudyError(f"{field_path(path, 'base')} must be one of {BLOCK_BASES}, got {influence['base']!r}")
            influence["origin"] = check_pair(field_path(path, "origin"), t.get("origin", (0.0, 0.0)), unit="mm")
        face = {key: t[key] for key in FACE_KEYS if key in t}
        try:
            RollingSpec(start=0.0, end=0.0, step=1.0, speed=1.0, **face)
        except SceneError as exc:
            raise StudyError(f"{path}: {str(exc).replace('rolling.', '')}") from None
        if kind == "halfspace" and "tyre_radius" not in face and "footprint" not in face:
            raise StudyError(f"{path}: a flat face on the half-space needs a footprint (or a tyre_radius)")
        out.append(RollingBody(t["name"], influence, face))
    return tuple(out)


def _materials(v: Any, base: Path) -> tuple:
    from ..io.scene_file import _material

    out, seen = [], set()
    for k, t in enumerate(_tables("material", v), start=1):
        path = f"material {k}"
        check_keys(path, t, ("name", "E", "nu", "prony", "prony_file"), required=("name",))
        _name(field_path(path, "name"), t["name"], seen)
        try:
            material = _material({key: val for key, val in t.items() if key != "name"}, os.fspath(base))
        except SceneError as exc:
            raise StudyError(f"{path}: {exc}") from None
        out.append(StudyMaterial(t["name"], material))
    return tuple(out)


def _loads(t: Mapping) -> tuple:
    check_keys("load", t, ("total", "penetration"))
    given = [k for k in ("total", "penetration") if k in t]
    if len(given) != 1:
        raise StudyError(f"load needs exactly one of load.total (N) and load.penetration (mm), got {dict(t)!r}")
    kind = given[0]
    values = _numbers(f"load.{kind}", t[kind], unit="N" if kind == "total" else "mm", positive=kind == "total")
    return tuple((kind, v) for v in values)


def _solver(t: Mapping) -> dict:
    from ..micro.policy import ITERATIONS

    check_keys("solver", t, ("tol", "iteration"))
    out: dict = {}
    if "tol" in t:
        out["tol"] = check_number("solver.tol", t["tol"], positive=True)
    if "iteration" in t:
        if t["iteration"] not in ("auto",) + ITERATIONS:
            raise StudyError(f"solver.iteration must be one of {('auto',) + ITERATIONS}, got {t['iteration']!r}")
        out["iteration"] = t["iteration"]
    return out


def _numbers(path: str, v: Any, *, unit: str, positive: bool = False) -> tuple:
    if not isinstance(v, list) or not v:
        raise StudyError(f"{path} must be a non-empty list of numbers ({unit}), got {v!r}")
    out = tuple(check_number(f"{path}[{i}]", x, positive=positive, unit=unit) for i, x in enumerate(v))
    if len(set(out)) != len(out):
        raise StudyError(f"{path} has repeated values, got {v!r}")
    return out
