"""The files of a history solve (:class:`~twoscale.viscoelastic.result.HistoryResult`).

* ``history.csv``: a row per output time; columns exactly ``time_s, penetration_mm,
  total_load_N, contact_area_mm2`` (then ``tilt_x_rad, tilt_y_rad`` under tilt), then
  ``force_1, ..., force_N`` (N; asperities numbered from 1 in scene order); header on the
  first line, no comment lines; ``history.csv-metadata.json`` beside it, as for every
  table (:mod:`.tables`: version, units, scene, what each column holds);
* ``result.json``: the material (branches, retardation times), the history, the steps
  taken (times, lengths, effective compliances, error estimates), the largest error
  estimate, the memory held, what the on-disk caches gave and took (``caches``), the
  histories as lists, the version and the scene, and ``warnings`` (as a static solve's
  ``result.json``: category, one-line message and count, a warning raised at every step once);
* ``fields.pvd`` (+ ``fields/t_NNNN.vti``): the pressure and the gap at each output time on
  one grid covering every field, a VTK time series ParaView opens and animates;
* ``history.png``: :func:`twoscale.plot.history.history_figure`.
"""

from __future__ import annotations

import json
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .._version import __version__
from ..grid import Grid
from ..scene import Scene
from .scene_file import scene_to_dict
from .tables import write_table

HISTORY_CSV_NAME = "history.csv"
HISTORY_JSON_NAME = "result.json"
HISTORY_FIELDS_NAME = "fields.pvd"
HISTORY_FIGURE_NAME = "history.png"
UNITS = {
    "time": "s",
    "length": "mm",
    "force": "N",
    "pressure": "MPa",
    "modulus": "MPa",
    "area": "mm^2",
    "compliance": "1/MPa",
    "angle": "rad",
}


def history_columns(n_asperities: int, tilt: bool) -> list[str]:
    """The header of ``history.csv``."""
    cols = ["time_s", "penetration_mm", "total_load_N", "contact_area_mm2"]
    if tilt:
        cols += ["tilt_x_rad", "tilt_y_rad"]
    return cols + [f"force_{k}" for k in range(1, n_asperities + 1)]


def write_history_csv(result, path, *, scene: Scene | None = None) -> list[Path]:
    """Write ``history.csv`` (module docstring) and its ``history.csv-metadata.json``, as
    every table (:func:`twoscale.io.tables.write_table`); the paths written, the CSV first."""
    path = Path(path)
    tilt = result.tilt is not None
    columns = history_columns(result.forces.shape[1], tilt)
    rows = []
    for k in range(len(result.times)):
        row = [result.times[k], result.penetration[k], result.total_load[k], result.contact_area[k]]
        if tilt:
            row += list(result.tilt[k])
        rows.append(dict(zip(columns, [float(v) for v in row + list(result.forces[k])])))
    descriptions = {
        "time_s": "output time, s",
        "penetration_mm": "rigid approach, mm",
        "total_load_N": "total normal load, N",
        "contact_area_mm2": "contact area, mm2",
        "tilt_x_rad": "tilt about x, rad",
        "tilt_y_rad": "tilt about y, rad",
        **{
            c: f"force of asperity {c[6:]} (numbered from 1 in scene order), N"
            for c in columns[4:]
            if c[:6] == "force_"
        },
    }
    record = {"units": dict(UNITS), "scene": None if scene is None else scene_to_dict(scene)}
    return write_table(
        path.parent,
        path.name.removesuffix(".csv"),
        rows,
        columns,
        title="a load history's answers, a row per output time",
        record=record,
        descriptions=descriptions,
    )


