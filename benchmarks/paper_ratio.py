"""The paper's cases: the default two-scale solve over the FFT reference, interleaved.

For each case of :mod:`paper_cases` (exact spheres, the paper's cell sizes), the default
solve (:func:`twoscale.driver.solve_twoscale`, tol 1e-6) and the Polonsky-Keer CG on the
reference grid (:func:`twoscale.reference.solve_cg`, the same call as ``paper_cases.py``)
run alternately ``--repeat`` times in this process after one warm-up each; printed: the
medians of CPU time (``time.process_time``, the steadier figure on a shared machine) and
of wall time, and their ratios. Target: default / reference <= 1.2.

Run: ``cd benchmarks && python paper_ratio.py [--repeat 100] [--layouts seven] [--spacings 0.1]``.
"""

from __future__ import annotations

import argparse
import sys
import time

import _common  # noqa: F401  (single-threaded defaults before numpy loads)
import numpy as np

from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg
from twoscale.paper import PAPER_SPACINGS, paper_case, reference_surface
from twoscale.driver import solve_twoscale


def _timed(fn) -> tuple[float, float]:
    c0, t0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - t0


def measure(layout: str, spacing: float, repeat: int) -> dict:
    """Medians (ms) of CPU and wall time of both solves on one case, interleaved."""
    case = paper_case(layout, spacing)
    hs = HalfSpace(case.material)
    surf = reference_surface(case)
    solves = {
        "2s": lambda: solve_twoscale(hs, case.asperities, h=case.h, penetration=case.penetration, tol=1e-6),
        "cg": lambda: solve_cg(hs, surf, penetration=case.penetration),
    }
    result = solves["2s"]()
    solves["cg"]()
    times = {k: [] for k in solves}
    for _ in range(repeat):
        for k, fn in solves.items():
            times[k].append(_timed(fn))
    med = {k: np.median(np.array(v), axis=0) * 1e3 for k, v in times.items()}
    return {
        "layout": layout,
        "s": spacing,
        "iteration": result.details.micro.strategy,
        "cpu_2s": med["2s"][0],
        "cpu_cg": med["cg"][0],
        "cpu_ratio": med["2s"][0] / med["cg"][0],
        "wall_2s": med["2s"][1],
        "wall_cg": med["cg"][1],
        "wall_ratio": med["2s"][1] / med["cg"][1],
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layouts", nargs="+", default=["two", "seven"], choices=["two", "seven"])
    ap.add_argument("--spacings", nargs="+", type=float, default=None, help="d/2R values (default: the paper's)")
    ap.add_argument("--repeat", type=int, default=50)
    args = ap.parse_args(argv)
    rows = [
        measure(layout, s, args.repeat) for layout in args.layouts for s in (args.spacings or PAPER_SPACINGS[layout])
    ]
    _common.print_table(
        rows,
        [
            ("layout", "layout", "s"),
            ("s", "d/2R", "g"),
            ("iteration", "iteration", "s"),
            ("cpu_2s", "cpu 2s ms", ".2f"),
            ("cpu_cg", "cpu cg ms", ".2f"),
            ("cpu_ratio", "cpu 2s/cg", ".3f"),
            ("wall_2s", "wall 2s ms", ".2f"),
            ("wall_cg", "wall cg ms", ".2f"),
            ("wall_ratio", "wall 2s/cg", ".3f"),
        ],
    )
    worst = max(r["cpu_ratio"] for r in rows)
    print(f"largest CPU ratio {worst:.3f} (target <= 1.2): {'PASS' if worst <= 1.2 else 'MISS'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
