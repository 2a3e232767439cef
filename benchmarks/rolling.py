"""Rolling benchmark: a slick tyre rolled over a chip-seal strip, elastic.

The tyre: radius ``--radius`` mm (300), ``--width`` mm wide (150: the footprint window's
width), ``--load`` N (3,000) held at every position, on a half-space of tread rubber (E =
10 MPa, nu = 0.5). The road: a seeded chip-seal strip (:func:`twoscale.rolling.road_strip`,
stones of 4-8 mm) at ``--h`` mm (0.25), long enough for the footprint plus the run of
``--length`` mm (1,000) in ``--step`` mm steps (1). Single-threaded
(``OMP_NUM_THREADS=1``).

Printed: the strip and its segmentation time, the time of every position (``--every`` of
them; mean, median, largest, the first and the second), the whole run; at ``--samples`` positions spread over the
run, the same position solved by the full-grid reference on every cell the stones can
reach (:func:`twoscale.rolling.reference.reference_position`), by the default two-scale
solve from cold (:func:`~twoscale.rolling.reference.cold_position`) and by
ContactMechanics (``FreeFFTElasticHalfSpace`` + ``minimize_proxy`` on the reference's grid
and heights, when installed), with the run's time per position over each (targets: <= 0.1
of the reference, <= 0.3 of the cold solve) and the run's load, approach, area and drag
against the reference's. The reference and the cold solve are each timed ``--repeat`` times
(3) at a sample, interleaved, and their median CPU is the ratios' denominator (with the
runs and their spread). A position of the run cannot be repeated without its history: its
single CPU time is what the targets are checked on; besides it, the median and the 90th
percentile of all positions after the first are printed over the samples' median
reference and cold solve (``positions_*``, ``median_over_*``, ``p90_over_*``), and their
CPU by CG iterations (per count, and a line's fixed part and cost an iteration:
``by_iterations``). Beside the cold solve, what a static solve of the road at that shift costs
a user who starts from the map: the cold solve plus the segmentation of the strip's raw
heights under the footprint at that shift (``segment_cpu_s``, ``ratio_cold_segmented``,
``*_over_cold_segmented``: the run segments the strip once). ``--out`` writes each position's shift, CPU and iterations too
(``positions``).

Usage::

    python benchmarks/rolling.py [--length 1000] [--step 1] [--h 0.25] [--load 3000] [--radius 300]
                                 [--width 150] [--samples 3] [--repeat 3] [--seed 1] [--every 50] [--no-cm]
                                 [--macro-start] [--visco] [--scale-out] [--system-heap] [--solver auto|window|twoscale]
                                 [--out FILE.json]

``--visco`` rolls the section elastic and with a ten-branch Prony tread (tau from 1e-6 to
1e3 s, glassy modulus five times the relaxed) instead, and prints the CPU ratio.

glibc's heap keeps the arrays a position frees, as ``twoscale solve`` has it for a rolling
run (:mod:`twoscale.cli.heap`; for the reference and the cold solve too: the same process);
``--system-heap`` leaves its defaults. The positions run with the objects made before them
out of the garbage collector's full passes, as :func:`twoscale.rolling.roll` runs them
(:mod:`twoscale.collector`).

``--scale-out`` runs the section in one and in two chunks on Dask worker processes
(:func:`twoscale.rolling.chunks.roll_chunks`) instead, and prints the speed-up.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from pathlib import Path

# single-threaded BLAS before numpy is first imported: imported after it, the BLAS threads
# were already started and their spinning counted in this process's CPU time (about 0.8 s
# a position against 0.45 s measured for the same positions)
sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001

import numpy as np  # noqa: E402

from twoscale import Material  # noqa: E402
from twoscale.cli.heap import keep_heap  # noqa: E402
from twoscale.indenters import surface_on  # noqa: E402
from twoscale.rolling import RollingOptions  # noqa: E402
from twoscale.collector import frozen_objects  # noqa: E402
from twoscale.rolling.reference import cold_position, reference_grid, reference_position  # noqa: E402
from twoscale.rolling.run import step, window_state  # noqa: E402
from twoscale.rolling.track import prepare, tyre_contact_length  # noqa: E402
from twoscale.surface import RawMap, build_surface  # noqa: E402

MAT = Material(10.0, 0.5)


def build(args) -> tuple:
    """The scene: the strip (footprint + run + margins long) segmented once, and the tyre."""
    import twoscale

    return tyre_scene(
        twoscale,
        args.length,
        step=args.step,
        load=args.load,
        radius=args.radius,
        width=args.width,
        h=args.h,
        seed=args.seed,
    )


def tyre_window(length: float) -> tuple:
    """The benchmark's tyre over ``length`` mm with this checkout's ``twoscale``, ready to roll
    position by position (``step(track, k, last, options, state)``): ``(track, options,
    state)``, the default options and a fresh window state (the stage-level benchmarks'
    set-up)."""
    import twoscale

    track = prepare(tyre_scene(twoscale, length)[0])
    options = RollingOptions()
    return track, options, window_state(track, options)


def tyre_scene(package, length: float, *, step=1.0, load=3000.0, radius=300.0, width=150.0, h=0.25, seed=1) -> tuple:
    """:func:`build`'s scene made by ``package`` (``twoscale``, or another tree's copy
    imported under another name: ``rolling_paired.py``) for ``length`` mm of run, and the
    strip's figures."""

    def module(name: str):
        return importlib.import_module(f"{package.__name__}.{name}")

    t0 = time.perf_counter()
    mat = package.Material(MAT.E, MAT.nu)
    half = 0.5 * 2.0 * 1.5 * np.sqrt(4 * load * radius / (np.pi * mat.E_star * width)) + 10.0
    strip = length + 2 * half
    z = module("rolling").road_strip(strip, width + 10.0, h, seed=seed)
    t1 = time.perf_counter()
    surface = module("surface").build_surface(module("surface").RawMap(z, spacing=h, units="mm"))
    t2 = time.perf_counter()
    # the strip is centred: at shift s it covers body x in [-strip/2 + s, strip/2 + s]
    spec = module("rolling").RollingSpec(
        start=-length / 2, end=length / 2, step=step, speed=50.0, tyre_radius=radius, footprint=(2 * half, width)
    )
    scene = module("scene").Scene(material=mat, surface=surface, total_load=load, rolling=spec)
    info = {
        "strip_mm": [strip, width + 10.0],
        "samples": list(z.shape),
        "stones": len(surface.asperities),
        "strip_s": t1 - t0,
        "segment_s": t2 - t1,
    }
    return scene, info


