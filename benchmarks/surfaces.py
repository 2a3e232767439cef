"""Measured-surface benchmark: a synthetic road on the half-space.

A seeded road texture (:func:`twoscale.surface.texture.road`: packed chippings of 4-8 mm
with a self-affine micro-roughness), ``--size`` mm square at ``--h`` mm (default 100 mm
at 0.1 mm: 10^6 cells), pressed into a half-space (E = 10 MPa, nu = 0.5) at ``--pressure``
MPa nominal (default 0.2: total load = pressure x map area), under load control. Codes, in
one process, one after the other, single-threaded (``OMP_NUM_THREADS=1``):

* ``ts``: the default two-scale solve from the height array: conditioning, segmentation
  and the equivalent spheres (``segment_s``), then ``solve_twoscale`` with the default
  ``law = "auto"`` and no cache (so the equivalent spheres' laws start the micro step;
  ``laws_s``/``laws``: any tabulation the solve did, 0 here; ``solve_s`` is the rest);
  the time compared is the sum; a ``ts-tabulated`` row forces the tabulated laws
  (computed from single-asperity solves, no cache) for comparison;
* ``ref``: the project's full-grid reference (constrained CG, FFT) on the whole map;
* ``CM``: ContactMechanics ``FreeFFTElasticHalfSpace`` + ``minimize_proxy`` on the same
  heights and grid, load control (when installed: ``pip install ".[bench]"``).

Accuracy against ``ref`` (target: within 1 %): total load and contact area (percent),
largest per-asperity force error among the asperities carrying more than 1 % of the
largest force (percent of their own force: ``force %``) and over all asperities (percent
of the largest force, the project's per-tip measure: ``of max %``), L2 of the pressure
field (percent). A second two-scale row runs with ``far_tol = 0.02`` instead of the
policy's 0.1 (a fresh surface, so its laws are computed again).

Usage::

    python benchmarks/surfaces.py [--size 100] [--h 0.1] [--pressure 0.2] [--seed 1] [--stones 2 4]
                                  [--no-cm] [--out FILE.json] [--quiet]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401  (single-threaded BLAS/FFT before numpy work)
import numpy as np  # noqa: E402  (after _common: OpenBLAS reads its thread count when loaded)

from twoscale import Material  # noqa: E402
from twoscale.indenters import surface_on  # noqa: E402
from twoscale.influence import HalfSpace  # noqa: E402
from twoscale.reference import solve_reference  # noqa: E402
from twoscale.surface import RawMap, SurfaceOptions, build_surface  # noqa: E402
from twoscale.surface.texture import road  # noqa: E402
from twoscale.driver import solve_twoscale  # noqa: E402

MAT = Material(10.0, 0.5)
#: A tighter far-field tolerance than the policy's (0.1), run as a second two-scale row.
TIGHT_FAR_TOL = 0.02


def run_twoscale(z: np.ndarray, h: float, load: float, *, law: str = "auto", **options) -> dict:
    c0 = time.process_time()
    t0 = time.perf_counter()
    surface = build_surface(RawMap(z, h, "mm", None, "synthetic road"), SurfaceOptions(law=law))
    t1 = time.perf_counter()
    laws = _timed_laws(surface.book)
    res = solve_twoscale(HalfSpace(MAT), surface.asperities, h=h, total_load=load, **options)
    t2 = time.perf_counter()
    return {
        "surface": surface,
        "result": res,
        "segment_s": t1 - t0,
        "laws_s": laws["seconds"],
        "laws": surface.book.tabulated,
        "solve_s": t2 - t1 - laws["seconds"],
        "time_s": t2 - t0,
        "cpu_s": time.process_time() - c0,
    }


def _timed_laws(book) -> dict:
    """Time spent tabulating laws inside the solve (the book's ``row`` wrapped)."""
    spent = {"seconds": 0.0}
    row = book.row

    def timed(label, material):
        t0 = time.perf_counter()
        try:
            return row(label, material)
        finally:
            spent["seconds"] += time.perf_counter() - t0

    book.row = timed
    return spent


def run_reference(surface, load: float) -> dict:
    t0, c0 = time.perf_counter(), time.process_time()
    res = solve_reference(HalfSpace(MAT), surface_on(surface.hmap.grid, surface.asperities), total_load=load)
    return {"result": res, "time_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def run_contact_mechanics(surface, load: float) -> dict | None:
    from _cm import contact_mechanics, installed

    if not installed():
        return None
    grid = surface.hmap.grid
    t0, c0 = time.perf_counter(), time.process_time()
    gap = surface_on(grid, surface.asperities).height
    cm = contact_mechanics(gap, grid.h, MAT.E_star, total_load=load, maxiter=2000, clip=np.inf)
    return {
        "pressure": cm.force / grid.h**2,  # the force per cell, N, over the cell's area
        "time_s": time.perf_counter() - t0,
        "cpu_s": time.process_time() - c0,
        "converged": cm.converged,
        "iterations": cm.iterations,
    }


def accuracy(pressure: np.ndarray, owner: np.ndarray, ref_pressure: np.ndarray, h: float, n: int) -> dict:
    """Errors of a pressure field against the reference's on the same grid, percent."""

    def forces(p):
        ok = owner >= 0
        return np.bincount(owner[ok], weights=p[ok] * h * h, minlength=n)

    f, g = forces(pressure), forces(ref_pressure)
    big = g > 0.01 * g.max()
    return {
        "load_pct": 100 * abs(f.sum() - g.sum()) / g.sum(),
        "area_pct": 100
        * abs(np.count_nonzero(pressure > 0) - np.count_nonzero(ref_pressure > 0))
        / np.count_nonzero(ref_pressure > 0),
        "force_pct": 100 * float(np.max(np.abs(f - g)[big] / g[big])),
        "force_of_max_pct": 100 * float(np.max(np.abs(f - g)) / g.max()),
        "l2_pct": 100 * float(np.linalg.norm(pressure - ref_pressure) / np.linalg.norm(ref_pressure)),
        "loaded_asperities": int(np.count_nonzero(g > 0)),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=100.0, help="side of the map, mm")
    parser.add_argument("--h", type=float, default=0.1, help="spacing = cell size, mm")
    parser.add_argument("--pressure", type=float, default=0.2, help="nominal pressure, MPa")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--stones",
        type=float,
        nargs=2,
        default=(2.0, 4.0),
        metavar=("LO", "HI"),
        help="stone radii, mm (default 2 4: 314 stones on 100 x 100 mm; 3 6: 161 larger ones)",
    )
    parser.add_argument("--no-cm", action="store_true", help="skip ContactMechanics")
    parser.add_argument("--out", default=None, help="write the figures as JSON")
    _common.add_quiet(parser)
    args = parser.parse_args(argv)
    z = road(args.size, args.h, seed=args.seed, stone_radius=tuple(args.stones))
    load = args.pressure * args.size**2
    print(
        f"road {args.size:g} x {args.size:g} mm at h = {args.h:g} mm ({z.size} cells), seed {args.seed}, "
        f"{args.pressure:g} MPa nominal: W = {load:g} N"
    )
    ts = run_twoscale(z, args.h, load)
    surface, res = ts["surface"], ts["result"]
    grid = surface.hmap.grid
    owner = surface_on(grid, surface.asperities).owner
    ref = run_reference(surface, load)
    ref_p = ref["result"].pressure_on(grid)
    rows = {
        "ts": {
            "time_s": ts["time_s"],
            "cpu_s": ts["cpu_s"],
            "converged": res.converged,
            **accuracy(res.pressure_on(grid), owner, ref_p, args.h, len(surface.asperities)),
        },
        "ref": {"time_s": ref["time_s"], "cpu_s": ref["cpu_s"], "converged": ref["result"].converged},
    }
    tab = run_twoscale(z, args.h, load, law="tabulated")
    rows["ts-tabulated"] = {
        "time_s": tab["time_s"],
        "cpu_s": tab["cpu_s"],
        "converged": tab["result"].converged,
        "laws": tab["laws"],
        **accuracy(tab["result"].pressure_on(grid), owner, ref_p, args.h, len(surface.asperities)),
    }
    tight = run_twoscale(z, args.h, load, far_tol=TIGHT_FAR_TOL)  # fresh surface
    rows[f"ts-{TIGHT_FAR_TOL:g}"] = {
        "time_s": tight["time_s"],
        "cpu_s": tight["cpu_s"],
        "converged": tight["result"].converged,
        **accuracy(tight["result"].pressure_on(grid), owner, ref_p, args.h, len(surface.asperities)),
    }
    cm = None if args.no_cm else run_contact_mechanics(surface, load)
    if cm is not None:
        rows["CM"] = {
            "time_s": cm["time_s"],
            "cpu_s": cm["cpu_s"],
            "converged": cm["converged"],
            "iterations": cm["iterations"],
            **accuracy(cm["pressure"], owner, ref_p, args.h, len(surface.asperities)),
        }
    record = {
        "size_mm": args.size,
        "h_mm": args.h,
        "cells": int(z.size),
        "seed": args.seed,
        "pressure_MPa": args.pressure,
        "load_N": load,
        "asperities": len(surface.asperities),
        "segment_s": ts["segment_s"],
        "laws_s": ts["laws_s"],
        "laws": ts["laws"],
        "solve_s": ts["solve_s"],
        "micro_iteration": res.details.micro.iteration,
        "codes": rows,
        "ref_over_ts": ref["time_s"] / ts["time_s"],
        "cm_over_ts": cm["time_s"] / ts["time_s"] if cm is not None else None,
        "ref_over_ts_cpu": ref["cpu_s"] / ts["cpu_s"],
        "cm_over_ts_cpu": cm["cpu_s"] / ts["cpu_s"] if cm is not None else None,
    }
    print(
        f"{len(surface.asperities)} asperities; two-scale: segmentation {ts['segment_s']:.3g} s, {ts['laws']} laws "
        f"{ts['laws_s']:.3g} s, solve {ts['solve_s']:.3g} s ({record['micro_iteration']})"
    )
    _common.print_table(
        [{"code": k, **v} for k, v in rows.items()],
        [
            ("code", "code", "s"),
            ("time_s", "time s", ".3g"),
            ("cpu_s", "CPU s", ".3g"),
            ("converged", "converged", ""),
            ("load_pct", "load %", ".2g"),
            ("area_pct", "area %", ".2g"),
            ("force_pct", "force %", ".2g"),
            ("force_of_max_pct", "of max %", ".2g"),
            ("l2_pct", "L2 %", ".2g"),
        ],
    )
    ok = [record["ref_over_ts"] >= 3.0] + ([record["cm_over_ts"] >= 5.0] if cm is not None else [])
    acc = rows["ts"]
    ok.append(acc["load_pct"] <= 0.5 and acc["area_pct"] <= 0.5 and acc["force_pct"] <= 1.0 and acc["l2_pct"] <= 2.0)
    print(
        f"ref / ts = {record['ref_over_ts']:.3g} (target >= 3)"
        + (f", CM / ts = {record['cm_over_ts']:.3g} (target >= 5)" if cm is not None else ", CM not run")
        + f": {'PASS' if all(ok) else 'MISS'}"
    )
    print(
        f"CPU time (the machine's load aside): ts / ref = {1 / record['ref_over_ts_cpu']:.3g}"
        + (f", ts / CM = {1 / record['cm_over_ts_cpu']:.3g}" if cm is not None else "")
    )
    if args.out:
        Path(args.out).write_text(json.dumps(record, indent=2, default=bool) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
