"""result.json: the summary of one solve, with the scene, the units and the version.

Fixed fields (names and meanings; see README.md): ``converged``, ``method``
(``"reference"`` or ``"twoscale"``), ``penetration`` (mm), ``tilt`` (``[alpha, beta]``
radians, or null without tilt), ``total_load`` (N), ``h`` (mm), ``asperities`` (scene
order: ``force`` N = integral of the final pressure over the cells the asperity owns,
``contact_area`` mm^2, ``max_pressure`` MPa, and ``macro_force`` N when the method has a
macro step), ``iterations``, ``timings_s``, ``version``. Added: ``message``, ``solver``
(the algorithm that ran: ``"twoscale"``, ``"dense"`` or ``"cg"``), ``h_source``, ``n_cells``,
``residuals`` (per stage: count, first, last, min), ``units``, ``scene``, ``caches`` (one
entry per on-disk cache the solve used: ``name``, ``folder``, entries ``read`` from it,
``written``, damaged entries ``dropped`` and computed again, and why new entries were not
stored, ``disabled``, "" when they were); the numbers first:
``contact_area`` (mm^2, the tips' contact areas summed), ``nominal_area`` (mm^2) and
``nominal_area_basis`` (what it is: the height map, the box of the tips' bases, cut to a
block's top face; :mod:`twoscale.setting`), ``contact_area_ratio`` (contact / nominal),
``body`` (``kind``, ``label``, and a block's ``size_mm``, ``base``, ``origin_mm``) and
``scene_name`` (when known); the two-scale
method adds ``macro``, ``micro_iteration``, ``micro_choice``, ``micro_attempts``,
``coupling`` and ``merged_patches`` (asperities numbered from 1), the reference method
``reference`` (solver, working grid, grid enlargements); a height-map scene adds
``height_map`` (the map as conditioned: ``file``, ``samples``, ``spacing_mm`` and
``measured_spacing_mm`` when resampled, ``units``
and ``units_from``, ``missing_samples`` and ``missing_treated_as``, ``edge_contacts`` and
``edge_asperities`` numbered from 1); ``warnings`` (always: the warnings the run raised, each
``category``, one-line ``message`` and ``count``, in the order first raised; empty when none). Everything is written from the typed
:attr:`ContactResult.details`, never from string-keyed extras.

:func:`read_forces` reads the per-asperity forces back.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from .atomic import atomic_output
from ..details import BulgeDetails, ReferenceDetails, SurfaceDetails, TwoScaleDetails
from ..scene import Scene
from .scene_file import scene_to_dict

__all__ = ["RESULT_NAME", "UNITS", "result_to_dict", "write_result", "read_forces", "read_forces_and_tips"]

RESULT_NAME = "result.json"
UNITS = {"length": "mm", "area": "mm2", "force": "N", "pressure": "MPa", "angle": "rad", "time": "s"}


def _num(v: Any) -> float | int | None:
    """A JSON-safe number: Python int/float; NaN and infinities become null."""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    v = float(v)
    return v if math.isfinite(v) else None


def _plain(v: Any) -> Any:
    """Recursively turn numpy scalars/arrays and tuples into JSON-safe values."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_plain(x) for x in v]
    if isinstance(v, (bool, np.bool_, int, float, np.integer, np.floating)):
        return _num(v)
    if v is None or isinstance(v, str):
        return v
    return str(v)


def _residual_summary(history: Any) -> dict:
    h = [float(x) for x in np.ravel(np.asarray(history, dtype=float))]
    if not h:
        return {"count": 0, "first": None, "last": None, "min": None}
    return {"count": len(h), "first": _num(h[0]), "last": _num(h[-1]), "min": _num(min(h))}