def contact_mechanics(track, position) -> dict | None:
    from _cm import contact_mechanics as solve_cm, installed

    if not installed():
        return None
    sel = position.selection
    low = min(s.z for s in sel.stones)
    d = position.result.penetration
    grid = reference_grid(track, sel, d + 0.5 * max(d - low, track.h))
    rec = surface_on(grid, sel.stones).height
    rec = np.where(np.isfinite(rec), rec, np.nanmax(np.where(np.isfinite(rec), rec, np.nan)) + 10.0)
    cm = solve_cm(rec, grid.h, MAT.E_star, total_load=track.scene.total_load, maxiter=2000, clip=np.inf)
    force = cm.force
    return {
        "time_s": cm.time_s,
        "cpu_s": cm.cpu_s,
        "converged": cm.converged,
        "area_mm2": float(np.count_nonzero(force > 0)) * grid.h**2,
        "cells": grid.size,
    }


def _shown(v) -> str:
    if isinstance(v, list):
        return "[" + ", ".join(_shown(x) for x in v) + "]"
    return f"{v:.4g}" if isinstance(v, float) else f"{v}"


def timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def repeated(fns: dict, repeat: int) -> dict:
    """Each of ``fns`` run ``repeat`` times, interleaved (one of each in turn, so the load of
    the moment falls on all alike): name -> (the first answer, the runs' CPU seconds, their
    wall seconds)."""
    out: dict = {name: (None, [], []) for name in fns}
    for _ in range(max(repeat, 1)):
        for name, fn in fns.items():
            answer, wall, cpu = timed(fn)
            first, cpus, walls = out[name]
            out[name] = (answer if first is None else first, cpus + [cpu], walls + [wall])
    return out


