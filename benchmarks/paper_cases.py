"""The paper's cases: two-scale against the dense and the FFT (CG) reference solvers.

Cesbron et al. (2009) report the two-scale method about 2x (two spheres) and 10x (seven
spheres) faster than the classical full matrix inversion. Here, at the paper's cell sizes
(two spheres h = 0.0125 R, d = 0.05 R; seven spheres h = 0.025 R, d = 0.1 R; R = 10 mm,
E = 10 MPa, nu = 0.5, exact spheres), for each d/2R:

* ``twoscale``: :func:`twoscale.driver.solve_twoscale` (macro + micro, ``--tol``, default 1e-6);
* ``dense``: Johnson's active-set inversion (:func:`twoscale.reference.solve_dense`) on the
  reference grid of :func:`twoscale.paper.reference_surface` (same lattice; only cells an
  indenter reaches carry unknowns);
* ``cg``: Polonsky-Keer constrained CG with FFT products on the same grid
  (:func:`twoscale.reference.solve_cg`).

Each time is the best wall time of ``--repeat`` runs (from geometry to pressure; the dense
solver runs ``repeat // 3`` times, at least once). The dense solver forms the influence
matrix of the whole rectangular grid (up to its ``MAX_DENSE_CELLS`` grid cells) or of the
reachable cells only; it is skipped (and reported) when that matrix would exceed
``--max-dense-gb``. Errors are ``100 ||p - p_r|| / ||p_r||`` with p_r from each reference.

Targets, per case: twoscale >= 2x (two spheres) or >= 10x (seven spheres) faster than dense,
and faster than cg on the full grid. Prints PASS/MISS per case and for each layout.

Run: ``python benchmarks/paper_cases.py [--layouts two seven] [--repeat 3] [--max-dense-gb 2]``.
"""

from __future__ import annotations

import argparse
import sys

import _common  # noqa: F401  (sets single-threaded defaults before numpy loads)
import numpy as np

from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg, solve_dense
from twoscale.reference.dense import MAX_DENSE_CELLS
from twoscale.paper import PAPER_SPACINGS, paper_case, reference_surface
from twoscale.driver import solve_twoscale

TARGET_VS_DENSE = {"two": 2.0, "seven": 10.0}


def _err(p, pr) -> float:
    return 100.0 * float(np.linalg.norm(p - pr) / np.linalg.norm(pr))


def run_case(layout: str, spacing: float, *, repeat: int, max_dense_gb: float, tol: float = 1e-6) -> dict:
    case = paper_case(layout, spacing)
    hs = HalfSpace(case.material)
    surf = reference_surface(case)
    d = case.penetration
    ts, t_ts = _common.best_time(lambda: solve_twoscale(hs, case.asperities, h=case.h, penetration=d, tol=tol), repeat)
    cg, t_cg = _common.best_time(lambda: solve_cg(hs, surf, penetration=d), repeat)
    p = ts.pressure_on(surf.grid)
    row = {
        "layout": layout,
        "s": spacing,
        "cells_2s": ts.n_cells,
        "cells_ref": int(np.isfinite(surf.height).sum()),
        "grid_ref": surf.grid.size,
        "sweeps": ts.iterations["micro"],
        "t_2s": t_ts,
        "t_cg": t_cg,
        "x_cg": t_cg / t_ts,
        "err_cg": _err(p, cg.pressure_on(surf.grid)),
        "converged": ts.converged and cg.converged,
    }
    # the dense solver forms the whole grid's matrix up to MAX_DENSE_CELLS grid cells, else
    # only that of the cells with material
    n = surf.grid.size if surf.grid.size <= MAX_DENSE_CELLS else row["cells_ref"]
    gb = 8.0 * n**2 / 1e9
    if gb <= max_dense_gb:
        dense, t_dense = _common.best_time(lambda: solve_dense(hs, surf, penetration=d), max(1, repeat // 3))
        row.update(t_dense=t_dense, x_dense=t_dense / t_ts, err_dense=_err(p, dense.pressure_on(surf.grid)))
        row["converged"] = row["converged"] and dense.converged
    else:
        row["dense_note"] = f"dense skipped: matrix {gb:.1f} GB > {max_dense_gb} GB"
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layouts", nargs="+", default=["two", "seven"], choices=["two", "seven"])
    ap.add_argument("--spacings", nargs="+", type=float, default=None, help="d/2R values (default: the paper's)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--max-dense-gb", type=float, default=2.0)
    ap.add_argument(
        "--tol", type=float, default=1e-6, help="two-scale eq. 9 tolerance (the paper's squared-norm epsilon is tol^2)"
    )
    _common.add_quiet(ap)
    args = ap.parse_args(argv)
    rows = []
    cases = [(layout, s) for layout in args.layouts for s in (args.spacings or PAPER_SPACINGS[layout])]
    with _common.progress(len(cases), "paper cases", args.quiet) as bar:
        for layout, s in cases:
            rows.append(run_case(layout, s, repeat=args.repeat, max_dense_gb=args.max_dense_gb, tol=args.tol))
            bar.update(note=f"{layout} d/2R = {s:g}")
    cols = [
        ("layout", "layout", "s"),
        ("s", "d/2R", "g"),
        ("cells_2s", "cells 2s", "d"),
        ("cells_ref", "cells ref", "d"),
        ("sweeps", "sweeps", "d"),
        ("t_2s", "t 2s (s)", ".3f"),
        ("t_dense", "t dense", ".3f"),
        ("t_cg", "t cg", ".3f"),
        ("x_dense", "x dense", ".2f"),
        ("x_cg", "x cg", ".2f"),
        ("err_dense", "err% dense", ".1e"),
        ("err_cg", "err% cg", ".1e"),
    ]
    _common.print_table(rows, cols)
    ok_all = True
    for layout in args.layouts:
        lrows = [r for r in rows if r["layout"] == layout]
        for r in lrows:
            verdict = []
            if "x_dense" in r:
                verdict.append(
                    f"vs dense {r['x_dense']:.2f}x (target {TARGET_VS_DENSE[layout]:g}x): "
                    f"{'PASS' if r['x_dense'] >= TARGET_VS_DENSE[layout] else 'MISS'}"
                )
            else:
                verdict.append(r["dense_note"])
            verdict.append(f"vs cg {r['x_cg']:.2f}x (target > 1x): {'PASS' if r['x_cg'] > 1.0 else 'MISS'}")
            verdict.append(f"error <= 0.1 %: {'PASS' if max(r.get('err_dense', 0), r['err_cg']) <= 0.1 else 'MISS'}")
            print(f"{layout} d/2R={r['s']:g}: " + "; ".join(verdict) + ("" if r["converged"] else "; NOT CONVERGED"))
        dense_ok = all(r["x_dense"] >= TARGET_VS_DENSE[layout] for r in lrows if "x_dense" in r)
        cg_ok = all(r["x_cg"] > 1.0 for r in lrows)
        ok_all &= dense_ok and cg_ok
        print(
            f"{layout} spheres: dense target {'PASS' if dense_ok else 'MISS'} "
            f"(on {sum('x_dense' in r for r in lrows)} of {len(lrows)} cases), cg target {'PASS' if cg_ok else 'MISS'}"
        )
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
