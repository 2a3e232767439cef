"""The study: what a study file (TOML) asks for, as plain validated data.

A study is a grid of cases: scenes x bodies x loads x positions, plus solver options
(:mod:`twoscale.studies.cases` expands it). The format (units mm, N, MPa)::

    [study]       name (default: the file's stem); method = "twoscale" | "reference"
    [[scene]]     file (a scene file, relative to the study file); name (default its stem)
    [[body]]      name; kind = "halfspace" | "block";
                  block only: size = [Lx, Ly, t], base = "bonded" | "sliding", origin = [x0, y0]
                  (as a scene's [influence]); window = [Wx, Wy] and centre = [x, y]: the
                  footprint, the rectangle where tips touch (half-space default: everywhere;
                  block default: its top face less `edge` = 10 mm on each side)
    [load]        total = [W, ...] (N) or penetration = [d, ...] (mm); tilt = true | false.
                  Without [load]: each scene's own load (its load.cases, else its one load)
    [positions]   shifts = [[sx, sy], ...] (mm), or a straight track
                  start = [x, y], end = [x, y], step = s (mm, > 0): start + k s u, k = 0, 1, ...
                  while within the end. Default: one position, no shift
    [solver]      h (mm, overrides the scenes' grid.h), tol, max_sweeps, iteration, far_tol
    [sensor]      nx, ny, cell (mm), centre = [x, y]: the sensor of e_m (default the paper's)

A position shifts the indenting surface (every tip) relative to the body, whose frame is
the scene's: the footprint, the pivot of a tilting joint and the sensor stay put while
the texture moves under them.

Every problem raises :class:`StudyError` (a :class:`~twoscale.scene.SceneError`) with a
one-line message naming the key (``body[1].base``) and the bad value. Scene files are read
by the scene loader (:func:`twoscale.io.scene_file.read_scene`); whatever it returns is a
scene here.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import StudyError
from ..io.scene_file import check_keys, field_path, read_scene, read_toml, table_of
from ..micro.policy import ITERATIONS
from ..scene import BLOCK_BASES, BLOCK_DEFAULT_SIZE, SCENE_METHODS, SceneError, check_number, check_pair
from ..sensor import Sensor
from .checks import name as _name, tables as _tables
from .keys import digest, scene_record

#: Largest number of cases a study may expand to (checked before expanding).
MAX_CASES = 1_000_000
#: Default inset of a block's footprint from each side of its top face, mm: the block's
#: correction is interpolated from a lattice that stays one source spacing (5 mm) inside
#: the sides, and a contact patch needs room around its tip.
BLOCK_EDGE = 10.0
#: Solver options a study may set, with the solver keyword each becomes.
SOLVER_KEYS = ("h", "tol", "max_sweeps", "iteration", "far_tol")

TOP_KEYS = ("study", "scene", "body", "load", "positions", "solver", "sensor")


@dataclass(frozen=True)
class StudyScene:
    """A scene of the study: its name, the file it came from, what the loader returned and
    the digest of its content (:func:`twoscale.studies.keys.digest` of its record)."""

    name: str
    path: str
    scene: Any
    digest: str = ""


@dataclass(frozen=True)
class Footprint:
    """The rectangle of the body frame where tips touch, mm (``size`` None: everywhere)."""

    size: tuple | None = None
    centre: tuple = (0.0, 0.0)

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """True for each point (rows of ``xy``, mm) inside the rectangle (edges included)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        if self.size is None:
            return np.ones(len(xy), dtype=bool)
        half = 0.5 * np.asarray(self.size)
        return np.all(np.abs(xy - np.asarray(self.centre)) <= half * (1 + 1e-12), axis=1)


@dataclass(frozen=True)
class Body:
    """An elastic body of the study: a scene ``[influence]`` table and its footprint."""

    name: str
    influence: dict
    footprint: Footprint


