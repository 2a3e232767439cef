"""The tables of a rolling study, summary.json and the terminal's table, read from the case
folders (so they cover every case finished so far, by this run or an earlier one).

* ``cases.csv`` (+ ``.parquet``): one row per case: section, offset, body, material, load,
  speed, status, and the run's summary: positions, distance and duration, mean and rms
  (mean removed) of the total load and of the approach, mean contact area, mean drag (the
  hysteresis friction on a viscoelastic body: the road's force on the rubber along the
  rolling direction), drag over load, and on a viscoelastic body the energy the branches
  dissipated per mm and the balance of the drag's work against it;
* ``bands.csv`` (+ ``.parquet``): one row per case and third-octave band, the levels of each
  case's ``bands.csv`` (of the total force, dB re 1 N, under penetration control; of the
  approach, dB re 1 um, under load control: ``signal`` says which). A wide table is one
  pandas call away: ``bands.pivot_table(index=["section", "speed_kmh"], columns="band_Hz",
  values="level_dB")``.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

from .._version import __version__
from ..io import tables
from ..io.atomic import atomic_output
from ..io.result_json import UNITS
from .rolling_cases import case_key, expand
from .rolling_spec import RollingStudy
from .store import CaseStore

WHERE_COLUMNS = ("section", "offset_mm", "body", "material", "viscoelastic", "load_kind", "load", "speed_kmh")
NUMBER_COLUMNS = (
    "positions",
    "converged_positions",
    "h_mm",
    "distance_mm",
    "duration_s",
    "mean_load_N",
    "load_rms_N",
    "mean_approach_mm",
    "approach_rms_mm",
    "mean_contact_area_mm2",
    "mean_drag_N",
    "friction_coefficient",
    "dissipated_per_mm_N",
    "energy_balance",
    "seconds_per_position",
)
CASE_COLUMNS = WHERE_COLUMNS + ("status", "reason") + NUMBER_COLUMNS + ("seconds", "key")
BAND_COLUMNS = ("section", "body", "material", "load_kind", "load", "speed_kmh", "signal", "band_Hz", "level_dB", "key")
TITLES = {
    "cases": "one row per rolling case: means and rms of the signals, mean drag (hysteresis friction), energy",
    "bands": "one row per rolling case and third-octave band: level of the total force (dB re 1 N) or of the "
    "approach (dB re 1 um)",
}
DESCRIPTIONS = {
    "offset_mm": "how far along the strip the run starts, mm",
    "speed_kmh": "rolling speed, km/h",
    "load_rms_N": "rms of the total load less its mean, N",
    "approach_rms_mm": "rms of the approach less its mean, mm",
    "mean_drag_N": "mean force of the road on the body along +x, N (hysteresis friction on a viscoelastic body)",
    "friction_coefficient": "mean drag over mean load",
    "dissipated_per_mm_N": "energy dissipated in the Prony branches per mm rolled, N mm / mm",
    "energy_balance": "(drag work + vertical work) over (stored energy change + dissipated) less 1: a few "
    "percent or more says the step is too coarse (rolling.json step_check)",
    "signal": "the signal of the levels: total_load_N (penetration control) or penetration_mm (load control)",
}


def _where(case) -> dict:
    return {
        "section": case.section.name,
        "offset_mm": case.section.offset,
        "body": case.body.name,
        "material": case.material.name,
        "viscoelastic": case.viscoelastic,
        "load_kind": case.load[0],
        "load": case.load[1],
        "speed_kmh": case.speed,
    }


def rows(study: RollingStudy, store: CaseStore) -> tuple[list, list, list]:
    """(case rows, band rows, keys) of every case (status "missing" when not solved yet)."""
    case_rows, band_rows, keys = [], [], []
    for case in expand(study):
        key = case_key(case, study)
        keys.append(key)
        rec = store.read(key) or {"status": "missing", "reason": "not solved yet"}
        numbers = rec.get("numbers") or {}
        case_rows.append(
            {
                **_where(case),
                "status": rec["status"],
                "reason": rec.get("reason", ""),
                **{c: numbers.get(c) for c in NUMBER_COLUMNS},
                "seconds": rec.get("seconds"),
                "key": key,
            }
        )
        signal = "total_load_N" if case.load[0] == "penetration" else "penetration_mm"
        for b in rec.get("bands") or ():
            band_rows.append(
                {k: v for k, v in _where(case).items() if k in BAND_COLUMNS}
                | {"signal": signal, "band_Hz": b["band_Hz"], "level_dB": b["level_dB"], "key": key}
            )
    return case_rows, band_rows, keys


def write_rolling_outputs(out: str | Path, study: RollingStudy, run=None) -> dict:
    """Write ``cases``, ``bands`` (CSV, metadata, Parquet) and ``summary.json``; returns the summary."""
    out = Path(out)
    case_rows, band_rows, _ = rows(study, CaseStore(out))
    record = {"units": dict(UNITS, speed="km/h"), "study": {"name": study.name, "source": study.source}}
    for name, table, columns in (("cases", case_rows, CASE_COLUMNS), ("bands", band_rows, BAND_COLUMNS)):
        tables.write_table(
            out, name, table, columns, title=TITLES[name], record=record, descriptions=DESCRIPTIONS, parquet=0
        )
    counts = {s: sum(r["status"] == s for r in case_rows) for s in ("converged", "not-converged", "failed", "missing")}

    def listed(status):
        return [{"case": _label(r), "key": r["key"], "reason": r["reason"]} for r in case_rows if r["status"] == status]

    run_record = {} if run is None else {k: v for k, v in dataclasses.asdict(run).items() if k != "keys"}
    summary = {
        "version": __version__,
        "units": dict(UNITS, speed="km/h"),
        "kind": "rolling",
        "cases": len(case_rows),
        "counts": counts,
        "failed": listed("failed"),
        "not_converged": listed("not-converged"),
        "run": run_record,
        "study": study_record(study),
    }
    with atomic_output(out / "summary.json") as tmp:
        tmp.write_text(json.dumps(summary, indent=1, allow_nan=False, default=_plain) + "\n", encoding="utf-8")
    return summary


def _load(kind: str, value: float) -> str:
    return f"W={value:g}N" if kind == "total" else f"d={value:g}mm"


def _label(row: dict) -> str:
    return (
        f"{row['section']} {row['body']} {row['material']} {_load(row['load_kind'], row['load'])} "
        f"{row['speed_kmh']:g}km/h"
    )


def _plain(v):
    if isinstance(v, tuple):
        return list(v)
    if hasattr(v, "item"):
        return v.item()
    raise TypeError(f"not JSON-serialisable: {v!r}")


def study_record(study: RollingStudy) -> dict:
    """The study as JSON-ready data."""
    return {
        "name": study.name,
        "source": study.source,
        "track": study.track,
        "speeds_kmh": list(study.speeds),
        "loads": [{k: v} for k, v in study.loads],
        "solver": dict(study.solver),
        "figures": study.figures,
        "sections": [
            {"name": s.name, "offset_mm": s.offset, "surface": s.surface, "generate": s.generate, "digest": s.digest}
            for s in study.sections
        ],
        "bodies": [{"name": b.name, "influence": b.influence, "face": b.face} for b in study.bodies],
        "materials": [
            {"name": m.name, "E": m.material.E, "nu": m.material.nu, "prony": [list(p) for p in m.material.prony]}
            for m in study.materials
        ],
    }


def _rms(row: dict, num) -> str:
    """The fluctuating signal's rms: the approach's under a held load, the load's under a held approach."""
    if row["load_kind"] == "total":
        return num(row["approach_rms_mm"], ".3g") + " mm"
    return num(row["load_rms_N"], ".3g") + " N"


