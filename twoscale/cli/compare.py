"""Compare bodies: solve a scene on the half-space and the finite block, tabulate and plot.

``twoscale compare SCENE.toml [--loads W ...] [--out DIR] [--method twoscale|reference]
[--h H] [--vtk] [--measured-forces CSV] [--measured-map CSV] [--centre-pivot]
[--sensor NX NY CELL] [--sensor-centre X Y] [--quiet]``

Solves the scene on the elastic half-space and, when the finite-block provider
(``fem_influence``) is available, on the block with a bonded and with a sliding base
(size and origin from the scene's ``[influence]`` when it is a block, else the paper's
140 x 140 x 20 mm block centred under the scene). Without the block it runs the
half-space only and says so on stderr and in every table. Each load case of the scene
(``[load] cases``, else its one load) is run in turn in place of ``load.total``;
``--loads`` gives other cases instead.

Measured data of one load case (``twoscale.sensor`` formats) add a ``measured`` column
and e_M / e_m of every body against the measurement (given only a sensor map, the tip
forces are integrated from it, each loaded cell to its nearest tip, as in the paper); ``--centre-pivot`` first shifts
the tips so the joint sits at the measured force centre (paper eq. 13). The sensor is
the paper's, 44 x 44 cells of 1.9 mm centred on the scene origin, unless ``--sensor``
and ``--sensor-centre`` say otherwise; a measured map has the sensor's NY rows of NX
values.

Writes into DIR (default ``<scene name>_compare``), created only after every solve has
returned, through a temporary folder renamed to DIR at the end (Ctrl-C leaves no partial DIR;
exit code 130):

* ``forces.csv``: one row per load, body and asperity (force N, contact area mm^2,
  max pressure MPa, macro-step force N when the method has one), after four ``#``
  lines with the version and units, the scene, the bodies (each one's influence
  settings and loads) and the sensor, as JSON;
* ``forces.md``: the same as Markdown tables, plus e_M (tip forces) and e_m (sensor
  cells) in percent between each pair of bodies, and the bodies, sensor and scene;
* ``summary.json``: the indicators, convergence, timings, version, units, scene, bodies
  and sensor;
* ``forces_<W>N.png`` (forces side by side, as the paper's Figs. 10-11) and
  ``maps_<W>N.png`` (pressure maps side by side) and ``sensor_<W>N.png`` (the same
  averaged on the sensor cells, what e_m compares) for each load, each recording the
  scene, bodies and sensor in its PNG ``Description``;
* ``runs/<body>_<W>N/result.json`` (and ``fields.vtu`` with ``--vtk``) for each solve.

Exit codes: 0 every solve converged; 1 some solve did not converge or a body could not
be built (everything else still written, with the reason); 2 bad input (one
``error: ...`` line, nothing written).
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from .._version import __version__
from ..io.atomic import atomic_output
from ..io.result_json import UNITS, write_result
from ..io.scene_file import read_scene, scene_to_dict
from ..progress import Progress
from ..resources import check_memory, estimate_memory
from ..scene import BLOCK_DEFAULT_SIZE, METHODS, Scene, SceneError, default_h
from ..sensor import (Sensor, centred_tips, e_M, e_m, forces_from_map, pivot_from_forces, read_sensor_map,
                      read_tip_forces)
from .solve import check_out_dir, positive_option
from .staging import staged_directory

#: The paper's pressure sensor, used unless --sensor / --sensor-centre say otherwise.
DEFAULT_SENSOR = Sensor()

#: Bodies compared, in table order: name -> (influence kind, block base).
BODIES = {"halfspace": ("halfspace", None), "block-bonded": ("block", "bonded"),
          "block-sliding": ("block", "sliding")}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``twoscale compare``."""
    parser.add_argument("scene", metavar="SCENE.toml", help="scene file (TOML; units mm, N, MPa)")
    parser.add_argument("--loads", metavar="W", nargs="+", default=None,
                        help="total loads in N, each replacing load.total of the scene "
                             "(default: the scene's [load] cases, else its one load)")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="output directory (default: <scene name>_compare)")
    parser.add_argument("--method", choices=METHODS, default="twoscale",
                        help="solver for every body (default twoscale)")
    parser.add_argument("--h", metavar="H", default=None,
                        help="cell size in mm, overriding [grid] h of the scene")
    parser.add_argument("--vtk", action="store_true", help="also write runs/*/fields.vtu")
    parser.add_argument("--measured-forces", metavar="CSV", default=None,
                        help="measured tip forces (header x,y,force or index,force; N), one load case")
    parser.add_argument("--measured-map", metavar="CSV", default=None,
                        help="measured sensor map: NY rows of NX pressures (MPa; the sensor's, default "
                             "44 x 44), first row at smallest y; without --measured-forces the tip forces "
                             "are integrated from it")
    parser.add_argument("--centre-pivot", action="store_true",
                        help="shift the tips so the joint sits at the measured force centre (paper eq. 13)")
    parser.add_argument("--sensor", metavar=("NX", "NY", "CELL"), nargs=3, default=None,
                        help=f"sensor cells along x and y (integers >= 1) and cell side in mm "
                             f"(default {DEFAULT_SENSOR.nx} {DEFAULT_SENSOR.ny} {DEFAULT_SENSOR.cell:g})")
    parser.add_argument("--sensor-centre", metavar=("X", "Y"), nargs=2, default=None,
                        help="sensor centre in scene coordinates, mm (default 0 0)")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors and warnings")


