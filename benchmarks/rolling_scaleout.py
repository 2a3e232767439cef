"""Scale-out of a rolling run: the same section in chunks on a local Dask cluster of one and of
two single-threaded worker processes (:func:`twoscale.rolling.chunks.roll_chunks`), wall-clock
ratio, the runs interleaved (1, 2, 1, 2, ...) so that the machine's other load falls on both.

The section: the example strip (``examples/rolling/strip.npz``, 200 x 50 mm of chip seal at
0.25 mm) under a slice of slick tyre (R 300 mm, a 80 x 40 mm footprint) at 300 N, elastic,
rolled ``--length`` mm in ``--step`` mm steps, in ``--chunks`` chunks on both clusters (the
one-worker cluster runs them one after the other: the same work, the cold start of every
chunk included). Each cluster is started once and warmed by a 3-position run first (worker
imports, the strip's pickle). Printed per run: wall seconds, positions' seconds summed over
the chunks, the load average before and after; then the ratio of the median walls.

Run: ``python benchmarks/rolling_scaleout.py [--length 120] [--step 1] [--rounds 2] [--chunks 2]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded defaults before numpy loads)

from twoscale.io.scene_file import read_scene
from twoscale.rolling.chunks import roll_chunks
from twoscale.studies.dask_backend import dask_client

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rolling" / "tyre.toml"


def section(length: float, step: float):
    scene = read_scene(EXAMPLE)
    spec = dataclasses.replace(scene.rolling, start=-0.5 * length, end=0.5 * length, step=step)
    return dataclasses.replace(scene, rolling=spec)


def timed(scene, client, chunks: int):
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    result = roll_chunks(scene, chunks=chunks, scheduler=client)
    wall = time.perf_counter() - t0
    return wall, float(result.timings_s["positions"]), load0, os.getloadavg()[0], result


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--length", type=float, default=120.0, help="mm of road rolled")
    ap.add_argument("--step", type=float, default=1.0, help="mm between positions")
    ap.add_argument("--rounds", type=int, default=2, help="runs on each cluster, interleaved")
    ap.add_argument("--chunks", type=int, default=2)
    args = ap.parse_args(argv)
    scene = section(args.length, args.step)
    n = scene.rolling.count
    print(
        f"{n} positions ({args.length:g} mm in {args.step:g} mm steps), {args.chunks} chunks; "
        f"{os.cpu_count()} CPUs, load average {os.getloadavg()}"
    )
    walls: dict = {1: [], 2: []}
    with dask_client(workers=1) as one, dask_client(workers=2) as two:
        clients = {1: one, 2: two}
        for w, client in clients.items():
            client.wait_for_workers(w, timeout=120)
            warm = section(3 * args.step, args.step)
            roll_chunks(warm, chunks=w, scheduler=client)
        reference = None
        for r in range(args.rounds):
            for w in (1, 2):
                wall, positions, la0, la1, result = timed(scene, clients[w], args.chunks)
                walls[w].append(wall)
                if reference is None:
                    reference = result
                same = abs(result.total_load - reference.total_load).max() if reference is not result else 0.0
                print(
                    f"round {r + 1}, {w} worker{'s' if w > 1 else ''}: wall {wall:7.2f} s, positions "
                    f"{positions:7.2f} s summed over the chunks, load average {la0:.2f} -> {la1:.2f}, "
                    f"all converged {result.all_converged}, largest load difference to the first run "
                    f"{same:.2e} N",
                    flush=True,
                )
    m1, m2 = statistics.median(walls[1]), statistics.median(walls[2])
    print(
        f"median wall: 1 worker {m1:.2f} s, 2 workers {m2:.2f} s: 2 workers {m1 / m2:.2f}x one "
        f"(target >= 1.6); per round {[f'{a / b:.2f}' for a, b in zip(walls[1], walls[2])]}"
    )


if __name__ == "__main__":
    main()