def rolling_table(out: str | Path, max_rows: int = 40) -> str:
    """The terminal's table, read back from ``cases.csv`` as any user's script would."""
    out = Path(out)
    with open(out / "cases.csv", newline="", encoding="utf-8") as fh:
        cases = list(csv.DictReader(fh))
    head = [
        "section",
        "body",
        "material",
        "load",
        "km/h",
        "status",
        "mean load N",
        "mean approach mm",
        "rms (held load: approach; held approach: load)",
        "mean drag N",
        "drag/load",
    ]

    def num(v: str, spec: str) -> str:
        return "-" if v in ("", None) or not math.isfinite(float(v)) else format(float(v), spec)

    body = [
        [
            r["section"],
            r["body"],
            r["material"],
            _load(r["load_kind"], float(r["load"])),
            num(r["speed_kmh"], "g"),
            r["status"],
            num(r["mean_load_N"], ".5g"),
            num(r["mean_approach_mm"], ".4g"),
            _rms(r, num),
            num(r["mean_drag_N"], ".4g"),
            num(r["friction_coefficient"], ".3g"),
        ]
        for r in cases[:max_rows]
    ]
    widths = [max(len(x) for x in col) for col in zip(head, *body)]
    lines = ["  " + "  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in [head, *body]]
    if len(cases) > max_rows:
        lines.append(f"  ... {len(cases) - max_rows} more rows: {out / 'cases.csv'}")
    lines.append(
        f"tables: {out}/cases.csv, bands.csv (each with .csv-metadata.json); summary: {out}/summary.json; "
        f"each case's files: {out}/cases/<key>/"
    )
    lines += _no_bands_line(out, cases)
    return "\n".join(lines)


def _no_bands_line(out: Path, cases: list[dict]) -> list[str]:
    """A line saying why ``bands.csv`` has no rows, when it has none: every run too short
    for a band's 3 frequency bins (1 / duration apart) below the step's Nyquist frequency."""
    with open(out / "bands.csv", newline="", encoding="utf-8") as fh:
        if sum(1 for _ in csv.reader(fh)) > 1:
            return []
    runs = [float(r["distance_mm"]) for r in cases if r.get("distance_mm") not in ("", None)]
    longest = f" (the longest run {max(runs):g} mm of road)" if runs else ""
    return [
        f"bands.csv has no rows: no case's run resolves a third-octave band{longest}; a band needs 3 frequency "
        f"bins, 1 / duration apart, below the step's Nyquist frequency: roll a longer run (docs/rolling.md)"
    ]
