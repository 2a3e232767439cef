"""Solve a scene file; print a summary and write DIR/result.json (+ asperities.csv, fields.vtm, figures).

``twoscale solve SCENE.toml [--method twoscale|reference] [--out DIR [--overwrite]] [--h H] [--far-tol F]
[--block-field] [--quiet]``

A scene with a ``[rolling]`` table runs every position of the road under the body and
writes its signals instead (:mod:`twoscale.cli.rolling`).

Exit codes: 0 converged; 1 not converged (result.json still written, with
``converged = false`` and the solver's message); 2 bad input (one ``error: ...`` line
on stderr naming the field and the value; nothing written, DIR not created; also when
the solve would need more than 80 % of the available memory, estimated before anything
large is allocated: the line gives the estimate in GB and says to raise ``--h``); 130
interrupted (Ctrl-C). ``--out`` naming an existing file, or a non-empty folder without
``--overwrite``, is bad input found before solving (see :mod:`twoscale.cli.staging`:
``--overwrite`` removes only the files an earlier twoscale run listed in the folder's
manifest). The files are written into a temporary folder renamed to DIR at the end, so an
interrupted run leaves no partial DIR. Without ``--out`` nothing is written.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

from ..io.asperity_csv import ASPERITY_CSV_NAME
from ..io.result_json import RESULT_NAME, result_to_dict, write_result
from ..io.solve_outputs import write_fields_and_figures
from ..io.warning_log import WarningLog
from ..options import MICRO_ITERATIONS
from ..progress import StatusLine
from .body import build_body, with_build
from .route_text import iteration_text, method_lines
from ..results import ContactResult
from ..api import solve_scene
from ..scene import SCENE_METHODS, SceneError, default_h
from .options import positive_option, read_scene_at_h
from .staging import check_output_folder, staged_directory

#: Tips listed in the summary in scene order at most; with more, the TOP_ROWS most loaded.
MAX_ROWS = 30
TOP_ROWS = 10


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``twoscale solve``."""
    parser.add_argument("scene", metavar="SCENE.toml", help="scene file (TOML; units mm, N, MPa)")
    parser.add_argument(
        "--method",
        choices=SCENE_METHODS,
        default="twoscale",
        help="two-scale solver (default) or classical reference solver on the full grid",
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        default=None,
        help="write DIR/result.json, asperities.csv, fields.vtm (+ fields/), pressure.png, "
        "forces.png; a load history: history.csv, history.png, fields.pvd, result.json; a "
        "[rolling] scene: signals.csv, asperity_signals.csv, rolling.json, figures, fields.pvd "
        "(DIR created after a successful solve; a non-empty DIR needs --overwrite)",
    )
    parser.add_argument("--h", metavar="H", default=None, help="cell size in mm, overriding [grid] h of the scene")
    parser.add_argument(
        "--iteration",
        choices=MICRO_ITERATIONS,
        default="auto",
        help="micro step's iteration (experts; default auto: chosen by the solver's "
        "policy from the scene, with its reason in result.json)",
    )
    parser.add_argument(
        "--far-tol",
        metavar="F",
        default=None,
        help="far-field coupling tolerance of the block iterations (experts; 0 < F < 1): "
        "patches farther apart than (r_k + r_l)/sqrt(F) interact through nine point "
        "forces per patch that carry its load's resultant and first and second moments; "
        "alone it selects the two-level iteration",
    )
    parser.add_argument(
        "--block-field",
        action="store_true",
        help='with [influence] kind = "block" and --out: also write '
        "DIR/block_displacement.vtu (displacement inside the block)",
    )
    parser.add_argument(
        "--step-error",
        action="store_true",
        help="[rolling] with a viscoelastic material: roll again at twice the step and report the "
        "hysteresis friction's step error in rolling.json (costs half the run again)",
    )
    parser.add_argument(
        "--quiet",
        action="store_true",
        help="print nothing but errors and warnings (no status line or progress bar either; they are "
        "drawn only when stderr is a terminal)",
    )


def check_out_dir(out, *, overwrite: bool = False) -> None:
    """Refuse, before any solve, an output folder that cannot be written (an existing file, a
    non-empty folder unless ``overwrite`` and it holds only an earlier twoscale output:
    :mod:`twoscale.cli.staging`) with an OutputFolderError (a ValueError naming ``--out``,
    the path and why); ``None`` passes."""
    if out is not None:
        check_output_folder(out, overwrite=overwrite)


