"""Which rolling positions are slow, and what they share: each position's CPU beside its work.

The section of ``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip seal at
0.25 mm, 1 mm steps) is rolled on the window path; per position (after the first) are taken:
its CPU time (the process's, around :func:`twoscale.rolling.run.step`), its CG iterations,
the stones given (and how many entered or left the selection since the last position), the
stones in contact (and how many came into or went out of contact), the loaded cells, the
stone blocks inverted afresh and updated (:class:`twoscale.rolling.blocks.StoneBlocks`), whether
the cut or the window changed, the two-scale solves (a fallback, or none), the garbage
collector's passes and their CPU (``gc.callbacks``), and the page faults and the involuntary
context switches the process took meanwhile (``getrusage``: the host's other jobs taking the
core). The positions run as :func:`twoscale.rolling.roll` runs them, the objects made before
them out of the collector's full passes (:mod:`twoscale.collector`); ``--unfrozen``
leaves them in, for comparison.

Printed: the CPU's median and 90th percentile; for each quantity its mean over the slowest
``--slow`` fraction of the positions and over the others, and its correlation with the CPU;
the CPU by CG iterations (per count, and the least-squares line: a position's cost besides its
iterations and an iteration's); the CPU less the iterations' part (what the iterations do not
explain) against the context switches; the slowest positions. ``--out`` writes the rows as
JSON. ``--repeat N`` instead rolls the section N times over in one process, one pass after
the other, each with a window state of its own: the same work at N moments seconds apart (a
host's busy spell lasts seconds: passes interleaved position by position share it, and
correlate at 0.6-0.8 whatever the work), so the least of a position's N CPU times is its work
with the least of the host's, and the spread of each pass beside that of the least says how
much of the tail is the host's. The iteration counts and the other work are deterministic; the CPU is the host's too.
Single-threaded.

Usage::

    PYTHONPATH=. python benchmarks/rolling_tail.py [--length 200] [--slow 0.15] [--unfrozen] [--out FILE.json]
    PYTHONPATH=. python benchmarks/rolling_tail.py --length 100 --repeat 3
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

import numpy as np  # noqa: E402

from twoscale.cli.heap import keep_heap  # noqa: E402
from twoscale.rolling import run as rolling_run  # noqa: E402
from twoscale.collector import frozen_objects  # noqa: E402

QUANTITIES = (
    "iterations",
    "stones",
    "stones_in",
    "stones_out",
    "touching",
    "touching_in",
    "touching_out",
    "loaded",
    "afresh",
    "updated",
    "cut_changed",
    "window_changed",
    "two_scale",
    "collections",
    "collector_s",
    "faults",
    "switches",
)


def collector_clock() -> list:
    """``[passes, CPU seconds]`` of the garbage collector from now on (a ``gc.callbacks``
    entry adds to it)."""
    total, started = [0, 0.0], [0.0]

    def timed(phase: str, info: dict) -> None:
        if phase == "start":
            started[0] = time.process_time()
        else:
            total[0] += 1
            total[1] += time.process_time() - started[0]

    gc.callbacks.append(timed)
    return total


def rows_of(length: float, frozen: bool = True) -> list:
    """The section's positions, one row each (module docstring)."""
    track, options, state = rolling_benchmark.tyre_window(length)
    collector = collector_clock()
    with frozen_objects() if frozen else contextlib.nullcontext():
        return _rows(track, options, state, collector)


def _rows(track, options, state, collector: list) -> list:
    """:func:`rows_of`'s positions on the prepared ``track``."""
    calls = [0]
    solve_position = rolling_run.solve_position

    def counted(*args, **kwargs):
        calls[0] += 1
        return solve_position(*args, **kwargs)

    rolling_run.solve_position = counted  # (in this process only: the two-scale solves counted)
    rows, last, touching = [], None, set()
    for k in range(len(track.shifts)):
        before = (calls[0], state.blocks.built, state.blocks.updated, state.cut, state.grid, *collector)
        use = resource.getrusage(resource.RUSAGE_SELF)
        c0 = time.process_time()
        pos = rolling_run.step(track, k, last, options, state)
        cpu = time.process_time() - c0
        now = resource.getrusage(resource.RUSAGE_SELF)
        numbers = set(pos.selection.numbers.tolist())
        given = set() if last is None else set(last.selection.numbers.tolist())
        on = pos.result.asperities.contact_areas > 0
        touch = set(pos.selection.numbers[on].tolist())
        field = pos.result.fields[0] if pos.result.fields else None
        rows.append(
            {
                "position": k,
                "cpu_s": cpu,
                "iterations": int(pos.result.iterations.get("cg", pos.result.iterations.get("micro", 0))),
                "stones": len(numbers),
                "stones_in": len(numbers - given),
                "stones_out": len(given - numbers),
                "touching": len(touch),
                "touching_in": len(touch - touching),
                "touching_out": len(touching - touch),
                "loaded": 0 if field is None else int(np.count_nonzero(field.pressure)),
                "afresh": state.blocks.built - before[1],
                "updated": state.blocks.updated - before[2],
                "cut_changed": int(state.cut is not before[3]),
                "window_changed": int(state.grid is not before[4]),
                "two_scale": calls[0] - before[0],
                "collections": collector[0] - before[5],
                "collector_s": collector[1] - before[6],
                "faults": now.ru_minflt - use.ru_minflt,
                "switches": now.ru_nivcsw - use.ru_nivcsw,
                "converged": bool(pos.result.converged),
            }
        )
        last, touching = pos, touch
    rolling_run.solve_position = solve_position
    return rows


