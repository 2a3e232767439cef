"""A 40-case study serially and on a 2-worker local Dask cluster (issue 17, point 7).

The study: the S2 scene of ``examples/S2.toml`` (25 spheres of R = 5 mm on a 10 mm lattice,
E = 6 MPa, nu = 0.5, ball-and-socket joint, h = 0.1 mm) on 2 bodies (the half-space with a
60 x 60 mm window, the 140 x 140 x 20 mm bonded block) at 4 total loads (150, 200, 250,
300 N) and 5 positions (0 to 8 mm along x, step 2 mm): 2 x 4 x 5 = 40 cases.

Measured, in one process, in this order (every process single-threaded, ``_common``; the
block's correction is built first into a fresh disk cache and timed):

1. ``plain``: the same 40 solves in a plain loop, ``solve_twoscale`` with each body's
   provider built once (what a hand-written script would do), no files;
2. ``serial``: ``run_study(..., workers=0)``: the study machinery in this process (keys,
   case folders, records);
3. ``dask``: ``run_study(..., workers=2)`` into a fresh folder: a new local cluster of two
   worker processes, which start while the study warms the block up;
4. ``side by side``: two plain loops over half the cases each, in two processes at once
   (no Dask): what two solvers running together cost on this machine.

Each run is timed around the whole ``run_study`` call. On a shared machine wall times count
the waits for a core, so CPU times are reported beside them: the process CPU of each run, the
2-worker run's worker processes' CPU (start-up and imports included), each case's own CPU
(its record's ``cpu_seconds``), and the load average before and after each run. Reported:
the wall speed-up ``serial / dask`` (target >= 1.7), and an estimate for the two cores to
itself (the serial run's CPU against half the CPU the 2-worker run used, here and in its
workers); the machinery's CPU per case (serial run's CPU less its cases' own, target
<= 0.2 s) and the Dask overhead per case ``(2 x dask wall - the cases' own wall) / 40``
(worker start, scheduling, transfers, idle workers);
then what a 100,000-case study (10 textures x 3 bodies x 10 loads x 333 positions) would
cost on N machines of 2 or 32 cores at the measured per-case CPU time and efficiency.

Usage::

    cd benchmarks && python study.py [--out study_bench.json] [--quiet]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded processes)

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

STUDY = """
[study]
name = "bench40"
[[scene]]
file = "{scene}"
name = "S2"
[[body]]
name = "halfspace"
kind = "halfspace"
window = [60.0, 60.0]
[[body]]
name = "block"
kind = "block"
[load]
total = [150.0, 200.0, 250.0, 300.0]
[positions]
start = [0.0, 0.0]
end = [8.0, 0.0]
step = 2.0
"""
#: The on-paper study of the issue.
BIG = {"textures": 10, "bodies": 3, "loads": 10, "positions": 333}


def plain_loop(study, part: slice = slice(None)) -> dict:
    """The 40 solves (or ``part`` of them) in a plain loop, providers built once: wall and
    CPU seconds."""
    from twoscale.scene import default_h
    from twoscale.studies.cases import case_scene, expand
    from twoscale.twoscale import solve_twoscale

    providers = {}
    t0, c0 = time.perf_counter(), time.process_time()
    for case in expand(study)[part]:
        sc = case_scene(case, study)
        if case.body.name not in providers:
            providers[case.body.name] = sc.provider(**({"progress": False} if case.body.name == "block" else {}))
        r = solve_twoscale(providers[case.body.name], sc.asperities, h=default_h(sc), total_load=sc.total_load,
                           tilt=sc.tilt, pivot=sc.pivot)
        assert r.converged, case.label
    return {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def _half_loop(path: str, part: int) -> dict:
    """:func:`plain_loop` over every other case (``part`` 0 or 1), in a process of its own."""
    from twoscale.scene import default_h  # noqa: F401  (imports before the clock starts)
    from twoscale.studies.spec import read_study
    from twoscale.twoscale import solve_twoscale  # noqa: F401

    return plain_loop(read_study(path), slice(part, None, 2))


def side_by_side(path: Path) -> dict:
    """Two plain loops over half the cases each, in two processes at once: what running two
    solvers side by side costs on this machine, without Dask. Wall (the slower) and CPU
    (the sum) seconds of the loops."""
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(2) as pool:
        halves = pool.starmap(_half_loop, [(str(path), 0), (str(path), 1)])
    return {"wall_s": max(h["wall_s"] for h in halves), "cpu_s": sum(h["cpu_s"] for h in halves)}


def timed_study(study, out: Path, workers: int, quiet: bool) -> dict:
    """``run_study`` into ``out``: wall and process CPU seconds, the cluster's start-up, and
    the sums of the cases' own wall and CPU seconds (as their records give them)."""
    from twoscale.studies.execute import run_study
    from twoscale.studies.store import CaseStore

    load = os.getloadavg()[0]
    c0, k0, t0 = time.process_time(), _children_cpu(), time.perf_counter()
    run = run_study(study, out, workers=workers, quiet=quiet)
    wall, cpu, children = time.perf_counter() - t0, time.process_time() - c0, _children_cpu() - k0
    recs = [CaseStore(out).read(k) for k in dict.fromkeys(run.keys)]
    assert all(r["status"] == "converged" for r in recs), [r["reason"] for r in recs if r["status"] != "converged"]
    return {"wall_s": wall, "solving_wall_s": run.seconds, "cpu_s": cpu, "workers_cpu_s": children,
            "startup_s": run.startup_seconds, "load_before": load, "load_after": os.getloadavg()[0],
            "cases_wall_s": sum(r["seconds"] for r in recs), "cases_cpu_s": sum(r["cpu_seconds"] for r in recs)}


