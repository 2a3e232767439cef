"""Scene files (TOML; units mm, N, MPa): read, validate, and turn back into a dict.

The format (see README.md)::

    [material]            E (MPa, > 0), nu (-1 < nu <= 0.5)           required
                          prony = [[E_k, tau_k], ...] (MPa, s) or prony_file = "x.csv"
                          (columns E_k, tau_k): viscoelastic, E is then the relaxed modulus
    [load]                exactly one of penetration (mm) / total (N)  required
                          either may be a history [[t, value], ...] (s; mm or N)
                          tilt = true (with total only), pivot = [x, y] (mm, with tilt)
                          cases = [W1, W2, ...] (N, with total only): load cases of
                          `twoscale compare`; `solve` uses total (the first case)
    [grid]                h (mm, > 0)                                  optional
    [time]                with a history: output = [t1, ...] (s), tol, growth, steps
                          (fixed count) or dt (fixed size, s), max_steps
    [influence]           kind = "halfspace" | "block" (+ size, base, origin for "block")
    [[asperity]]          x, y (mm), R (mm, > 0) required; z (mm) default 0;
                          shape = "sphere" (default) | "paraboloid"
    [surface]             instead of [[asperity]]: a height map (twoscale.surface);
                          file (relative to the scene file) required, see
                          twoscale.surface.scene_table for the other keys
    [rolling]             start, end, step (mm), speed (km/h) required; tyre_radius (mm),
                          tyre_shape, footprint = [length, width] (mm): the road rolls
                          under the body (twoscale.rolling.spec)

Every problem raises :class:`SceneError` (a ``ValueError``) with a one-line message
naming the field path (``asperity 4: R``; asperities numbered from 1 in file order) and
the bad value. Unknown keys are errors, never ignored.
"""

from __future__ import annotations

import os
from typing import Any, Mapping

from ..indenters import SHAPES, Asperity
from ..material import Material
from ..scene import Scene, SceneError, check_number
from .table_checks import check_keys, field_path, table_of

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["SceneError", "read_scene", "scene_from_dict", "scene_to_dict"]

TOP_KEYS = ("material", "load", "grid", "influence", "asperity", "surface", "time", "rolling")
MATERIAL_KEYS = ("E", "nu", "prony", "prony_file")
LOAD_KEYS = ("penetration", "total", "tilt", "pivot", "cases")
GRID_KEYS = ("h",)
TIME_KEYS = ("output", "tol", "growth", "steps", "dt", "max_steps")
ASPERITY_KEYS = ("x", "y", "z", "R", "shape")


def read_scene(path: str | os.PathLike, *, h: float | None = None, h_name: str = "h") -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str or path-like
        TOML scene file.
    h : float, optional
        Cell size, mm, in place of the file's ``[grid] h`` (the command line's ``--h``). A
        height map is conditioned at it directly, so that a map too large at its own spacing
        but not at ``h`` is read, and one too large at ``h`` is refused naming ``h_name``.
    h_name : str, default "h"
        Where ``h`` came from, as a refusal names it (``"--h"`` on the command line).

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        File missing or unreadable, invalid TOML, or invalid content; the message
        starts with the file name and names the field and the value.
    """
    data = read_toml(path, "scene", SceneError)
    try:
        return scene_from_dict(data, base_dir=os.path.dirname(os.path.abspath(path)), h=h, h_name=h_name)
    except SceneError as exc:
        raise SceneError(f"{os.fspath(path)}: {exc}") from None


def read_toml(path: str | os.PathLike, what: str, error: type[Exception]) -> dict:
    """The TOML table of ``path``, or ``error`` with one line naming the file (missing, a
    folder, not TOML); ``what`` names the kind of file ("scene", "study")."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise error(f"{what} file not found: {os.fspath(path)!r}") from None
    except IsADirectoryError:
        raise error(f"{what} file is a directory: {os.fspath(path)!r}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{os.fspath(path)}: invalid TOML: {exc}") from None


