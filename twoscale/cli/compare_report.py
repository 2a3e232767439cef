"""What ``twoscale compare`` says: the records every file carries, the Markdown report
(``forces.md``) and the compact terminal summary that leads with the differences.

The summary gives, per load, each body's approach and contact area with their change against
the reference body (the half-space), e_M and e_m with what they mean, and the tips whose
force changes most, in percent of the tip's own force on the reference body (tips carrying
under 1 % of the largest force are not ranked); every tip's change is in ``changes.csv``.
"""

from __future__ import annotations

import math

from .._version import __version__
from ..comparison import Measured, Run, largest_changes, load_title, sensor_text
from ..io.scene_file import scene_to_dict
from ..display import tilt_text
from ..scene import Scene
from ..sensor import Sensor
from .options import DEFAULT_SENSOR


def sensor_record(sensor: Sensor) -> dict:
    """The sensor as JSON-ready data (what the files record)."""
    return {
        "nx": int(sensor.nx),
        "ny": int(sensor.ny),
        "cell_mm": float(sensor.cell),
        "centre_mm": [float(v) for v in sensor.centre],
    }


# ---------------------------------------------------------------- what every file records
def _load_record(run: Run) -> dict:
    sc = run.scene
    value = {"total": float(sc.total_load)} if sc.total_load is not None else {"penetration": float(sc.penetration)}
    return {"label": run.load, **value}


def bodies_record(runs) -> dict:
    """Per body, in table order: its influence settings (kind; size, base and origin of a
    block) and every load it was solved at (``label`` and ``total`` N or ``penetration`` mm)."""
    out: dict = {}
    for r in runs:
        body = out.setdefault(r.body, {"influence": scene_to_dict(r.scene)["influence"], "loads": []})
        body["loads"].append(_load_record(r))
    return out


def compare_record(scene: Scene, runs, sensor: Sensor) -> dict:
    """What every top-level file of ``compare`` records: the scene as given (after
    ``--h`` and ``--centre-pivot``; ``load.cases`` lists every load run, ``load.total``
    is the first), the bodies (:func:`bodies_record`) and the sensor."""
    return {"scene": scene_to_dict(scene), "bodies": bodies_record(runs), "sensor": sensor_record(sensor)}


# ---------------------------------------------------------------- tables
def _fmt(v) -> str:
    return "n/a" if v is None else f"{v:.3g}"