def compare(track, pos, run_cpu: float, use_cm: bool, repeat: int = 1) -> dict:
    """The position solved two other ways ``repeat`` times each, interleaved, and the ratios
    of the run's single time over their medians (module docstring), besides ContactMechanics."""
    for stone in pos.selection.stones:  # (what a basin finds when first asked for, found before the timers)
        getattr(stone, "extent", None), getattr(stone, "dist", None)
    window = road_window(track, pos)
    runs = repeated(
        {
            "ref": lambda: reference_position(track, pos),
            "cold": lambda: cold_position(track, pos),
            "segment": lambda: build_surface(window),
        },
        repeat,
    )
    (ref, ref_cpus, ref_walls), (cold, cold_cpus, cold_walls) = runs["ref"], runs["cold"]
    segment_cpu = float(np.median(runs["segment"][1]))
    ref_s, ref_cpu = float(np.median(ref_walls)), float(np.median(ref_cpus))
    cold_s, cold_cpu = float(np.median(cold_walls)), float(np.median(cold_cpus))
    from twoscale.rolling.run import drag_of

    r = pos.result
    row = {
        "shift_mm": float(track.shifts[pos.index]),
        "stones": len(pos.selection.stones),
        "run_s": pos.seconds,
        "run_cpu_s": run_cpu,
        "ref_s": ref_s,
        "ref_cpu_s": ref_cpu,
        "ref_cells": ref.n_cells,
        "cold_s": cold_s,
        "cold_cpu_s": cold_cpu,
        "twoscale_cells": r.n_cells,
        "ratio_ref": run_cpu / ref_cpu,
        "ratio_cold": run_cpu / cold_cpu,
        "segment_cpu_s": segment_cpu,
        "ratio_cold_segmented": run_cpu / (cold_cpu + segment_cpu),
        "approach_err_mm": abs(r.penetration - ref.penetration),
        "area_err_pct": 100 * abs(r.contact_area - ref.contact_area) / ref.contact_area,
        "drag_run_N": pos.drag,
        "drag_ref_N": drag_of(track, pos.selection, ref),
        "ref_converged": bool(ref.converged),
        "cold_converged": bool(cold.converged),
        "repeat": len(ref_cpus),
        "ref_cpu_runs_s": ref_cpus,
        "cold_cpu_runs_s": cold_cpus,
        "ref_cpu_spread": (max(ref_cpus) - min(ref_cpus)) / ref_cpu,
        "cold_cpu_spread": (max(cold_cpus) - min(cold_cpus)) / cold_cpu,
    }
    cm = contact_mechanics(track, pos) if use_cm else None
    if cm is not None:
        row.update(
            {
                "cm_cpu_s": cm["cpu_s"],
                "ratio_cm": run_cpu / cm["cpu_s"],
                "cm_converged": cm["converged"],
                "cm_area_err_pct": 100 * abs(cm["area_mm2"] - ref.contact_area) / ref.contact_area,
            }
        )
    return row


def road_window(track, pos):
    """The map a static solve of the road at ``pos``'s shift starts from: the strip's raw
    heights over the footprint's length at that shift (a road point at x lies under body x +
    shift; the strip is centred), its full width, as :class:`~twoscale.surface.RawMap`."""
    raw = track.scene.surface.raw
    z, h = raw.heights, float(raw.spacing)
    half, shift = 0.5 * float(track.spec.footprint[0]), float(track.shifts[pos.index])
    centre = 0.5 * z.shape[1] * h  # road x = 0 at the strip's middle
    j0, j1 = (max(0, int(round((centre - shift + e) / h))) for e in (-half, half))
    return RawMap(np.ascontiguousarray(z[:, j0:j1]), spacing=h, units="mm")