def history_to_dict(result, scene: Scene, *, warnings=()) -> dict:
    """The record of ``result.json`` for a history; ``warnings``: the run's
    (:meth:`twoscale.io.warning_log.WarningLog.entries`)."""
    from ..viscoelastic.prony import creep_compliance

    J = creep_compliance(result.material)
    m = result.material
    return {
        "version": __version__,
        "units": UNITS,
        "kind": "history",
        "method": result.method,
        "converged": bool(result.converged),
        "message": result.message,
        "material": {
            "E_relaxed": m.E,
            "nu": m.nu,
            "E_glassy": m.E_glassy,
            "prony": [list(b) for b in m.prony],
            "retardation_times": J.lambdas.tolist(),
            "creep_weights": J.c.tolist(),
            "J_relaxed": J.J_inf,
            "J_glassy": J.J0,
        },
        "history": {
            "control": result.history.kind,
            "points": [list(p) for p in result.history.points],
            "steps_rule": result.history.steps.describe(),
        },
        "steps": {
            "count": len(result.steps),
            "redone": int(result.rejected),
            "error_estimate": result.error_estimate,
            "t": [s.t for s in result.steps],
            "dt": [s.dt for s in result.steps],
            "J_eff": [s.J_eff for s in result.steps],
            "error": [s.error for s in result.steps],
            "iterations": [s.iterations for s in result.steps],
            "seconds": [s.seconds for s in result.steps],
        },
        "memory": dict(result.memory),
        "outputs": {
            "time_s": result.times.tolist(),
            "penetration_mm": result.penetration.tolist(),
            "total_load_N": result.total_load.tolist(),
            "contact_area_mm2": result.contact_area.tolist(),
            "tilt_rad": None if result.tilt is None else result.tilt.tolist(),
            "forces_N": result.forces.tolist(),
        },
        "timings_s": dict(result.timings_s),
        # what came from the on-disk caches and what was written or dropped there
        "caches": [u.as_dict() for u in result.caches],
        "scene": scene_to_dict(scene),
        "warnings": [dict(w) for w in warnings],
    }


def write_history_json(result, scene: Scene, path, *, warnings=()) -> Path:
    path = Path(path)
    path.write_text(json.dumps(history_to_dict(result, scene, warnings=warnings), indent=1))
    return path


def _covering(results) -> Grid | None:
    """One grid over every output time's fields (None when no time has any: no contact at
    all). A time without contact (a history starting at zero) has no fields."""
    fields = [f for r in results for f in r.fields]
    if not fields:
        return None
    boxes = np.array([f.grid.bounds for f in fields])
    h = fields[0].grid.h
    anchor = (fields[0].grid.x0, fields[0].grid.y0)
    e = 0.25 * h
    return Grid.covering(
        boxes[:, 0].min() + e, boxes[:, 1].max() - e, boxes[:, 2].min() + e, boxes[:, 3].max() - e, h, anchor=anchor
    )


def write_history_fields(result, path, *, comment: str | None = None) -> Path | None:
    """Write ``fields.pvd`` and ``fields/t_NNNN.vti`` (pressure MPa, gap mm, owner from 1);
    nothing (None) when no output time has a contact."""
    from .vti import write_image

    path = Path(path)
    grid = _covering(result.results)
    if grid is None:
        return None
    folder = path.parent / path.stem
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    for k, (t, res) in enumerate(zip(result.times, result.results)):
        p = res.pressure_on(grid)
        gap = np.full(grid.shape, np.nan)
        owner = np.zeros(grid.shape, dtype=np.int32)
        for f in res.fields:
            rows, cols = f.grid.window_in(grid)
            gap[rows, cols] = np.where(np.isfinite(f.gap), f.gap, np.nan)
            owner[rows, cols] = np.where(f.owner >= 0, f.owner + 1, owner[rows, cols])
        name = f"t_{k:04d}.vti"
        write_image(folder / name, grid, {"pressure_MPa": p, "gap_mm": gap, "asperity": owner}, comment=comment)
        entries.append((float(t), f"{folder.name}/{name}"))
    lines = ['<?xml version="1.0"?>\n']
    if comment:
        lines.append(f"<!-- {comment} -->\n")
    lines.append('<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n<Collection>\n')
    lines += [f'<DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>\n' for t, f in entries]
    lines.append("</Collection>\n</VTKFile>\n")
    path.write_text("".join(lines))
    return path


def write_history_outputs(
    result,
    scene: Scene,
    out_dir,
    *,
    figures: bool = True,
    vtk: bool = True,
    name: str | None = None,
    warnings=(),
) -> list[Path]:
    """Every file of a history into ``out_dir`` (module docstring); ``name`` (the scene
    file's stem) titles the figure with the body; ``warnings``: the run's, for ``result.json``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [
        *write_history_csv(result, out / HISTORY_CSV_NAME, scene=scene),
        write_history_json(result, scene, out / HISTORY_JSON_NAME, warnings=warnings),
    ]
    if vtk:
        fields = write_history_fields(
            result, out / HISTORY_FIELDS_NAME, comment=f"twoscale {__version__}; units mm, MPa, s"
        )
        written += [fields] if fields is not None else []
    if figures:
        from ..plot.history import history_figure

        written.append(history_figure(result, out / HISTORY_FIGURE_NAME, scene=scene, name=name))
    return written


__all__ = [
    "HISTORY_CSV_NAME",
    "HISTORY_FIELDS_NAME",
    "HISTORY_FIGURE_NAME",
    "history_columns",
    "history_to_dict",
    "write_history_csv",
    "write_history_fields",
    "write_history_json",
    "write_history_outputs",
]