def markdown(
    scene_path: str,
    runs,
    ind: dict,
    notes: list[str],
    method: str,
    measured: Measured | None = None,
    sensor: Sensor = DEFAULT_SENSOR,
    changes: list | None = None,
) -> str:
    """The Markdown report: what changes between the bodies (with ``changes``, the rows of
    :func:`twoscale.comparison.tip_changes`), per-load tables of forces, areas and peak
    pressures, indicators, and what each body was (influence settings and loads)."""
    lines = [f"# twoscale compare {scene_path}", "", f"twoscale {__version__}; method {method}; units mm, N, MPa.", ""]
    lines += [f"> **Note:** {n}" for n in notes] + ([""] if notes else [])
    if changes is not None and len({r.body for r in runs}) > 1:
        lines += changes_markdown(runs, ind, changes)
    for load in dict.fromkeys(r.load for r in runs):
        group = [r for r in runs if r.load == load]
        lines += [f"## Load case: {load_title(load)}", ""]
        for r in group:
            tilt = "" if r.result.tilt is None else f", tilt (alpha, beta) ({tilt_text(r.result)}) rad"
            conv = "converged" if r.result.converged else f"NOT converged: {r.result.message}"
            lines.append(
                f"- {r.body}: total {r.result.total_load:.5g} N, approach "
                f"{r.result.penetration:.5g} mm{tilt}; {conv}; {r.seconds:.3g} s"
            )
        lines.append("")
        mf = None if measured is None else measured.forces
        head = (
            ["asperity"]
            + ([] if mf is None else ["measured F (N)"])
            + [f"{r.body} {q}" for q in ("F (N)", "A (mm^2)", "p_max (MPa)") for r in group]
        )
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        n = len(group[0].result.asperities.forces)
        for k in range(n):
            vals = ([] if mf is None else [f"{mf[k]:.4g}"]) + [
                f"{getattr(r.result.asperities, q)[k]:.4g}"
                for q in ("forces", "contact_areas", "max_pressures")
                for r in group
            ]
            lines.append(f"| {k + 1} | " + " | ".join(vals) + " |")
        lines.append("")
        if load in ind:
            lines += [
                "e_M / e_m in percent (row: reference body in the denominator; e_m on the "
                f"{sensor_text(sensor)}). Both are ratios of squared norms, "
                "e_M = 100 sum|P - P~|^2 / sum|P~|^2: one tip of seven 7 % off gives about 0.07 %, "
                "so compare the per-tip forces above as well (docs/method.md section 5).",
                "",
            ]
            names = [r.body for r in group]
            lines += ["| reference | " + " | ".join(names) + " |", "|" + "---|" * (len(names) + 1)]
            for a in [x for x in ["measured"] + names if x in ind[load]]:
                cells = [
                    "-" if a == b else f"{_fmt(ind[load][a][b]['e_M'])} / {_fmt(ind[load][a][b]['e_m'])}" for b in names
                ]
                lines.append(f"| {a} | " + " | ".join(cells) + " |")
            lines.append("")
    lines += [
        "## Bodies",
        "",
        "| body | influence | size (mm) | base | origin (mm) | loads |",
        "|---|---|---|---|---|---|",
    ]
    for name, b in bodies_record(runs).items():
        inf = b["influence"]
        size = " x ".join(f"{v:g}" for v in inf["size"]) if "size" in inf else "-"
        origin = "({:g}, {:g})".format(*inf["origin"]) if "origin" in inf else "-"
        loads = ", ".join(load_title(x["label"]) for x in b["loads"])
        lines.append(f"| {name} | {inf['kind']} | {size} | {inf.get('base', '-')} | {origin} | {loads} |")
    lines += ["", f"Sensor: {sensor_text(sensor)}.", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------- the terminal
def _change(value: float, ref: float) -> str:
    if ref == 0:
        return ""
    pct = round(100.0 * (value - ref) / ref, 1) + 0.0  # + 0.0: a change that rounds to 0 prints as +0.0, not -0.0
    return f" ({pct:+.1f} %)"


def _e_text(v) -> str:
    return "-" if v is None else f"{v:.3g}"


def change_table(runs, ind: dict, changes: list[dict]) -> dict:
    """Per load label: ``(reference body, rows)``, a row per body of strings ``[body,
    approach (change), contact area (change), e_M, e_m, largest tip changes]``."""
    out = {}
    for load in dict.fromkeys(r.load for r in runs):
        group = [r for r in runs if r.load == load]
        ref = group[0]
        rows = []
        for r in group:
            res, base = r.result, ref.result
            approach = f"{res.penetration:.4g}" + ("" if r is ref else _change(res.penetration, base.penetration))
            area = f"{res.contact_area:.4g}" + ("" if r is ref else _change(res.contact_area, base.contact_area))
            e = ind.get(load, {}).get(ref.body, {}).get(r.body, {})
            top = largest_changes([c for c in changes if c["body"] == r.body and _same_load(c, r.scene)])
            tips = ", ".join(f"tip {c['asperity']} {c['change_percent']:+.1f} %" for c in top)
            rows.append(
                [r.body, approach, area, _e_text(e.get("e_M")), _e_text(e.get("e_m")), tips if r is not ref else "-"]
            )
        out[load] = (ref.body, rows)
    return out


def indicator_note(runs, ind: dict) -> str:
    """What e_M and e_m are, with the largest e_M against the first body read as a
    root-mean-square difference."""
    first = runs[0].body
    e_M = [v["e_M"] for load in ind.values() for v in load.get(first, {}).values() if v["e_M"] is not None]
    worst = max(e_M, default=0.0)
    example = (
        (
            f": e_M = {worst:.3g} % means tip forces {10 * math.sqrt(worst):.2g} % apart in the root-mean-square "
            "sense, and single tips can change much more (last column)"
        )
        if worst > 0
        else ""
    )
    return (
        "e_M, e_m: the paper's indicators, 100 sum|P - P_ref|^2 / sum|P_ref|^2 in percent, over the tip "
        "forces (e_M) and the sensor cells' mean pressures (e_m), P_ref the reference body's. They are "
        f"squares{example}."
    )


def _labels(runs) -> dict:
    return {r.body: (r.result.body.label if getattr(r.result, "body", None) is not None else r.body) for r in runs}


def terminal_summary(scene_path: str, runs, ind: dict, changes: list[dict], out, method: str) -> str:
    """The compact summary printed by ``twoscale compare`` (see module doc)."""
    labels = _labels(runs)
    lines = [
        f"twoscale compare {scene_path}: method {method}; {len(runs[0].scene.asperities)} tips",
        "  bodies: " + "; ".join(f"{b} = {label}" for b, label in labels.items()),
    ]
    width = max(len(b) for b in labels)
    for load, (ref, rows) in change_table(runs, ind, changes).items():
        lines += [
            "",
            f"{load_title(load)}; changes against {ref}",
            f"  {'body':<{width}}  {'approach mm':<20} {'contact area mm2':<20} {'e_M %':>6} {'e_m %':>6}"
            f"   largest tip changes, % of the tip's {ref} force",
        ]
        for body, approach, area, e_M, e_m, tips in rows:
            lines.append(f"  {body:<{width}}  {approach:<20} {area:<20} {e_M:>6} {e_m:>6}   {tips}")
    lines += ["", indicator_note(runs, ind)]
    lines.append(
        f"every tip's change: {out}/changes.csv; forces, areas and pressures: {out}/forces.csv "
        f"(and forces.md); figures: {out}/*.png"
    )
    return "\n".join(lines)


def changes_markdown(runs, ind: dict, changes: list[dict]) -> list[str]:
    """The same as :func:`terminal_summary`, as the first section of forces.md."""
    lines = [
        "## What changes",
        "",
        "Bodies: " + "; ".join(f"{b} = {label}" for b, label in _labels(runs).items()) + ".",
        "",
    ]
    for load, (ref, rows) in change_table(runs, ind, changes).items():
        lines += [
            f"**{load_title(load)}**, changes against {ref}:",
            "",
            f"| body | approach (mm) | contact area (mm^2) | e_M % | e_m % | largest tip changes, % of the tip's "
            f"{ref} force |",
            "|---|---|---|---|---|---|",
        ]
        lines += ["| " + " | ".join(r) + " |" for r in rows] + [""]
    return lines + [indicator_note(runs, ind) + " Every tip's change is in changes.csv.", ""]


def _same_load(row: dict, scene: Scene) -> bool:
    return row["load_N"] == scene.total_load and row["penetration_mm"] == scene.penetration