def run(args: argparse.Namespace) -> int:
    """Run ``twoscale solve``; the exit code (module doc). Warnings print as ever and are
    listed in the files written (``warnings``: :mod:`twoscale.io.warning_log`)."""
    with WarningLog() as log:
        return _run(args, log)


def _run(args: argparse.Namespace, log: WarningLog) -> int:
    try:
        scene = read_scene_at_h(args.scene, args.h)
        if scene.rolling is not None:  # the road rolls under the body: twoscale.cli.rolling
            from .rolling import run_rolling

            return run_rolling(scene, args, log)
        options, iteration = _solver_options(scene, args)
        t0 = time.perf_counter()
        body, built = build_body(scene, quiet=args.quiet)  # a block: built once, its cache read once
        # before anything large is allocated: refuse a solve the machine cannot hold
        from ..resources import check_solve_memory  # scipy: imported by a solve, not by --help

        check_solve_memory(
            scene,
            default_h(scene),
            args.method,
            iteration=iteration,
            option="--h",
            h_given=args.h is not None,
            provider=body,
        )
        with StatusLine(quiet=args.quiet) as status:
            if args.method == "twoscale" and scene.history is None:
                options["progress"] = status
            result = solve_scene(scene, method=args.method, provider=body, memory_limit=math.inf, **options)
        result, wall = with_build(result, built), time.perf_counter() - t0
        if isinstance(result, ContactResult):  # a history's result names its scene per output time
            result = dataclasses.replace(result, scene_name=Path(args.scene).stem)  # for titles and result.json
    except ValueError as exc:  # SceneError and solver input checks
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if scene.history is not None:
        return _history_done(result, scene, args, wall, log)
    return _static_done(result, scene, args, wall, log, body)


def _solver_options(scene, args: argparse.Namespace) -> tuple[dict, str]:
    """The command line's options for the solver (``far_tol``, ``iteration``) and the
    iteration asked for, checked against the method and the scene (SceneError naming the
    option); the output folder checked too, all before anything is solved."""
    if getattr(args, "step_error", False):
        raise SceneError("--step-error applies to a [rolling] scene with a viscoelastic material")
    if getattr(args, "block_field", False):
        if scene.influence["kind"] != "block":
            raise SceneError(f'--block-field needs [influence] kind = "block", got kind = {scene.influence["kind"]!r}')
        if args.out is None:
            raise SceneError("--block-field needs --out DIR")
    check_out_dir(args.out, overwrite=getattr(args, "overwrite", False))
    options = {}
    far_tol = positive_option(getattr(args, "far_tol", None), "--far-tol", unit="dimensionless")
    if far_tol is not None:
        if not far_tol < 1.0:
            raise SceneError(f"--far-tol must be < 1, got {args.far_tol!r}")
        if args.method != "twoscale":
            raise SceneError(f"--far-tol is an option of --method twoscale, got --method {args.method}")
        options["far_tol"] = far_tol
    iteration = getattr(args, "iteration", "auto")
    if iteration != "auto":
        if args.method != "twoscale":
            raise SceneError(f"--iteration is an option of --method twoscale, got --method {args.method}")
        if far_tol is not None and iteration == "union-cg":
            raise SceneError("--far-tol applies to the block iterations, not to --iteration union-cg")
        options["iteration"] = iteration
    return options, iteration


def _static_done(
    result: ContactResult, scene, args: argparse.Namespace, wall: float, log: WarningLog, body=None
) -> int:
    """Write and report one static solve (``DIR/result.json`` and the rest); the exit code.
    ``body``: the block solved on (its factorisation serves ``--block-field``), or None."""
    path = None
    # result.json's content and the terminal summary: one dictionary
    record = (
        None
        if args.out is None and args.quiet
        else result_to_dict(
            result, scene, method=args.method, h_source="--h" if args.h is not None else None, warnings=log.entries()
        )
    )
    if args.out is not None:
        try:
            write_outputs(result, scene, args, record=record, body=body)
        except (OSError, ValueError) as exc:  # a folder changed during the solve, a full disk, ...
            print(f"error: writing {args.out}: {exc}", file=sys.stderr)
            return 2
        path = Path(args.out) / RESULT_NAME
    if not args.quiet:
        print(summary(record, args.scene, wall, path))
    if not result.converged:
        print(f"warning: the solve did not converge: {result.message}", file=sys.stderr)
        return 1
    return 0


