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
* ``runs/<body>_<W>N/result.json`` (and ``fields.vtm`` with ``--vtk``) for each solve.

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


from .._version import __version__
from ..api import solve
from ..comparison import (ROW_FIELDS, Measured, Run, centre_pivot, indicators, load_label, load_title,
                          per_asperity_rows, sensor_notes, sensor_text)
from ..influence.registry import make_body, unavailable
from ..io.atomic import atomic_output
from ..io.result_json import UNITS, write_result
from ..io.scene_file import read_scene, scene_to_dict
from ..progress import Progress
from ..resources import check_solve_memory
from ..scene import METHODS, Scene, SceneError, default_h, normalise_influence
from ..sensor import Sensor, forces_from_map, read_sensor_map, read_tip_forces
from .options import DEFAULT_SENSOR, add_sensor_arguments, sensor_from_args
from .options import positive_option, with_h_option
from .solve import check_out_dir
from .staging import staged_directory

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
    parser.add_argument("--vtk", action="store_true", help="also write runs/*/fields.vtm")
    parser.add_argument("--measured-forces", metavar="CSV", default=None,
                        help="measured tip forces (header x,y,force, asperity,force (from 1) or index,force (from 0); N), one load case")
    parser.add_argument("--measured-map", metavar="CSV", default=None,
                        help="measured sensor map: NY rows of NX pressures (MPa; the sensor's, default "
                             "44 x 44), first row at smallest y; without --measured-forces the tip forces "
                             "are integrated from it")
    parser.add_argument("--centre-pivot", action="store_true",
                        help="shift the tips so the joint sits at the measured force centre (paper eq. 13)")
    add_sensor_arguments(parser)
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors and warnings")


# ---------------------------------------------------------------- input
def _scenes(args) -> list[Scene]:
    """The scene once per load case (validated; raises SceneError)."""
    scene = read_scene(args.scene)
    scene = with_h_option(scene, args.h)
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


def sensor_record(sensor: Sensor) -> dict:
    """The sensor as JSON-ready data (what the files record)."""
    return {"nx": int(sensor.nx), "ny": int(sensor.ny), "cell_mm": float(sensor.cell),
            "centre_mm": [float(v) for v in sensor.centre]}


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


def _block_factory():
    """The finite-block provider factory (``make_body("block", material, **options)``), or
    (None, reason) when it cannot be built here."""
    why = unavailable("block")
    if why:
        return None, why
    return (lambda material, **options: make_body("block", material, **options)), ""


def _influence(scene: Scene, body: str) -> dict:
    kind, base = BODIES[body]
    if kind == "halfspace":
        return {"kind": "halfspace"}
    # the scene's own block options where it has a block, else the defaults, with this base
    own = {k: v for k, v in scene.influence.items() if k != "base"} if scene.influence["kind"] == "block" else {}
    inf = normalise_influence({**own, "kind": "block", "base": base})
    return {"kind": "block", "size": tuple(inf["size"]), "base": base, "origin": tuple(inf["origin"]),
            "source_spacing": inf["source_spacing"]}


# ---------------------------------------------------------------- solving
def _solve_all(scenes, bodies, method, quiet) -> list[Run]:
    """Every scene on every body. ``bodies`` (name -> provider) is emptied as it goes: a
    body's provider is dropped once its solves are done, so two finite blocks (each
    holding a factorised FEM model, ~1 GB) are never held at once."""
    runs = []
    with Progress(len(scenes) * len(bodies), label="compare", quiet=quiet) as bar:
        for body in list(bodies):
            provider = bodies.pop(body)
            for sc in scenes:
                sc = dataclasses.replace(sc, influence=_influence(sc, body))
                t0 = time.perf_counter()
                # the provider built once per body (the block is costly); memory checked before
                res = solve(sc, method=method, provider=provider, memory_limit=math.inf)
                runs.append(Run(load_label(sc), body, sc, res, time.perf_counter() - t0))
                bar.update(note=f"{body} {runs[-1].load}")
            del provider
    return runs


def _check_memory(scenes, method: str) -> None:
    """Refuse (SceneError naming --h) a comparison whose solves would not fit in memory;
    with the finite block available, each solve counts the block provider too."""
    body = "block-bonded" if _block_factory()[0] is not None else "halfspace"
    for sc in scenes:
        sc = dataclasses.replace(sc, influence=_influence(sc, body))
        check_solve_memory(sc, default_h(sc), method, option="--h")


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
                                      origin=opts["origin"], source_spacing=opts["source_spacing"],
                                      progress=not quiet)
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
        lines += [f"## Load case: {load_title(load)}", ""]
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
                      f"{sensor_text(sensor)}). Both are ratios of squared norms, "
                      "e_M = 100 sum|P - P~|^2 / sum|P~|^2: one tip of seven 7 % off gives about 0.07 %, "
                      "so compare the per-tip forces above as well (docs/method.md section 5).", ""]
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
        loads = ", ".join(load_title(x["label"]) for x in b["loads"])
        lines.append(f"| {name} | {inf['kind']} | {size} | {inf.get('base', '-')} | {origin} | {loads} |")
    lines += ["", f"Sensor: {sensor_text(sensor)}.", ""]
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
    w = csv.DictWriter(buf, fieldnames=ROW_FIELDS, lineterminator="\n")
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
    name = Path(args.scene).stem   # every figure's title starts with the scene's name
    for load in dict.fromkeys(r.load for r in runs):
        group = {r.body: r.result for r in runs if r.load == load}
        tips = runs[0].scene.asperities
        compare_forces(group, out / f"forces_{load}.png", title=f"force per asperity, {load_title(load)}",
                       measured=None if measured is None else measured.forces, scene=scene_dict, meta=meta,
                       name=name)
        compare_maps(group, out / f"maps_{load}.png", tips=tips, title=f"pressure, {load_title(load)}",
                     scene=scene_dict, meta=meta, name=name)
        compare_maps(group, out / f"sensor_{load}.png", tips=tips, sensor=sensor, scene=scene_dict, meta=meta,
                     title=f"sensor-cell means ({sensor_text(sensor)}), {load_title(load)}", name=name)
        if len(group) > 1:  # each body's tip forces minus the first body's (the half-space)
            difference_map(group, out / f"difference_{load}.png", tips=tips, scene=scene_dict, meta=meta,
                           title=f"force difference per tip, {load_title(load)}", name=name)
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
        sensor = sensor_from_args(args)
        measured = _measured(args, scenes, sensor)
        notes = []
        if measured is not None and measured.forces_from_map:
            notes.append("measured tip forces integrated from the sensor map (each loaded cell to "
                         "its nearest tip)")
        if args.centre_pivot:
            scenes[0], note = centre_pivot(scenes[0], measured.forces)
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