def repeated(length: float, count: int) -> tuple:
    """``(cpu, iterations)``: each position's CPU seconds in ``count`` passes over one track,
    ``(count, positions)``, and its CG iterations in each (module docstring's ``--repeat``)."""
    track, options, _ = rolling_benchmark.tyre_window(length)
    cpu = np.zeros((count, len(track.shifts)))
    its = np.zeros((count, len(track.shifts)), dtype=int)
    for j in range(count):
        state, last = rolling_run.window_state(track, options), None
        with frozen_objects():
            for k in range(len(track.shifts)):
                c0 = time.process_time()
                last = rolling_run.step(track, k, last, options, state)
                cpu[j, k] = time.process_time() - c0
                its[j, k] = last.result.iterations.get("cg", -1)
    return cpu, its


def report_repeated(cpu: np.ndarray, its: np.ndarray) -> None:
    """Print what the repeats tell apart: each run's spread, the least's, the iterations'."""
    cpu, its = cpu[:, 1:], its[:, 1:]
    least = cpu.min(axis=0)

    def spread(t: np.ndarray) -> str:
        return f"median {np.median(t):.4f} s, 90th percentile {np.percentile(t, 90):.4f} s ({np.percentile(t, 90) / np.median(t):.3f})"

    for j, t in enumerate(cpu):
        print(f"run {j}: {spread(t)}")
    print(f"the least of the {len(cpu)} runs at each position: {spread(least)}")
    print(f"CG iterations equal in every run: {bool((its == its[0]).all())}")
    fit = rolling_benchmark.by_iterations(least, its[0])
    work = fit["fixed_s"] + fit["per_iteration_s"] * its[0]
    print(
        f"the least against the iterations: {fit['fixed_s'] * 1e3:.1f} ms + {fit['per_iteration_s'] * 1e3:.2f} ms an "
        f"iteration; the iterations' part 90th percentile over median {np.percentile(work, 90) / np.median(work):.3f}"
    )
    pairs = [np.corrcoef(cpu[i], cpu[j])[0, 1] for i in range(len(cpu)) for j in range(i + 1, len(cpu))]
    print(f"two runs' CPU of a position correlate at {', '.join(f'{c:.2f}' for c in pairs)}")
    slow = least >= np.percentile(least, 90)
    print("the slowest tenth by the least: positions", " ".join(str(int(i) + 1) for i in np.flatnonzero(slow)))
    print(f"  their iterations {its[0][slow].mean():.2f} against {its[0][~slow].mean():.2f}")


def report(rows: list, slow_fraction: float) -> None:
    """Print the comparison of the module docstring for ``rows`` (the first left out)."""
    rows = rows[1:]
    cpu = np.array([r["cpu_s"] for r in rows])
    slow = cpu >= np.quantile(cpu, 1.0 - slow_fraction)
    print(
        f"{len(rows)} positions after the first, all converged {all(r['converged'] for r in rows)}: CPU median "
        f"{np.median(cpu):.4f} s, 90th percentile {np.percentile(cpu, 90):.4f} s"
    )
    print(f"quantity: mean over the slowest {slow_fraction:.0%} / over the others, correlation with the CPU")
    for name in QUANTITIES:
        v = np.array([float(r[name]) for r in rows])
        corr = np.corrcoef(v, cpu)[0, 1] if v.std() > 0 else 0.0
        print(f"  {name:15s} {v[slow].mean():10.2f} / {v[~slow].mean():10.2f}   {corr:+.2f}")
    its = np.array([r["iterations"] for r in rows], dtype=float)
    fit = rolling_benchmark.by_iterations(cpu, its.astype(int))
    rest = cpu - fit["per_iteration_s"] * its
    switches = np.array([r["switches"] for r in rows], dtype=float)
    explained = np.corrcoef(switches, rest)[0, 1] if switches.std() > 0 else 0.0
    print(
        f"the CPU less the iterations' part: spread (90th percentile over median) {np.percentile(rest, 90) / np.median(rest):.3f}, "
        f"correlation with the context switches {explained:+.2f}; the iterations' part alone: 90th percentile "
        f"over median {np.percentile(fit['fixed_s'] + fit['per_iteration_s'] * its, 90) / np.median(fit['fixed_s'] + fit['per_iteration_s'] * its):.3f}"
    )
    spent = np.array([r["collector_s"] for r in rows])
    print(
        f"the garbage collector: {sum(r['collections'] for r in rows)} passes, {spent.sum():.3f} s of CPU in all, "
        f"{np.sum(spent > 0.01)} positions over 10 ms of it (the largest {spent.max() * 1e3:.1f} ms)"
    )
    print("the slowest positions:")
    for i in np.argsort(-cpu)[:10]:
        r = rows[i]
        print("  " + ", ".join(f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in r.items()))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--length", type=float, default=200.0, help="run length, mm")
    p.add_argument("--slow", type=float, default=0.15, help="the fraction of the positions called slow")
    p.add_argument("--unfrozen", action="store_true", help="the old objects in the collector's passes, for comparison")
    p.add_argument("--out", default=None, help="write the rows as JSON")
    p.add_argument("--repeat", type=int, default=0, help="roll the section this many times in turn (docstring)")
    args = p.parse_args()
    keep_heap()
    if args.repeat:
        report_repeated(*repeated(args.length, args.repeat))
        return
    rows = rows_of(args.length, frozen=not args.unfrozen)
    report(rows, args.slow)
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
