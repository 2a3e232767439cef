"""The scene-space sweep: every plausible scene, default options, against the references.

Scenes come from :mod:`twoscale.scenespace` (seeded: ``--seed``, ``--count``). For each,
in fresh subprocesses (peak RSS = the child's own ``VmHWM``, the interpreter included),
interleaved scene by scene so that the machine's load hits both alike:

* ``ts``: ``twoscale.solve(scene)`` with the default options, as a user's
  ``twoscale solve`` runs it: converged, refused (a :class:`~twoscale.scene.SceneError`
  before solving, and how long the refusal took), time, peak memory against
  :func:`twoscale.resources.estimate_memory` for the h the solve used, the policy's choice
  and every attempt of the micro step;
* ``ref``: the full-grid reference ``solve(scene, method="reference")`` at the same h,
  where its memory estimate fits ``--ref-max-gb`` (and ``--ref-timeout``);
* ``CM``: ContactMechanics on the reference grid (half-space scenes of tips, grids up to
  ``--cm-max-cells``), when installed (``pip install ".[bench]"``).

Where the reference takes under ``--repeat-below`` s of CPU (3 s), the default and the
reference are timed ``--repeats`` times each (3), alternating, and their median CPU times
make the ratio: one sub-second time moves by 10-30 % on a shared machine; under
``--tiny-below`` (0.3 s), where one solve of tens of ms in a fresh process moves by up to a
third, ``2 --repeats + 1`` times each (7). A solve under 0.1 s of CPU is also run again in its own
process until its runs add up to 0.3 s, and their mean is its time (``cpu_first_s`` keeps
the first run's): on a loaded host a process's CPU clock advances by its scheduling slices,
as coarse as the solve.

Reported per scene: the per-tip force error ``max_k |F_k - F_ref,k| / max F_ref`` and the
total-load error (percent), the time ratio ts / ref (CPU time of the solve, and wall), the
share of the reference's box in contact (its loaded cells' area over the box's) and, where
that share is under 20 % and the reference takes over 1 s of CPU, whether the default met
0.3x the reference's CPU time (the sparse-contact target; the summary lists the scenes that
missed it); the worst cases first. ``--table FILE.md`` writes the
Markdown table recorded in docs/records/.

Usage::

    python benchmarks/sweep.py --count 200 --seed 0 --out sweep.jsonl [--table sweep.md]
    python benchmarks/sweep.py --only 17 42        # rerun two scenes, printed in full
    python benchmarks/sweep.py --part 0/2 --out a.jsonl & python benchmarks/sweep.py --part 1/2 --out b.jsonl
    python benchmarks/sweep.py --out a.jsonl --read b.jsonl --count 0 --table sweep.md   # one table of both

Results are appended to ``--out`` as one JSON line a scene; a rerun skips the scenes
already there (delete the file to start again).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks import _common  # noqa: E402,F401  (single-threaded BLAS/FFT by default)
import numpy as np  # noqa: E402  (after _common: OpenBLAS reads its thread count when loaded)
from benchmarks.sweep_report import _fmt, _load, contact_fraction, row, summary, table  # noqa: E402

GB = 1e9
BODY_MODULES = _common.BODY_MODULES  # outside the timed call, as the solvers' own modules
#: A solve under this many s of CPU is timed again in its process until the runs add up to
#: ``INSIDE_TOTAL`` s (at most ``INSIDE_MAX`` runs), their mean kept: on a loaded host a
#: process's CPU clock advances in its scheduling slices (a 10-20 ms solve read 11.9, 12.0,
#: 15.9, 16.0 or 24.0 ms in fresh processes: medians 1.33x apart for the same route), so a
#: single run cannot tell two solves of that size apart; the mean of runs adding up to 0.3 s
#: can. The first run (``cpu_first_s``, its imports' and caches' first use in) is kept apart.
INSIDE_BELOW = 0.1
INSIDE_TOTAL = 0.3
INSIDE_MAX = 40


def _rss_mb() -> float:
    """This process's peak resident memory, MB: ``VmHWM`` of /proc/self/status, the high-water
    mark of its own address space. ``ru_maxrss`` would do elsewhere, but on Linux it keeps the
    forking parent's resident size across ``exec`` (the sweep's parent grows to 300 MB and
    more as it builds scenes: small solves then read that instead of their own ~110 MB)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _scene(spec_dict: dict, folder: str):
    from twoscale.scenespace import SceneSpec, build

    return build(SceneSpec(**spec_dict), folder)


