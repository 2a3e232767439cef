"""Scale-out of a rolling run: the same section in chunks on a local Dask cluster of one and of
two single-threaded worker processes (:func:`twoscale.rolling.chunks.roll_chunks`), measured
so that a shared machine's other load shows.

The section: the example strip (``examples/rolling/strip.npz``, 200 x 50 mm of chip seal at
0.25 mm) under a slice of slick tyre (R 300 mm, a 80 x 40 mm footprint) at 300 N, elastic,
rolled ``--length`` mm in ``--step`` mm steps, in ``--chunks`` chunks on both clusters (the
one-worker cluster runs them one after the other: the same work, the cold start of every
chunk included). Both clusters are started once and warmed by a 3-position run (worker
imports, the strip's pickle); their workers' thread settings are printed (BLAS/OpenMP
threads must be 1 a worker, and the worker's thread count).

Rounds interleave the two clusters, alternating which goes first (1, 2 / 2, 1 / ...), so
that a change of the machine's load falls on both. Per run: the wall time; each worker's CPU
seconds over the run (``psutil``: all its threads), this process's; the CPU seconds the
*other* processes of the machine used meanwhile (the machine's busy CPU time less this
run's processes: the load from others, made visible); the load average; per chunk the
positions' summed wall time and its first (cold) position against the chunk's median. Then
per round the ratio 1-worker wall over 2-worker wall, their median, and the ratio of the
median walls. The serial parts of :func:`~twoscale.rolling.chunks.roll_chunks` (the track's
preparation in this process, the scene pickled for every chunk) are timed once first.

Run: ``python benchmarks/rolling_scaleout.py [--length 80] [--step 1] [--rounds 3] [--chunks 2]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pickle
import statistics
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded defaults before numpy loads)
import numpy as np
import psutil

from twoscale.io.scene_file import read_scene
from twoscale.rolling.chunks import THREAD_VARIABLES, chunk_bounds, roll_chunks
from twoscale.rolling.track import prepare
from twoscale.studies.dask_backend import dask_client

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rolling" / "tyre.toml"


def section(length: float, step: float):
    scene = read_scene(EXAMPLE)
    spec = dataclasses.replace(scene.rolling, start=-0.5 * length, end=0.5 * length, step=step)
    return dataclasses.replace(scene, rolling=spec)


def _cpu_seconds() -> float:
    """CPU seconds of the calling process, all its threads (user + system)."""
    t = psutil.Process().cpu_times()
    return t.user + t.system


def _thread_settings() -> dict:
    """What a worker runs with: the BLAS/OpenMP thread variables and its thread count."""
    return {**{k: os.environ.get(k) for k in THREAD_VARIABLES}, "threads": psutil.Process().num_threads()}


def _busy_seconds() -> float:
    """CPU seconds the whole machine has been busy (all cores, every process)."""
    t = psutil.cpu_times()
    return t.user + t.nice + t.system + getattr(t, "irq", 0.0) + getattr(t, "softirq", 0.0)


def serial_parts(scene, chunks: int) -> dict:
    """The parts of ``roll_chunks`` that run in this process before the workers start."""
    t0 = time.perf_counter()
    prepare(scene)
    t1 = time.perf_counter()
    blob = pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL)
    t2 = time.perf_counter()
    return {"prepare_s": t1 - t0, "pickle_s": (t2 - t1) * chunks, "pickle_MB": len(blob) / 1e6 * chunks}


def timed(scene, client, chunks: int) -> dict:
    """One run of ``scene`` on ``client``'s cluster, with what the module docstring lists."""
    workers0 = client.run(_cpu_seconds)
    own0, busy0, load0 = _cpu_seconds(), _busy_seconds(), os.getloadavg()[0]
    t0 = time.perf_counter()
    result = roll_chunks(scene, chunks=chunks, scheduler=client)
    wall = time.perf_counter() - t0
    workers1 = client.run(_cpu_seconds)
    own, busy = _cpu_seconds() - own0, _busy_seconds() - busy0
    worker_cpu = [workers1[a] - workers0[a] for a in sorted(workers0)]
    parts = []
    for i0, i1 in chunk_bounds(len(result.shifts), chunks):
        s = np.asarray(result.seconds[i0:i1])
        parts.append(
            {"sum": float(s.sum()), "first": float(s[0]), "median": float(np.median(s[1:] if s.size > 1 else s))}
        )
    return {
        "wall": wall,
        "worker_cpu": worker_cpu,
        "own_cpu": own,
        "others_cpu": max(busy - own - sum(worker_cpu), 0.0),
        "load": (load0, os.getloadavg()[0]),
        "chunks": parts,
        "result": result,
    }