@dataclass(frozen=True)
class Study:
    """A validated study file.

    Attributes
    ----------
    name : str
    method : {"twoscale", "reference"}
    scenes : tuple of StudyScene
    bodies : tuple of Body
    loads : tuple of (kind, value) or None
        ``("total", W N)`` or ``("penetration", d mm)``; None: each scene's own loads.
    tilt : bool or None
        Ball-and-socket joint under load control; None: each scene's own.
    positions : (P, 2) tuple of shifts, mm
    track : bool
        Whether the positions are a straight track (figures plot against the distance along it).
    solver : dict
        Solver keyword arguments (``h`` is applied to the scene instead).
    sensor : Sensor
    source : str
        The study file.
    """

    name: str
    method: str
    scenes: tuple
    bodies: tuple
    loads: tuple | None
    tilt: bool | None
    positions: tuple
    track: bool
    solver: dict = field(default_factory=dict)
    sensor: Sensor = Sensor()
    source: str = ""

    def loads_of(self, scene) -> tuple:
        """The loads run on ``scene``: the study's, else the scene's own."""
        if self.loads is not None:
            return self.loads
        if scene.penetration is not None:
            return (("penetration", float(scene.penetration)),)
        return tuple(("total", float(w)) for w in (scene.load_cases or (scene.total_load,)))

    @property
    def n_cases(self) -> int:
        """Number of cases the study expands to."""
        per_scene = sum(len(self.loads_of(s.scene)) for s in self.scenes)
        return per_scene * len(self.bodies) * len(self.positions)


# ---------------------------------------------------------------- reading
def read_study(path: str | os.PathLike) -> Study:
    """Read and validate a study file (and every scene file it names); a file with a
    ``[rolling]`` table is a rolling study (:mod:`twoscale.studies.rolling_spec`).

    Raises
    ------
    StudyError
        One line starting with the file name, naming the key and the bad value.
    """
    data = read_toml(path, "study", StudyError)
    try:
        if "rolling" in data:  # road sections x bodies x materials x loads x speeds
            from .rolling_spec import rolling_study_from_dict

            return rolling_study_from_dict(data, base=Path(path).parent, name=Path(path).stem, source=os.fspath(path))
        return study_from_dict(data, base=Path(path).parent, name=Path(path).stem, source=os.fspath(path))
    except SceneError as exc:
        raise StudyError(f"{os.fspath(path)}: {exc}") from None


def study_from_dict(data: Mapping, *, base: str | os.PathLike = ".", name: str = "study", source: str = "") -> Study:
    """Validate a study given as nested dicts (the parsed TOML); scene files are read
    relative to ``base``."""
    rolling = [k for k in ("section", "material") if k in data]
    if rolling:
        raise StudyError(
            f"{rolling[0]} is a rolling study's table, and this study has no [rolling] table: give "
            f"[rolling] (start, end, step, speeds) to roll the sections, or [[scene]] tables to solve "
            f"scenes at positions (docs/studies.md)"
        )
    _keys("", data, TOP_KEYS, required=("scene", "body"))
    head = table_of("study", data.get("study", {}))
    _keys("study", head, ("name", "method"))
    method = head.get("method", "twoscale")
    if method not in SCENE_METHODS:
        raise StudyError(f"study.method must be one of {SCENE_METHODS}, got {method!r}")
    load = table_of("load", data.get("load", {}))
    loads, tilt = _loads(load)
    positions, track = _positions(table_of("positions", data.get("positions", {})))
    study = Study(
        name=str(head.get("name", name)),
        method=method,
        scenes=_scenes(data["scene"], Path(base)),
        bodies=_bodies(data["body"]),
        loads=loads,
        tilt=tilt,
        positions=positions,
        track=track,
        solver=_solver(table_of("solver", data.get("solver", {}))),
        sensor=_sensor(table_of("sensor", data.get("sensor", {}))),
        source=source,
    )
    twoscale_only = sorted(set(study.solver) - {"h", "tol"})
    if method == "reference" and twoscale_only:
        raise StudyError(
            f"solver.{twoscale_only[0]} is an option of the two-scale solver, not of "
            f"study.method = 'reference', got {study.solver[twoscale_only[0]]!r}"
        )
    if study.n_cases > MAX_CASES:
        raise StudyError(
            f"the study expands to {study.n_cases} cases, more than {MAX_CASES}; split it into several studies"
        )
    return study


