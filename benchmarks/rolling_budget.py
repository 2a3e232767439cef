"""Where a steady rolling position's CPU goes: each stage's own time, the stages nested.

The section of ``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip seal at
0.25 mm, 1 mm steps) is rolled on the window path; from position ``--skip`` on, the CPU time
of each stage below is taken around its function (a wrapper in this process only), less the
time of the stages called from it, so that the rows add up to the positions' CPU:

* the operator's products: the float32 product's forward half (its transforms of the values)
  and back half (the kernel's spectrum, the transforms back), their Parseval sum, the
  anchor's float64 product and the float32 product on the whole grid (the confirmation);
* the stone blocks: the inverses kept, updated or made afresh, the rest of their build
  (stacks, coupling), their applications;
* the kernel's columns (the displacement's correction where a few cells changed) and its
  own passes (:func:`twoscale.pk.pk_solve` less the products, the columns and the blocks),
  and the answer's result (fields, forces);
* the road's stones, the window's surface, the check outside the cut, the drag, the
  start and the kept fields; and what is left of a position (``step`` itself).

Printed: per stage the calls and the CPU (ms) a position, and the positions' CPU. The
stages' times carry the timers' cost (~1 us a call). Single-threaded.

Usage::

    PYTHONPATH=. python benchmarks/rolling_budget.py [--length 30] [--skip 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

from twoscale.cli.heap import keep_heap  # noqa: E402
from twoscale.influence import convolution, on_cells, table_columns  # noqa: E402
from twoscale.reference import cg  # noqa: E402
from twoscale.rolling import blocks, road, run, window  # noqa: E402

#: (module or class, function name, stage label), wrapped in this order.
STAGES = (
    (on_cells.CellProduct, "forward", "product: forward half (float32)"),
    (on_cells.CellProduct, "finish", "product: back half (float32)"),
    (on_cells.CellProduct, "energy", "product: Parseval sum"),
    (convolution._SingleConvolution, "exact", "product: anchor (float64)"),
    (convolution._SingleConvolution, "apply", "product: whole grid (float32)"),
    (blocks, "fresh_blocks", "blocks: inverses afresh"),
    (blocks, "updated", "blocks: inverses updated"),
    (blocks.StoneBlocks, "inverses", "blocks: inverses found (the rest)"),
    (blocks.BlockInverse, "_build", "blocks: build (the rest)"),
    (blocks.BlockInverse, "_apply", "blocks: applications"),
    (table_columns.TargetColumns, "__call__", "kernel: columns"),
    (cg, "pk_solve", "kernel's own passes"),
    (cg, "build_result", "the answer's result"),
    (road.Road, "stones_at", "road: stones at the shift"),
    (window, "_window_surface", "window: surface"),
    (window, "touching_outside", "window: check outside the cut"),
    (window.WindowState, "start", "window: start"),
    (window.WindowState, "keep", "window: kept fields"),
    (run, "drag_of", "drag"),
    (run, "step", "the rest of a position"),
)


class Budget:
    """Exclusive CPU time per label: a stack of the running stages, each charged its time
    less its children's."""

    def __init__(self):
        self.on = False
        self.stack: list = []
        self.own: dict = {}
        self.calls: dict = {}

    def wrap(self, owner, name: str, label: str) -> None:
        inner = getattr(owner, name)
        budget = self

        def timed(*args, **kwargs):
            if not budget.on:
                return inner(*args, **kwargs)
            budget.stack.append(0.0)
            c0 = time.process_time()
            try:
                return inner(*args, **kwargs)
            finally:
                spent = time.process_time() - c0
                children = budget.stack.pop()
                if budget.stack:
                    budget.stack[-1] += spent
                budget.own[label] = budget.own.get(label, 0.0) + spent - children
                budget.calls[label] = budget.calls.get(label, 0) + 1

        setattr(owner, name, timed)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--length", type=float, default=30.0, help="run length, mm")
    p.add_argument("--skip", type=int, default=3, help="positions rolled before the timing starts")
    args = p.parse_args()
    keep_heap()
    budget = Budget()
    for owner, name, label in STAGES:
        budget.wrap(owner, name, label)
    track, options, state = rolling_benchmark.tyre_window(args.length)
    last, cpu = None, []
    for k in range(len(track.shifts)):
        budget.on = k >= args.skip
        c0 = time.process_time()
        last = run.step(track, k, last, options, state)
        if budget.on:
            cpu.append(time.process_time() - c0)
    n = max(len(cpu), 1)
    print(f"{len(cpu)} positions from the {args.skip + 1}th: {1e3 * sum(cpu) / n:.1f} ms of CPU a position")
    for _, _, label in STAGES:
        if label in budget.own:
            print(f"  {label:36s} {budget.calls[label] / n:6.1f} calls {1e3 * budget.own[label] / n:7.2f} ms")
    print(f"  {'sum of the stages':36s} {'':12s} {1e3 * sum(budget.own.values()) / n:7.2f} ms")


if __name__ == "__main__":
    main()