def report(r: int, w: int, run: dict, reference) -> None:
    diff = float(np.abs(run["result"].total_load - reference.total_load).max())
    chunks = ", ".join(
        f"{c['sum']:.1f} s (first {c['first']:.2f} s, median {c['median']:.2f} s)" for c in run["chunks"]
    )
    print(
        f"round {r + 1}, {w} worker{'s' if w > 1 else ' '}: wall {run['wall']:6.2f} s; worker CPU "
        f"{' + '.join(f'{c:.1f}' for c in run['worker_cpu'])} s, this process {run['own_cpu']:.1f} s, "
        f"other processes {run['others_cpu']:.1f} s ({run['others_cpu'] / run['wall']:.2f} cores); "
        f"load average {run['load'][0]:.2f} -> {run['load'][1]:.2f}\n"
        f"    chunks' positions: {chunks}; converged {run['result'].all_converged}, "
        f"largest load difference to the first run {diff:.1e} N",
        flush=True,
    )


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--length", type=float, default=80.0, help="mm of road rolled")
    ap.add_argument("--step", type=float, default=1.0, help="mm between positions")
    ap.add_argument("--rounds", type=int, default=3, help="runs on each cluster, interleaved")
    ap.add_argument("--chunks", type=int, default=2)
    args = ap.parse_args(argv)
    scene = section(args.length, args.step)
    print(
        f"{scene.rolling.count} positions ({args.length:g} mm in {args.step:g} mm steps), {args.chunks} chunks; "
        f"{os.cpu_count()} CPUs, load average {os.getloadavg()}"
    )
    print("serial parts in this process:", {k: round(v, 3) for k, v in serial_parts(scene, args.chunks).items()})
    walls: dict = {1: [], 2: []}
    cpus: dict = {1: [], 2: []}
    with dask_client(workers=1) as one, dask_client(workers=2) as two:
        clients = {1: one, 2: two}
        for w, client in clients.items():
            client.wait_for_workers(w, timeout=120)
            roll_chunks(section(3 * args.step, args.step), chunks=w, scheduler=client)
            print(f"{w}-worker cluster's workers:", list(client.run(_thread_settings).values()))
        reference = None
        for r in range(args.rounds):
            for w in (1, 2) if r % 2 == 0 else (2, 1):
                run = timed(scene, clients[w], args.chunks)
                reference = reference if reference is not None else run["result"]
                walls[w].append(run["wall"])
                cpus[w].append(run["worker_cpu"])
                report(r, w, run, reference)
    ratios = [a / b for a, b in zip(walls[1], walls[2])]
    # what the workers' CPU seconds say the ratio would be on two free cores: the one worker's
    # CPU over the busier of the two (the same work split; the other jobs add wall, not CPU)
    bound = [sum(a) / max(b) for a, b in zip(cpus[1], cpus[2])]
    split = [sum(b) / sum(a) for a, b in zip(cpus[1], cpus[2])]
    m1, m2 = statistics.median(walls[1]), statistics.median(walls[2])
    print(
        f"per round, 1-worker wall / 2-worker wall: {', '.join(f'{x:.2f}' for x in ratios)}; median "
        f"{statistics.median(ratios):.2f} (target >= 1.6); median walls {m1:.2f} s and {m2:.2f} s: {m1 / m2:.2f}x\n"
        f"per round, the 1-worker run's worker CPU over the 2-worker run's busier worker's CPU (the ratio on two "
        f"free cores): {', '.join(f'{x:.2f}' for x in bound)}, median {statistics.median(bound):.2f}; the two "
        f"workers' CPU over the one's (the cost of splitting): {', '.join(f'{x:.2f}' for x in split)}"
    )


if __name__ == "__main__":
    main()
