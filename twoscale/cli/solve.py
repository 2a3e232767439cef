"""Solve a scene file; print a summary and write DIR/result.json (+ asperities.csv, fields.vtm, figures).

``twoscale solve SCENE.toml [--method twoscale|reference] [--out DIR [--overwrite]] [--h H] [--far-tol F]
[--block-field] [--quiet]``

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
from ..io.scene_file import read_scene
from ..io.solve_outputs import write_fields_and_figures
from ..micro.policy import ITERATIONS
from ..progress import StatusLine
from ..resources import check_memory, estimate_memory
from ..scene import METHODS, SceneError, default_h, solve_scene
from .options import positive_option
from .staging import check_output_folder, staged_directory

#: Asperity rows printed in the summary before it is cut short.
MAX_ROWS = 30


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``twoscale solve``."""
    parser.add_argument("scene", metavar="SCENE.toml", help="scene file (TOML; units mm, N, MPa)")
    parser.add_argument("--method", choices=METHODS, default="twoscale",
                        help="two-scale solver (default) or classical reference solver on the full grid")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="write DIR/result.json, asperities.csv, fields.vtm (+ fields/), pressure.png, "
                             "forces.png (DIR created after a successful solve; a non-empty DIR needs --overwrite)")
    parser.add_argument("--h", metavar="H", default=None,
                        help="cell size in mm, overriding [grid] h of the scene")
    parser.add_argument("--iteration", choices=("auto",) + ITERATIONS, default="auto",
                        help="micro step's iteration (experts; default auto: chosen by the solver's "
                             "policy from the scene, with its reason in result.json)")
    parser.add_argument("--far-tol", metavar="F", default=None,
                        help="far-field coupling tolerance of the block iterations (experts; 0 < F < 1): "
                             "patches farther apart than (r_k + r_l)/sqrt(F) interact through their "
                             "resultant forces; alone it selects the two-level iteration")
    parser.add_argument("--block-field", action="store_true",
                        help="with [influence] kind = \"block\" and --out: also write "
                             "DIR/block_displacement.vtu (displacement inside the block)")
    parser.add_argument("--quiet", action="store_true",
                        help="print nothing but errors (no status line or progress bar either; they are "
                             "drawn only when stderr is a terminal)")


def check_out_dir(out, *, overwrite: bool = False) -> None:
    """Refuse, before any solve, an output folder that cannot be written: ``out`` names an
    existing file, or a non-empty folder (unless ``overwrite`` and it holds only an earlier
    twoscale output; see :mod:`twoscale.cli.staging`). ``None`` passes.

    Raises
    ------
    OutputFolderError
        A ValueError naming ``--out``, the path and the reason.
    """
    if out is not None:
        check_output_folder(out, overwrite=overwrite)


def run(args: argparse.Namespace) -> int:
    """Run ``twoscale solve``; returns the exit code (0, 1 or 2, see module doc)."""
    try:
        scene = read_scene(args.scene)
        h = positive_option(args.h, "--h", unit="mm")
        if h is not None:
            scene = dataclasses.replace(scene, h=h)
        if getattr(args, "block_field", False):
            if scene.influence["kind"] != "block":
                raise SceneError(f"--block-field needs [influence] kind = \"block\", "
                                 f"got kind = {scene.influence['kind']!r}")
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
        # before anything large is allocated: refuse a solve the machine cannot hold
        check_memory(estimate_memory(scene, default_h(scene), args.method, iteration=iteration), option="--h")
        t0 = time.perf_counter()
        quiet_block = {"progress": False} if args.quiet and scene.influence["kind"] == "block" else None
        with StatusLine(quiet=args.quiet) as status:
            if args.method == "twoscale" and scene.history is None:
                options["progress"] = status
            result = solve_scene(scene, method=args.method, provider_options=quiet_block, memory_limit=math.inf,
                                 **options)
        wall = time.perf_counter() - t0
    except ValueError as exc:  # SceneError and solver input checks
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if scene.history is not None:
        return _history_done(result, scene, args, wall)
    path = None
    if args.out is not None:
        try:
            write_outputs(result, scene, args)
        except (OSError, ValueError) as exc:  # a folder changed during the solve, a full disk, ...
            print(f"error: writing {args.out}: {exc}", file=sys.stderr)
            return 2
        path = Path(args.out) / RESULT_NAME
    if not args.quiet:
        h_source = "--h" if args.h is not None else None
        print(summary(result_to_dict(result, scene, method=args.method, h_source=h_source), args.scene, wall, path))
    if not result.converged:
        print(f"warning: the solve did not converge: {result.message}", file=sys.stderr)
        return 1
    return 0