def result_to_dict(
    result, scene: Scene, *, method: str | None = None, h_source: str | None = None, warnings: Any = ()
) -> dict:
    """The result.json content of a solve.

    Parameters
    ----------
    result : ContactResult
    scene : Scene
        The scene that was solved (recorded in ``"scene"``; its ``h`` tells whether the
        cell size was given or chosen, ``"h_source"``).
    method : str, optional
        Method name to record; default ``result.method`` ("twoscale" or "reference";
        the solver that ran is ``"solver"``).
    warnings : list of dict, optional
        The warnings the run raised (``"warnings"``: :meth:`twoscale.io.warning_log.WarningLog.entries`);
        default none.

    Returns
    -------
    dict
        JSON-safe (floats, ints, lists, None). Asperities are listed in scene order;
        ``merged_patches`` numbers them from 1, as the scene file does.
    """
    details = result.details
    macro = result.macro_forces
    summ = result.asperities
    asperities = []
    for k in range(len(summ.forces)):
        row = {
            "force": _num(summ.forces[k]),
            "contact_area": _num(summ.contact_areas[k]),
            "max_pressure": _num(summ.max_pressures[k]),
        }
        if macro is not None:
            row["macro_force"] = _num(macro[k])
        asperities.append(row)
    h = result.fields[0].grid.h if result.fields else scene.h
    out = {
        "converged": bool(result.converged),
        "method": result.method if method is None else method,
        "penetration": _num(result.penetration),
        "tilt": None if result.tilt is None else [_num(t) for t in result.tilt],
        "total_load": _num(result.total_load),
        "h": _num(h),
        "asperities": asperities,
        "iterations": _plain(dict(result.iterations)),
        "timings_s": _plain(dict(result.timings_s)),
        "version": __version__,
        "message": result.message,
        "solver": result.solver,
        "h_source": h_source or _h_source(scene),
        "n_cells": int(result.n_cells),
        "residuals": {str(k): _residual_summary(v) for k, v in result.residuals.items()},
        "units": dict(UNITS),
        "scene": scene_to_dict(scene),
        # what came from the on-disk caches and what was written or dropped there
        "caches": [u.as_dict() for u in result.caches],
        "warnings": [dict(w) for w in warnings],  # category, one-line message, count
    }
    out.update(_setting_record(result, scene))
    if isinstance(details, TwoScaleDetails):
        out.update(_twoscale_record(details))
    elif isinstance(details, ReferenceDetails):
        out["reference"] = _plain({k: v for k, v in dataclasses.asdict(details).items() if k != "surface"})
    surface = getattr(details, "surface", None)
    if surface is not None:
        out["height_map"] = _height_map_record(surface)
    return out


def _height_map_record(s: SurfaceDetails) -> dict:
    """The ``height_map`` of result.json: the map as conditioned, and the asperities
    (numbered from 1) whose contact reaches its edge."""
    return {
        "file": s.source,
        "samples": list(s.samples),
        "spacing_mm": _num(s.spacing),
        "measured_spacing_mm": None if s.measured_spacing is None else _num(s.measured_spacing),
        "units": s.units,
        "units_from": s.units_from,
        "missing_samples": s.missing,
        "missing_treated_as": s.fill,
        "edge_contacts": len(s.edge_contacts),
        "edge_asperities": [k + 1 for k in s.edge_contacts],
    }


def _h_source(scene: Scene) -> str:
    """Where the cell size came from, without a command-line option: the scene's h, the
    default rule, or a height map's own spacing (a map's default)."""
    if scene.surface is not None and scene.surface.hmap.measured_spacing is None:
        return "map spacing"
    return "scene" if scene.h is not None else "default"


def _setting_record(result, scene: Scene) -> dict:
    """The body solved, the contact area and its ratio to the nominal area (a result made
    without :func:`twoscale.solve` gets them from the scene here)."""
    if result.body is None:
        from ..setting import with_setting

        result = with_setting(result, scene, _InfluenceOnly(scene.influence))
    ratio = result.contact_ratio
    return {
        "contact_area": _num(result.contact_area),
        "nominal_area": _num(result.nominal_area),
        "nominal_area_basis": result.nominal_area_basis,
        "contact_area_ratio": None if ratio is None else _num(ratio),
        "body": result.body.as_dict(),
        "scene_name": result.scene_name,
    }


class _InfluenceOnly:
    """A block's settings standing for its provider (the body's description needs no model)."""

    def __init__(self, influence) -> None:
        self.kind, self.size, self.base, self.origin = (influence.get(k) for k in ("kind", "size", "base", "origin"))


