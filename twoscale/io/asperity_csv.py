"""The per-asperity table of a solve as CSV (``asperities.csv``).

One row per asperity, numbered from 1 in scene order (the numbers drawn on the figures
and written in the ``owner`` array of the field files), after ``#`` comment lines with
the version and units, and the scene as one line of JSON:

``asperity, x_mm, y_mm, z_mm, R_mm, shape, force_N, contact_area_mm2,
max_pressure_MPa, mean_pressure_MPa[, macro_force_N]``

``z_mm`` is the tip recess (how far the tip sits above the lowest tip level); R and
shape are the indenter's; force, contact area and peak pressure are integrals of the
final pressure over the cells the asperity owns (so the forces sum to the total load);
mean pressure is force / contact area (0 without contact); the macro step's force is
present for methods that have a macro step.
"""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any, Mapping, Sequence

from .._version import __version__
from .atomic import atomic_output

ASPERITY_CSV_NAME = "asperities.csv"
COLUMNS = ("asperity", "x_mm", "y_mm", "z_mm", "R_mm", "shape", "force_N", "contact_area_mm2",
           "max_pressure_MPa", "mean_pressure_MPa")


def asperity_rows(result, asperities: Sequence) -> list[dict]:
    """One dict per asperity (the CSV rows, numbers as floats), in scene order."""
    s, macro = result.asperities, result.macro_forces
    if len(asperities) != s.forces.size:
        raise ValueError(f"{len(asperities)} asperities given, the result has {s.forces.size}")
    rows = []
    for k, a in enumerate(asperities):
        f, area = float(s.forces[k]), float(s.contact_areas[k])
        row = {"asperity": k + 1, "x_mm": float(a.x), "y_mm": float(a.y), "z_mm": float(a.z),
               "R_mm": float(a.R), "shape": a.shape, "force_N": f, "contact_area_mm2": area,
               "max_pressure_MPa": float(s.max_pressures[k]),
               "mean_pressure_MPa": f / area if area > 0 else 0.0}
        if macro is not None:
            row["macro_force_N"] = float(macro[k])
        rows.append(row)
    return rows


def write_asperity_csv(result, asperities: Sequence, path: str | Path, *,
                       scene: Mapping[str, Any] | None = None, source: str = "") -> Path:
    """Write the per-asperity table (see module doc) to ``path``, atomically.

    Parameters
    ----------
    result : ContactResult
    asperities : sequence of Asperity
        The scene's indenters, in scene order.
    path : path-like
    scene : mapping, optional
        The scene as JSON-able data, recorded in a ``# scene:`` line.
    source : str, default ""
        What produced the file (e.g. the scene file's name), in the first line.

    Returns
    -------
    Path written.
    """
    rows = asperity_rows(result, asperities)
    buf = io.StringIO()
    buf.write(f"# twoscale {__version__} {source}; asperities numbered from 1 in scene order; "
              f"units: length mm, force N, area mm^2, pressure MPa\n".replace("  ", " "))
    if scene is not None:
        buf.write(f"# scene: {json.dumps(dict(scene), separators=(',', ':'))}\n")
    fields = COLUMNS + (("macro_force_N",) if rows and "macro_force_N" in rows[0] else ())
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    for row in rows:
        w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    with atomic_output(path) as tmp:
        tmp.write_text(buf.getvalue(), encoding="utf-8", newline="")
    return Path(path)
