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
   worker processes (its start-up reported apart).

On a shared machine wall times count the waits for a core, so CPU times are reported
beside them: the process CPU of each run and each case's own CPU (its record's
``cpu_seconds``). Reported: the wall speed-up ``serial / dask`` (target >= 1.7) with and
without the cluster's start-up, and an estimate for an idle machine (serial CPU against
half the workers' case CPU plus the start-up); the machinery's CPU per case (serial run's
CPU less its cases' own, target <= 0.2 s) and the Dask overhead per case
``(2 x dask wall - the cases' own wall) / 40`` (scheduling, transfers, idle workers);
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


def plain_loop(study) -> dict:
    """The 40 solves in a plain loop, providers built once: wall and CPU seconds."""
    from twoscale.scene import default_h
    from twoscale.studies.cases import case_scene, expand
    from twoscale.twoscale import solve_twoscale

    providers = {}
    t0, c0 = time.perf_counter(), time.process_time()
    for case in expand(study):
        sc = case_scene(case, study)
        if case.body.name not in providers:
            providers[case.body.name] = sc.provider(**({"progress": False} if case.body.name == "block" else {}))
        r = solve_twoscale(providers[case.body.name], sc.asperities, h=default_h(sc), total_load=sc.total_load,
                           tilt=sc.tilt, pivot=sc.pivot)
        assert r.converged, case.label
    return {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def timed_study(study, out: Path, workers: int, quiet: bool) -> dict:
    """``run_study`` into ``out``: wall and process CPU seconds, the cluster's start-up, and
    the sums of the cases' own wall and CPU seconds (as their records give them)."""
    from twoscale.studies.execute import run_study
    from twoscale.studies.store import CaseStore

    c0 = time.process_time()
    run = run_study(study, out, workers=workers, quiet=quiet)
    cpu = time.process_time() - c0
    recs = [CaseStore(out).read(k) for k in dict.fromkeys(run.keys)]
    assert all(r["status"] == "converged" for r in recs), [r["reason"] for r in recs if r["status"] != "converged"]
    return {"wall_s": run.seconds, "cpu_s": cpu, "startup_s": run.startup_seconds,
            "cases_wall_s": sum(r["seconds"] for r in recs), "cases_cpu_s": sum(r["cpu_seconds"] for r in recs)}


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
    solving = dask["wall_s"] - dask["startup_s"]
    rec = {"cases": n, "block_build_s": warm, "plain": plain, "serial": serial, "dask": dask,
           "speedup": serial["wall_s"] / dask["wall_s"], "speedup_without_startup": serial["wall_s"] / solving,
           # the machinery's own CPU: the serial run's process CPU less the cases' own
           "machinery_cpu_per_case_s": (serial["cpu_s"] - serial["cases_cpu_s"]) / n,
           "serial_minus_plain_cpu_per_case_s": (serial["cpu_s"] - plain["cpu_s"]) / n,
           # scheduling, transfers and idle workers: two workers' time not spent in cases
           "dask_overhead_per_case_s": (2 * solving - dask["cases_wall_s"]) / n,
           "worker_cpu_ratio": dask["cases_cpu_s"] / serial["cases_cpu_s"],
           "per_case_cpu_s": serial["cases_cpu_s"] / n}
    # with a core per worker (no one else on the machine) the two workers would take about
    # their cases' CPU time each, halved, plus the start-up
    rec["speedup_idle_estimate"] = serial["cpu_s"] / (dask["cases_cpu_s"] / 2 + dask["startup_s"])
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
          f"{rec['per_case_cpu_s']:.2f} s per case)")
    print(f"  machinery CPU per case {rec['machinery_cpu_per_case_s']:+.3f} s (serial study CPU - plain CPU: "
          f"{rec['serial_minus_plain_cpu_per_case_s']:+.3f} s per case); target <= 0.2 s")
    print(f"study, 2 workers  wall {d['wall_s']:6.1f} s  (cluster start {d['startup_s']:.1f} s; cases' own wall "
          f"{d['cases_wall_s']:.1f} s, CPU {d['cases_cpu_s']:.1f} s = {rec['worker_cpu_ratio']:.2f} x serial)")
    print(f"  Dask overhead per case {rec['dask_overhead_per_case_s']:+.3f} s (2 x wall - cases' own wall, / {n})")
    print(f"speed-up serial / dask (wall) {rec['speedup']:.2f}x ({rec['speedup_without_startup']:.2f}x without the "
          f"start-up); estimated with a core per worker {rec['speedup_idle_estimate']:.2f}x; target >= 1.7x")
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
    rec = figures(plain, serial, dask, warm)
    report(rec)
    if args.out:
        Path(args.out).write_text(json.dumps(rec, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