# ---------------------------------------------------------------- input
def _scenes(args) -> list[Scene]:
    """The scene once per load case (validated; raises SceneError)."""
    scene = read_scene(args.scene)
    if args.h is not None:
        scene = dataclasses.replace(scene, h=positive_option(args.h, "--h", unit="mm"))
    if args.loads is None:
        if not scene.load_cases:
            return [scene]
        loads = list(scene.load_cases)
    else:
        if scene.total_load is None:
            raise SceneError(f"--loads needs a scene under load control (load.total); "
                             f"{args.scene} gives load.penetration = {scene.penetration!r}")
        loads = [positive_option(w, "--loads", unit="N") for w in args.loads]
        if len(set(loads)) != len(loads):
            raise SceneError(f"--loads has repeated values, got {args.loads!r}")
    # every solve records the cases actually run (--loads replaces the scene's)
    return [dataclasses.replace(scene, total_load=w, load_cases=tuple(loads)) for w in loads]


def _int_option(text: str, name: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = 0
    if v < 1:
        raise SceneError(f"{name} must be an integer >= 1, got {text!r}")
    return v


def _finite_option(text: str, name: str, *, unit: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise SceneError(f"{name} must be a finite number ({unit}), got {text!r}")
    return v


def _sensor(args) -> Sensor:
    """The sensor of ``--sensor NX NY CELL`` and ``--sensor-centre X Y`` (raises SceneError)."""
    s = DEFAULT_SENSOR
    nx, ny, cell, centre = s.nx, s.ny, s.cell, s.centre
    if args.sensor is not None:
        nx = _int_option(args.sensor[0], "--sensor NX")
        ny = _int_option(args.sensor[1], "--sensor NY")
        cell = positive_option(args.sensor[2], "--sensor CELL", unit="mm")
    if args.sensor_centre is not None:
        centre = (_finite_option(args.sensor_centre[0], "--sensor-centre X", unit="mm"),
                  _finite_option(args.sensor_centre[1], "--sensor-centre Y", unit="mm"))
    return Sensor(nx, ny, cell, centre)


def _sensor_text(sensor: Sensor) -> str:
    text = f"{sensor.nx} x {sensor.ny} sensor cells of {sensor.cell:g} mm"
    cx, cy = sensor.centre
    return text if (cx, cy) == (0.0, 0.0) else f"{text} centred at ({cx:g}, {cy:g}) mm"


def sensor_record(sensor: Sensor) -> dict:
    """The sensor as JSON-ready data (what the files record)."""
    return {"nx": int(sensor.nx), "ny": int(sensor.ny), "cell_mm": float(sensor.cell),
            "centre_mm": [float(v) for v in sensor.centre]}


@dataclasses.dataclass(frozen=True)
class Measured:
    """Measured data for one load case: tip forces (N, scene order) and/or a sensor map (MPa)."""

    forces: np.ndarray | None
    sensor_map: np.ndarray | None
    forces_from_map: bool = False


def _measured(args, scenes: list[Scene], sensor: Sensor = DEFAULT_SENSOR) -> Measured | None:
    """Read the measured data named on the command line (raises ValueError)."""
    if args.measured_forces is None and args.measured_map is None:
        if args.centre_pivot:
            raise SceneError("--centre-pivot needs measured data (--measured-forces or --measured-map): "
                             "eq. 13 uses the measured forces")
        return None
    if len(scenes) != 1:
        if args.loads is None:
            raise SceneError(f"measured data belong to one load case; the scene lists load.cases = "
                             f"{list(scenes[0].load_cases)!r}: choose one with --loads W")
        raise SceneError(f"measured data belong to one load case; give at most one --loads value, "
                         f"got {args.loads!r}")
    forces = None
    if args.measured_forces is not None:
        forces = read_tip_forces(args.measured_forces, n_asperities=len(scenes[0].asperities)).force
    smap = read_sensor_map(args.measured_map, sensor=sensor) if args.measured_map is not None else None
    if forces is None:  # as the paper did: integrate the measured map around each tip
        return Measured(forces_from_map(smap, scenes[0].tips, sensor=sensor), smap, forces_from_map=True)
    return Measured(forces, smap)


def _centre_pivot(scene: Scene, forces: np.ndarray) -> tuple[Scene, str]:
    """Tips shifted by (-x0, -y0) of eq. 13, and a note saying by how much."""
    x0, y0 = pivot_from_forces(scene.tips, forces, total=scene.total_load)
    tips = centred_tips(scene.tips, forces, total=scene.total_load)
    asps = tuple(dataclasses.replace(a, x=float(t[0]), y=float(t[1])) for a, t in zip(scene.asperities, tips))
    note = (f"tips shifted by ({-x0:.4g}, {-y0:.4g}) mm so the joint sits at the measured force "
            f"centre (paper eq. 13)")
    return dataclasses.replace(scene, asperities=asps), note


def _block_factory():
    """The finite-block provider class, or (None, reason) when it is not available."""
    try:
        import fem_influence
    except ImportError as exc:
        return None, f"the fem_influence package cannot be imported ({exc})"
    factory = getattr(fem_influence, "FiniteBlock", None) or getattr(fem_influence, "BlockProvider", None)
    if factory is None:
        return None, "fem_influence provides no finite-block provider yet"
    return factory, ""


def _influence(scene: Scene, body: str) -> dict:
    kind, base = BODIES[body]
    if kind == "halfspace":
        return {"kind": "halfspace"}
    inf = scene.influence
    size = inf["size"] if inf["kind"] == "block" else BLOCK_DEFAULT_SIZE
    origin = inf["origin"] if inf["kind"] == "block" else (0.0, 0.0)
    return {"kind": "block", "size": tuple(size), "base": base, "origin": tuple(origin)}


# ---------------------------------------------------------------- solving
def _solve(scene: Scene, provider, method: str):
    """``solve_scene`` with a provider built once per body (the block is costly)."""
    h = default_h(scene)
    if method == "twoscale":
        from ..twoscale import solve_twoscale

        return solve_twoscale(provider, scene.asperities, h=h, penetration=scene.penetration,
                              total_load=scene.total_load, tilt=scene.tilt, pivot=scene.pivot)
    from ..scene import _solve_reference_scene

    return _solve_reference_scene(scene, provider, h)


@dataclasses.dataclass(frozen=True)
class Run:
    """One solve: the load case, the body, the scene solved and its result."""

    load: str
    body: str
    scene: Scene
    result: object
    seconds: float


def _load_label(scene: Scene) -> str:
    if scene.total_load is not None:
        return f"{scene.total_load:g}N"
    return f"d{scene.penetration:g}mm"


def _load_title(label: str) -> str:
    """Readable form of a load label: "50N" -> "total load 50 N", "d0.5mm" -> "approach 0.5 mm"."""
    return f"approach {label[1:-2]} mm" if label.startswith("d") else f"total load {label[:-1]} N"


def _solve_all(scenes, bodies, method, quiet) -> list[Run]:
    runs = []
    with Progress(len(scenes) * len(bodies), label="compare", quiet=quiet) as bar:
        for body, provider in bodies.items():
            for sc in scenes:
                sc = dataclasses.replace(sc, influence=_influence(sc, body))
                t0 = time.perf_counter()
                res = _solve(sc, provider, method)
                runs.append(Run(_load_label(sc), body, sc, res, time.perf_counter() - t0))
                bar.update(note=f"{body} {runs[-1].load}")
    return runs


def _check_memory(scenes, method: str) -> None:
    """Refuse (SceneError naming --h) a comparison whose solves would not fit in memory;
    with the finite block available, each solve counts the block provider too."""
    body = "block-bonded" if _block_factory()[0] is not None else "halfspace"
    for sc in scenes:
        sc = dataclasses.replace(sc, influence=_influence(sc, body))
        check_memory(estimate_memory(sc, default_h(sc), method), option="--h")


def _providers(scene: Scene, quiet: bool) -> tuple[dict, list[str]]:
    """Providers by body name, and notes on bodies left out (never silently)."""
    providers = {"halfspace": dataclasses.replace(scene, influence={"kind": "halfspace"}).provider()}
    notes = []
    factory, why = _block_factory()
    if factory is None:
        notes.append(f"finite block not compared: {why}; half-space only")
        return providers, notes
    for body in ("block-bonded", "block-sliding"):
        opts = _influence(scene, body)
        try:  # the block draws its own progress line while it is built
            providers[body] = factory(scene.material, size=opts["size"], base=opts["base"],
                                      origin=opts["origin"], progress=not quiet)
        except (ValueError, RuntimeError) as exc:
            notes.append(f"{body} could not be built: {exc}")
    return providers, notes


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
FIELDS = ("load", "body", "asperity", "force_N", "contact_area_mm2", "max_pressure_MPa", "macro_force_N")


def per_asperity_rows(runs, measured: Measured | None = None) -> list[dict]:
    """One dict per load, body and asperity (the CSV rows); measured forces as body "measured"."""
    rows = []
    if measured is not None and measured.forces is not None:
        rows += [{"load": runs[0].load, "body": "measured", "asperity": k + 1, "force_N": float(f),
                  "contact_area_mm2": "", "max_pressure_MPa": "", "macro_force_N": ""}
                 for k, f in enumerate(measured.forces)]
    for run in runs:
        s = run.result.asperities
        macro = run.result.extra.get("macro_forces")
        for k in range(len(s.forces)):
            rows.append({"load": run.load, "body": run.body, "asperity": k + 1,
                         "force_N": float(s.forces[k]), "contact_area_mm2": float(s.contact_areas[k]),
                         "max_pressure_MPa": float(s.max_pressures[k]),
                         "macro_force_N": "" if macro is None else float(np.asarray(macro)[k])})
    return rows


def indicators(runs, sensor: Sensor = DEFAULT_SENSOR, measured: Measured | None = None) -> dict:
    """e_M and e_m (percent) of every body against every other, per load.

    ``out[load][reference][other] = {"e_M": ..., "e_m": ...}``, with the reference body's
    forces (sensor map) in the denominator. With measured data, the reference
    ``"measured"`` is added (``None`` for an indicator whose data were not given). e_m is
    ``None`` when the reference map is zero on every sensor cell (a sensor placed away
    from the contact; :func:`sensor_notes` says so).
    """
    def e_m_or_none(p, p_ref):
        return e_m(p, p_ref) if np.any(p_ref != 0) else None

    out: dict = {}
    maps = {(r.load, r.body): sensor.average(r.result) for r in runs}
    if measured is not None:
        for r in runs:
            out.setdefault(r.load, {}).setdefault("measured", {})[r.body] = {
                "e_M": None if measured.forces is None else e_M(r.result.asperities.forces, measured.forces),
                "e_m": None if measured.sensor_map is None else e_m_or_none(maps[r.load, r.body],
                                                                            measured.sensor_map),
            }
    for ref in runs:
        for other in runs:
            if other.load != ref.load or other.body == ref.body:
                continue
            out.setdefault(ref.load, {}).setdefault(ref.body, {})[other.body] = {
                "e_M": e_M(other.result.asperities.forces, ref.result.asperities.forces),
                "e_m": e_m_or_none(maps[other.load, other.body], maps[ref.load, ref.body]),
            }
    return out


def sensor_notes(runs, sensor: Sensor, *, rtol: float = 1e-3) -> list[str]:
    """One note per solve whose load the sensor does not fully carry (part of the contact
    lies outside it, so e_m compares only what the sensor sees)."""
    notes = []
    for r in runs:
        seen = sensor.force(sensor.average(r.result))
        if seen < (1.0 - rtol) * r.result.total_load:
            notes.append(f"the sensor ({_sensor_text(sensor)}) carries {seen:.4g} N of the "
                         f"{r.result.total_load:.4g} N of {r.body} at {_load_title(r.load)}")
    return notes


def _fmt(v) -> str:
    return "n/a" if v is None else f"{v:.3g}"


def markdown(scene_path: str, runs, ind: dict, notes: list[str], method: str,
             measured: Measured | None = None, sensor: Sensor = DEFAULT_SENSOR) -> str:
    """The Markdown report: per-load tables of forces, areas and peak pressures, indicators,
    and what each body was (influence settings and loads)."""
    lines = [f"# twoscale compare {scene_path}", "",
             f"twoscale {__version__}; method {method}; units mm, N, MPa.", ""]
    lines += [f"> **Note:** {n}" for n in notes] + ([""] if notes else [])
    for load in dict.fromkeys(r.load for r in runs):
        group = [r for r in runs if r.load == load]
        lines += [f"## Load case: {_load_title(load)}", ""]
        for r in group:
            tilt = "" if r.result.tilt is None else (f", tilt alpha {r.result.tilt[0]:.4g} rad, "
                                                     f"beta {r.result.tilt[1]:.4g} rad")
            conv = "converged" if r.result.converged else f"NOT converged: {r.result.message}"
            lines.append(f"- {r.body}: total {r.result.total_load:.5g} N, approach "
                         f"{r.result.penetration:.5g} mm{tilt}; {conv}; {r.seconds:.3g} s")
        lines.append("")
        mf = None if measured is None else measured.forces
        head = (["asperity"] + ([] if mf is None else ["measured F (N)"])
                + [f"{r.body} {q}" for q in ("F (N)", "A (mm^2)", "p_max (MPa)") for r in group])
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        n = len(group[0].result.asperities.forces)
        for k in range(n):
            vals = ([] if mf is None else [f"{mf[k]:.4g}"]) + [
                f"{getattr(r.result.asperities, q)[k]:.4g}"
                for q in ("forces", "contact_areas", "max_pressures") for r in group]
            lines.append(f"| {k + 1} | " + " | ".join(vals) + " |")
        lines.append("")
        if load in ind:
            lines += ["e_M / e_m in percent (row: reference body in the denominator; e_m on the "
                      f"{_sensor_text(sensor)}):", ""]
            names = [r.body for r in group]
            lines += ["| reference | " + " | ".join(names) + " |", "|" + "---|" * (len(names) + 1)]
            for a in [x for x in ["measured"] + names if x in ind[load]]:
                cells = ["-" if a == b else f"{_fmt(ind[load][a][b]['e_M'])} / {_fmt(ind[load][a][b]['e_m'])}"
                         for b in names]
                lines.append(f"| {a} | " + " | ".join(cells) + " |")
            lines.append("")
    lines += ["## Bodies", "", "| body | influence | size (mm) | base | origin (mm) | loads |", "|---|---|---|---|---|---|"]
    for name, b in bodies_record(runs).items():
        inf = b["influence"]
        size = " x ".join(f"{v:g}" for v in inf["size"]) if "size" in inf else "-"
        origin = "({:g}, {:g})".format(*inf["origin"]) if "origin" in inf else "-"
        loads = ", ".join(_load_title(x["label"]) for x in b["loads"])
        lines.append(f"| {name} | {inf['kind']} | {size} | {inf.get('base', '-')} | {origin} | {loads} |")
    lines += ["", f"Sensor: {_sensor_text(sensor)}.", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------- writing
def _write_text(path: Path, text: str) -> None:
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="")


def _csv_text(rows, scene_path: str, record: dict) -> str:
    """CSV after four ``#`` comment lines: version and units, then the scene, the bodies
    and the sensor of :func:`compare_record`, each as one line of JSON."""
    buf = io.StringIO()
    buf.write(f"# twoscale {__version__} compare {scene_path}; units: force N, area mm^2, pressure MPa\n")
    for key in ("scene", "bodies", "sensor"):
        buf.write(f"# {key}: {json.dumps(record[key], separators=(',', ':'))}\n")
    w = csv.DictWriter(buf, fieldnames=FIELDS, lineterminator="\n")
    w.writeheader()
    for row in rows:
        w.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items()})
    return buf.getvalue()


