"""The per-asperity table of a solve as CSV (``asperities.csv``).

One row per asperity, numbered from 1 in scene order (the numbers drawn on the figures
and written in the ``owner`` array of the field files), header on the first line; the
version, units and scene in ``asperities.csv-metadata.json`` beside it, and the same rows
in ``asperities.parquet`` for a long table (1,000 tips or more) when pyarrow is installed (:mod:`twoscale.io.tables`):

``asperity, x_mm, y_mm, z_mm, R_mm, shape, force_N, contact_area_mm2,
max_pressure_MPa, mean_pressure_MPa[, macro_force_N]``

``z_mm`` is the tip recess as given (its height above z = 0, where the approach d is
measured: the local approach is d - z); R and
shape are the indenter's; force, contact area and peak pressure are integrals of the
final pressure over the cells the asperity owns (so the forces sum to the total load);
mean pressure is force / contact area (0 without contact); the macro step's force is
present for methods that have a macro step.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from .tables import LONG_TABLE, write_table

#: Units of every table (column names carry them too).
UNITS = {"length": "mm", "force": "N", "area": "mm2", "pressure": "MPa"}

ASPERITY_CSV_NAME = "asperities.csv"
COLUMNS = (
    "asperity",
    "x_mm",
    "y_mm",
    "z_mm",
    "R_mm",
    "shape",
    "force_N",
    "contact_area_mm2",
    "max_pressure_MPa",
    "mean_pressure_MPa",
)


def asperity_rows(result, asperities: Sequence) -> list[dict]:
    """One dict per asperity (the CSV rows, numbers as floats), in scene order."""
    s, macro = result.asperities, result.macro_forces
    if len(asperities) != s.forces.size:
        raise ValueError(f"{len(asperities)} asperities given, the result has {s.forces.size}")
    rows = []
    for k, a in enumerate(asperities):
        f, area = float(s.forces[k]), float(s.contact_areas[k])
        row = {
            "asperity": k + 1,
            "x_mm": float(a.x),
            "y_mm": float(a.y),
            "z_mm": float(a.z),
            "R_mm": float(a.R),
            "shape": a.shape,
            "force_N": f,
            "contact_area_mm2": area,
            "max_pressure_MPa": float(s.max_pressures[k]),
            "mean_pressure_MPa": f / area if area > 0 else 0.0,
        }
        if macro is not None:
            row["macro_force_N"] = float(macro[k])
        rows.append(row)
    return rows


#: What each column holds (recorded in the metadata JSON beside the CSV).
DESCRIPTIONS = {
    "asperity": "tip number, from 1 in scene order (as on the figures and in the owner array)",
    "x_mm": "tip position x, mm",
    "y_mm": "tip position y, mm",
    "z_mm": "tip recess z as given, mm: height above z = 0, where the approach d is measured (local approach d - z)",
    "R_mm": "tip radius, mm",
    "shape": "sphere or paraboloid",
    "force_N": "integral of the final pressure over the cells the tip owns, N",
    "contact_area_mm2": "area of the loaded cells the tip owns, mm2",
    "max_pressure_MPa": "largest cell pressure on the tip, MPa",
    "mean_pressure_MPa": "force / contact area, MPa (0 without contact)",
    "macro_force_N": "the macro step's force on the tip, N (two-scale method)",
}


def write_asperity_csv(
    result, asperities: Sequence, path: str | Path, *, scene: Mapping[str, Any] | None = None, source: str = ""
) -> list[Path]:
    """Write the per-asperity table (see module doc) at ``path``, its metadata JSON and,
    with pyarrow, its Parquet copy beside it (:func:`twoscale.io.tables.write_table`).

    Parameters
    ----------
    result : ContactResult
    asperities : sequence of Asperity
        The scene's indenters, in scene order.
    path : path-like
        The CSV's path (``.../asperities.csv``).
    scene : mapping, optional
        The scene as JSON-able data, recorded in the metadata JSON.
    source : str, default ""
        What produced the file (e.g. ``solve S1.toml``), recorded in the metadata JSON.

    Returns
    -------
    list of Path written, the CSV first.
    """
    rows = asperity_rows(result, asperities)
    fields = COLUMNS + (("macro_force_N",) if rows and "macro_force_N" in rows[0] else ())
    record = {"source": source, "units": dict(UNITS), "scene": None if scene is None else dict(scene)}
    path = Path(path)
    return write_table(
        path.parent,
        path.name.removesuffix(".csv"),
        rows,
        fields,
        record=record,
        title="per-tip forces, contact areas and pressures of a solve",
        descriptions=DESCRIPTIONS,
        parquet=LONG_TABLE,
    )