def _children_cpu() -> float:
    """CPU seconds of this process's finished child processes (the local cluster's workers,
    counted once the cluster is closed)."""
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def on_paper(per_case_s: float, efficiency: float, block_build_s: float) -> list[dict]:
    """Hours for the 100,000-case study on N machines of c cores, at the measured per-case
    time and parallel efficiency; each machine builds the correction of each of the two
    block bodies (of the three) once, ``block_build_s`` each."""
    n = BIG["textures"] * BIG["bodies"] * BIG["loads"] * BIG["positions"]
    rows = []
    for cores in (2, 32):
        for machines in (1, 10, 100):
            hours = (n * per_case_s / (machines * cores * efficiency) + 2 * block_build_s) / 3600
            rows.append({"cases": n, "machines": machines, "cores_each": cores, "hours": hours})
    return rows


def figures(plain: dict, serial: dict, dask: dict, warm: float, n: int = 40) -> dict:
    """The benchmark's figures from the three timed runs (see the module doc)."""
    rec = {"cases": n, "block_build_s": warm, "plain": plain, "serial": serial, "dask": dask,
           "speedup": serial["wall_s"] / dask["wall_s"],
           # the machinery's own CPU: the serial run's process CPU less the cases' own
           "machinery_cpu_per_case_s": (serial["cpu_s"] - serial["cases_cpu_s"]) / n,
           "serial_minus_plain_cpu_per_case_s": (serial["cpu_s"] - plain["cpu_s"]) / n,
           # scheduling, transfers, worker start and idle workers: two workers' time not in cases
           "dask_overhead_per_case_s": (2 * dask["wall_s"] - dask["cases_wall_s"]) / n,
           "worker_cpu_ratio": dask["cases_cpu_s"] / serial["cases_cpu_s"],
           "per_case_cpu_s": serial["cases_cpu_s"] / n}
    # with the two cores to itself, the 2-worker run would take at least the CPU it used
    # (workers: start-up, imports, cases; this process: scheduler, case folders) spread
    # over them: an estimate that ignores the last case's tail
    dask_cpu = dask["workers_cpu_s"] + dask["cpu_s"]
    rec["dask_cpu_s"] = dask_cpu
    rec["speedup_idle_estimate"] = serial["cpu_s"] / (dask_cpu / 2)
    efficiency = min(1.0, rec["speedup_idle_estimate"] / 2)
    rec["efficiency"] = efficiency
    rec["on_paper"] = on_paper(rec["per_case_cpu_s"] + max(rec["machinery_cpu_per_case_s"], 0.0), efficiency,
                               block_build_s=warm)
    return rec