def _scenes(v: Any, base: Path) -> tuple:
    out, seen = [], set()
    for k, t in enumerate(_tables("scene", v)):
        _keys(f"scene {k + 1}", t, ("file", "name"), required=("file",))
        if not isinstance(t["file"], str):
            raise StudyError(f"scene {k + 1}: file must be a path (string), got {t['file']!r}")
        path = base / t["file"]
        nm = t.get("name", Path(t["file"]).stem)
        _name(f"scene {k + 1}: name", nm, seen)
        scene = read_scene(path)
        if scene.history is not None or scene.rolling is not None:  # a case is one static solve
            what = "a load history" if scene.history is not None else "a [rolling] table"
            raise StudyError(
                f"scene {k + 1}: {t['file']} has {what}, and a study's case is one static solve: run it "
                f"with twoscale solve{', or roll it in a study with a [rolling] table' if scene.rolling else ''}"
            )
        out.append(StudyScene(nm, os.fspath(path), scene, digest(scene_record(scene))))
    return tuple(out)


def _bodies(v: Any) -> tuple:
    out, seen = [], set()
    for k, t in enumerate(_tables("body", v)):
        path = f"body {k + 1}"  # numbered from 1, as the [[body]] tables are read
        kind = t.get("kind")
        if kind not in ("halfspace", "block"):
            raise StudyError(f"{field_path(path, 'kind')} must be one of ('halfspace', 'block'), got {kind!r}")
        block = ("size", "base", "origin") if kind == "block" else ()
        _keys(path, t, ("name", "kind", "window", "centre") + block, required=("name", "kind"))
        _name(f"{field_path(path, 'name')}", t["name"], seen)
        if kind == "halfspace":
            influence = {"kind": "halfspace"}
            centre = check_pair(f"{field_path(path, 'centre')}", t.get("centre", (0.0, 0.0)), unit="mm")
            window = (
                check_pair(f"{field_path(path, 'window')}", t["window"], positive=True, unit="mm")
                if "window" in t
                else None
            )
        else:
            influence, window, centre = _block(path, t)
        out.append(Body(t["name"], influence, Footprint(window, centre)))
    return tuple(out)


def _block(path: str, t: Mapping) -> tuple:
    size = check_pair(f"{field_path(path, 'size')}", t.get("size", BLOCK_DEFAULT_SIZE), 3, positive=True, unit="mm")
    base = t.get("base", "bonded")
    if base not in BLOCK_BASES:
        raise StudyError(f"{field_path(path, 'base')} must be one of {BLOCK_BASES}, got {base!r}")
    origin = check_pair(f"{field_path(path, 'origin')}", t.get("origin", (0.0, 0.0)), unit="mm")
    face = (-origin[0], -origin[1])  # the top face's centre in the scene frame
    if "window" in t:
        window = check_pair(f"{field_path(path, 'window')}", t["window"], positive=True, unit="mm")
        if window[0] > size[0] or window[1] > size[1]:
            raise StudyError(
                f"{field_path(path, 'window')} {list(window)!r} is larger than the block's top face "
                f"{list(size[:2])!r} mm"
            )
    else:
        window = (size[0] - 2 * BLOCK_EDGE, size[1] - 2 * BLOCK_EDGE)
        if min(window) <= 0:
            raise StudyError(
                f"{field_path(path, 'size')} {list(size)!r}: the top face leaves no footprint inside "
                f"{BLOCK_EDGE} mm of its sides; give {field_path(path, 'window')}"
            )
    centre = check_pair(f"{field_path(path, 'centre')}", t.get("centre", face), unit="mm")
    return {"kind": "block", "size": size, "base": base, "origin": origin}, window, centre


