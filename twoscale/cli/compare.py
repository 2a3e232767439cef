"""Compare bodies: solve a scene on the half-space and the finite block, and show what changes.

``twoscale compare SCENE.toml [--loads W ...] [--out DIR] [--method twoscale|reference]
[--h H] [--block-size W D T] [--base bonded|sliding|both] [--vtk] [--measured-forces CSV]
[--measured-map CSV] [--centre-pivot] [--sensor NX NY CELL] [--sensor-centre X Y] [--quiet]``

Solves the scene on the elastic half-space and, when the finite-block provider
(``fem_influence``) is available, on the block with a bonded and with a sliding base
(``--base`` keeps one of them; size and origin from the scene's ``[influence]`` when it is
a block, else the paper's 140 x 140 x 20 mm block centred under the scene; ``--block-size``
sets width, depth and thickness in mm). Without the block it runs the half-space only and
says so on stderr and in every table. Each load case of the scene (``[load] cases``, else
its one load) is run in turn in place of ``load.total``; ``--loads`` gives other cases
instead.

The terminal shows, per load, each body's approach and contact area with their change
against the half-space, e_M and e_m (explained below the table), and the three tips whose
force changes most in percent of the tip's own half-space force; the files hold the rest.

Measured data of one load case (``twoscale.sensor`` formats) add a ``measured`` body
and e_M / e_m of every body against the measurement (given only a sensor map, the tip
forces are integrated from it, each loaded cell to its nearest tip, as in the paper); ``--centre-pivot`` first shifts
the tips so the joint sits at the measured force centre (paper eq. 13). The sensor is
the paper's, 44 x 44 cells of 1.9 mm centred on the scene origin, unless ``--sensor``
and ``--sensor-centre`` say otherwise; a measured map has the sensor's NY rows of NX
values.

Writes into DIR (default ``<scene name>_compare``), created only after every solve has
returned, through a temporary folder renamed to DIR at the end (Ctrl-C leaves no partial DIR;
exit code 130):

* ``forces.csv``: one row per load, body and asperity (``load_N`` or ``penetration_mm``,
  ``body``, ``asperity``, force N, contact area mm^2, max pressure MPa, macro-step force N
  when the method has one); ``changes.csv``: one row per load, block body and asperity,
  the tip's force against its half-space force (``change_N``, ``change_percent`` of the
  tip's own half-space force). Each has its ``.csv-metadata.json`` (version, units, the
  scene, the bodies and the sensor) and, from 1,000 rows and with pyarrow, a ``.parquet`` copy;
* ``forces.md``: the same as Markdown tables, plus e_M (tip forces) and e_m (sensor
  cells) in percent between each pair of bodies, and the bodies, sensor and scene;
* ``summary.json``: the indicators, per run the convergence, approach, contact area, the
  body's label and the time, and the version, units, scene, bodies and sensor;
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
import dataclasses
import math
import sys
import time
from pathlib import Path


from ..api import solve
from ..comparison import Measured, Run, centre_pivot, indicators, load_label, tip_changes, sensor_notes
from ..influence.registry import make_body, unavailable
from ..io.cache_entry import with_construction
from ..io.warning_log import WarningLog
from ..progress import Progress
from ..resources import check_solve_memory
from ..scene import SCENE_METHODS, Scene, SceneError, default_h, normalise_influence
from ..sensor import Sensor, forces_from_map, read_sensor_map, read_tip_forces
from .options import DEFAULT_SENSOR, add_sensor_arguments, sensor_from_args
from .compare_outputs import Comparison, write_outputs
from .compare_report import terminal_summary
from .options import positive_option, read_scene_at_h
from .solve import check_out_dir
from .staging import staged_directory

#: Bodies compared, in table order: name -> (influence kind, block base).
COMPARED_BODIES = {
    "halfspace": ("halfspace", None),
    "block-bonded": ("block", "bonded"),
    "block-sliding": ("block", "sliding"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``twoscale compare``."""
    parser.add_argument("scene", metavar="SCENE.toml", help="scene file (TOML; units mm, N, MPa)")
    parser.add_argument(
        "--loads",
        metavar="W",
        nargs="+",
        default=None,
        help="total loads in N, each replacing load.total of the scene "
        "(default: the scene's [load] cases, else its one load)",
    )
    parser.add_argument("--out", metavar="DIR", default=None, help="output directory (default: <scene name>_compare)")
    parser.add_argument(
        "--method", choices=SCENE_METHODS, default="twoscale", help="solver for every body (default twoscale)"
    )
    parser.add_argument("--h", metavar="H", default=None, help="cell size in mm, overriding [grid] h of the scene")
    parser.add_argument("--vtk", action="store_true", help="also write runs/*/fields.vtm")
    parser.add_argument(
        "--measured-forces",
        metavar="CSV",
        default=None,
        help="measured tip forces (header x,y,force, asperity,force (from 1) or index,force (from 0); N), one load case",
    )
    parser.add_argument(
        "--measured-map",
        metavar="CSV",
        default=None,
        help="measured sensor map: NY rows of NX pressures (MPa; the sensor's, default "
        "44 x 44), first row at smallest y; without --measured-forces the tip forces "
        "are integrated from it",
    )
    parser.add_argument(
        "--centre-pivot",
        action="store_true",
        help="shift the tips so the joint sits at the measured force centre (paper eq. 13)",
    )
    parser.add_argument(
        "--block-size",
        metavar=("W", "D", "T"),
        nargs=3,
        default=None,
        help="the finite block's width, depth and thickness in mm (default: the scene's "
        "[influence] block, else 140 x 140 x 20)",
    )
    parser.add_argument(
        "--base",
        choices=("bonded", "sliding", "both"),
        default="both",
        help="the finite block's base: bonded (no displacement), sliding (no vertical "
        "displacement, no shear) or both (default), each compared with the half-space",
    )
    add_sensor_arguments(parser)
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors and warnings")


