"""Hertz benchmark: the reference solvers against Hertz, beside ContactMechanics and Tamaas.

Rigid paraboloid R = 10 mm on a half-space E = 10 MPa, nu = 0.5, penetration d = 0.5 mm
(contact radius a = sqrt(R d) = 2.236 mm), at n = 2a/h cells across the contact diameter.
Our grid covers 1.1 a around the tip, which sits at the corner of four cells.

Codes, all single-threaded and at the same cell size h:

* ``dense``: Johnson's active-set matrix inversion (only up to ``--max-dense`` cells);
* ``cg``: our FFT constrained conjugate gradient (Polonsky & Keer) at its default
  tolerance 1e-8, and ``cg-1e-6`` at tol 1e-6;
* ``CM``: ContactMechanics ``FreeFFTElasticHalfSpace`` + its constrained CG
  (``NonSmoothContactSystem.minimize_proxy``), same grid, default tolerances, then
  ``CM-1e-6`` and ``CM-1e-9`` with ``pentol = 1e-6 d`` and ``1e-9 d``;
* ``Tamaas``: ``PolonskyKeerRey`` on its periodic ``basic_2d`` model in a cell 8a wide,
  load control with the Hertz load (periodic images: not the same problem, error floor).

Per code: best wall time of ``--repeat`` runs (from geometry to pressure, including
building operators), the relative errors against Hertz (total load, L2 of the pressure at
the cell centres, contact area), and for the codes sharing our discretisation (uniform
pressure on square cells, Love's kernel) the *solver error*: L2 distance to our CG
solution at tol 1e-12. All three share the same converged answer, so their Hertz errors
differ only by how far each stopped from it. "Equal error": a run counts when its L2
error against Hertz is within 1 % of that of the converged discrete solution (the
discretisation error). The PASS/MISS line takes, per size, the fastest counting run of
our cg and of CM and compares their times (target: cg at least 3x faster).

Run: ``python benchmarks/hertz.py [--sizes 32 64 128] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import warnings

import _common  # noqa: F401  (sets single-threaded defaults before numpy loads)
import numpy as np

try:
    import twoscale  # noqa: F401
except ImportError:  # running from a source checkout without installation
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from twoscale import Grid, Material
from twoscale.analytic import hertz
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg, solve_dense

from _common import best_time, print_table

MAT = Material(10.0, 0.5)
R, D = 10.0, 0.5
A = math.sqrt(R * D)
P_HERTZ = float(hertz.load(R, D, MAT.E_star))


def hertz_grid(n: int, margin: float = 1.1) -> Grid:
    h = 2 * A / n
    return Grid.covering(-margin * A, margin * A, -margin * A, margin * A, h, anchor=(0.5 * h, 0.5 * h))


def errors(p: np.ndarray, X: np.ndarray, Y: np.ndarray, h: float) -> dict:
    pe = hertz.pressure(np.hypot(X, Y), R, D, MAT.E_star)
    return {
        "load_err": abs(h * h * p.sum() / P_HERTZ - 1),
        "l2_err": float(np.linalg.norm(p - pe) / np.linalg.norm(pe)),
        "area_err": abs(h * h * np.count_nonzero(p > 0) / (math.pi * A * A) - 1),
    }


# ------------------------------------------------------------------ the codes
def run_ours(solver, grid, **kw):
    hs = HalfSpace(MAT)

    def go():
        s = surface_on(grid, [Asperity(0.0, 0.0, 0.0, R, "paraboloid")])
        return solver(hs, s, penetration=D, **kw)

    return go


def run_contact_mechanics(grid, pentol=None):
    from ContactMechanics import FreeFFTElasticHalfSpace
    from ContactMechanics.Systems import NonSmoothContactSystem
    from SurfaceTopography import Topography

    X, Y = grid.centres()
    size = (grid.ny * grid.h, grid.nx * grid.h)

    def go():
        # CM: rigid heights (peak at 0), offset = indentation; forces per pixel
        heights = -(X**2 + Y**2) / (2 * R)
        substrate = FreeFFTElasticHalfSpace(grid.shape, MAT.E_star, size)
        system = NonSmoothContactSystem(substrate, Topography(heights, physical_sizes=size))
        kw = {} if pentol is None else {"pentol": pentol}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sol = system.minimize_proxy(offset=D, **kw)
        return sol

    return go


def run_tamaas(n_cells: int, h: float):
    import tamaas as tm

    tm.set_log_level(tm.LogLevel.error)
    L = n_cells * h
    x = (np.arange(n_cells) + 0.5) * h - 0.5 * L  # tip at the corner of four cells
    X, Y = np.meshgrid(x, x, indexing="ij")

    def go():
        model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [L, L], [n_cells, n_cells])
        model.E, model.nu = MAT.E, MAT.nu
        solver = tm.PolonskyKeerRey(model, -(X**2 + Y**2) / (2 * R), 1e-12)
        solver.solve(P_HERTZ / L**2)
        return np.array(model.traction)

    return go, X, Y


def _available(module: str) -> bool:
    try:
        __import__(module)
        return True
    except Exception:
        return False


# ------------------------------------------------------------------ one size
def bench_size(n: int, repeat: int, max_dense: int) -> list[dict]:
    grid = hertz_grid(n)
    X, Y = grid.centres()
    h = grid.h
    exact = run_ours(solve_cg, grid, tol=1e-12)().fields[0].pressure
    rows = []

    def ours(name, solver, **kw):
        r, t = best_time(run_ours(solver, grid, **kw), repeat)
        p = r.fields[0].pressure
        it = r.iterations.get("cg", r.iterations.get("outer"))
        rows.append(
            {
                "code": name,
                "n": n,
                "cells": grid.size,
                "time": t,
                "iters": it,
                "converged": r.converged,
                "solver_err": float(np.linalg.norm(p - exact) / np.linalg.norm(exact)),
                **errors(p, X, Y, h),
            }
        )

    floor = errors(exact, X, Y, h)["l2_err"]
    if grid.size <= max_dense:
        ours("dense", solve_dense)
    ours("cg", solve_cg)
    ours("cg-1e-6", solve_cg, tol=1e-6)
    if _available("ContactMechanics") and _available("SurfaceTopography"):
        for name, pentol in (("CM", None), ("CM-1e-6", 1e-6 * D), ("CM-1e-9", 1e-9 * D)):
            sol, t = best_time(run_contact_mechanics(grid, pentol), repeat)
            p = np.asarray(sol.jac) / (h * h)
            rows.append(
                {
                    "code": name,
                    "n": n,
                    "cells": grid.size,
                    "time": t,
                    "iters": sol.nit,
                    "converged": bool(sol.success),
                    "solver_err": float(np.linalg.norm(p - exact) / np.linalg.norm(exact)),
                    **errors(p, X, Y, h),
                }
            )
    if _available("tamaas"):
        n_cells = 4 * n  # periodic cell 8a wide
        go, TX, TY = run_tamaas(n_cells, h)
        p, t = best_time(go, repeat)
        rows.append(
            {
                "code": "Tamaas",
                "n": n,
                "cells": n_cells * n_cells,
                "time": t,
                "iters": None,
                "converged": True,
                "solver_err": None,
                **errors(p, TX, TY, h),
            }
        )
    for row in rows:
        row["equal"] = row["converged"] and abs(row["l2_err"] - floor) <= 0.01 * floor
    return rows


def _fastest(rows: list[dict], family: str) -> dict | None:
    runs = [r for r in rows if r["code"].split("-")[0] == family and r["equal"]]
    return min(runs, key=lambda r: r["time"]) if runs else None


def verdict(rows: list[dict]) -> tuple[bool, list[str]]:
    """PASS when, at every size, our fastest equal-error cg run is >= 3x faster than
    the fastest equal-error ContactMechanics run."""
    lines, ok, seen = [], True, False
    for n in sorted({r["n"] for r in rows}):
        here = [r for r in rows if r["n"] == n]
        cg, cm = _fastest(here, "cg"), _fastest(here, "CM")
        if not any(r["code"].startswith("CM") for r in here):
            continue
        seen = True
        if cg is None or cm is None:
            ok = False
            lines.append(f"2a/h = {n:4d}: no equal-error run of {'cg' if cg is None else 'CM'} -> MISS")
            continue
        ratio = cm["time"] / cg["time"]
        ok &= ratio >= 3.0
        lines.append(
            f"2a/h = {n:4d}: {cm['code']} {cm['time']:.3f} s / {cg['code']} {cg['time']:.3f} s = "
            f"{ratio:5.2f} (target >= 3), L2 error {100 * cg['l2_err']:.4f} % vs "
            f"{100 * cm['l2_err']:.4f} % -> {'PASS' if ratio >= 3.0 else 'MISS'}"
        )
        tam = [r for r in here if r["code"] == "Tamaas"]
        if tam:
            lines.append(
                f"              Tamaas {tam[0]['time']:.3f} s / {cg['code']} = "
                f"{tam[0]['time'] / cg['time']:5.2f} (periodic cell 8a; its L2 error "
                f"{100 * tam[0]['l2_err']:.3f} % is not equal)"
            )
    return ok and seen, lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=[32, 64, 128],
        help="cells across the contact diameter 2a/h (default: 32 64 128)",
    )
    parser.add_argument("--repeat", type=int, default=3, help="runs per code, best time kept (default 3)")
    parser.add_argument(
        "--max-dense", type=int, default=10_000, help="largest grid (cells) given to the dense solver (default 10000)"
    )
    _common.add_quiet(parser)
    args = parser.parse_args(argv)
    print(
        f"Hertz: R = {R} mm, E = {MAT.E} MPa, nu = {MAT.nu}, d = {D} mm, a = {A:.4f} mm, "
        f"P = {P_HERTZ:.4f} N; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}"
    )
    rows = []
    with _common.progress(len(args.sizes), "hertz sizes", args.quiet) as bar:
        for n in args.sizes:
            rows += bench_size(n, args.repeat, args.max_dense)
            bar.update(note=f"2a/h = {n}")
    print_table(
        rows,
        [
            ("code", "code", "s"),
            ("n", "2a/h", "d"),
            ("cells", "cells", "d"),
            ("time", "time s", ".3f"),
            ("iters", "iters", "d"),
            ("load_err", "load err", ".2e"),
            ("l2_err", "L2 err", ".3e"),
            ("area_err", "area err", ".2e"),
            ("solver_err", "solver err", ".1e"),
            ("converged", "converged", ""),
            ("equal", "equal err", ""),
        ],
    )
    ok, lines = verdict(rows)
    for line in lines:
        print(line)
    if not lines:
        print("ContactMechanics not importable: no speed verdict")
        return 0
    print(f"{'PASS' if ok else 'MISS'}: cg >= 3x faster than ContactMechanics at equal error at every size")
    return 0


if __name__ == "__main__":
    sys.exit(main())