def run(args) -> dict:
    scene, info = build(args)
    t0 = time.perf_counter()
    track = prepare(scene)
    info["prepare_s"] = time.perf_counter() - t0
    info["positions"] = len(track.shifts)
    info["footprint_estimate_mm"] = tyre_contact_length(track)
    print(
        f"strip {info['strip_mm'][0]:.0f} x {info['strip_mm'][1]:.0f} mm at {args.h} mm ({info['samples'][1]} x "
        f"{info['samples'][0]} samples, {info['stones']} stones): made in {info['strip_s']:.1f} s, segmented in "
        f"{info['segment_s']:.1f} s; track prepared in {info['prepare_s']:.1f} s; {info['positions']} positions",
        flush=True,
    )
    sample = set(np.linspace(1, len(track.shifts) - 1, args.samples).astype(int)) if args.samples else set()
    times, cpu, rows, previous = [], [], [], None
    options = RollingOptions(pressure_start=not args.macro_start, solver=args.solver)
    state = window_state(track, options)
    info["solver"] = "window" if state is not None else "twoscale"
    t_run = time.perf_counter()
    iterations = []
    with frozen_objects():  # as roll() runs the positions (twoscale.collector)
        for k in range(len(track.shifts)):
            c0 = time.process_time()
            pos = step(track, k, previous, options, state)
            cpu.append(time.process_time() - c0)
            times.append(pos.seconds)
            iterations.append(int(pos.result.iterations.get("cg", pos.result.iterations.get("micro", 0))))
            if k % args.every == 0 or k == len(track.shifts) - 1:
                print(
                    f"  position {k:5d} shift {track.shifts[k]:8.2f} mm: {pos.result.total_load:8.1f} N, approach "
                    f"{pos.result.penetration:.4f} mm, area {pos.result.contact_area:8.1f} mm2, drag {pos.drag:7.2f} N, "
                    f"{len(pos.selection.stones)} stones, {pos.seconds:.2f} s, converged {pos.result.converged}",
                    flush=True,
                )
            if k in sample:
                rows.append(compare(track, pos, cpu[-1], not args.no_cm, args.repeat))
                print(
                    "  sample " + ", ".join(f"{key} {_shown(v)}" for key, v in rows[-1].items()),
                    flush=True,
                )
            previous = pos
    wall = time.perf_counter() - t_run
    t = np.array(times)
    c = np.array(cpu)
    summary = {
        "run_s": wall,
        "run_cpu_s": float(c.sum()),
        "mean_s": float(t.mean()),
        "median_s": float(np.median(t)),
        "max_s": float(t.max()),
        "mean_cpu_s": float(c.mean()),
        "median_cpu_s": float(np.median(c)),
        "max_cpu_s": float(c.max()),
        "first_cpu_s": float(c[0]),
        "second_cpu_s": float(c[1]) if len(c) > 1 else float("nan"),
        "estimate_1m_cpu_s": float(c.mean()) * 1000.0 / args.step,
        "iterations_mean": float(np.mean(iterations)),
        "iterations_max": int(np.max(iterations)),
    }
    print(
        f"run: {wall:.1f} s wall (with the samples' comparisons), {summary['run_cpu_s']:.1f} s CPU in the "
        f"{len(t)} positions; per position CPU mean {summary['mean_cpu_s']:.3f} s, median "
        f"{summary['median_cpu_s']:.3f} s, largest {summary['max_cpu_s']:.3f} s (wall mean {summary['mean_s']:.3f} s), "
        f"the first {summary['first_cpu_s']:.3f} s, the second {summary['second_cpu_s']:.3f} s; "
        f"1 m at this CPU rate: {summary['estimate_1m_cpu_s']:.0f} s; CG iterations (micro sweeps) mean "
        f"{summary['iterations_mean']:.1f}, largest {summary['iterations_max']} ({info['solver']})"
    )
    for key in ("ratio_ref", "ratio_cold", "ratio_cold_segmented", "ratio_cm"):
        vals = [r[key] for r in rows if key in r]
        if vals:
            print(f"{key}: " + ", ".join(f"{v:.3f}" for v in vals))
    if len(c) > 2:
        summary["by_iterations"] = by_iterations(c[1:], np.array(iterations[1:]))
    if rows and len(c) > 1:
        summary.update(spread(c[1:], rows))
        print(
            f"the positions after the first (each timed once: a position cannot be repeated without its "
            f"history, so the targets are checked on each sampled position's own time above): CPU median "
            f"{summary['positions_median_cpu_s']:.3f} s, 90th percentile {summary['positions_p90_cpu_s']:.3f} s; "
            f"over the median reference {summary['ref_median_cpu_s']:.3f} s: {summary['median_over_ref']:.3f}, "
            f"{summary['p90_over_ref']:.3f}; over the median cold solve {summary['cold_median_cpu_s']:.3f} s: "
            f"{summary['median_over_cold']:.3f}, {summary['p90_over_cold']:.3f} (the samples' reference and cold "
            f"solve each timed {rows[0]['repeat']} times, interleaved; their spread (largest - least) / median: "
            f"reference {max(r['ref_cpu_spread'] for r in rows):.2f}, cold {max(r['cold_cpu_spread'] for r in rows):.2f} "
            f"at most); over the median cold solve with its window's segmentation "
            f"{summary['cold_segmented_median_cpu_s']:.3f} s: {summary['median_over_cold_segmented']:.3f}, "
            f"{summary['p90_over_cold_segmented']:.3f}"
        )
    positions = [
        {"shift_mm": float(x), "cpu_s": float(t), "iterations": int(i)} for x, t, i in zip(track.shifts, c, iterations)
    ]
    return {"args": vars(args), "info": info, "summary": summary, "samples": rows, "positions": positions}