def _history_done(result, scene, args, wall: float, log: WarningLog) -> int:
    """Write and report a history (:mod:`twoscale.io.history_outputs`); the exit code."""
    from ..io.history_outputs import write_history_outputs

    if args.out is not None:
        try:
            with staged_directory(
                args.out, overwrite=getattr(args, "overwrite", False), command=f"solve {args.scene}"
            ) as tmp:
                write_history_outputs(result, scene, tmp, name=Path(args.scene).stem, warnings=log.entries())
        except (OSError, ValueError) as exc:
            print(f"error: writing {args.out}: {exc}", file=sys.stderr)
            return 2
    if not args.quiet:
        print(
            f"twoscale solve {args.scene}: history, method {result.method}\n"
            f"  steps        {len(result.steps)} ({result.rejected} redone), error estimate "
            f"{result.error_estimate:.2g}\n"
            f"  output times {len(result.times)}, from {result.times[0]:.4g} to {result.times[-1]:.4g} s\n"
            f"  last         load {result.total_load[-1]:.6g} N, approach {result.penetration[-1]:.6g} mm, "
            f"contact area {result.contact_area[-1]:.6g} mm2\n"
            f"  time         {wall:.3g} s" + (f"\n{_wrote_line(Path(args.out))}" if args.out else "")
        )
    if not result.converged:
        print(f"warning: the history did not converge: {result.message}", file=sys.stderr)
        return 1
    return 0


def write_outputs(result, scene, args, *, record: dict | None = None, body=None) -> None:
    """Write every file of ``--out`` into a temporary folder renamed to DIR at the end
    (whole or nothing; an earlier output replaced only with ``--overwrite``); ``record``:
    result.json's content when already built."""
    with staged_directory(args.out, overwrite=getattr(args, "overwrite", False), command=f"solve {args.scene}") as tmp:
        write_result(
            result, scene, tmp, method=args.method, h_source="--h" if args.h is not None else None, record=record
        )
        write_fields_and_figures(result, scene, tmp, source=str(args.scene))
        if getattr(args, "block_field", False):
            write_block_field_file(result, scene, tmp, quiet=args.quiet, provider=body)


def write_block_field_file(result, scene, out_dir, *, quiet: bool = False, provider=None):
    """Write ``DIR/block_displacement.vtu`` for a block scene (see :mod:`twoscale.io.block_field`)."""
    from ..io.block_field import BLOCK_FIELD_NAME, write_block_field
    from ..io.scene_file import scene_to_dict

    if provider is None:  # else the block the solve ran on: its factorisation is not made again
        provider = scene.provider(**({"progress": False} if quiet else {}))
    return write_block_field(result, provider, Path(out_dir) / BLOCK_FIELD_NAME, scene=scene_to_dict(scene))


def near_zero(values, scale: float, rtol: float = 1e-6) -> list[str]:
    """Each value formatted to 4 digits, or "0" when below ``rtol * scale`` in size."""
    return ["0" if abs(v) <= rtol * scale else f"{v:.4g}" for v in values]


def summary(res: dict, scene_path: str, wall: float, path) -> str:
    """A short human-readable summary of a result.json dict: what was solved, the numbers
    a reader looks for first, then the tips."""
    n = len(res["asperities"])
    material = res["scene"]["material"]
    lines = [
        f"twoscale solve {scene_path}",
        f"  body         {res['body']['label']} (E = {material['E']:g} MPa, nu = {material['nu']:g}); "
        f"{n} tip{'s' if n != 1 else ''}",
        *method_lines(res),
        f"  converged    {'yes' if res['converged'] else 'NO: ' + res['message']} ({iteration_text(res['iterations'])})",
        f"  total load   {res['total_load']:.6g} N",
        f"  approach     {res['penetration']:.6g} mm",
    ]
    if res["tilt"] is not None:
        # the tilt moves the farthest tip by angle x distance: below 1e-6 of the approach it is round-off
        reach = max([math.hypot(a["x"], a["y"]) for a in res["scene"].get("asperity", [])] or [1.0]) or 1.0
        alpha, beta = near_zero(res["tilt"], abs(res["penetration"]) / reach)
        lines.append(f"  tilt         alpha {alpha} rad, beta {beta} rad")
    touching = sum(a["contact_area"] > 0 for a in res["asperities"])
    area = f"  contact area {res['contact_area']:.5g} mm2 on {touching} of {n} tips"
    if res["contact_area_ratio"] is not None:
        area += (
            f", {100 * res['contact_area_ratio']:.3g} % of the nominal {res['nominal_area']:.5g} mm2 "
            f"({res['nominal_area_basis']})"
        )
    lines.append(area)
    lines.append(f"  cell size    h = {res['h']:.6g} mm ({res['h_source']}), {res['n_cells']} cells")
    if res.get("height_map") is not None:
        lines.extend(_map_lines(res["height_map"]))
    if "micro_choice" in res:
        lines.extend(_micro_lines(res))
    lines.extend(_tip_lines(res, path))
    lines.append(f"  time         {wall:.3g} s")
    if path is not None:
        lines.append(_wrote_line(Path(path).parent))
    return "\n".join(lines)


