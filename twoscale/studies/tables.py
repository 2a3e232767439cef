"""Tidy tables of a study, e_M / e_m between bodies, and summary.json.

Read from the case folders (:mod:`twoscale.studies.store`), so they cover every case
finished so far, by this run or an earlier one. Tables (one row per observation, units in
the column names), each as CSV with its ``.csv-metadata.json`` and, when ``pyarrow`` is
installed, Parquet (:mod:`twoscale.io.tables`):

* ``cases``: one row per case (status, reason, total load, approach, tilt, contact area,
  the cell size ``h_mm`` and ``h_source``: ``solver.h``, ``scene`` or ``lightest load``,
  see :mod:`twoscale.studies.cases`);
* ``asperities``: one row per case and tip under the footprint (scene index of the tip,
  its position in the body frame, force, contact area, peak pressure);
* ``indicators``: per scene, load and position, e_M (tip forces) and e_m (sensor cells)
  of each body against the first body of the study, in percent; a tip outside a body's
  footprint carries no force there.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .._version import __version__
from ..io import tables
from ..io.atomic import atomic_output
from ..io.result_json import UNITS
from ..comparison import e_m_or_none
from ..sensor import e_M
from .cases import Case, h_source
from .keys import scene_record
from .spec import Study
from .store import CaseStore

#: The columns that say which case a row belongs to (both tables start with them).
STATIC_WHERE_COLUMNS = (
    "scene",
    "body",
    "load_kind",
    "load",
    "position",
    "shift_x_mm",
    "shift_y_mm",
    "distance_mm",
)
CASE_COLUMNS = (
    *STATIC_WHERE_COLUMNS,
    "status",
    "reason",
    "n_tips",
    "total_load_N",
    "approach_mm",
    "tilt_alpha_rad",
    "tilt_beta_rad",
    "contact_area_mm2",
    "h_mm",
    "h_source",
    "strategy",
    "seconds",
    "key",
)
TIP_COLUMNS = (
    *STATIC_WHERE_COLUMNS,
    "asperity",
    "x_mm",
    "y_mm",
    "force_N",
    "contact_area_mm2",
    "max_pressure_MPa",
    "key",
)
INDICATOR_COLUMNS = (
    "scene",
    "load_kind",
    "load",
    "position",
    "distance_mm",
    "reference",
    "body",
    "e_M_percent",
    "e_m_percent",
)


def _where(study: Study, case: Case) -> dict:
    sx, sy = case.shift
    x0, y0 = study.positions[0]
    return {
        "scene": case.scene.name,
        "body": case.body.name,
        "load_kind": case.load[0],
        "load": float(case.load[1]),
        "position": case.position,
        "shift_x_mm": sx,
        "shift_y_mm": sy,
        "distance_mm": float(math.hypot(sx - x0, sy - y0)),
    }


def rows(study: Study, cases: list, keys: list, records: dict) -> tuple[list, list]:
    """(case rows, tip rows) of the cases from their records (``case.json`` by key;
    status "missing" when there is none)."""
    case_rows, tip_rows = [], []
    for case, key in zip(cases, keys):
        rec = records.get(key) or {"status": "missing", "reason": "not solved yet", "tips": []}
        res = rec.get("result")
        where = _where(study, case)
        row = {
            **where,
            "status": rec["status"],
            "reason": rec.get("reason", ""),
            "n_tips": len(rec["tips"]),
            "total_load_N": None,
            "approach_mm": None,
            "tilt_alpha_rad": None,
            "tilt_beta_rad": None,
            "contact_area_mm2": None,
            "h_mm": None,
            "h_source": h_source(case, study),
            "strategy": None,
            "seconds": rec.get("seconds"),
            "key": key,
        }
        if res is not None:
            tilt = res["tilt"] or (None, None)
            row.update(
                total_load_N=res["total_load"],
                approach_mm=res["penetration"],
                tilt_alpha_rad=tilt[0],
                tilt_beta_rad=tilt[1],
                contact_area_mm2=float(np.sum(res["contact_areas"])),
                h_mm=res["h"],
                strategy=res["strategy"],
            )
            asps = case.scene.scene.asperities
            for j, k in enumerate(rec["tips"]):
                tip_rows.append(
                    {
                        **where,
                        "asperity": k + 1,
                        "x_mm": asps[k].x + case.shift[0],
                        "y_mm": asps[k].y + case.shift[1],
                        "force_N": res["forces"][j],
                        "contact_area_mm2": res["contact_areas"][j],
                        "max_pressure_MPa": res["max_pressures"][j],
                        "key": key,
                    }
                )
        case_rows.append(row)
    return case_rows, tip_rows


def indicator_rows(study: Study, cases: list, keys: list, records: dict, store: CaseStore) -> list:
    """e_M and e_m (percent) of each body against the study's first body that has a result,
    per scene, load and position (sensor maps read from ``store``)."""
    groups: dict = {}
    for case, key in zip(cases, keys):
        rec = records.get(key)
        if rec is not None and rec.get("result") is not None:
            g = groups.setdefault((case.scene.name, case.load, case.position), [])
            g.append((case, key, rec))
    out = []
    for (scene, load, position), members in groups.items():
        ref_case, ref_key, ref = members[0]
        ref_map = store.sensor_map(ref_key)
        n = len(ref_case.scene.scene.asperities)
        P_ref = _scene_forces(ref, n)
        for case, key, rec in members[1:]:
            p = store.sensor_map(key)
            out.append(
                {
                    "scene": scene,
                    "load_kind": load[0],
                    "load": float(load[1]),
                    "position": position,
                    "distance_mm": _where(study, case)["distance_mm"],
                    "reference": ref_case.body.name,
                    "body": case.body.name,
                    "e_M_percent": e_M(_scene_forces(rec, n), P_ref) if np.any(P_ref) else None,
                    "e_m_percent": e_m_or_none(p, ref_map),
                }
            )
    return out


def _scene_forces(rec: dict, n: int) -> np.ndarray:
    """Forces of every tip of the scene (0 for the tips not under the footprint)."""
    P = np.zeros(n)
    P[np.asarray(rec["tips"], dtype=int)] = rec["result"]["forces"]
    return P


def study_record(study: Study) -> dict:
    """The study as JSON-ready data (recorded in summary.json)."""
    return {
        "name": study.name,
        "source": study.source,
        "method": study.method,
        "scenes": [
            {"name": s.name, "file": s.path, "digest": s.digest, "scene": scene_record(s.scene)} for s in study.scenes
        ],
        "bodies": [
            {
                "name": b.name,
                "influence": {k: (list(v) if isinstance(v, tuple) else v) for k, v in b.influence.items()},
                "footprint": {
                    "window": None if b.footprint.size is None else list(b.footprint.size),
                    "centre": list(b.footprint.centre),
                },
            }
            for b in study.bodies
        ],
        "loads": None if study.loads is None else [{k: v} for k, v in study.loads],
        "tilt": study.tilt,
        "positions": [list(p) for p in study.positions],
        "track": study.track,
        "solver": dict(study.solver),
        "sensor": {
            "nx": study.sensor.nx,
            "ny": study.sensor.ny,
            "cell": study.sensor.cell,
            "centre": list(study.sensor.centre),
        },
    }


def summary(study: Study, case_rows: list, indicators: list, run: dict) -> dict:
    """summary.json: counts by status, failures and non-converged cases with their reasons,
    the run, the indicators, the study, the program version and the units."""
    counts = {s: sum(r["status"] == s for r in case_rows) for s in ("converged", "not-converged", "failed", "missing")}

    def listed(status):
        return [
            {
                "case": f"{r['scene']} {r['body']} {r['load_kind']}={r['load']:g} p{r['position']}",
                "key": r["key"],
                "reason": r["reason"],
            }
            for r in case_rows
            if r["status"] == status
        ]

    return {
        "version": __version__,
        "units": dict(UNITS),
        "cases": len(case_rows),
        "counts": counts,
        "failed": listed("failed"),
        "not_converged": listed("not-converged"),
        "run": run,
        "indicators_percent": indicators,
        "study": study_record(study),
    }


#: One line per table: what it holds (its metadata JSON's title).
TITLES = {
    "cases": "one row per case of the study: status, total load, approach, tilt, contact area, cell size",
    "asperities": "one row per case and tip under the footprint: position, force, contact area, peak pressure",
    "indicators": "e_M (tip forces) and e_m (sensor cells) of each body against the study's first body, percent",
}


def write_table(out: Path, name: str, table: list, columns: tuple, study: Study | None = None) -> list:
    """Write ``name.csv``, its metadata JSON and (with pyarrow) ``name.parquet``
    (:func:`twoscale.io.tables.write_table`); returns the paths written."""
    record = {"units": dict(UNITS)}
    if study is not None:
        record["study"] = {"name": study.name, "source": study.source}
    return tables.write_table(out, name, table, columns, title=TITLES.get(name, name), record=record, parquet=0)


def write_tables(out: Path, study: Study, cases: list, keys: list, store: CaseStore, run: dict) -> tuple:
    """Write the three tables and summary.json into ``out``; returns (case rows, tip rows,
    indicator rows, summary)."""
    records = {k: store.read(k) for k in dict.fromkeys(keys)}
    case_rows, tip_rows = rows(study, cases, keys, records)
    ind = indicator_rows(study, cases, keys, records, store)
    write_table(out, "cases", case_rows, CASE_COLUMNS, study)
    write_table(out, "asperities", tip_rows, TIP_COLUMNS, study)
    write_table(out, "indicators", ind, INDICATOR_COLUMNS, study)
    record = summary(study, case_rows, ind, run)
    with atomic_output(out / "summary.json") as tmp:
        tmp.write_text(json.dumps(record, indent=1, allow_nan=False, default=_json_default) + "\n", encoding="utf-8")
    return case_rows, tip_rows, ind, record


def _json_default(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    raise TypeError(f"not JSON-serialisable: {v!r}")