def _prepared(spec_dict: dict, folder: str):
    """What a user starts a solve from, made before the clock starts: a tip scene (the
    draw's work), or a height map written into ``folder`` with its scene table (generating
    the texture: 1.2 s of the 1.9 s a 70 mm road scene took to build, charged to both
    solvers until 2026-11-26 09:00). Returns the call that reads it as the solve does."""
    from twoscale.io.scene_file import scene_from_dict
    from twoscale.scenespace import SceneSpec, build, map_table

    spec = SceneSpec(**spec_dict)
    if spec.kind == "tips":
        scene = build(spec)
        return lambda: scene
    table = map_table(spec, folder)
    return lambda: scene_from_dict(table, base_dir=folder)


def _figures(res) -> dict:
    forces = np.asarray(res.asperities.forces, dtype=float)
    micro = getattr(res.details, "micro", None)
    out = {
        "converged": bool(res.converged),
        "message": res.message,
        "forces": forces.tolist(),
        "total_load": float(res.total_load),
        "penetration": float(res.penetration),
        "cells": int(res.n_cells),
        "area": float(np.sum(res.asperities.contact_areas)),
    }
    if res.method == "reference":  # the default route of the smallest scenes: their full grid's CG
        out["choice"] = "full-grid"
        out["reason"] = res.message.split(";")[0]
    if micro is not None:
        out["choice"] = micro.choice.iteration
        out["reason"] = micro.choice.reason
        out["work"] = micro.choice.estimates.get("work")
        out["coverage"] = micro.choice.estimates.get("coverage")
        out["patches"] = micro.choice.estimates.get("patches")
        out["merged_contacts"] = micro.choice.estimates.get("merged_contacts")
        out["height_map"] = micro.choice.estimates.get("height_map")
        out["precorrected"] = int(micro.coupling.precorrected)  # the sparse part's cheap products
        out["attempts"] = [[a.iteration, a.far_tol, a.converged, a.sweeps, round(a.seconds, 3)] for a in micro.attempts]
    return out


def _timed_again(read, method: str, h, popts, wall: float, cpu: float) -> tuple[float, float, int]:
    """``(wall, cpu, runs)``: the first run's times, or where its CPU is under
    :data:`INSIDE_BELOW` the mean of it and further runs of the same read and solve until
    their CPU adds up to :data:`INSIDE_TOTAL` s (at most :data:`INSIDE_MAX` runs)."""
    import twoscale

    if cpu >= INSIDE_BELOW:
        return wall, cpu, 1
    walls, cpus = [wall], [cpu]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        while sum(cpus) < INSIDE_TOTAL and len(cpus) < INSIDE_MAX:
            t0, c0 = time.perf_counter(), time.process_time()
            twoscale.solve(read(), method=method, h=h, provider_options=popts)
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
    return float(np.mean(walls)), float(np.mean(cpus)), len(cpus)


def run_one(method: str, spec_dict: dict, h: float | None) -> dict:
    """One solve in this process: ``method`` "twoscale" (default options) or "reference"."""
    import twoscale

    _common.import_solver_modules()  # the solvers' and the block's, outside the timed call
    from twoscale.resources import estimate_memory
    from twoscale.scene import SceneError, default_h

    with tempfile.TemporaryDirectory() as folder:
        try:
            read = _prepared(spec_dict, folder)
        except SceneError:  # refused while preparing (a map's default h): the whole build is timed
            read = lambda: _scene(spec_dict, folder)  # noqa: E731
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                scene = read()
                popts = {"progress": False} if scene.influence["kind"] == "block" else None
                res = twoscale.solve(scene, method=method, h=h, provider_options=popts)
        except SceneError as exc:
            return {"refused": str(exc), "time_s": time.perf_counter() - t0, "peak_mb": _rss_mb()}
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        first, (wall, cpu, runs) = cpu, _timed_again(read, method, h, popts, wall, cpu)
        # the estimate the solve checked, made again outside the timed call (the benchmark's own)
        used_h = default_h(scene) if h is None else h
        est = estimate_memory(scene, used_h, "twoscale" if method == "twoscale" else "reference")
        out = {
            "time_s": wall,
            "cpu_s": cpu,
            "cpu_first_s": first,
            "inside_runs": runs,
            "peak_mb": _rss_mb(),
            "h": float(used_h),
            "estimate_mb": est.bytes / 1e6,
            "estimate_cells": est.cells,
            # what the estimate says the union CG would need where the policy may take either
            "estimate_union_mb": None if est.union_bytes is None else est.union_bytes / 1e6,
            "warnings": sorted({str(w.message).split(":")[0][:80] for w in caught}),
        }
        out.update(_figures(res))
        return out