def _loads(t: Mapping) -> tuple:
    _keys("load", t, ("total", "penetration", "tilt"))
    tilt = t.get("tilt")
    if tilt is not None and not isinstance(tilt, bool):
        raise StudyError(f"load.tilt must be true or false, got {tilt!r}")
    given = [k for k in ("total", "penetration") if k in t]
    if len(given) > 1:
        raise StudyError(
            f"load needs at most one of load.total and load.penetration, got both: "
            f"total = {t['total']!r}, penetration = {t['penetration']!r}"
        )
    if not given:
        return None, tilt
    kind = given[0]
    values = t[kind]
    if not isinstance(values, list) or not values:
        raise StudyError(f"load.{kind} must be a non-empty list of numbers, got {values!r}")
    unit = "N" if kind == "total" else "mm"
    out = tuple(check_number(f"load.{kind}[{i}]", v, positive=kind == "total", unit=unit) for i, v in enumerate(values))
    if len(set(out)) != len(out):
        raise StudyError(f"load.{kind} has repeated values, got {values!r}")
    if kind == "penetration" and tilt:
        raise StudyError(
            f"load.tilt = true needs load.total (the tilt is solved under a given load), got penetration = {values!r}"
        )
    return tuple((kind, v) for v in out), tilt


def _positions(t: Mapping) -> tuple:
    _keys("positions", t, ("shifts", "start", "end", "step"))
    if "shifts" in t:
        if any(k in t for k in ("start", "end", "step")):
            raise StudyError(f"positions: give shifts or a track (start, end, step), not both; got {dict(t)!r}")
        v = t["shifts"]
        if not isinstance(v, list) or not v:
            raise StudyError(f"positions.shifts must be a non-empty list of [sx, sy] (mm), got {v!r}")
        return tuple(check_pair(f"positions.shifts[{i}]", s, unit="mm") for i, s in enumerate(v)), False
    if not t:
        return ((0.0, 0.0),), False
    missing = [k for k in ("start", "end", "step") if k not in t]
    if missing:
        raise StudyError(f"positions.{missing[0]} is missing: a track needs start, end and step, got {dict(t)!r}")
    a = np.array(check_pair("positions.start", t["start"], unit="mm"))
    b = np.array(check_pair("positions.end", t["end"], unit="mm"))
    step = check_number("positions.step", t["step"], positive=True, unit="mm")
    length = float(np.hypot(*(b - a)))
    if not step <= length:
        raise StudyError(f"positions.step must be at most the track's length {length:g} mm, got {t['step']!r}")
    n = int(math.floor(length / step * (1 + 1e-12))) + 1
    if n > MAX_CASES:
        raise StudyError(f"positions: the track has {n} positions, more than {MAX_CASES}; got step = {t['step']!r}")
    u = (b - a) / length
    return tuple((float(a[0] + k * step * u[0]), float(a[1] + k * step * u[1])) for k in range(n)), True


def _solver(t: Mapping) -> dict:
    _keys("solver", t, SOLVER_KEYS)
    out: dict = {}
    if "h" in t:
        out["h"] = check_number("solver.h", t["h"], positive=True, unit="mm")
    if "tol" in t:
        out["tol"] = check_number("solver.tol", t["tol"], positive=True)
    if "max_sweeps" in t:
        v = t["max_sweeps"]
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise StudyError(f"solver.max_sweeps must be an integer >= 1, got {v!r}")
        out["max_sweeps"] = v
    if "iteration" in t:
        if t["iteration"] not in ("auto",) + ITERATIONS:
            raise StudyError(f"solver.iteration must be one of {('auto',) + ITERATIONS}, got {t['iteration']!r}")
        out["iteration"] = t["iteration"]
    if "far_tol" in t:
        v = check_number("solver.far_tol", t["far_tol"], positive=True)
        if not v < 1:
            raise StudyError(f"solver.far_tol must be in (0, 1), got {t['far_tol']!r}")
        out["far_tol"] = v
    return out


def _sensor(t: Mapping) -> Sensor:
    _keys("sensor", t, ("nx", "ny", "cell", "centre"))
    d = Sensor()
    for k in ("nx", "ny"):
        v = t.get(k, getattr(d, k))
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise StudyError(f"sensor.{k} must be an integer >= 1, got {v!r}")
    return Sensor(
        t.get("nx", d.nx),
        t.get("ny", d.ny),
        check_number("sensor.cell", t.get("cell", d.cell), positive=True, unit="mm"),
        check_pair("sensor.centre", t.get("centre", d.centre), unit="mm"),
    )


# ---------------------------------------------------------------- helpers
_keys = check_keys  # the scene file's key checks: unknown keys are errors, never ignored