def _write_outputs(out: Path, args, scene: Scene, runs, ind, notes, measured: Measured | None,
                   sensor: Sensor) -> None:
    from ..io.solve_outputs import FIELDS_NAME
    from ..io.vtk import write_vtk
    from ..plot import compare_forces, compare_maps, difference_map

    out.mkdir(parents=True, exist_ok=True)
    record = compare_record(scene, runs, sensor)
    scene_dict, meta = record["scene"], {"bodies": record["bodies"], "sensor": record["sensor"]}
    _write_text(out / "forces.csv", _csv_text(per_asperity_rows(runs, measured), args.scene, record))
    md = markdown(args.scene, runs, ind, notes, args.method, measured, sensor)
    md += ("\n<details><summary>scene, bodies and sensor (JSON)</summary>\n\n```json\n"
           + json.dumps(record, indent=1) + "\n```\n</details>\n")
    _write_text(out / "forces.md", md)
    summary = {"version": __version__, "units": dict(UNITS), "method": args.method, "notes": notes,
               **record, "indicators_percent": ind,
               "runs": [{"load": r.load, "body": r.body, "converged": bool(r.result.converged),
                         "message": r.result.message, "total_load": float(r.result.total_load),
                         "seconds": r.seconds} for r in runs]}
    _write_text(out / "summary.json", json.dumps(summary, indent=2, allow_nan=False) + "\n")
    for load in dict.fromkeys(r.load for r in runs):
        group = {r.body: r.result for r in runs if r.load == load}
        tips = runs[0].scene.asperities
        compare_forces(group, out / f"forces_{load}.png", title=f"force per asperity, {_load_title(load)}",
                       measured=None if measured is None else measured.forces, scene=scene_dict, meta=meta)
        compare_maps(group, out / f"maps_{load}.png", tips=tips, title=f"pressure, {_load_title(load)}",
                     scene=scene_dict, meta=meta)
        compare_maps(group, out / f"sensor_{load}.png", tips=tips, sensor=sensor, scene=scene_dict, meta=meta,
                     title=f"sensor-cell means ({_sensor_text(sensor)}), {_load_title(load)}")
        if len(group) > 1:  # each body's tip forces minus the first body's (the half-space)
            difference_map(group, out / f"difference_{load}.png", tips=tips, scene=scene_dict, meta=meta,
                           title=f"force difference per tip, {_load_title(load)}")
    for r in runs:
        d = out / "runs" / f"{r.body}_{r.load}"
        write_result(r.result, r.scene, d, method=args.method)
        if args.vtk:
            write_vtk(r.result, d / FIELDS_NAME, asperities=r.scene.asperities, pivot=r.scene.pivot,
                      scene=scene_to_dict(r.scene))


