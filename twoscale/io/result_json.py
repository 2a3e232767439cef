"""result.json: the summary of one solve, with the scene, the units and the version.

Fixed fields (names and meanings; see README.md): ``converged``, ``method``
(``"reference"`` or ``"twoscale"``), ``penetration`` (mm), ``tilt`` (``[alpha, beta]``
radians, or null without tilt), ``total_load`` (N), ``h`` (mm), ``asperities`` (scene
order: ``force`` N = integral of the final pressure over the cells the asperity owns,
``contact_area`` mm^2, ``max_pressure`` MPa, and ``macro_force`` N when the method has a
macro step), ``iterations``, ``timings_s``, ``version``. Added: ``message``, ``solver``,
``h_source``, ``n_cells``, ``residuals`` (per stage: count, first, last, min), ``units``,
``scene``.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from .atomic import atomic_output
from ..scene import Scene
from .scene_file import scene_to_dict

__all__ = ["RESULT_NAME", "UNITS", "result_to_dict", "write_result"]

RESULT_NAME = "result.json"
UNITS = {"length": "mm", "force": "N", "pressure": "MPa", "angle": "rad", "time": "s"}
#: Solver names in ContactResult.method that belong to the reference method.
_REFERENCE_SOLVERS = ("dense", "cg", "reference")


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


def result_to_dict(result, scene: Scene, *, method: str | None = None, h_source: str | None = None) -> dict:
    """The result.json content of a solve.

    Parameters
    ----------
    result : ContactResult
    scene : Scene
        The scene that was solved (recorded in ``"scene"``; its ``h`` tells whether the
        cell size was given or chosen, ``"h_source"``).
    method : str, optional
        Method name to record; default from ``result.method`` (``"dense"``/``"cg"`` ->
        ``"reference"``).

    Returns
    -------
    dict
        JSON-safe (floats, ints, lists, None).
    """
    if method is None:
        method = "reference" if result.method in _REFERENCE_SOLVERS else result.method
    macro = result.extra.get("macro_forces")
    summ = result.asperities
    asperities = []
    for k in range(len(summ.forces)):
        row = {"force": _num(summ.forces[k]), "contact_area": _num(summ.contact_areas[k]),
               "max_pressure": _num(summ.max_pressures[k])}
        if macro is not None:
            row["macro_force"] = _num(np.asarray(macro)[k])
        asperities.append(row)
    h = result.fields[0].grid.h if result.fields else scene.h
    out = {
        "converged": bool(result.converged),
        "method": method,
        "penetration": _num(result.penetration),
        "tilt": None if result.tilt is None else [_num(t) for t in result.tilt],
        "total_load": _num(result.total_load),
        "h": _num(h),
        "asperities": asperities,
        "iterations": _plain(dict(result.iterations)),
        "timings_s": _plain(dict(result.timings_s)),
        "version": __version__,
        "message": result.message,
        "solver": result.method,
        "h_source": h_source or ("scene" if scene.h is not None else "default"),
        "n_cells": int(result.n_cells),
        "residuals": {str(k): _residual_summary(v) for k, v in result.residuals.items()},
        "units": dict(UNITS),
        "scene": scene_to_dict(scene),
    }
    if "macro_interaction" in result.extra:
        # how the macro step held the interaction, and the measured error of a fast operator
        err = result.extra.get("macro_operator_error")
        out["macro"] = {"interaction": result.extra["macro_interaction"],
                        "operator_error": None if err is None else _num(err)}
    if "micro_iteration" in result.extra:
        out["micro_iteration"] = result.extra["micro_iteration"]
    if "micro_choice" in result.extra:
        # what the policy chose and why, and every attempt the driver made, in order
        out["micro_choice"] = _plain(dict(result.extra["micro_choice"]))
        out["micro_attempts"] = [_plain(dict(a)) for a in result.extra["micro_attempts"]]
    if "coupling" in result.extra:
        out["coupling"] = {k: _num(v) if v is not None else None for k, v in result.extra["coupling"].items()}
    if "merged_patches" in result.extra:
        # asperities numbered from 1, as in the scene file
        out["merged_patches"] = [[int(k) + 1 for k in m] for m in result.extra["merged_patches"]]
    return out


def write_result(result, scene: Scene, out_dir: str | os.PathLike, *, method: str | None = None,
                 h_source: str | None = None) -> Path:
    """Write ``out_dir/result.json`` atomically (temporary file, then ``os.replace``).

    The directory is created if needed; call this only once a solve has returned, so a
    failed run leaves nothing behind. Returns the path written.
    """
    text = json.dumps(result_to_dict(result, scene, method=method, h_source=h_source), indent=2, allow_nan=False) + "\n"
    target = Path(out_dir) / RESULT_NAME
    with atomic_output(target) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return target
