"""Segment the height map of a scene's [surface] and tabulate its asperity laws, without solving.

``twoscale surface SCENE.toml --out DIR [--overwrite] [--no-laws] [--quiet]`` writes DIR/segmentation.png
(basins and summits over the height map), DIR/segmentation.csv (per asperity: summit
position and height, recess, prominence, basin area, equivalent-sphere radius, law
exponent, the sphere law's error against the tabulated one; with its
segmentation.csv-metadata.json and, from 1,000 asperities and with pyarrow, segmentation.parquet) and
DIR/surface.json (the map as conditioned, the options, the timings). Exit codes: 0 done; 2 bad input (one
``error: ...`` line naming the file or the key; nothing written); 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..io.scene_file import read_scene, scene_to_dict
from ..progress import StatusLine
from .solve import check_out_dir
from .staging import staged_directory

NAMES = ("segmentation.png", "segmentation.csv", "surface.json")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``twoscale surface``."""
    parser.add_argument("scene", metavar="SCENE.toml", help="scene file with a [surface] table")
    parser.add_argument(
        "--out", metavar="DIR", required=True, help="write DIR/segmentation.png, segmentation.csv, surface.json"
    )
    parser.add_argument(
        "--no-laws",
        action="store_true",
        help="segment only: no single-asperity solves (no law exponents, no sphere error)",
    )
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors and warnings")


def run(args: argparse.Namespace) -> int:
    """Run ``twoscale surface``; returns the exit code."""
    from ..scene import SceneError
    from ..surface.figure import segmentation_figure
    from ..surface.laws import sphere_law_error
    from ..surface.report import asperity_rows, surface_summary, write_json, write_segmentation_table

    t0 = time.perf_counter()
    try:
        check_out_dir(args.out, overwrite=getattr(args, "overwrite", False))
        scene = read_scene(args.scene)
        if scene.surface is None:
            raise SceneError(f"{args.scene}: no [surface] table (twoscale surface segments a height map)")
        surface = scene.surface
        t1 = time.perf_counter()
        table = error = None
        if not args.no_laws:
            with StatusLine(quiet=args.quiet) as status:
                table = surface.book.table(scene.material, progress=status)
            error = sphere_law_error(table, surface.asperities)  # the table just built
        t2 = time.perf_counter()
    except ValueError as exc:  # SceneError, SurfaceError
        print(f"error: {exc}", file=sys.stderr)
        return 2
    record = scene_to_dict(scene)
    rows = asperity_rows(surface, table, error)
    summary = surface_summary(
        surface, record, table=table, sphere_error=error, seconds={"read_and_segment": t1 - t0, "laws": t2 - t1}
    )
    with staged_directory(
        args.out, overwrite=getattr(args, "overwrite", False), command=f"surface {args.scene}"
    ) as tmp:
        segmentation_figure(surface, Path(tmp) / NAMES[0], scene=record)
        write_segmentation_table(rows, tmp, record={"scene": record})
        write_json(summary, Path(tmp) / NAMES[2])
    if not args.quiet:
        print(_text(args.scene, summary, args.out))
    return 0


#: Where the map's units came from, in words.
_FROM = {"map": "as the file says", "option": "as surface.units says", "default": "none given: mm"}


def _text(scene_path: str, s: dict, out) -> str:
    m, seg = s["map"], s["segmentation"]
    lines = [
        f"twoscale surface {scene_path}",
        f"  map          {m['file']}: {m['samples'][0]} x {m['samples'][1]} samples at {m['spacing_mm']:g} mm, "
        f"{m['missing_samples']} missing ({m['missing_treated_as']}); heights "
        f"{m['height_range_mm'][0]:.4g} to {m['height_range_mm'][1]:.4g} mm (given in {m['units']}, "
        f"{_FROM[m['units_from']]})",
        f"  asperities   {seg['asperities']} (of {seg['candidates']} local maxima; min distance "
        f"{seg['min_distance_mm']:g} mm, prominence {seg['prominence_mm']:g} mm)",
    ]
    if s["laws"] is not None:
        e = s["laws"]["sphere_law_error"]
        lines.append(
            f"  laws         tabulated to {s['laws']['depth_mm']:g} mm; equivalent spheres off by "
            f"{100 * e['median']:.3g} % (median), {100 * e['largest']:.3g} % (largest)"
        )
    laws = f", {s['seconds']['laws']:.3g} s laws" if s["laws"] is not None else ""
    lines.append(f"  time         {s['seconds']['read_and_segment']:.3g} s segmentation{laws}")
    names = sorted(p.name for p in Path(out).iterdir() if not p.name.startswith("."))
    lines.append(f"  wrote        {out}/: {', '.join(names)}")
    return "\n".join(lines)
