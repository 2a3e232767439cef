"""A 40-case study serially and on a 2-worker local Dask cluster.

The study: the S2 scene of ``examples/S2.toml`` (25 spheres of R = 5 mm on a 10 mm lattice,
E = 6 MPa, nu = 0.5, ball-and-socket joint, h = 0.1 mm) on 2 bodies (the half-space with a
60 x 60 mm window, the 140 x 140 x 20 mm bonded block) at 4 total loads (150, 200, 250,
300 N) and 5 positions (0 to 8 mm along x, step 2 mm): 2 x 4 x 5 = 40 cases.

The block's correction is built first, in this process, into a fresh disk cache (timed);
every run below then reads it from disk, as a rerun of a user's study does. Each run is a
**fresh Python process** (this script with ``--child``), as a user's ``twoscale study``
is: it pays the interpreter's start, the imports, its providers' first use and, with
Dask, the cluster's start and close (every process single-threaded, ``_common``):

1. ``plain``: the 40 solves in a plain loop, ``solve_twoscale`` with each body's provider
   built once (what a hand-written script would do), no files;
2. ``serial``: ``run_study(..., workers=0)``: the study machinery in one process (keys,
   case folders, records);
3. ``dask``: ``run_study(..., workers=2)``: a new local cluster of two worker processes,
   which start while the study warms the block up;
4. ``pair``: two plain loops over half the cases each, two processes at once (no Dask):
   what two solvers running together cost on this machine.

Each run is timed twice: from outside (the process's wall time from launch to exit, and the
CPU of the process and of everything it started: Dask's workers) and from inside (around
the loop or the ``run_study`` call, after the imports: the figures earlier versions of this
benchmark gave, with the process's imports already paid). Each case also records the CPU
time of its own thread. On a shared machine wall times count the waits for a core, so CPU
times are reported beside them, with the load average before and after each run.
Reported: the speed-up ``serial / dask`` (target >= 1.7) in wall time from outside and from
inside, and an estimate for the two cores to itself (the serial process's CPU against half
the 2-worker process tree's); the machinery's CPU per case (serial run's CPU less its cases'
own, target <= 0.2 s) and the Dask overhead per case ``(2 x dask wall - the cases' own
wall) / 40``; the ceiling two processes reach here (the plain process's CPU against half
the pair's); then what a 100,000-case study (10 textures x 3 bodies x 10 loads x 333
positions) would cost on N machines of 2 or 32 cores at the measured per-case CPU time and
efficiency.

Usage::

    cd benchmarks && python study.py [--out study_bench.json] [--quiet] [--repeat N]
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
#: The study described above (scene, bodies, loads, positions).
BIG = {"textures": 10, "bodies": 3, "loads": 10, "positions": 333}


def plain_loop(study, part: slice = slice(None)) -> dict:
    """The 40 solves (or ``part`` of them) in a plain loop, providers built once: wall and
    CPU seconds."""
    from twoscale.scene import default_h
    from twoscale.studies.cases import case_scene, expand
    from twoscale.driver import solve_twoscale

    providers = {}
    t0, c0 = time.perf_counter(), time.process_time()
    for case in expand(study)[part]:
        sc = case_scene(case, study)
        if case.body.name not in providers:
            providers[case.body.name] = sc.provider(**({"progress": False} if case.body.name == "block" else {}))
        r = solve_twoscale(
            providers[case.body.name],
            sc.asperities,
            h=default_h(sc),
            total_load=sc.total_load,
            tilt=sc.tilt,
            pivot=sc.pivot,
        )
        assert r.converged, case.label
    return {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def child(kind: str, path: str, out: str) -> dict:
    """One run in this (fresh) process: ``plain``, ``half0``/``half1`` (every other case),
    ``serial`` or ``dask``. Its inside figures, plus ``startup_cpu_s``: the CPU this process
    spent before the run (interpreter start and the imports of the study machinery; what
    the run imports later, lazily, is in the run's own figures)."""
    from twoscale.studies.spec import read_study

    study = read_study(path)
    startup = time.process_time()
    if kind == "plain":
        rec = plain_loop(study)
    elif kind in ("half0", "half1"):
        rec = plain_loop(study, slice(int(kind[-1]), None, 2))
    else:
        rec = timed_study(study, Path(out), {"serial": 0, "dask": 2}[kind], quiet=True)
    return {**rec, "startup_cpu_s": startup}


def launch(kinds: list[str], path: Path, tmp: Path) -> dict:
    """Start a fresh process per run of ``kinds`` at once (``--child``) and wait for them:
    wall time from launch to the last exit, CPU of the processes and of everything they
    started (Dask's workers: reaped before their process exits), load average before and
    after, and each child's own figures (:func:`child`)."""
    import subprocess

    load, k0, t0 = os.getloadavg()[0], _children_cpu(), time.perf_counter()
    procs = [
        subprocess.Popen(
            [sys.executable, __file__, "--child", kind, "--study", str(path), "--dir", str(tmp / kind)],
            stdout=subprocess.PIPE,
            text=True,
        )
        for kind in kinds
    ]
    outs = [p.communicate()[0] for p in procs]
    wall, cpu = time.perf_counter() - t0, _children_cpu() - k0
    if any(p.returncode for p in procs):
        raise RuntimeError(f"a run of {kinds} failed: exit codes {[p.returncode for p in procs]}")
    inside = [json.loads(o.strip().splitlines()[-1]) for o in outs]
    return {
        "process_wall_s": wall,
        "process_cpu_s": cpu,
        "load_before": load,
        "load_after": os.getloadavg()[0],
        "inside": inside,
    }


def run(kind: str, path: Path, tmp: Path) -> dict:
    """A run of ``kind`` in a fresh process (``pair``: two halves at once), its figures
    flattened: outside (``process_*``) and inside (the child's own; a pair's wall is the
    slower half's, its CPU the sum)."""
    if kind != "pair":
        r = launch([kind], path, tmp)
        return {**{k: v for k, v in r.items() if k != "inside"}, **r["inside"][0]}
    r = launch(["half0", "half1"], path, tmp)
    halves = r.pop("inside")
    return {
        **r,
        "wall_s": max(h["wall_s"] for h in halves),
        "cpu_s": sum(h["cpu_s"] for h in halves),
        "startup_cpu_s": sum(h["startup_cpu_s"] for h in halves),
    }


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
    return {
        "wall_s": wall,
        "solving_wall_s": run.seconds,
        "cpu_s": cpu,
        "workers_cpu_s": children,
        "startup_s": run.startup_seconds,
        "load_before": load,
        "load_after": os.getloadavg()[0],
        "cases_wall_s": sum(r["seconds"] for r in recs),
        "cases_cpu_s": sum(r["cpu_seconds"] for r in recs),
    }


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


def figures(runs: dict, warm: float, n: int = 40) -> dict:
    """The benchmark's figures from the four runs of :func:`run` (see the module doc)."""
    plain, serial, dask, pair = (runs[k] for k in ("plain", "serial", "dask", "pair"))
    rec = {
        "cases": n,
        "block_build_s": warm,
        **runs,
        "speedup": serial["process_wall_s"] / dask["process_wall_s"],
        "speedup_inside": serial["wall_s"] / dask["wall_s"],
        # the machinery's own CPU: the serial run's CPU less the cases' own
        "machinery_cpu_per_case_s": (serial["cpu_s"] - serial["cases_cpu_s"]) / n,
        "serial_minus_plain_cpu_per_case_s": (serial["process_cpu_s"] - plain["process_cpu_s"]) / n,
        # scheduling, transfers, worker start and idle workers: two workers' time not in cases
        "dask_overhead_per_case_s": (2 * dask["wall_s"] - dask["cases_wall_s"]) / n,
        "worker_cpu_ratio": dask["cases_cpu_s"] / serial["cases_cpu_s"],
        "per_case_cpu_s": serial["cases_cpu_s"] / n,
        # with the two cores to itself, a run would take at least the CPU its process tree
        # used spread over them (an estimate that ignores the last case's tail)
        "speedup_idle_estimate": serial["process_cpu_s"] / (dask["process_cpu_s"] / 2),
        "pair_ceiling": plain["process_cpu_s"] / (pair["process_cpu_s"] / 2),
        "pair_cpu_ratio": pair["process_cpu_s"] / plain["process_cpu_s"],
        "dask_over_pair_wall": dask["process_wall_s"] / pair["process_wall_s"],
        "dask_over_pair_cpu": dask["process_cpu_s"] / pair["process_cpu_s"],
    }
    efficiency = min(1.0, rec["speedup_idle_estimate"] / 2)
    rec["efficiency"] = efficiency
    rec["on_paper"] = on_paper(
        rec["per_case_cpu_s"] + max(rec["machinery_cpu_per_case_s"], 0.0), efficiency, block_build_s=warm
    )
    return rec


def report(rec: dict) -> None:
    n = rec["cases"]
    print(
        f"{n} cases (S2, half-space + block, 4 loads x 5 positions); block correction built in "
        f"{rec['block_build_s']:.1f} s before the runs; each run a fresh process"
    )
    print("run         process wall / CPU (s)   inside wall / CPU (s)   start-up CPU (s)   load")
    for k in ("plain", "serial", "dask", "pair"):
        r = rec[k]
        print(
            f"{k:10s}  {r['process_wall_s']:8.1f} / {r['process_cpu_s']:6.1f}      {r['wall_s']:8.1f} / "
            f"{r['cpu_s']:6.1f}     {r['startup_cpu_s']:6.2f}           {r['load_before']:.1f} -> {r['load_after']:.1f}"
        )
    s, d = rec["serial"], rec["dask"]
    print(
        f"serial cases' own CPU {s['cases_cpu_s']:.1f} s ({rec['per_case_cpu_s']:.2f} s per case); the workers' "
        f"{d['cases_cpu_s']:.1f} s = {rec['worker_cpu_ratio']:.2f} x; workers' processes {d['workers_cpu_s']:.1f} s CPU"
    )
    print(
        f"machinery CPU per case {rec['machinery_cpu_per_case_s']:+.3f} s (serial process CPU - plain's: "
        f"{rec['serial_minus_plain_cpu_per_case_s']:+.3f} s per case); target <= 0.2 s"
    )
    print(f"Dask overhead per case {rec['dask_overhead_per_case_s']:+.3f} s (2 x wall - cases' own wall, / {n})")
    print(
        f"pair: CPU {rec['pair_cpu_ratio']:.2f} x the plain process's (ceiling for two processes here "
        f"{rec['pair_ceiling']:.2f}x); the 2-worker study took {rec['dask_over_pair_wall']:.2f}x its wall, "
        f"{rec['dask_over_pair_cpu']:.2f}x its CPU"
    )
    print(
        f"speed-up serial / dask: processes' wall {rec['speedup']:.2f}x, inside {rec['speedup_inside']:.2f}x; "
        f"estimated with the two cores to itself (CPU) {rec['speedup_idle_estimate']:.2f}x; target >= 1.7x"
    )
    print(
        f"on paper, 100,000 cases at {rec['per_case_cpu_s']:.2f} s CPU per case, parallel efficiency "
        f"{rec['efficiency']:.2f}, 2 block builds of {rec['block_build_s']:.0f} s per machine:"
    )
    for r in rec["on_paper"]:
        print(f"  {r['machines']:4d} machines x {r['cores_each']:2d} cores: {r['hours']:8.2f} h")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="also write the figures as JSON")
    parser.add_argument("--repeat", type=int, default=1, help="rounds of the four runs (figures of each)")
    parser.add_argument("--child", choices=("plain", "half0", "half1", "serial", "dask"), help=argparse.SUPPRESS)
    parser.add_argument("--study", help=argparse.SUPPRESS)
    parser.add_argument("--dir", help=argparse.SUPPRESS)
    _common.add_quiet(parser)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child, args.study, args.dir)))
        return 0
    from twoscale.studies.providers import warm_blocks
    from twoscale.studies.cases import case_scene, expand
    from twoscale.studies.spec import read_study

    recs = []
    with tempfile.TemporaryDirectory() as tmp:
        # a fresh disk cache: the block's correction is built (and timed) once, and the
        # runs inherit the variable and read it
        os.environ["TWOSCALE_CACHE_DIR"] = str(Path(tmp) / "fem")
        path = Path(tmp) / "bench.toml"
        path.write_text(STUDY.format(scene=(ROOT / "examples" / "S2.toml").as_posix()), encoding="utf-8")
        study = read_study(path)
        assert study.n_cases == 40
        t = time.perf_counter()  # the block's correction, once
        warm_blocks([case_scene(c, study) for c in expand(study) if c.body.name == "block"], progress=not args.quiet)
        warm = time.perf_counter() - t
        for i in range(args.repeat):
            runs = {k: run(k, path, Path(tmp) / f"round{i}") for k in ("plain", "serial", "dask", "pair")}
            recs.append(figures(runs, warm))
            report(recs[-1])
    if args.out:
        Path(args.out).write_text(json.dumps(recs, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