def _twoscale_record(details: TwoScaleDetails) -> dict:
    """The two-scale method's own fields of result.json (from the typed details)."""
    macro, micro = details.macro, details.micro
    choice = micro.choice
    return {
        # how the macro step held the interaction, and the measured error of a fast operator
        "macro": {
            "interaction": macro.interaction,
            "operator_error": None if macro.operator_error is None else _num(macro.operator_error),
        },
        "micro_iteration": micro.iteration,
        # what the policy chose and why, and every attempt the driver made, in order
        "micro_choice": {
            "iteration": choice.iteration,
            "far_tol": _plain(choice.far_tol),
            "reason": choice.reason,
            "by_caller": bool(choice.by_caller),
            "estimates": _plain(dict(choice.estimates)),
        },
        "micro_attempts": [_plain(dataclasses.asdict(a)) for a in micro.attempts],
        "coupling": _plain(dataclasses.asdict(micro.coupling)),
        # asperities numbered from 1, as in the scene file (0-based in Python)
        "merged_patches": [[k + 1 for k in m] for m in micro.merged_patches],
        **({} if details.bulge is None else {"bulge": _bulge_record(details.bulge)}),
    }


def _bulge_record(b: BulgeDetails) -> dict:
    """The ``bulge`` of result.json: the tips above the approach the body's rising surface
    lifted into contact (``taken``) and those still lifted (``left``), numbered from 1."""
    return {
        "rounds": int(b.rounds),
        "taken": [k + 1 for k in b.taken],
        "left": [k + 1 for k in b.left],
        "left_gaps_mm": [_num(g) for g in b.left_gaps],
    }


def write_result(
    result,
    scene: Scene,
    out_dir: str | os.PathLike,
    *,
    method: str | None = None,
    h_source: str | None = None,
    record: dict | None = None,
    warnings: Any = (),
) -> Path:
    """Write ``out_dir/result.json`` atomically (temporary file, then ``os.replace``).

    The directory is created if needed; call this only once a solve has returned, so a
    failed run leaves nothing behind. ``record``: :func:`result_to_dict`'s answer for the
    same arguments when the caller has it already; ``warnings``: as there. Returns the path written.
    """
    if record is None:
        record = result_to_dict(result, scene, method=method, h_source=h_source, warnings=warnings)
    text = json.dumps(record, indent=2, allow_nan=False) + "\n"
    target = Path(out_dir) / RESULT_NAME
    with atomic_output(target) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return target


def read_forces(folder: str | os.PathLike) -> np.ndarray:
    """Per-asperity forces (N, scene order) of ``folder/result.json`` written by :func:`write_result`.

    Raises
    ------
    ValueError
        One line naming the file: missing, or not a twoscale result.json.
    """
    return read_forces_and_tips(folder)[0]


def read_forces_and_tips(folder: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """:func:`read_forces` and the tip positions (N, 2) mm of the recorded scene, from one
    read of ``folder/result.json`` (NaN where the scene gives no tip position). A height
    map's scene lists no tips: their positions (the summits) are read from the
    ``asperities.csv`` beside it, when it is there and has a row per force."""
    path = Path(folder) / RESULT_NAME
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        history = isinstance(data, dict) and data.get("kind") == "history"
        forces = None if history else np.array([float(a["force"]) for a in data["asperities"]])
    except FileNotFoundError:
        if (Path(folder) / "rolling.json").exists():
            raise ValueError(
                f"{folder} holds a rolling run (rolling.json, signals.csv), not one solve's result.json"
            ) from None
        raise ValueError(f"{path} does not exist (a folder written by twoscale solve --out)") from None
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path} is not a twoscale result.json ({exc})") from None
    if history:
        raise ValueError(f"{path} is a load history's (its forces per output time are in history.csv), not one solve's")
    scene = data.get("scene", {})
    tips = [[a.get("x", np.nan), a.get("y", np.nan)] for a in scene.get("asperity", [])]
    if not tips and "surface" in scene:
        tips = _csv_tips(Path(folder), forces.size)
    return forces, np.array(tips, dtype=float).reshape(-1, 2)


def _csv_tips(folder: Path, n: int) -> list:
    """The ``x_mm, y_mm`` of ``folder/asperities.csv``'s rows, or no tips when the file is
    absent, unreadable or has not ``n`` rows (the tips are then not compared)."""
    import csv

    from .asperity_csv import ASPERITY_CSV_NAME

    try:
        with open(folder / ASPERITY_CSV_NAME, newline="", encoding="utf-8") as fh:
            tips = [[float(r["x_mm"]), float(r["y_mm"])] for r in csv.DictReader(fh)]
    except (OSError, KeyError, TypeError, ValueError):
        return []
    return tips if len(tips) == n else []