def run_cm(spec_dict: dict, h: float, maxiter: int = 1000) -> dict:
    """ContactMechanics on the scene's reference grid (half-space, non-periodic)."""
    from benchmarks._cm import contact_mechanics, modules

    from twoscale.indenters import surface_on
    from twoscale.reference.on_scene import reference_grid

    modules()  # its imports outside the timed call, as for the other solvers (~1.1 s of CPU)
    with tempfile.TemporaryDirectory() as folder:
        scene = _scene(spec_dict, folder)
        t0, c0 = time.perf_counter(), time.process_time()
        grid = reference_grid(scene, h)
        surf = surface_on(grid, scene.asperities)
        load = {"penetration": scene.penetration} if scene.penetration is not None else {"total_load": scene.total_load}
        cm = contact_mechanics(surf.height, grid.h, scene.material.E_star, maxiter=maxiter, **load)
        pix = cm.force.ravel()
        own = surf.owner.ravel()
        ok = own >= 0
        forces = np.bincount(own[ok], weights=pix[ok], minlength=len(scene.asperities))
        return {
            "time_s": time.perf_counter() - t0,
            "cpu_s": time.process_time() - c0,
            "peak_mb": _rss_mb(),
            "converged": cm.converged,
            "forces": forces.tolist(),
            "cells": int(grid.size),
        }


def _cpu_limit(seconds: float):
    """A child's limit of CPU seconds (the machine is shared: wall time is not the code's)."""

    def apply():
        limit = int(math.ceil(seconds))
        resource.setrlimit(resource.RLIMIT_CPU, (limit, limit + 5))

    return apply


def _child(kind: str, spec: dict, h, timeout: float, wall_factor: float = 1.0) -> dict:
    """One solve in a fresh process, stopped after ``timeout`` s of CPU time (and
    ``wall_factor`` times that of wall time when that factor is above 1)."""
    cmd = [sys.executable, os.path.abspath(__file__), "--child", kind, "--spec", json.dumps(spec), "--h", json.dumps(h)]
    t0 = time.perf_counter()
    cpu_limited = wall_factor > 1.0
    try:
        out = subprocess.run(
            cmd,
            capture_output=True,
            text=True,
            timeout=timeout * wall_factor,
            preexec_fn=_cpu_limit(timeout) if cpu_limited else None,
        )
    except subprocess.TimeoutExpired:
        return {"error": f"timeout after {timeout * wall_factor:g} s of wall time", "time_s": time.perf_counter() - t0}
    if cpu_limited and out.returncode in (-signal.SIGXCPU, -signal.SIGKILL):
        return {"error": f"timeout after {timeout:g} s of CPU time", "time_s": time.perf_counter() - t0}
    lines = (out.stderr or "").strip().splitlines()
    if out.returncode != 0 or not (out.stdout or "").strip():
        why = lines[-1] if lines else f"exit code {out.returncode}"
        return {"error": why[:300], "time_s": time.perf_counter() - t0, "exit": out.returncode}
    return json.loads(out.stdout.strip().splitlines()[-1])


def _errors(f, r) -> dict:
    f, r = np.asarray(f, dtype=float), np.asarray(r, dtype=float)
    if r.size == 0 or not r.max() > 0:
        return {}
    return {
        "tip_pct": 100.0 * float(np.max(np.abs(f - r))) / float(r.max()),
        "total_pct": 100.0 * abs(float(f.sum()) - float(r.sum())) / float(r.sum()),
    }


