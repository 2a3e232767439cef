"""The rolling window's CG with the squares' coarse correction over its stone blocks: the CG
iterations a position and its CPU, against the blocks alone.

The window CG's preconditioner (:class:`twoscale.rolling.blocks.StoneBlocks`) inverts each
stone's contact exactly and couples the stones by their monopoles (Woodbury). Here that
inverse takes the place of the torus inverse inside :class:`twoscale.pk.coarse.SquaresCorrection`
(the union CG's coarse correction over squares of ``--side`` cells, switched on once at most
``--start`` of the loaded cells changed in a step), composed in this process only: the
correction's size limits (``MIN_CELLS``, ``MAX_FILL``) are lifted for it, and the kernel is
told when the preconditioner changes (its conjugate directions restart then). The scene is
``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip seal at 0.25 mm, 1 mm
steps); positions from the fourth on.

Printed: the mean CG iterations a position, the median CPU a position, whether every position
converged on the window, and the last position's approach.

Usage::

    PYTHONPATH=. python benchmarks/rolling_coarse.py [--length 20] [--side 25] [--start 0.01] [--off]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

import numpy as np  # noqa: E402

from twoscale.cli.heap import keep_heap  # noqa: E402
from twoscale.pk import coarse  # noqa: E402
from twoscale.reference import _precondition  # noqa: E402
from twoscale.rolling import blocks, run  # noqa: E402


class Corrected:
    """A position's block inverse with the squares' correction on the CG's part."""

    def __init__(self, inverse, table: np.ndarray, shape: tuple, side: int, start: float):
        self.inverse = inverse
        self.squares = coarse.SquaresCorrection(None, table, shape, side=side, start=start)

    def apply(self, gap: np.ndarray, on: np.ndarray) -> np.ndarray:
        return self.inverse.apply(gap, on)

    def on_part(self, cells: np.ndarray):
        blocks_on_part, loaded = self.inverse.on_part(cells), {}
        inner = coarse.Corrected(lambda w: blocks_on_part(w, loaded["on"]), self.squares, np.asarray(cells, np.intp))

        def apply(v: np.ndarray, on: np.ndarray) -> np.ndarray:
            if np.ndim(v) == 1:  # (the second position's linearised step: the blocks alone)
                return blocks_on_part(v, on)
            loaded["on"] = on[0]
            return inner(v, on)

        apply.restart = inner.restart
        return apply


class Custom(_precondition._Custom):
    """:class:`~twoscale.reference._precondition._Custom` passing a part's ``restart`` on."""

    def on_part(self, cells: np.ndarray):
        own = self.custom.on_part(cells)
        return own if hasattr(own, "restart") else super().on_part(cells)


def compose(side: int, start: float) -> None:
    """The stone blocks' factory wrapped in :class:`Corrected` (this process only)."""
    coarse.MIN_CELLS, coarse.MAX_FILL = 0, np.inf
    _precondition._Custom = Custom
    at = blocks.StoneBlocks.at

    def corrected_at(self, stones, shift, h):
        factory = at(self, stones, shift, h)
        return lambda surface: Corrected(factory(surface), self.table(surface.grid), surface.grid.shape, side, start)

    blocks.StoneBlocks.at = corrected_at


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length", type=float, default=20.0, help="run length, mm")
    parser.add_argument("--side", type=int, default=coarse.SIDE, help="the squares' side, cells")
    parser.add_argument("--start", type=float, default=coarse.START, help="changed fraction to switch at")
    parser.add_argument("--off", action="store_true", help="the stone blocks alone")
    args = parser.parse_args()
    keep_heap()
    if not args.off:
        compose(args.side, args.start)
    track, options, state = rolling_benchmark.tyre_window(args.length)
    last, iterations, cpu, window = None, [], [], True
    for k in range(len(track.shifts)):
        c0 = time.process_time()
        last = run.step(track, k, last, options, state)
        if k >= 3:
            cpu.append(time.process_time() - c0)
            iterations.append(last.result.iterations.get("cg", np.nan))
            window &= "cg" in last.result.iterations and last.result.converged
    print(
        f"{'blocks alone' if args.off else f'squares of {args.side} over the blocks'}: "
        f"{np.mean(iterations):.2f} CG iterations a position, {1e3 * np.median(cpu):.1f} ms CPU (median), "
        f"every position on the window and converged: {window}, approach {last.result.penetration:.12f} mm"
    )


if __name__ == "__main__":
    main()
