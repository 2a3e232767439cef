"""What ``twoscale compare`` writes: its tables, Markdown, summary, figures and runs.

The comparison itself (the bodies' solves, indicators and per-tip changes) is made by
:mod:`twoscale.cli.compare`; this module only writes it into the output folder (a staged
temporary folder, renamed at the end).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

from .._version import __version__
from ..comparison import CHANGE_FIELDS, ROW_FIELDS, Measured, Run, load_title, per_asperity_rows, sensor_text
from ..io.atomic import atomic_output
from ..io.result_json import UNITS, write_result
from ..io.scene_file import scene_to_dict
from ..io.tables import LONG_TABLE, write_table
from ..scene import Scene
from ..sensor import Sensor
from .compare_report import compare_record, markdown

#: What the columns of forces.csv and changes.csv hold (in their metadata JSON).
FORCE_COLUMNS = {
    "load_N": "the given total load, N (empty under penetration control)",
    "penetration_mm": "the given rigid approach, mm (empty under load control)",
    "body": "halfspace, block-bonded, block-sliding, or measured",
    "asperity": "tip number, from 1 in scene order",
    "force_N": "tip force, N",
    "contact_area_mm2": "tip contact area, mm2",
    "max_pressure_MPa": "largest pressure on the tip, MPa",
    "macro_force_N": "the macro step's tip force, N (two-scale method)",
}
CHANGE_COLUMNS = {
    **{k: FORCE_COLUMNS[k] for k in ("load_N", "penetration_mm", "asperity")},
    "reference": "the body compared with (the first: the half-space)",
    "body": "the body judged",
    "reference_force_N": "the tip's force on the reference body, N",
    "force_N": "the tip's force, N",
    "change_N": "force_N - reference_force_N, N",
    "change_percent": "change in percent of the tip's own reference force (empty when it is 0)",
}


@dataclass(frozen=True)
class Comparison:
    """One comparison's answers: the scene (its first load case), every run, the
    indicators (percent), the notes, the measured data (or None), the sensor and the
    per-tip changes against the half-space."""

    scene: Scene
    runs: list[Run]
    indicators: dict
    notes: list[str]
    measured: Measured | None
    sensor: Sensor
    changes: list


def _write_text(path: Path, text: str) -> None:
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="")


def write_outputs(out: Path, args: argparse.Namespace, comparison: Comparison) -> None:
    """Write every file of ``twoscale compare`` into ``out`` (see :mod:`twoscale.cli.compare`)."""
    out.mkdir(parents=True, exist_ok=True)
    record = compare_record(comparison.scene, comparison.runs, comparison.sensor)
    _write_tables(out, args, comparison, record)
    _write_summary(out, args, comparison, record)
    _write_figures(out, Path(args.scene).stem, comparison, record)
    _write_runs(out, args, comparison.runs)


def _write_tables(out: Path, args, c: Comparison, record: dict) -> None:
    tables = {"source": f"compare {args.scene}", "units": dict(UNITS), **record}
    write_table(
        out,
        "forces",
        per_asperity_rows(c.runs, c.measured),
        ROW_FIELDS,
        record=tables,
        parquet=LONG_TABLE,
        title="per load, body and tip: force, contact area, peak pressure",
        descriptions=FORCE_COLUMNS,
    )
    write_table(
        out,
        "changes",
        c.changes,
        CHANGE_FIELDS,
        record=tables,
        parquet=LONG_TABLE,
        descriptions=CHANGE_COLUMNS,
        title="per load and tip: each body's tip force against the reference body's (the half-space)",
    )
    md = markdown(args.scene, c.runs, c.indicators, c.notes, args.method, c.measured, c.sensor, c.changes)
    md += (
        "\n<details><summary>scene, bodies and sensor (JSON)</summary>\n\n```json\n"
        + json.dumps(record, indent=1)
        + "\n```\n</details>\n"
    )
    _write_text(out / "forces.md", md)


def _write_summary(out: Path, args, c: Comparison, record: dict) -> None:
    summary = {
        "version": __version__,
        "units": dict(UNITS),
        "method": args.method,
        "notes": c.notes,
        **record,
        "indicators_percent": c.indicators,
        "runs": [
            {
                "load": r.load,
                "body": r.body,
                "converged": bool(r.result.converged),
                "message": r.result.message,
                "total_load": float(r.result.total_load),
                "approach_mm": float(r.result.penetration),
                "contact_area_mm2": r.result.contact_area,
                "body_label": r.result.body.label if r.result.body is not None else r.body,
                "seconds": r.seconds,
            }
            for r in c.runs
        ],
    }
    _write_text(out / "summary.json", json.dumps(summary, indent=2, allow_nan=False) + "\n")


def _write_figures(out: Path, name: str, c: Comparison, record: dict) -> None:
    """Per load: forces side by side, pressure maps, sensor-cell means and, with more than
    one body, each body's tip forces minus the half-space's; every title starts with the
    scene's ``name``."""
    from ..plot import Caption, compare_forces, compare_maps, difference_map

    meta = {"bodies": record["bodies"], "sensor": record["sensor"]}

    def caption(title: str) -> Caption:
        return Caption(title=title, scene=record["scene"], name=name, meta=meta)

    runs, tips = c.runs, c.runs[0].scene.asperities
    for load in dict.fromkeys(r.load for r in runs):
        group = {r.body: r.result for r in runs if r.load == load}
        compare_forces(
            group,
            out / f"forces_{load}.png",
            measured=None if c.measured is None else c.measured.forces,
            caption=caption(f"force per asperity, {load_title(load)}"),
        )
        compare_maps(group, out / f"maps_{load}.png", tips=tips, caption=caption(f"pressure, {load_title(load)}"))
        compare_maps(
            group,
            out / f"sensor_{load}.png",
            tips=tips,
            sensor=c.sensor,
            caption=caption(f"sensor-cell means ({sensor_text(c.sensor)}), {load_title(load)}"),
        )
        if len(group) > 1:
            difference_map(
                group,
                out / f"difference_{load}.png",
                tips=tips,
                caption=caption(f"force difference per tip, {load_title(load)}"),
            )


def _write_runs(out: Path, args, runs: list[Run]) -> None:
    from ..io.solve_outputs import FIELDS_NAME
    from ..io.vtk import write_vtk

    for r in runs:
        d = out / "runs" / f"{r.body}_{r.load}"
        write_result(r.result, r.scene, d, method=args.method, warnings=r.warnings)
        if args.vtk:
            write_vtk(
                r.result,
                d / FIELDS_NAME,
                asperities=r.scene.asperities,
                pivot=r.scene.pivot,
                scene=scene_to_dict(r.scene),
            )