def scene_from_dict(
    data: Mapping[str, Any], *, base_dir: str | None = None, h: float | None = None, h_name: str = "h"
) -> Scene:
    """Validate a scene given as nested dicts (the parsed TOML) and build a :class:`Scene`.
    ``base_dir``: where a ``[surface]`` file name is relative to (default: the current folder);
    ``h``, ``h_name``: a cell size in place of ``[grid] h`` and its name (:func:`read_scene`)."""
    check_keys("", data, TOP_KEYS, required=("material", "load"))
    material = _material(table_of("material", data["material"]), base_dir)
    surface = None
    if "asperity" not in data and "surface" not in data:
        raise SceneError("asperity is missing (required: [[asperity]] tables, or a [surface] table)")
    if "asperity" in data and "surface" in data:
        raise SceneError("a scene needs exactly one of [[asperity]] tables and a [surface] table, got both")
    load = table_of("load", data["load"])
    check_keys("load", load, LOAD_KEYS)
    grid = table_of("grid", data.get("grid", {}))
    check_keys("grid", grid, GRID_KEYS)
    influence = table_of("influence", data.get("influence", {}))
    if "cases" in load and isinstance(load["cases"], list) and not load["cases"]:
        # Scene() reads () as "no list"; in a file an empty list is a mistake
        raise SceneError("load.cases is empty, got [] (list at least one total load, N, or leave the key out)")
    history = _history(load, table_of("time", data.get("time", {})))
    if history is not None:
        load = {k: v for k, v in load.items() if k != history.kind}
    rolling = None
    if "rolling" in data:
        from ..rolling.spec import rolling_from_table

        rolling = rolling_from_table(table_of("rolling", data["rolling"]))
    # the tables above first: a mistake in them is named before a height map is read and segmented
    if "surface" in data:
        from ..surface.scene_table import surface_from_table

        given = (h, h_name) if h is not None else (grid.get("h"), "grid.h")
        surface = surface_from_table(
            table_of("surface", data["surface"]), base_dir=base_dir, h=given[0], h_name=given[1]
        )
        asperities = surface.asperities
    else:
        asperities = tuple(
            _asperity(f"asperity {k}", t) for k, t in enumerate(_tables("asperity", data["asperity"]), start=1)
        )
    return Scene(
        material=material,
        asperities=asperities,
        history=history,
        rolling=rolling,
        penetration=load.get("penetration"),
        total_load=load.get("total"),
        tilt=load.get("tilt", False),
        pivot=load.get("pivot", (0.0, 0.0)),
        h=grid.get("h") if h is None else h,
        influence=dict(influence) or None,
        load_cases=load.get("cases", ()),
        surface=surface,
    )


def scene_to_dict(scene: Scene) -> dict:
    """The scene as nested dicts in the file's layout (JSON/TOML-ready; floats, lists).

    ``scene_from_dict(scene_to_dict(s)) == s``.
    """
    load: dict[str, Any] = {}
    if scene.history is not None:
        load[scene.history.kind] = [[t, v] for t, v in scene.history.points]
    elif scene.penetration is not None:
        load["penetration"] = float(scene.penetration)
    else:
        load["total"] = float(scene.total_load)
    if scene.tilt:
        load["tilt"] = True
        load["pivot"] = [float(v) for v in scene.pivot]
    if scene.load_cases:
        load["cases"] = [float(w) for w in scene.load_cases]
    out: dict[str, Any] = {
        "material": {"E": float(scene.material.E), "nu": float(scene.material.nu)},
        "load": load,
    }
    if scene.material.prony:
        out["material"]["prony"] = [list(b) for b in scene.material.prony]
    if scene.history is not None:
        out["time"] = _time_table(scene.history)
    if scene.h is not None:
        out["grid"] = {"h": float(scene.h)}
    if scene.rolling is not None:
        out["rolling"] = scene.rolling.to_table()
    out["influence"] = {k: (list(v) if isinstance(v, tuple) else v) for k, v in scene.influence.items()}
    if scene.surface is not None:  # the [surface] table (file made absolute), not its basins
        from ..surface.scene_table import surface_to_table

        out["surface"] = surface_to_table(scene.surface)
        return out
    out["asperity"] = [
        {"x": float(a.x), "y": float(a.y), "z": float(a.z), "R": float(a.R), "shape": a.shape} for a in scene.asperities
    ]
    return out