def _history_done(result, scene, args, wall: float) -> int:
    """Write and report a history (``DIR/history.csv``, ``history.png``, ``fields.pvd``,
    ``result.json``: :mod:`twoscale.io.history_outputs`); the exit code."""
    from ..io.history_outputs import write_history_outputs

    if args.out is not None:
        try:
            with staged_directory(args.out, overwrite=getattr(args, "overwrite", False),
                                  command=f"solve {args.scene}") as tmp:
                write_history_outputs(result, scene, tmp)
        except (OSError, ValueError) as exc:
            print(f"error: writing {args.out}: {exc}", file=sys.stderr)
            return 2
    if not args.quiet:
        print(f"twoscale solve {args.scene}: history, method {result.method}\n"
              f"  steps        {len(result.steps)} ({result.rejected} redone), error estimate "
              f"{result.error_estimate:.2g}\n"
              f"  output times {len(result.times)}, from {result.times[0]:.4g} to {result.times[-1]:.4g} s\n"
              f"  last         load {result.total_load[-1]:.6g} N, approach {result.penetration[-1]:.6g} mm, "
              f"area {result.contact_area[-1]:.6g} mm^2\n"
              f"  time         {wall:.3g} s" + (f"\n  wrote        {args.out}/" if args.out else ""))
    if not result.converged:
        print(f"warning: the history did not converge: {result.message}", file=sys.stderr)
        return 1
    return 0


def write_outputs(result, scene, args) -> None:
    """Write every file of ``--out`` into a temporary folder renamed to DIR at the end
    (whole or nothing; an earlier output replaced only with ``--overwrite``)."""
    with staged_directory(args.out, overwrite=getattr(args, "overwrite", False),
                          command=f"solve {args.scene}") as tmp:
        write_result(result, scene, tmp, method=args.method, h_source="--h" if args.h is not None else None)
        write_fields_and_figures(result, scene, tmp, source=str(args.scene))
        if getattr(args, "block_field", False):
            write_block_field_file(result, scene, tmp, quiet=args.quiet)


def write_block_field_file(result, scene, out_dir, *, quiet: bool = False):
    """Write ``DIR/block_displacement.vtu`` for a block scene (see :mod:`twoscale.io.block_field`)."""
    from ..io.block_field import BLOCK_FIELD_NAME, write_block_field
    from ..io.scene_file import scene_to_dict

    provider = scene.provider(**({"progress": False} if quiet else {}))
    return write_block_field(result, provider, Path(out_dir) / BLOCK_FIELD_NAME, scene=scene_to_dict(scene))


def summary(res: dict, scene_path: str, wall: float, path) -> str:
    """A short human-readable summary of a result.json dict."""
    iters = ", ".join(f"{k} {v}" for k, v in res["iterations"].items()) or "-"
    lines = [
        f"twoscale solve {scene_path}: method {res['method']} ({res['solver']})",
        f"  converged    {'yes' if res['converged'] else 'NO: ' + res['message']} (iterations: {iters})",
        f"  penetration  {res['penetration']:.6g} mm",
        f"  total load   {res['total_load']:.6g} N",
    ]
    if res["tilt"] is not None:
        lines.append(f"  tilt         alpha {res['tilt'][0]:.4g} rad, beta {res['tilt'][1]:.4g} rad")
    lines.append(f"  cell size    h = {res['h']:.6g} mm ({res['h_source']}), {res['n_cells']} cells")
    if "micro_choice" in res:
        lines.extend(_micro_lines(res))
    macro = any("macro_force" in a for a in res["asperities"])
    lines.append("  asperity      force N   area mm^2  p_max MPa" + ("   macro N" if macro else "")
                 + "   (numbered from 1, scene order)")
    for k, a in enumerate(res["asperities"][:MAX_ROWS]):
        row = f"  {k + 1:8d} {a['force']:11.5g} {a['contact_area']:11.5g} {a['max_pressure']:10.5g}"
        if macro:
            row += f" {a['macro_force']:9.5g}"
        lines.append(row)
    if len(res["asperities"]) > MAX_ROWS:
        where = (f"in {Path(path).parent / ASPERITY_CSV_NAME}" if path is not None
                 else "(--out DIR writes them all to DIR/asperities.csv)")
        lines.append(f"  ... {len(res['asperities']) - MAX_ROWS} more {where}")
    lines.append(f"  time         {wall:.3g} s")
    if path is not None:
        folder = Path(path).parent
        names = sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
        lines.append(f"  wrote        {folder}/: {', '.join(names)}")
    return "\n".join(lines)


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