def by_iterations(cpu: np.ndarray, iterations: np.ndarray) -> dict:
    """The positions' CPU (after the first) by their CG iterations: per count the positions
    and their median CPU, and the least-squares line ``fixed + per_iteration x iterations``
    (what a position costs besides its iterations, and an iteration), printed."""
    counts = {
        int(n): {"positions": int(np.sum(iterations == n)), "median_cpu_s": float(np.median(cpu[iterations == n]))}
        for n in np.unique(iterations)
    }
    line = np.polyfit(iterations, cpu, 1) if np.ptp(iterations) > 0 else (0.0, float(np.mean(cpu)))
    print(
        "CPU by CG iterations (positions after the first): "
        + ", ".join(f"{n}: {v['positions']} at {v['median_cpu_s']:.3f} s" for n, v in counts.items())
        + f"; least squares: {line[1]:.3f} s + {line[0] * 1e3:.1f} ms an iteration"
    )
    return {"counts": counts, "fixed_s": float(line[1]), "per_iteration_s": float(line[0])}


def spread(cpu: np.ndarray, rows: list) -> dict:
    """The positions' CPU (``cpu``: each timed once) by its median and 90th percentile, over
    the median of the samples' reference and cold-solve times (each a median of its runs)."""
    ref = float(np.median([r["ref_cpu_s"] for r in rows]))
    cold = float(np.median([r["cold_cpu_s"] for r in rows]))
    segmented = float(np.median([r["cold_cpu_s"] + r["segment_cpu_s"] for r in rows]))
    med, p90 = float(np.median(cpu)), float(np.percentile(cpu, 90))
    return {
        "cold_segmented_median_cpu_s": segmented,
        "median_over_cold_segmented": med / segmented,
        "p90_over_cold_segmented": p90 / segmented,
        "positions_median_cpu_s": med,
        "positions_p90_cpu_s": p90,
        "ref_median_cpu_s": ref,
        "cold_median_cpu_s": cold,
        "median_over_ref": med / ref,
        "p90_over_ref": p90 / ref,
        "median_over_cold": med / cold,
        "p90_over_cold": p90 / cold,
    }