# ---------------------------------------------------------------- input
def _scenes(args) -> list[Scene]:
    """The scene once per load case (validated; raises SceneError)."""
    scene = _with_block_size(read_scene_at_h(args.scene, args.h), args)
    _static_only(scene, args.scene)
    if args.loads is None:
        if not scene.load_cases:
            return [scene]
        loads = list(scene.load_cases)
    else:
        if scene.total_load is None:
            raise SceneError(
                f"--loads needs a scene under load control (load.total); "
                f"{args.scene} gives load.penetration = {scene.penetration!r}"
            )
        loads = [positive_option(w, "--loads", unit="N") for w in args.loads]
        if len(set(loads)) != len(loads):
            raise SceneError(f"--loads has repeated values, got {args.loads!r}")
    # every solve records the cases actually run (--loads replaces the scene's)
    return [dataclasses.replace(scene, total_load=w, load_cases=tuple(loads)) for w in loads]


def _static_only(scene: Scene, path) -> None:
    """Refuse (SceneError) a scene that is not one static load per body: a load history
    (viscoelastic rubber) or a road rolling under the body."""
    if scene.history is None and scene.rolling is None:
        return
    what = (
        "a load history (load.total or load.penetration as [[t, value], ...])" if scene.history else "a [rolling] table"
    )
    raise SceneError(
        f"{path}: compare solves one static load on each body, and this scene has {what}: "
        f'run it with twoscale solve {path} --out DIR, once per body ([influence] kind = "block" for the block)'
    )


def _with_block_size(scene: Scene, args) -> Scene:
    """The scene whose block (its own, else the default one) has the size of ``--block-size``."""
    if getattr(args, "block_size", None) is None:
        return scene
    size = tuple(positive_option(v, "--block-size", unit="mm") for v in args.block_size)
    own = dict(scene.influence) if scene.influence["kind"] == "block" else {"kind": "block"}
    return dataclasses.replace(scene, influence=normalise_influence({**own, "size": size}))


def _measured(args, scenes: list[Scene], sensor: Sensor = DEFAULT_SENSOR) -> Measured | None:
    """Read the measured data named on the command line (raises ValueError)."""
    if args.measured_forces is None and args.measured_map is None:
        if args.centre_pivot:
            raise SceneError(
                "--centre-pivot needs measured data (--measured-forces or --measured-map): "
                "eq. 13 uses the measured forces"
            )
        return None
    if len(scenes) != 1:
        if args.loads is None:
            raise SceneError(
                f"measured data belong to one load case; the scene lists load.cases = "
                f"{list(scenes[0].load_cases)!r}: choose one with --loads W"
            )
        raise SceneError(f"measured data belong to one load case; give at most one --loads value, got {args.loads!r}")
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
    kind, base = COMPARED_BODIES[body]
    if kind == "halfspace":
        return {"kind": "halfspace"}
    # the scene's own block options where it has a block, else the defaults, with this base
    own = {k: v for k, v in scene.influence.items() if k != "base"} if scene.influence["kind"] == "block" else {}
    inf = normalise_influence({**own, "kind": "block", "base": base})
    return {
        "kind": "block",
        "size": tuple(inf["size"]),
        "base": base,
        "origin": tuple(inf["origin"]),
        "source_spacing": inf["source_spacing"],
    }


