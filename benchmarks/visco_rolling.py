"""Rolling on a viscoelastic body against the same run on an elastic one: cost and drag.

Two runs, each solved with a 10-branch Prony series over six decades (relaxation times
1e-3 ... 1e3 s, glassy modulus ``--ratio`` times the relaxed E = 6 MPa, nu = 0.5) and
with the elastic material at the relaxed modulus (no branches), same positions, same
solver:

* ``sphere``: a sphere (R 10 mm) on the half-space at an approach of 0.2 mm, moved 20 mm
  in steps of one cell (h = 0.1 mm) at ``--speed`` km/h, by the full-grid reference and by
  the two-scale method (memory grid: :func:`twoscale.viscoelastic.moving.sweep_grid`);
* ``road``: a synthetic chip seal (``twoscale.surface.texture.road``, seeded, 100 x 100 mm
  at 0.25 mm, one asperity per stone by the watershed segmentation) moved 50 mm in 0.5 mm
  steps under a 40 x 20 mm window of the half-space (the memory grid: contact cut at its
  y edges) whose face is a slick tyre's (a cylinder of radius 300 mm about the y axis, so
  the contact stays clear of the x edges) under 80 N (load control), by the full-grid
  reference (CG).

Printed per run: positions, CPU seconds (total and per position) of the viscoelastic and
the elastic run (relaxed modulus) and their ratio (target <= 2), the same against the
elastic run at the glassy modulus (under load control its contact is smaller), the mean drag over the second half, the
energy dissipated there and the drag work against it, the peak memory. CPU time is
``time.process_time`` (the machine is shared).

Run: ``cd benchmarks && python visco_rolling.py [--speed 50] [--ratio 20] [--runs sphere road]``.
"""

from __future__ import annotations

import argparse
import time

import _common  # noqa: F401  (single-threaded defaults before numpy loads)
import numpy as np

from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.influence.halfspace import HalfSpace
from twoscale.material import Material
from twoscale.viscoelastic.moving import MovingOptions, solve_moving, sweep_grid
from twoscale.viscoelastic.moving_indenter import MovingAsperities, MovingHeights

KMH = 1e6 / 3600.0  # mm/s per km/h


def prony(E_inf: float, ratio: float, n: int = 10) -> tuple:
    """``n`` branches, relaxation times 1e-3 ... 1e3 s, summing to ``(ratio - 1) E_inf``
    (as benchmarks/viscoelastic.py)."""
    tau = np.geomspace(1e-3, 1e3, n)
    w = np.geomspace(2.0, 1.0, n)
    E = (ratio - 1.0) * E_inf * w / w.sum()
    return tuple((float(e), float(t)) for e, t in zip(E, tau))


def sphere_case():
    tips = (Asperity(0.0, 0.0, 0.0, 10.0),)
    h = 0.1
    shifts = np.arange(-10.0, 10.0 + 1e-9, h)
    return (
        MovingAsperities(tips),
        shifts,
        {"penetration": 0.2},
        lambda m: sweep_grid(m, tips, shifts, h, penetration=0.2),
        False,
    )


def road_case():
    from twoscale.surface.heightmap import HeightMap
    from twoscale.surface.segmentation import segment
    from twoscale.surface.texture import road

    h, size = 0.25, 100.0
    z = road(size, h, seed=2026)
    hmap = HeightMap(z, h, x0=-0.5 * size + 0.5 * h, y0=-0.5 * size + 0.5 * h)
    seg = segment(hmap)
    indenter = MovingHeights.from_map(
        float(np.nanmax(z)) - z, seg.labels, hmap.grid, face=lambda X, Y: X**2 / (2.0 * 300.0)
    )
    window = Grid.covering(-20.0, 20.0, -10.0, 10.0, h, anchor=(hmap.grid.x0, hmap.grid.y0))
    shifts = np.arange(-25.0, 25.0 + 1e-9, 0.5)
    return indenter, shifts, {"total_load": 80.0}, lambda m: window, True


def run(name, material, case, method, speed):
    indenter, shifts, control, grid_of, open_edges = case
    grid = grid_of(material)
    opts = MovingOptions(method=method, open_edges=open_edges)
    c0 = time.process_time()
    r = solve_moving(
        material, HalfSpace(material.relaxed()), indenter, shifts, speed=speed, grid=grid, options=opts, **control
    )
    return r, time.process_time() - c0


def report(name, method, visco, elastic, glassy):
    (rv, cv), (re, ce), (rg, cg) = visco, elastic, glassy
    n = rv.shifts.size
    half = n // 2
    D = rv.dissipated_between(half)
    print(
        f"{name:7s} {method:9s} {n:4d} positions, grid {rv.grid.nx} x {rv.grid.ny}: viscoelastic "
        f"{cv:7.2f} s ({1e3 * cv / n:6.1f} ms/pos), elastic {ce:7.2f} s ({1e3 * ce / n:6.1f} ms/pos), "
        f"ratio {cv / ce:4.2f}; elastic at the glassy modulus {cg:7.2f} s, ratio {cv / cg:4.2f}; "
        f"iterations {rv.iterations.sum()} vs {re.iterations.sum()} and {rg.iterations.sum()}"
    )
    print(
        f"        mean drag {np.mean(rv.drag[half:]):.4g} N (elastic {np.mean(re.drag[half:]):.3g} N), "
        f"mean load {np.mean(rv.total_load[half:]):.4g} N; second half: drag work {rv.drag_work(half):.4g} N mm "
        f"+ vertical {rv.vertical_work(half):.4g} N mm, "
        f"dissipated {D:.4g} N mm, stored change {rv.stored[-1] - rv.stored[half]:.3g} N mm; "
        f"memory peak {rv.memory['peak_cells']} cells ({rv.memory['peak_bytes'] / 1e6:.2f} MB); "
        f"converged {rv.converged and re.converged}; max error estimate {rv.max_error:.2g}"
    )


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=50.0, help="km/h")
    ap.add_argument("--ratio", type=float, default=20.0, help="glassy / relaxed modulus")
    ap.add_argument("--runs", nargs="+", default=["sphere", "road"], choices=["sphere", "road"])
    args = ap.parse_args(argv)
    E_inf = 6.0
    visco = Material(E_inf, 0.5, prony=prony(E_inf, args.ratio))
    elastic = Material(E_inf, 0.5)
    speed = args.speed * KMH
    print(f"speed {args.speed:g} km/h ({speed:.4g} mm/s), 10 branches, glassy / relaxed {args.ratio:g}")
    cases = {"sphere": (sphere_case, ("reference", "twoscale")), "road": (road_case, ("reference",))}
    for name in args.runs:
        make, methods = cases[name]
        case = make()
        for method in methods:
            report(
                name,
                method,
                run(name, visco, case, method, speed),
                run(name, elastic, case, method, speed),
                run(name, visco.at_modulus(visco.E_glassy), case, method, speed),
            )


if __name__ == "__main__":
    main()