def run(args: argparse.Namespace) -> int:
    """Run ``twoscale compare``; returns the exit code (0, 1 or 2, see module doc)."""
    out = Path(args.out) if args.out is not None else Path(f"{Path(args.scene).stem}_compare")
    try:
        check_out_dir(out, overwrite=args.overwrite)
        scenes = _scenes(args)
        sensor = _sensor(args)
        measured = _measured(args, scenes, sensor)
        notes = []
        if measured is not None and measured.forces_from_map:
            notes.append("measured tip forces integrated from the sensor map (each loaded cell to "
                         "its nearest tip)")
        if args.centre_pivot:
            scenes[0], note = _centre_pivot(scenes[0], measured.forces)
            notes.append(note)
        _check_memory(scenes, args.method)  # before the block provider and the solves
        providers, block_notes = _providers(scenes[0], args.quiet)
        notes += block_notes
        for n in notes:
            print(f"note: {n}", file=sys.stderr)
        runs = _solve_all(scenes, providers, args.method, args.quiet)
    except ValueError as exc:  # SceneError and solver input checks
        print(f"error: {exc}", file=sys.stderr)
        return 2
    ind = indicators(runs, sensor, measured)
    for n in sensor_notes(runs, sensor):
        print(f"note: {n}", file=sys.stderr)
        notes.append(n)
    with staged_directory(out, overwrite=args.overwrite, command=f"compare {args.scene}") as tmp:
        _write_outputs(tmp, args, scenes[0], runs, ind, notes, measured, sensor)
    if not args.quiet:
        print(markdown(args.scene, runs, ind, notes, args.method, measured, sensor))
        print(f"\nwrote {out}/")
    failed = [r for r in runs if not r.result.converged]
    for r in failed:
        print(f"warning: {r.body} at {r.load} did not converge: {r.result.message}", file=sys.stderr)
    built_all = not any("could not be built" in n for n in notes)
    return 0 if (not failed and built_all) else 1