def _wrote_line(folder: Path) -> str:
    """The summary's line naming the output folder and every file in it."""
    names = sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
    return f"  wrote        {folder}/: {', '.join(names)}"


#: How result.json's ``units_from`` reads in the summary.
_UNITS_FROM = {"map": "the map's", "option": "surface.units", "default": "none given: mm"}


def _map_lines(m: dict) -> list:
    """The height map as conditioned: samples, units, missing samples, edge contacts."""
    ny, nx = m["samples"]
    resampled = "" if m.get("measured_spacing_mm") is None else f" (resampled from {m['measured_spacing_mm']:.6g} mm)"
    units = f"{m['units']} ({_UNITS_FROM.get(m['units_from'], m['units_from'])})"
    out = [
        f"  height map   {m['file']}: {ny} x {nx} samples at {m['spacing_mm']:.6g} mm{resampled}, heights in {units}"
    ]
    missing = m["missing_samples"]
    how = (
        "filled from the nearest measured height"
        if m["missing_treated_as"] == "nearest"
        else "left without material (never in contact)"
    )
    out.append(
        f"               missing samples: {missing:,} ({100.0 * missing / (nx * ny):.3g} %)"
        + (f", {how}" if missing else "")
    )
    ks = m["edge_asperities"]
    if ks:
        names = ", ".join(str(k) for k in ks[:5]) + (f" and {len(ks) - 5} more" if len(ks) > 5 else "")
        many = len(ks) > 1
        out.append(
            f"               edge contacts: {len(ks)} asperit{'ies' if many else 'y'} ({names}) "
            f"touch{'' if many else 'es'} the map's edge, where the scan ends in a wall"
        )
    else:
        out.append("               edge contacts: none")
    return out


def _tip_lines(res: dict, path) -> list[str]:
    """The tips: all of them up to MAX_ROWS, else the TOP_ROWS most loaded."""
    asps = res["asperities"]
    macro = any("macro_force" in a for a in asps)
    order = list(range(len(asps)))
    few = len(asps) <= MAX_ROWS
    if not few:
        order = sorted(order, key=lambda k: -asps[k]["force"])[:TOP_ROWS]
    lines = [
        "  asperity      force N   area mm2  p_max MPa"
        + ("   macro N" if macro else "")
        + ("   (numbered from 1, scene order)" if few else f"   (the {TOP_ROWS} most loaded of {len(asps)})")
    ]
    for k in order:
        a = asps[k]
        row = f"  {k + 1:8d} {a['force']:11.5g} {a['contact_area']:10.5g} {a['max_pressure']:10.5g}"
        if macro:
            row += f" {a['macro_force']:9.5g}"
        lines.append(row)
    if not few:
        where = (
            f"in {Path(path).parent / ASPERITY_CSV_NAME}"
            if path is not None
            else "(--out DIR writes them all to DIR/asperities.csv)"
        )
        lines.append(f"  ... {len(asps) - TOP_ROWS} more {where}")
    return lines


def _micro_lines(res: dict) -> list:
    """What the micro step ran: the choice and why, and each attempt (one line each)."""
    choice = res["micro_choice"]
    who = "fixed" if choice["by_caller"] else "chosen"
    out = [f"  micro step   {res['micro_iteration']}", f"               {who}: {choice['reason']}"]
    if len(res["micro_attempts"]) > 1:
        for a in res["micro_attempts"]:
            state = "converged" if a["converged"] else "did not converge"
            out.append(f"    attempt    {a['iteration']}: {a['sweeps']} sweeps, {a['seconds']:.3g} s, {state}")
    return out