def _ref_fits(spec: dict, h: float, max_gb: float) -> tuple[bool, float]:
    from twoscale.resources import estimate_memory

    with tempfile.TemporaryDirectory() as folder:
        scene = _scene(spec, folder)
        est = estimate_memory(scene, h, "reference")
        return est.bytes <= max_gb * GB, est.cells


def _repeat_short(rec: dict, spec: dict, h: float, args) -> None:
    """Where the reference took under ``--repeat-below`` s of CPU, time the default and the
    reference ``--repeats`` times each, in alternation, and keep the medians as their
    ``cpu_s`` (every run's in ``cpu_runs``): a single sub-second CPU time moves by 10-30 %
    on a shared machine, a median of interleaved runs much less. The forces are the first
    runs' (the repeats are the same solves)."""
    if args.repeats <= 1 or rec["ref"]["cpu_s"] >= args.repeat_below or "forces" not in rec["ts"]:
        return
    runs = {"ts": [rec["ts"]["cpu_s"]], "ref": [rec["ref"]["cpu_s"]]}
    # a solve of tens of ms in a fresh process moves by a third between runs: more of them
    repeats = 2 * args.repeats + 1 if rec["ref"]["cpu_s"] < args.tiny_below else args.repeats
    for _ in range(repeats - 1):
        for key, method, limit in (("ts", "twoscale", args.timeout), ("ref", "reference", args.ref_timeout)):
            again = _child(method, spec, None if key == "ts" else h, limit, args.wall_factor)
            if "cpu_s" in again and "error" not in again:
                runs[key].append(again["cpu_s"])
    for key, cpu in runs.items():
        rec[key]["cpu_runs"] = cpu
        rec[key]["cpu_s"] = float(np.median(cpu))