def report(rec: dict) -> None:
    p, s, d, n = rec["plain"], rec["serial"], rec["dask"], rec["cases"]
    print(f"40 cases (S2, half-space + block, 4 loads x 5 positions); block correction built in "
          f"{rec['block_build_s']:.1f} s before the runs")
    print(f"plain loop        wall {p['wall_s']:6.1f} s  CPU {p['cpu_s']:6.1f} s")
    print(f"study, serial     wall {s['wall_s']:6.1f} s  CPU {s['cpu_s']:6.1f} s  (cases' own CPU {s['cases_cpu_s']:.1f} s: "
          f"{rec['per_case_cpu_s']:.2f} s per case; load average {s['load_before']:.1f} -> {s['load_after']:.1f})")
    print(f"  machinery CPU per case {rec['machinery_cpu_per_case_s']:+.3f} s (serial study CPU - plain CPU: "
          f"{rec['serial_minus_plain_cpu_per_case_s']:+.3f} s per case); target <= 0.2 s")
    print(f"study, 2 workers  wall {d['wall_s']:6.1f} s  CPU {d['cpu_s']:.1f} s here + {d['workers_cpu_s']:.1f} s in the "
          f"workers (scheduler start {d['startup_s']:.2f} s; cases' own wall {d['cases_wall_s']:.1f} s, CPU "
          f"{d['cases_cpu_s']:.1f} s = {rec['worker_cpu_ratio']:.2f} x serial; load average {d['load_before']:.1f} -> "
          f"{d['load_after']:.1f})")
    print(f"  Dask overhead per case {rec['dask_overhead_per_case_s']:+.3f} s (2 x wall - cases' own wall, / {n})")
    if "side_by_side" in rec:
        print(f"two plain loops side by side (half the cases each, no Dask): wall {rec['side_by_side']['wall_s']:.1f} s, "
              f"CPU {rec['side_by_side']['cpu_s']:.1f} s = {rec['side_by_side_cpu_ratio']:.2f} x the plain loop's "
              f"(ceiling for two processes here: {rec['side_by_side_idle_estimate']:.2f}x); the 2-worker study took "
              f"{rec['dask_over_side_by_side_wall']:.2f}x its wall, {rec['dask_over_side_by_side_cpu']:.2f}x its CPU")
    print(f"speed-up serial / dask (wall) {rec['speedup']:.2f}x; estimated with the two cores to itself (serial CPU "
          f"against half the 2-worker run's CPU) {rec['speedup_idle_estimate']:.2f}x; target >= 1.7x")
    print(f"on paper, 100,000 cases at {rec['per_case_cpu_s']:.2f} s CPU per case, parallel efficiency "
          f"{rec['efficiency']:.2f}, 2 block builds of {rec['block_build_s']:.0f} s per machine:")
    for r in rec["on_paper"]:
        print(f"  {r['machines']:4d} machines x {r['cores_each']:2d} cores: {r['hours']:8.2f} h")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="also write the figures as JSON")
    _common.add_quiet(parser)
    args = parser.parse_args(argv)
    from twoscale.studies.providers import warm_blocks
    from twoscale.studies.cases import case_scene, expand
    from twoscale.studies.spec import read_study

    with tempfile.TemporaryDirectory() as tmp:
        # a fresh disk cache: the block's correction is built (and timed) once, and the
        # workers inherit the variable and read it
        os.environ["TWOSCALE_CACHE_DIR"] = str(Path(tmp) / "fem")
        path = Path(tmp) / "bench.toml"
        path.write_text(STUDY.format(scene=(ROOT / "examples" / "S2.toml").as_posix()), encoding="utf-8")
        study = read_study(path)
        assert study.n_cases == 40
        t = time.perf_counter()   # the block's correction, once
        warm_blocks([case_scene(c, study) for c in expand(study) if c.body.name == "block"], progress=not args.quiet)
        warm = time.perf_counter() - t
        plain = plain_loop(study)
        serial = timed_study(study, Path(tmp) / "serial", 0, args.quiet)
        dask = timed_study(study, Path(tmp) / "dask", 2, args.quiet)
        pair = side_by_side(path)
    rec = figures(plain, serial, dask, warm)
    rec["side_by_side"] = pair
    rec["side_by_side_cpu_ratio"] = pair["cpu_s"] / plain["cpu_s"]
    # the machine's own ceiling for two processes (plain CPU against half the pair's), and
    # the 2-worker run against the pair (Dask's cost on top of running two solvers at once)
    rec["side_by_side_idle_estimate"] = plain["cpu_s"] / (pair["cpu_s"] / 2)
    rec["dask_over_side_by_side_wall"] = dask["wall_s"] / pair["wall_s"]
    rec["dask_over_side_by_side_cpu"] = rec["dask_cpu_s"] / pair["cpu_s"]
    report(rec)
    if args.out:
        Path(args.out).write_text(json.dumps(rec, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
