"""The full grid's CG on one sweep scene with other settings, in one process, interleaved.

The default route solves a scene whose tips crowd their grid as the reference's full grid
(:func:`twoscale.full_grid.solve_full_grid`); this script runs that grid's CG
(:func:`twoscale.reference.solve_cg` on the reference's surface) with each variant in turn,
``--repeat`` rounds, the order reversed every other round, and prints per variant the median
CPU seconds, their ratio to the reference's (the plain double-precision CG), the CG's
iterations and products, and the largest per-tip force difference from the reference's over
its largest force. Variants (``VARIANTS``):

* ``reference``: the yardstick; ``route``: the default route's settings
  (:func:`twoscale.full_grid.full_grid_settings`);
* ``kept``: the route's with the union CG's kept directions and half products;
* ``torus``: the route's preconditioned by the torus inverse;
* ``coarse``: the torus with its coarse correction over squares, built on any grid (the
  module's ``MIN_CELLS`` set to 0 for this run); ``union``: ``kept`` and ``coarse`` with the
  step length by the torus (the union CG's settings on the full grid);
* ``oracle``: the route's from the reference's own answer at a KKT residual of 1e-3 (made
  before the clock starts): what a start as good as that leaves to the CG.

In-process figures share warm FFT plans and buffers; a route's change is measured in fresh
processes too (``ab_trees.py``).

Usage::

    python benchmarks/full_grid_variants.py 7 176 --repeat 3
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from _common import import_solver_modules  # noqa: E402

ROUTE = {"kept": {"keep_conjugacy": 0.005, "half_products": True}, "torus": {"precondition": True}}
ROUTE["coarse"] = {**ROUTE["torus"], "coarse": True}
ROUTE["union"] = {**ROUTE["kept"], **ROUTE["coarse"], "step_model": True}
VARIANTS = ("reference", "route", "kept", "torus", "coarse", "union", "oracle")


def grid_problem(seed: int, index: int):
    """The sweep scene's reference surface, its provider, approach (mm) and the route's options."""
    from twoscale import scenespace
    from twoscale.api import default_h
    from twoscale.full_grid import full_grid_settings
    from twoscale.micro.sampling import box_surface
    from twoscale.reference.on_scene import reference_grid

    (spec,) = [s for s in scenespace.sweep(200, seed) if s.index == index]
    scene = scenespace.build(spec)
    if scene.penetration is None or scene.tilt:
        raise SystemExit("a scene under penetration control without tilt is expected")
    grid = reference_grid(scene, default_h(scene))
    route = full_grid_settings(grid.size, len(scene.asperities)).options()
    route.pop("solver")
    return box_surface(grid, scene.asperities), scene.provider(), scene.penetration, route


def forces(surface, pressure: np.ndarray) -> np.ndarray:
    loaded = pressure > 0
    return np.bincount(surface.owner[loaded], weights=pressure[loaded], minlength=surface.n_asperities)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("seed", type=int)
    parser.add_argument("index", type=int)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--variants", nargs="*", default=list(VARIANTS))
    args = parser.parse_args(argv)
    import_solver_modules()
    import twoscale.pk.coarse as coarse
    from twoscale.reference import solve_cg

    coarse.MIN_CELLS = 0  # (the coarse variants on grids below the union CG's bound)
    surface, provider, d, route = grid_problem(args.seed, args.index)
    rough = solve_cg(provider, surface, penetration=d, tol=1e-3, **route).fields[0].pressure
    options = {"reference": {}, "route": route, "oracle": {**route, "start": rough}}
    options.update({k: {**route, **v} for k, v in ROUTE.items()})
    runs: dict = {v: [] for v in args.variants}
    for r in range(args.repeat):
        for v in args.variants if r % 2 == 0 else args.variants[::-1]:
            t0 = time.process_time()
            result = solve_cg(provider, surface, penetration=d, **options[v])
            runs[v].append((time.process_time() - t0, result))
    ref = statistics.median(t for t, _ in runs["reference"]) if "reference" in runs else None
    f_ref = forces(surface, runs["reference"][0][1].fields[0].pressure) if ref else None
    for v, done in runs.items():
        cpu, result = statistics.median(t for t, _ in done), done[0][1]
        f = forces(surface, result.fields[0].pressure)
        line = f"{v:9s} cpu {cpu:.3f} s  iterations {result.iterations['cg']:3d}  products {result.iterations['products']:3d}"
        if ref:
            line += f"  ratio {cpu / ref:.2f}  force diff {np.max(np.abs(f - f_ref)) / np.max(f_ref):.1e}"
        print(line + ("" if result.converged else "  NOT converged"), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