# ---------------------------------------------------------------- solving
def _solve_all(scenes, bodies, method, quiet, name: str = "") -> list[Run]:
    """Every scene on every body. ``bodies`` (name -> provider) is emptied as it goes: a
    body's provider is dropped once its solves are done, so two finite blocks (each
    holding a factorised FEM model, ~1 GB) are never held at once."""
    runs = []
    with Progress(len(scenes) * len(bodies), label="compare", quiet=quiet) as bar, WarningLog() as log:
        for body in list(bodies):
            provider = bodies.pop(body)
            built = provider.cache_usage()  # what its caches did while it was built
            for sc in scenes:
                sc = dataclasses.replace(sc, influence=_influence(sc, body))
                t0, mark = time.perf_counter(), log.mark()
                # the provider built once per body (the block is costly); memory checked before
                res = solve(sc, method=method, provider=provider, memory_limit=math.inf)
                # for the figures' titles; the first solve records the corrections read
                # (or dropped) when the block was built, as a solve that builds it does
                res = dataclasses.replace(res, scene_name=name, caches=with_construction(res.caches, built))
                built = ()
                runs.append(Run(load_label(sc), body, sc, res, time.perf_counter() - t0, tuple(log.entries(mark))))
                bar.update(note=f"{body} {runs[-1].load}")
            del provider
    return runs


def _check_memory(scenes, method: str, providers: dict) -> None:
    """Refuse (SceneError naming --h) a comparison whose solves would not fit in memory;
    with a finite block built, each solve counts that block too (the provider the solves
    use: built again here, it would read the block's cache a second time, and a damaged
    entry dropped here would be missing from the solves' records)."""
    body = next((b for b in ("block-bonded", "block-sliding") if b in providers), "halfspace")
    for sc in scenes:
        sc = dataclasses.replace(sc, influence=_influence(sc, body))
        check_solve_memory(
            sc, default_h(sc), method, option="--h", provider=providers[body] if body != "halfspace" else None
        )


def _providers(scene: Scene, quiet: bool, base: str = "both") -> tuple[dict, list[str]]:
    """Providers by body name (the blocks of ``base``: "bonded", "sliding" or "both"), and
    notes on bodies left out (never silently)."""
    providers = {"halfspace": dataclasses.replace(scene, influence={"kind": "halfspace"}).provider()}
    notes = []
    factory, why = _block_factory()
    if factory is None:
        notes.append(f"finite block not compared: {why}; half-space only")
        return providers, notes
    for body in [b for b in ("block-bonded", "block-sliding") if base in ("both", COMPARED_BODIES[b][1])]:
        opts = _influence(scene, body)
        try:  # the block draws its own progress line while it is built
            providers[body] = factory(
                scene.material,
                size=opts["size"],
                base=opts["base"],
                origin=opts["origin"],
                source_spacing=opts["source_spacing"],
                progress=not quiet,
            )
        except (ValueError, RuntimeError) as exc:
            notes.append(f"{body} could not be built: {exc}")
    return providers, notes


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
            notes.append("measured tip forces integrated from the sensor map (each loaded cell to its nearest tip)")
        if args.centre_pivot:
            scenes[0], note = centre_pivot(scenes[0], measured.forces)
            notes.append(note)
        providers, block_notes = _providers(scenes[0], args.quiet, getattr(args, "base", "both"))
        _check_memory(scenes, args.method, providers)  # before the solves (a block factorises in its first)
        notes += block_notes
        for n in notes:
            print(f"note: {n}", file=sys.stderr)
        runs = _solve_all(scenes, providers, args.method, args.quiet, Path(args.scene).stem)
    except ValueError as exc:  # SceneError and solver input checks
        print(f"error: {exc}", file=sys.stderr)
        return 2
    ind = indicators(runs, sensor, measured)
    changes = tip_changes(runs)
    for n in sensor_notes(runs, sensor):
        print(f"note: {n}", file=sys.stderr)
        notes.append(n)
    with staged_directory(out, overwrite=args.overwrite, command=f"compare {args.scene}") as tmp:
        write_outputs(tmp, args, Comparison(scenes[0], runs, ind, notes, measured, sensor, changes))
    if not args.quiet:
        print(terminal_summary(args.scene, runs, ind, changes, out, args.method))
    failed = [r for r in runs if not r.result.converged]
    for r in failed:
        print(f"warning: {r.body} at {r.load} did not converge: {r.result.message}", file=sys.stderr)
    built_all = not any("could not be built" in n for n in notes)
    return 0 if (not failed and built_all) else 1