# ---------------------------------------------------------------- helpers
def _tables(path: str, v: Any) -> list:
    if not isinstance(v, list):
        raise SceneError(f"{path} must be an array of tables ([[{path}]]), got {v!r}")
    if not v:
        raise SceneError(f"{path} list is empty, got [] (a scene needs at least one [[{path}]])")
    for k, t in enumerate(v, start=1):
        table_of(f"{path} {k}", t)
    return v


def _material(t: Mapping, base_dir: str | None = None) -> Material:
    check_keys("material", t, MATERIAL_KEYS, required=("E", "nu"))
    E = check_number("material.E", t["E"], positive=True, unit="MPa")
    nu = check_number("material.nu", t["nu"])
    if not -1.0 < nu <= 0.5:
        raise SceneError(f"material.nu must satisfy -1 < nu <= 0.5, got {t['nu']!r}")
    if "prony" in t and "prony_file" in t:
        raise SceneError(f"give material.prony or material.prony_file, not both (got {t['prony_file']!r})")
    prony = t.get("prony", ())
    if "prony_file" in t:
        from .prony_csv import read_prony_csv

        prony = read_prony_csv(t["prony_file"], base_dir=base_dir)
    if prony == []:
        raise SceneError("material.prony is empty, got [] (list at least one [E_k, tau_k] or leave it out)")
    try:
        return Material(E, nu, prony=prony)
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _history(load: Mapping, time_table: Mapping):
    """The load history of ``[load]`` (a list of points as total or penetration) with the
    ``[time]`` options, or None (``[time]`` then must be empty)."""
    from ..viscoelastic.history import LoadHistory
    from ..viscoelastic.stepping import TimeSteps

    check_keys("time", time_table, TIME_KEYS)
    kinds = [k for k in ("total", "penetration") if isinstance(load.get(k), list)]
    if not kinds:
        if time_table:
            raise SceneError(f"[time] is only used with a load history ([[t, value], ...]), got {dict(time_table)!r}")
        return None
    if "total" in load and "penetration" in load:
        raise SceneError(
            f"give one of load.total and load.penetration, got both "
            f"(total = {load['total']!r}, penetration = {load['penetration']!r})"
        )
    for key in ("cases",):
        if key in load:
            raise SceneError(f"load.{key} cannot go with a load history, got {load[key]!r}")
    opts = {"tol": "tol", "growth": "growth", "steps": "count", "dt": "size", "max_steps": "max_steps"}
    try:
        steps = TimeSteps(**{opts[k]: v for k, v in time_table.items() if k in opts})
        return LoadHistory(kinds[0], load[kinds[0]], output=time_table.get("output"), steps=steps)
    except (TypeError, ValueError) as exc:
        raise SceneError(str(exc)) from None


def _time_table(history) -> dict:
    out: dict[str, Any] = {}
    if history.output is not None:
        out["output"] = list(history.output)
    s = history.steps
    for key, name in (
        ("tol", "tol"),
        ("growth", "growth"),
        ("count", "steps"),
        ("size", "dt"),
        ("max_steps", "max_steps"),
    ):
        v = getattr(s, key)
        if v is not None:
            out[name] = v
    return out


def _asperity(path: str, t: Mapping) -> Asperity:
    check_keys(path, t, ASPERITY_KEYS, required=("x", "y", "R"))
    x = check_number(field_path(path, "x"), t["x"], unit="mm")
    y = check_number(field_path(path, "y"), t["y"], unit="mm")
    z = check_number(field_path(path, "z"), t.get("z", 0.0), unit="mm")
    R = check_number(field_path(path, "R"), t["R"], positive=True, unit="mm")
    shape = t.get("shape", "sphere")
    if shape not in SHAPES:
        raise SceneError(f"{field_path(path, 'shape')} must be one of {', '.join(SHAPES)}, got {shape!r}")
    return Asperity(x, y, z, R, shape)
