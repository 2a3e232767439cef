"""The Polonsky-Keer kernel (twoscale.pk) in its three uses: one block, stacked blocks, the full grid.

Half-space E = 10 MPa, nu = 0.5, cell h = 0.04 mm. Prints CPU time per solve (best of
``--repeat``) and iterations for:

* one block of n x n cells (n = 12, 24, 48, a sphere R = 4 mm at approach 6 um): cold
  (from zero, relative change 1e-9) and warm (from the converged pressure of a 0.1 %
  smaller approach, 1e-6: what a Gauss-Seidel sweep near convergence asks), and eq. 7's
  load-controlled solve;
* 32 such blocks of 24 x 24 cells (radii 2-6 mm) solved as one stack and one by one (the
  stack's speed-up is the reason it exists);
* the full-grid reference (``solve_cg``) on a Hertz sphere, 480 x 480 cells, load control.

Run: ``python benchmarks/pk_kernel.py [--repeat 5]`` (about 30 s). The per-call cost of a
small block is mostly numpy's per-call overhead, not arithmetic: compare figures from one
machine only.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks import _common  # noqa: E402  (single-threaded BLAS/FFT by default)
import numpy as np  # noqa: E402  (after _common: OpenBLAS reads its thread count when loaded)

H = 0.04


def _cpu(fn, repeat: int, inner: int = 1) -> tuple[object, float]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.process_time()
        for _ in range(inner):
            out = fn()
        best = min(best, (time.process_time() - t0) / inner)
    return out, best


def _sphere(n: int, R: float = 4.0) -> np.ndarray:
    X, Y = np.meshgrid(np.arange(n) * H, np.arange(n) * H)
    return ((X - X.mean()) ** 2 + (Y - Y.mean()) ** 2) / (2.0 * R)


def one_block(hs, repeat: int) -> list[dict]:
    from twoscale.grid import Grid
    from twoscale.micro.pk import pk_fixed_approach, pk_fixed_force

    rows = []
    for n in (12, 24, 48):
        z = _sphere(n).ravel()
        op = hs.grid_operator(Grid(0.0, 0.0, H, n, n))
        mv = lambda v, op=op, n=n: op.apply(v.reshape(n, n)).ravel()  # noqa: E731
        b = 0.006 - z
        p0, _, _ = pk_fixed_approach(mv, b * 0.999, np.zeros(n * n), rtol=1e-12)
        cases = {
            "cold": lambda: pk_fixed_approach(mv, b, np.zeros(n * n), rtol=1e-9),
            "warm": lambda: pk_fixed_approach(mv, b, p0, rtol=1e-6),
            "eq. 7": lambda: pk_fixed_force(mv, z, 0.05, H, np.ones(n * n), rtol=1e-9),
        }
        for name, fn in cases.items():
            out, t = _cpu(fn, repeat, inner=20)
            rows.append({"case": f"one block {n}x{n} {name}", "it": int(out[-1]), "ms": 1e3 * t})
    return rows


def stacked(hs, repeat: int) -> list[dict]:
    from twoscale.grid import Grid
    from twoscale.micro.pk import fixed_approach, pk_fixed_approach

    rng = np.random.default_rng(0)
    n, count = 24, 32
    b = np.stack([0.006 - _sphere(n, rng.uniform(2.0, 6.0)) for _ in range(count)])
    op = hs.grid_operator(Grid(0.0, 0.0, H, n, n))
    mask = np.ones(b.shape, bool)
    out, t_stack = _cpu(lambda: fixed_approach(op.apply_stack, b, np.zeros(b.shape), mask, rtol=1e-9), repeat)
    mv = lambda v: op.apply(v.reshape(n, n)).ravel()  # noqa: E731
    _, t_one = _cpu(lambda: [pk_fixed_approach(mv, bk.ravel(), np.zeros(n * n), rtol=1e-9) for bk in b], repeat)
    return [
        {"case": f"{count} blocks {n}x{n} stacked", "it": int(out[2].max()), "ms": 1e3 * t_stack},
        {"case": f"{count} blocks {n}x{n} one by one", "it": int(out[2].max()), "ms": 1e3 * t_one},
    ]


def reference(hs, repeat: int) -> list[dict]:
    from twoscale.grid import Grid
    from twoscale.indenters import Asperity, surface_on
    from twoscale.reference import solve_cg

    g = Grid.covering(-1.2, 1.2, -1.2, 1.2, 2.4 / 480)
    surf = surface_on(g, [Asperity(0.0, 0.0, 0.0, 10.0)])
    res, t = _cpu(lambda: solve_cg(hs, surf, total_load=5.0), max(1, repeat // 2))
    return [{"case": "reference Hertz 480x480 load", "it": res.iterations["cg"], "ms": 1e3 * t}]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    from twoscale import Material
    from twoscale.influence import HalfSpace

    hs = HalfSpace(Material(10.0, 0.5))
    rows = one_block(hs, args.repeat) + stacked(hs, args.repeat) + reference(hs, args.repeat)
    _common.print_table(rows, [("case", "case", "<34"), ("it", "iterations", "d"), ("ms", "CPU ms", ".3f")])
    return 0


if __name__ == "__main__":
    sys.exit(main())
