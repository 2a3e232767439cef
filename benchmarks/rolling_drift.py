"""Whether a rolling position could take its exact products about the last position's answer
instead of a float64 anchor of its own: the float32 error of the change, measured.

A position's CG takes one float64 product (its anchor, once the KKT residual is below
:data:`~twoscale.pk.products.FAST_RESIDUAL`) and its later exact products as the anchor's
displacement plus the float32 product of the change since. The last position's displacement,
moved with the road, is known to ~1e-12 on the cut (translation invariance, but for the
columns that enter at the cut's edge): it could serve as this position's anchor if the
float32 product of the change from it erred by far less than the stopping test (the KKT
residual ``tol x UNION_TOL_FACTOR`` = 1e-8 of the largest displacement).

Printed per position of ``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip
seal at 0.25 mm, 1 mm steps) on an unchanged cut, for two candidate anchors ``q`` of the
answer ``p`` (the last answer moved with the road; the position's start, extrapolated from
the two last): ``max|A (p - q)|`` and ``max|A32 (p - q) - A (p - q)|``, both over
``max|A p|`` (``A`` the cut's float64 product, ``A32`` its float32 one), and the medians.

Usage::

    PYTHONPATH=. python benchmarks/rolling_drift.py [--length 12]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

import numpy as np  # noqa: E402

from twoscale.cli.heap import keep_heap  # noqa: E402
from twoscale.rolling import run  # noqa: E402
from twoscale.rolling.boxes import moved  # noqa: E402


def errors(op, p: np.ndarray, q: np.ndarray) -> tuple[float, float]:
    """``max|A (p - q)|`` and the float32 product's largest error on it, over ``max|A p|``."""
    largest = float(np.abs(op.apply(p)).max())
    change = p - q
    exact = op.apply(change)
    single = op.single_precision().apply(change)
    return float(np.abs(exact).max()) / largest, float(np.abs(single - exact).max()) / largest


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length", type=float, default=12.0, help="run length, mm")
    args = parser.parse_args()
    keep_heap()
    track, options, state = rolling_benchmark.tyre_window(args.length)
    last, rows = None, []
    for k in range(len(track.shifts)):
        shift = float(track.shifts[k])
        cut = state.cut
        start = state.start(cut, shift) if cut is not None and len(state.past) == 2 else None
        previous = state.past[-1] if state.past else None
        last = run.step(track, k, last, options, state)
        f = last.result.fields[0]
        if start is None or f.grid != cut or previous is None:
            continue
        op = state.body.grid_operator(f.grid).op
        q = np.maximum(moved(*previous, f.grid, shift), 0.0)  # (the kept field is minus the gap off the contact)
        rows.append((*errors(op, f.pressure, q), *errors(op, f.pressure, start)))
        print(
            f"position {k}: last moved {rows[-1][0]:.2e} (float32 {rows[-1][1]:.2e}); start {rows[-1][2]:.2e} (float32 {rows[-1][3]:.2e})"
        )
    if rows:
        m = np.median(np.array(rows), axis=0)
        print(
            f"medians over {len(rows)} positions: last moved {m[0]:.2e} (float32 {m[1]:.2e}); start {m[2]:.2e} (float32 {m[3]:.2e})"
        )


if __name__ == "__main__":
    main()