#: Ten Prony branches over six decades (tau 1e-6 to 1e3 s), glassy modulus 5 x the relaxed.
TEN_BRANCHES = tuple((4.0 * MAT.E / 10.0, float(t)) for t in np.logspace(-6.0, 3.0, 10))


def visco(args) -> dict:
    """The section rolled elastic and viscoelastic (ten branches), CPU time of each."""
    import dataclasses

    from twoscale.rolling import roll

    scene, info = build(args)
    times = {}
    for name, material in (("elastic", MAT), ("viscoelastic", Material(MAT.E, MAT.nu, prony=TEN_BRANCHES))):
        c0 = time.process_time()
        res = roll(dataclasses.replace(scene, material=material))
        times[name] = time.process_time() - c0
        print(
            f"{name}: {times[name]:.1f} s CPU for {len(res.shifts)} positions, all converged {res.all_converged}, "
            f"mean drag {res.mean_drag:.4g} N",
            flush=True,
        )
    print(f"viscoelastic / elastic: {times['viscoelastic'] / times['elastic']:.2f} (target <= 2)")
    return {"args": vars(args), "info": info, "cpu_s": times, "ratio": times["viscoelastic"] / times["elastic"]}


def scale_out(args) -> dict:
    """The run on one and on two Dask worker processes (elastic: independent chunks)."""
    from twoscale.rolling.chunks import roll_chunks

    scene, info = build(args)
    times = {}
    for n in (1, 2):
        t0 = time.perf_counter()
        res = roll_chunks(scene, chunks=n, scheduler="processes")
        times[n] = time.perf_counter() - t0
        print(
            f"{n} chunk(s): {times[n]:.1f} s wall for {len(res.shifts)} positions, all converged {res.all_converged}",
            flush=True,
        )
    print(f"speed-up of 2 workers: {times[1] / times[2]:.2f}")
    return {"args": vars(args), "info": info, "wall_s": times, "speedup": times[1] / times[2]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--length", type=float, default=1000.0, help="run length, mm")
    p.add_argument("--step", type=float, default=1.0, help="step between positions, mm")
    p.add_argument("--h", type=float, default=0.25, help="strip spacing = cell size, mm")
    p.add_argument("--load", type=float, default=3000.0, help="tyre load, N")
    p.add_argument("--radius", type=float, default=300.0, help="tyre radius, mm")
    p.add_argument("--width", type=float, default=150.0, help="tyre (footprint) width, mm")
    p.add_argument("--samples", type=int, default=3, help="positions compared with the reference")
    p.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="times the reference and the cold solve are each timed at a sample, interleaved (their median is taken)",
    )
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--every", type=int, default=50, help="print every n-th position")
    p.add_argument("--no-cm", action="store_true", help="skip ContactMechanics")
    p.add_argument(
        "--visco",
        action="store_true",
        help="instead of the run: the section rolled elastic and with "
        "a ten-branch Prony tread (CPU time of each, their ratio; target <= 2)",
    )
    p.add_argument(
        "--scale-out",
        action="store_true",
        help="instead of the run: the run in 1 and in 2 chunks on "
        "Dask worker processes (twoscale.rolling.chunks), wall times and speed-up",
    )
    p.add_argument(
        "--macro-start",
        action="store_true",
        help="start each position's macro step only (no pressure start), for comparison",
    )
    p.add_argument(
        "--solver",
        default="auto",
        choices=("auto", "window", "twoscale"),
        help="the positions' solver (RollingOptions.solver)",
    )
    p.add_argument(
        "--system-heap",
        action="store_true",
        help="leave glibc's heap thresholds at their defaults (else raised as "
        "'twoscale solve' raises them for a rolling run: twoscale.cli.heap), for comparison",
    )
    p.add_argument("--out", default=None, help="write the figures as JSON")
    args = p.parse_args(argv)
    if not args.system_heap:
        keep_heap()
    out = scale_out(args) if args.scale_out else visco(args) if args.visco else run(args)
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
