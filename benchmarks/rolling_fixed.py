"""A steady rolling position's fixed part by call: what a position costs besides its CG iterations.

The section of ``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip seal at
0.25 mm, 1 mm steps) is rolled on the window path, single-threaded, with the objects made
before the positions out of the collector's full passes (as :func:`twoscale.rolling.roll`
runs them); from position ``--skip`` on each position runs under ``cProfile`` timed by the
process's CPU (``time.process_time``: the other jobs of a shared host are not counted).

Printed, in ms a position (under the profiler: its cost per call is in every figure, the
shares compare): the calls a position makes once or a fixed number of times, each with its
inclusive CPU and the calls under it above ``--floor`` ms (the stones' selection, the
window's surface and checks, the start, the stones' blocks' build, the start's product, the
anchor and the confirmation, the two refreshes after the first steps, the answer's result,
the drag), their sum (the fixed part), and the position's CPU, its CG iterations and what
the iterations cost beside the fixed part; then the garbage collector's passes a position
and their CPU (``gc.callbacks``).

Usage::

    PYTHONPATH=. python benchmarks/rolling_fixed.py [--length 120] [--skip 20] [--floor 0.3]
"""

from __future__ import annotations

import argparse
import cProfile
import gc
import pstats
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

import numpy as np  # noqa: E402

from twoscale.cli.heap import keep_heap  # noqa: E402
from twoscale.collector import frozen_objects  # noqa: E402
from twoscale.rolling import run  # noqa: E402

#: (file, function, label): the fixed calls of a position (the refreshes by their caller).
FIXED = (
    ("road.py", "stones_at", "road: the stones at the shift"),
    ("run.py", "_bound", "load control: the approach bound"),
    ("window.py", "_window_surface", "window: the stones' surface and its cover"),
    ("window.py", "start", "window: the start extrapolated"),
    ("window.py", "last_moved", "window: the last field moved"),
    ("window.py", "cut_in", "window: the cut"),
    ("lift.py", "touching_outside", "window: the check outside the cut"),
    ("blocks.py", "_build", "blocks: the stones' inverses and coupling"),
    ("iteration.py", "__init__", "kernel: the start's product"),
    ("iteration.py", "check>refresh", "kernel: the anchor and the confirmation"),
    ("iteration.py", "update_displacement>refresh", "kernel: the refreshes after the first steps"),
    ("compact.py", "inputs", "kernel: the part's inputs gathered"),
    ("_start.py", "initial_pressure", "kernel: the start checked"),
    ("compact.py", "answer", "kernel: the answer on the cut"),
    ("_problem.py", "build_result", "the answer's result (fields, per-stone forces)"),
    ("run.py", "drag_of", "the drag"),
)


def profile(length: float, skip: int):
    """The positions from ``skip`` on profiled: (stats, CPU a position, iterations, gc)."""
    keep_heap()
    track, options, state = rolling_benchmark.tyre_window(length)
    prof, last, cpu, its = cProfile.Profile(time.process_time), None, [], []
    passes, spent, t0 = [0], [0.0], [0.0]

    def collected(phase, _info):
        if phase == "start":
            t0[0] = time.process_time()
        elif prof_on[0]:
            passes[0] += 1
            spent[0] += time.process_time() - t0[0]

    prof_on = [False]
    gc.callbacks.append(collected)
    with frozen_objects():
        for k in range(len(track.shifts)):
            prof_on[0] = k >= skip
            c0 = time.process_time()
            if prof_on[0]:
                prof.enable()
            last = run.step(track, k, last, options, state)
            if prof_on[0]:
                prof.disable()
                cpu.append(time.process_time() - c0)
                its.append(last.result.iterations.get("cg", 0))
    gc.callbacks.remove(collected)
    return pstats.Stats(prof), np.array(cpu), np.array(its), (passes[0], spent[0])


def inclusive(stats, where: str, name: str) -> tuple[float, dict]:
    """CPU (s) of ``name`` in files ending ``where`` (``caller>name``: under ``caller`` only)
    and the CPU of the calls under it, by name."""
    caller, _, name = name.rpartition(">")
    total, under = 0.0, {}
    for key, (_, _, _, cum, callers) in stats.stats.items():
        if not key[0].endswith(where) or key[2] != name:
            continue
        total += sum(v[3] for c, v in callers.items() if c[2] == caller) if caller else cum
        if not caller:
            for callee, v in stats.all_callees.get(key, {}).items():
                under[callee[2]] = under.get(callee[2], 0.0) + v[3]
    return total, under


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--length", type=float, default=120.0, help="run length, mm")
    p.add_argument("--skip", type=int, default=20, help="positions rolled before the profile starts")
    p.add_argument("--floor", type=float, default=0.3, help="least ms a position of a call under a fixed one shown")
    args = p.parse_args()
    stats, cpu, its, (passes, spent) = profile(args.length, args.skip)
    stats.calc_callees()
    n, fixed = len(cpu), 0.0
    print(f"{n} positions from the {args.skip + 1}th, under the profiler: ms a position (inclusive)")
    for where, name, label in FIXED:
        total, under = inclusive(stats, where, name)
        fixed += total
        inner = ", ".join(
            f"{k} {1e3 * v / n:.2f}"
            for k, v in sorted(under.items(), key=lambda kv: -kv[1])
            if 1e3 * v / n >= args.floor
        )
        print(f"  {label:48s} {1e3 * total / n:7.2f}" + (f"  ({inner})" if inner else ""))
    mean = 1e3 * cpu.mean()
    print(
        f"  {'the fixed part':48s} {1e3 * fixed / n:7.2f} of {mean:.2f} ms a position (median {1e3 * np.median(cpu):.2f})"
    )
    print(
        f"  the CG iterations: {its.mean():.2f} a position, {(mean - 1e3 * fixed / n) / its.mean():.2f} ms each beside the fixed part"
    )
    print(f"the collector: {passes / n:.2f} passes a position, {1e3 * spent / n:.2f} ms a position")


if __name__ == "__main__":
    main()
