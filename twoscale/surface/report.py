"""Records of a measured surface: the per-asperity CSV and the JSON summary that
``twoscale surface`` writes (I/O module; every file records the version and units)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .._version import __version__
from ..io.atomic import atomic_output

CSV_COLUMNS = (
    "asperity",
    "x_mm",
    "y_mm",
    "summit_height_mm",
    "recess_z_mm",
    "prominence_mm",
    "basin_area_mm2",
    "sphere_R_mm",
    "law_exponent",
    "sphere_law_error",
)


def asperity_rows(surface, table=None, sphere_error=None) -> list[dict]:
    """One row per asperity: summit position and height, its recess below the highest
    summit, prominence, basin area, equivalent-sphere radius and, with the law ``table``,
    the law's exponent over its last tabulated step and the sphere law's largest error."""
    seg = surface.segmentation
    exponents = table.exponents() if table is not None else None
    rows = []
    for k, a in enumerate(surface.asperities):
        rows.append(
            {
                "asperity": k + 1,
                "x_mm": a.x,
                "y_mm": a.y,
                "summit_height_mm": float(seg.heights[k]),
                "recess_z_mm": a.z,
                "prominence_mm": float(seg.prominence[k]),
                "basin_area_mm2": float(seg.areas[k]),
                "sphere_R_mm": a.R,
                "law_exponent": float(exponents[k]) if exponents is not None else math.nan,
                "sphere_law_error": float(sphere_error.per_asperity[k]) if sphere_error is not None else math.nan,
            }
        )
    return rows


#: What each column of segmentation.csv holds (recorded in its metadata JSON).
DESCRIPTIONS = {
    "asperity": "asperity number, from 1 as in every table",
    "x_mm": "summit position x, mm",
    "y_mm": "summit position y, mm",
    "summit_height_mm": "summit height on the map, mm",
    "recess_z_mm": "recess below the highest summit, mm",
    "prominence_mm": "summit prominence, mm",
    "basin_area_mm2": "area of the asperity's basin, mm2",
    "sphere_R_mm": "radius of the equivalent sphere, mm",
    "law_exponent": "exponent m of P ~ delta^m over the law's last tabulated step (empty with --no-laws)",
    "sphere_law_error": "max |P_sphere - P_tab| / P_tab over the tabulated depths (empty with --no-laws)",
}


def write_segmentation_table(
    rows: list[dict], out_dir: str | Path, name: str = "segmentation", *, record: dict | None = None
) -> list[Path]:
    """The rows as ``NAME.csv`` with its metadata JSON (and Parquet with pyarrow) in
    ``out_dir`` (:func:`twoscale.io.tables.write_table`)."""
    from ..io.tables import LONG_TABLE, write_table

    return write_table(
        out_dir,
        name,
        rows,
        CSV_COLUMNS,
        title="asperities of a height map (segmentation)",
        record={"units": {"length": "mm", "area": "mm2"}, **(record or {})},
        descriptions=DESCRIPTIONS,
        parquet=LONG_TABLE,
    )


def surface_summary(surface, scene_record: dict, *, table=None, sphere_error=None, seconds: dict) -> dict:
    """JSON-ready summary: the map as conditioned, the segmentation, the laws, timings."""
    hm, seg = surface.hmap, surface.segmentation
    out = {
        "version": __version__,
        "units": {"length": "mm", "area": "mm2", "force": "N"},
        "scene": scene_record,
        "map": {
            "file": hm.source,
            "samples": list(hm.shape),
            "spacing_mm": hm.h,
            "measured_spacing_mm": hm.measured_spacing,
            "units": hm.units,
            "units_from": hm.units_from,
            "missing_samples": hm.filled,
            "missing_treated_as": surface.options.fill,
            "height_range_mm": [float(np.nanmin(hm.heights)), float(np.nanmax(hm.heights))],
        },
        "segmentation": {
            "asperities": len(seg),
            "candidates": seg.candidates,
            "min_distance_mm": seg.min_distance,
            "prominence_mm": seg.min_prominence,
        },
        "laws": None,
        "seconds": seconds,
    }
    if table is not None:
        out["laws"] = {
            "kind": surface.options.law,
            "depth_mm": surface.options.law_depth,
            "levels": surface.options.law_levels,
            "all_solves_converged": table.converged,
            "sphere_law_error": {"median": sphere_error.median, "largest": sphere_error.largest},
        }
    return out


def write_json(record: dict, path: str | Path) -> Path:
    with atomic_output(Path(path)) as tmp:
        tmp.write_text(json.dumps(record, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return Path(path)
