"""Direct FEM mode on the whole 140 x 140 x 20 mm block against Love's closed form.

One central 2 mm cell under unit pressure, the half-space displacement imposed on the sides
and base (``fem_influence.solve_cell_load(boundary="halfspace")``): the top-face displacement
must reproduce Love's closed form within 1 % at r = 0-40 mm. Prints the displacement, Love,
the relative error per radius, PASS/MISS, the solve's size, time and peak memory.

The tests check the same on a small box near the cell and at r >= 4 mm on the block with a
coarser local mesh (tests/test_fem_direct.py); this script is the full-size run.

Run: ``python benchmarks/direct_fem.py [--per-cell 6] [--growth 1.8]`` (about 9 minutes and
5.5 GB at the defaults on the 2-core machine).
"""

from __future__ import annotations

import argparse
import resource
import time

import _common  # noqa: F401  (single-threaded defaults before numpy loads)
import numpy as np

from fem_influence import solve_cell_load
from twoscale.analytic.halfspace import love_rectangle
from twoscale.material import Material

TARGET = 0.01


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-cell", type=int, default=6, help="elements per loaded-cell side (even)")
    ap.add_argument("--growth", type=float, default=1.8, help="element size ratio away from the cell")
    args = ap.parse_args()
    mat = Material(E=1.0, nu=0.5)
    h_cell = 2.0
    r = np.array([0.0, 1.0, 2.0, 4.0, 6.0, 10.0, 20.0, 30.0, 40.0])
    t0 = time.perf_counter()
    res = solve_cell_load(mat, boundary="halfspace", h_cell=h_cell, r=r, growth=args.growth, per_cell=args.per_cell)
    wall = time.perf_counter() - t0
    love = love_rectangle(r, 0 * r, h_cell / 2, h_cell / 2, mat.E_star)
    err = res.u / love - 1
    print(f"{'r mm':>6} {'FEM mm/MPa':>12} {'Love':>12} {'error %':>8}")
    for ri, ui, li, ei in zip(r, res.u, love, err):
        print(f"{ri:6.1f} {ui:12.6f} {li:12.6f} {100 * ei:8.3f}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(
        f"{res.n_unknowns} unknowns, {res.n_elements} elements (quarter block), residual {res.residual:.1e}, "
        f"{wall:.0f} s, peak {peak:.0f} MB"
    )
    ok = res.converged and np.abs(err).max() <= TARGET
    print(f"max |error| {100 * np.abs(err).max():.3f} % (target {100 * TARGET:.0f} %): {'PASS' if ok else 'MISS'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