def measure(spec: dict, args) -> dict:
    """Default two-scale solve, reference and ContactMechanics on one scene."""
    rec = {"spec": spec}
    if spec["body"] == "block":  # the FEM correction is built once and cached: not timed
        rec["warmup"] = _child("twoscale", spec, None, args.timeout * 3, args.wall_factor)
    rec["ts"] = _child("twoscale", spec, None, args.timeout, args.wall_factor)
    h = rec["ts"].get("h")
    if h is None:
        return rec
    fits, cells = _ref_fits(spec, h, args.ref_max_gb)
    rec["ref_cells"] = cells
    if fits:
        rec["ref"] = _child("reference", spec, h, args.ref_timeout, args.wall_factor)
        if "forces" in rec["ref"]:
            _repeat_short(rec, spec, h, args)
            rec["err"] = _errors(rec["ts"]["forces"], rec["ref"]["forces"])
            rec["ratio_cpu"] = rec["ts"]["cpu_s"] / max(rec["ref"]["cpu_s"], 1e-9)
            rec["ratio_wall"] = rec["ts"]["time_s"] / max(rec["ref"]["time_s"], 1e-9)
            rec["contact_fraction"] = contact_fraction(rec)
    if args.cm and spec["kind"] == "tips" and spec["body"] == "halfspace" and fits and cells <= args.cm_max_cells:
        rec["cm"] = _child("cm", spec, h, args.ref_timeout, args.wall_factor)
        if "forces" in rec["cm"] and "ref" in rec and "forces" in rec["ref"]:
            rec["cm_err"] = _errors(rec["cm"]["forces"], rec["ref"]["forces"])
    return rec


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--count", type=int, default=200)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--only", type=int, nargs="*")
    p.add_argument("--part", default="0/1", help="K/N: only the scenes whose index is K modulo N (run N at once)")
    p.add_argument(
        "--read", nargs="*", default=[], help="more result files to summarise with --out (their scenes are skipped)"
    )
    p.add_argument("--reverse", action="store_true", help="from the last scene down (a third process meets the others)")
    p.add_argument(
        "--smallest-first",
        action="store_true",
        help="scenes with fewer tips first (maps count as 100 tips): one lane covers the most scenes soonest",
    )
    p.add_argument(
        "--largest-first",
        action="store_true",
        help="the order of --smallest-first reversed: a process from the other end meets a smallest-first lane "
        "(give each the other's --out as --read)",
    )
    p.add_argument(
        "--record", action="store_true", help="with --only: append the reruns to --out (the last record counts)"
    )
    p.add_argument("--out", default="sweep.jsonl")
    p.add_argument("--table")
    p.add_argument("--timeout", type=float, default=180.0, help="s, a default solve")
    p.add_argument("--ref-timeout", type=float, default=600.0)
    p.add_argument(
        "--wall-factor",
        type=float,
        default=1.0,
        help="above 1: the timeouts are of CPU time, and wall time is limited to this times them (a shared machine)",
    )
    p.add_argument(
        "--repeat-below",
        type=float,
        default=3.0,
        help="s of the reference's CPU: shorter scenes are timed --repeats times each, interleaved, medians kept",
    )
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument(
        "--tiny-below",
        type=float,
        default=0.3,
        help="s of the reference's CPU: still shorter scenes are timed 2 --repeats + 1 times each",
    )
    p.add_argument("--ref-max-gb", type=float, default=8.0)
    p.add_argument("--cm-max-cells", type=int, default=1_000_000)
    p.add_argument("--no-cm", dest="cm", action="store_false")
    p.add_argument("--max-tips", type=int, default=10_000)
    p.add_argument("--child", choices=["twoscale", "reference", "cm"])
    p.add_argument("--spec")
    p.add_argument("--h")
    args = p.parse_args(argv)
    if args.child:
        spec, h = json.loads(args.spec), json.loads(args.h)
        out = run_cm(spec, h) if args.child == "cm" else run_one(args.child, spec, h)
        print(json.dumps(out))
        return 0
    if args.cm:
        try:
            import ContactMechanics  # noqa: F401
        except ImportError:
            args.cm = False
    from twoscale.scenespace import sweep

    specs = sweep(args.count, args.seed, max_tips=args.max_tips)
    if args.only and not args.record:
        print(f"--only without --record: the scenes' records are printed, not written to {args.out}", file=sys.stderr)
    if args.only:
        specs = [s for s in specs if s.index in args.only]
    k, n = (int(v) for v in args.part.split("/"))
    specs = [s for s in specs if s.index % n == k]
    if args.reverse:
        specs = specs[::-1]
    if args.smallest_first:
        specs = sorted(specs, key=lambda s: s.n if s.kind == "tips" else 100)
    if args.largest_first:
        specs = sorted(specs, key=lambda s: s.n if s.kind == "tips" else 100, reverse=True)
    for spec in specs:
        done = {r["spec"]["index"] for f in [args.out, *args.read] for r in _load(f)} if not args.only else set()
        if args.only and args.record:
            done = set()
        if spec.index in done:
            continue
        try:
            rec = measure(spec.to_dict(), args)
        except Exception as exc:  # the driver's own work on one scene: recorded, the sweep goes on
            rec = {"spec": spec.to_dict(), "ts": {"error": f"sweep driver: {type(exc).__name__}: {exc}"[:300]}}
        x = row(rec)
        print(
            f"{x['scene']}: {x['verdict']} {x['choice']} ts {_fmt(x['ts_s'], '.2f')} s ref "
            f"{_fmt(x['ref_s'], '.2f')} s ratio {_fmt(x['ratio'], '.3f')} err {_fmt(x['tip_pct'], '.2g')} % "
            f"peak {_fmt(x['peak_mb'], '.0f')}/{_fmt(x['est_mb'], '.0f')} MB",
            flush=True,
        )
        if args.only:
            print(json.dumps({k: v for k, v in rec.items() if k != "spec"}, default=str)[:3000])
        if not args.only or args.record:
            with open(args.out, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(rec) + "\n")
    records = sum((_load(f) for f in [args.out, *args.read]), []) if not args.only or args.record else []
    latest = {r["spec"]["index"]: r for r in records}  # a scene run again: its last record
    records = [latest[i] for i in sorted(latest)]
    if records:
        print(summary(records))
        if args.table:
            with open(args.table, "w", encoding="utf-8") as fh:
                fh.write(summary(records).replace("\n", "  \n") + "\n\n" + table(records))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
