"""Viscoelastic histories on the scene family: cost, steps and accuracy.

A 10-branch Prony series over six decades (relaxation times 1e-3 ... 1e3 s, glassy
modulus ``--ratio`` times the relaxed one, the family's E = 6 MPa relaxed) on the family's
dense scenes (``twoscale.synthetic.random_scene(n, kind="dense", seed=0)``, ``--tips``) and
on a road texture (``--road``: ``twoscale.surface.texture.road``, seeded, ``--road-size``
mm square sampled at ``--road-h`` mm, its stones the basins of the height map, 0.2 MPa
nominal), under

* ``creep``: the scene's load (2.5 N a tip; the road's nominal load) applied at t = 0 and
  held 1e3 s, 16 output times (0 and 1e-4 ... 1e3 s, two a decade);
* ``cycle``: load ramped up in 1 s, held 10 s, down to a fifth in 1 s (contacts shrink).

Printed per scene and history: the default run's CPU time (``time.process_time``) and
steps (redone), its cost in elastic solves (CPU of one default solve of the elastic scene
at the relaxed modulus, same cell size, same process), the largest error estimate; with
``--halved`` the largest difference of forces (relative to the largest force), total load
and approach against a run with every step halved (the time-stepping error); with
``--reference`` the full-grid reference with the same steps (skipped above
``--reference-max-cells`` cells), its CPU time and the ratio; with ``--exact`` (creep) the
approach against the correspondence principle's (elastic solves at modulus 1 / J(t),
same grid) at three output times; with ``--tamaas`` Tamaas' ``MaxwellViscoelastic``
(periodic, backward Euler, the surface at rest: it applies to these histories) on a
periodic box twice the memory grid, with the default run's step ends, at the cell size
``--tamaas-h`` (the two-scale history is run again there with the same steps to compare).

Run: ``cd benchmarks && PYTHONPATH=.. python viscoelastic.py [--tips 50 200] [--road]
[--histories creep cycle] [--reference] [--halved] [--exact] [--tamaas] [--far-tol 0.3]``
(``--far-tol``: the two-scale history with far-field coupling, every step).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import types

import _common  # noqa: F401  (single-threaded defaults before numpy loads)
import numpy as np

import twoscale
import twoscale.viscoelastic.solve
from twoscale.indenters import surface_on
from twoscale.material import Material
from twoscale.scene import Scene
from twoscale.synthetic import random_scene
from twoscale.viscoelastic import (
    LoadHistory,
    TimeSteps,
    creep_compliance,
    solve_history,
)

#: The road's nominal pressure, MPa (that of benchmarks/surfaces.py).
ROAD_PRESSURE = 0.2


def prony(E_inf: float, ratio: float, n: int = 10) -> tuple:
    """``n`` branches, relaxation times 1e-3 ... 1e3 s, moduli falling with tau, summing to
    ``(ratio - 1) E_inf``."""
    tau = np.geomspace(1e-3, 1e3, n)
    w = np.geomspace(2.0, 1.0, n)
    E = (ratio - 1.0) * E_inf * w / w.sum()
    return tuple((float(e), float(t)) for e, t in zip(E, tau))


def history(kind: str, W: float) -> LoadHistory:
    if kind == "creep":
        out = (0.0,) + tuple(np.geomspace(1e-4, 1e3, 15).tolist())
        return LoadHistory("total", ((0.0, W), (1e3, W)), output=out)
    return LoadHistory("total", ((0.0, 0.0), (1.0, W), (11.0, W), (12.0, 0.2 * W)))


def cpu(fn):
    t0 = time.process_time()
    out = fn()
    return out, time.process_time() - t0


def compare(a, b) -> dict:
    """Largest differences of ``a`` from ``b`` at ``a``'s output times (``b`` reports
    each of them: the same or halved steps)."""
    b = _at(b, np.isin(b.times, a.times))
    scale = float(np.abs(b.forces).max())
    return {
        "forces": float(np.abs(a.forces - b.forces).max() / scale),
        "load": float(np.abs(a.total_load - b.total_load).max() / np.abs(b.total_load).max()),
        "approach": float(np.abs(a.penetration - b.penetration).max() / np.abs(b.penetration).max()),
    }


def _at(r, keep: np.ndarray):
    """The histories of ``r`` at the output times ``keep`` selects."""
    return types.SimpleNamespace(
        times=r.times[keep], forces=r.forces[keep], total_load=r.total_load[keep], penetration=r.penetration[keep]
    )


def elastic_scene(name: str, args) -> Scene:
    """The elastic scene at the relaxed modulus and the full load."""
    if name == "road":
        from twoscale.surface import RawMap, build_surface
        from twoscale.surface.texture import road

        z = road(args.road_size, args.road_h, seed=1)
        surface = build_surface(RawMap(z, args.road_h, "mm", None, "synthetic road"))
        return Scene(Material(6.0, 0.5), surface=surface, total_load=ROAD_PRESSURE * args.road_size**2)
    return random_scene(int(name), kind="dense", seed=0, h=args.h)


def run_one(name: str, kind: str, args) -> None:
    base = elastic_scene(name, args)
    material = Material(base.material.E, base.material.nu, prony=prony(base.material.E, args.ratio))
    scene = dataclasses.replace(base, material=material, total_load=None, history=history(kind, base.total_load))
    h = twoscale.viscoelastic.solve.history_h(scene) if args.h is None or name == "road" else args.h
    _el, t_el = cpu(lambda: twoscale.solve(dataclasses.replace(base, h=h)))
    far = {} if args.far_tol is None else {"far_tol": args.far_tol}
    res, t_ts = cpu(lambda: solve_history(scene, method="twoscale", h=h, **far))
    label = f"road {args.road_size:g} mm ({len(base.asperities)} stones)" if name == "road" else f"{name} tips"
    print(
        f"\n{label}, {kind}: h = {h:.4g} mm, {len(res.steps)} steps ({res.rejected} redone), "
        f"error estimate {res.error_estimate:.2g}, converged {res.converged}",
        flush=True,
    )
    print(
        f"  two-scale history  CPU {t_ts:8.2f} s = {t_ts / t_el:6.2f} elastic solves ({t_el:.2f} s each); "
        f"memory {res.memory['peak_cells']} cells x {res.memory['bytes_per_cell']} B "
        f"(grid {res.memory['grid_cells']} cells)",
        flush=True,
    )
    ends = tuple(s.t for s in res.steps)
    if args.halved:
        half, t_half = cpu(lambda: solve_history(scene, method="twoscale", h=h, steps=TimeSteps.halved(ends), **far))
        d = compare(res, half)
        print(
            f"  halved steps       CPU {t_half:8.2f} s; max difference forces {100 * d['forces']:.3g} %, "
            f"load {100 * d['load']:.3g} %, approach {100 * d['approach']:.3g} %",
            flush=True,
        )
    if args.reference:
        cells = res.memory["grid_cells"]
        if cells > args.reference_max_cells:
            print(
                f"  reference, same steps: skipped ({cells} cells > --reference-max-cells "
                f"{args.reference_max_cells:g})",
                flush=True,
            )
        else:
            ref, t_ref = cpu(lambda: solve_history(scene, method="reference", h=h, steps=TimeSteps(at=ends)))
            d = compare(res, ref)
            print(
                f"  reference, same steps CPU {t_ref:8.2f} s; two-scale / reference {t_ts / t_ref:.3f}; "
                f"difference forces {100 * d['forces']:.3g} %, load {100 * d['load']:.3g} %, "
                f"approach {100 * d['approach']:.3g} %",
                flush=True,
            )
    if args.exact and kind == "creep":
        J = creep_compliance(material)
        worst = 0.0
        for k in (0, len(res.times) // 2, len(res.times) - 1):
            e = twoscale.solve(dataclasses.replace(base, h=h, material=Material(1.0 / float(J(res.times[k])), 0.5)))
            worst = max(worst, abs(res.penetration[k] / e.penetration - 1))
        print(f"  approach against the correspondence principle (3 times): {100 * worst:.3g} %", flush=True)
    if args.tamaas:
        compare_tamaas(scene, ends, args)


def tamaas_history(scene: Scene, grid, ends) -> tuple:
    """Tamaas' ``MaxwellViscoelastic`` on a periodic box twice ``grid`` (the scene's memory
    grid, the scene in its first quarter), one solve per step end (the step's time as
    its backward-Euler step): ``(forces (n_ends, n_asperities) N, contact area mm2)``."""
    import tamaas as tm

    tm.set_log_level(tm.LogLevel.error)
    s = surface_on(grid, scene.asperities)
    m, hist = scene.material, scene.history
    ny, nx = grid.shape
    finite = np.isfinite(s.height)
    heights = np.full((2 * ny, 2 * nx), -float(np.max(s.height[finite])) - 1.0)  # far below every tip
    heights[:ny, :nx] = np.where(finite, -s.height, heights[0, 0])
    model = tm.Model(tm.model_type.basic_2d, [2 * ny * grid.h, 2 * nx * grid.h], [2 * ny, 2 * nx])
    model.E, model.nu = float(m.E), float(m.nu)
    G = [float(E_k) / (2.0 * (1.0 + m.nu)) for E_k, _ in m.prony]
    solver = tm.MaxwellViscoelastic(
        model, heights, 1e-10, time_step=0.0, shear_moduli=G, characteristic_times=[float(t) for _, t in m.prony]
    )
    area = 4.0 * grid.size * grid.h**2
    owner = s.owner.ravel()
    forces, areas, t_prev = [], [], 0.0
    for t in ends:
        solver.time_step = float(t - t_prev)
        W = float(hist.value(t))
        p = np.zeros((2 * ny, 2 * nx))
        if W > 0:
            solver.solve(W / area)
            p = np.array(model.traction).reshape(2 * ny, 2 * nx)
        t_prev = t
        q = p[:ny, :nx].ravel() * grid.h**2
        forces.append(np.bincount(owner[owner >= 0], q[owner >= 0], minlength=s.n_asperities))
        areas.append(np.count_nonzero(p > 0) * grid.h**2)
    return np.array(forces), np.array(areas)


def compare_tamaas(scene: Scene, ends, args) -> None:
    try:
        import tamaas  # noqa: F401
    except ImportError:
        print("  Tamaas: not installed", flush=True)
        return
    h = args.tamaas_h if scene.surface is None else float(scene.h)
    coarse = dataclasses.replace(scene, h=h) if scene.surface is None else scene
    grid = twoscale.viscoelastic.solve._memory_grid(coarse, h)
    if 4 * grid.size > args.tamaas_max_cells:
        print(f"  Tamaas: skipped (box of {4 * grid.size} cells > --tamaas-max-cells {args.tamaas_max_cells:g})")
        return
    two, t_two = cpu(lambda: solve_history(coarse, method="twoscale", h=h, steps=TimeSteps(at=ends)))
    (forces, areas), t_tm = cpu(lambda: tamaas_history(coarse, grid, ends))
    keep = np.isin(np.asarray(ends), two.times)
    f = forces[keep]
    scale = float(np.abs(two.forces).max())
    print(
        f"  Tamaas MaxwellViscoelastic, box {2 * grid.shape[0]} x {2 * grid.shape[1]} at h = {h:g} mm, same "
        f"{len(ends)} steps: CPU {t_tm:8.2f} s (two-scale, same h and steps, {t_two:.2f} s); "
        f"forces differ by {100 * float(np.abs(f - two.forces).max()) / scale:.3g} % of the largest, "
        f"contact area by {100 * float(np.abs(areas[keep] / two.contact_area - 1).max()):.3g} %",
        flush=True,
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tips", type=int, nargs="*", default=[50, 200])
    ap.add_argument("--road", action="store_true", help="also the road texture (a height map)")
    ap.add_argument("--road-size", type=float, default=50.0, help="side of the road map, mm")
    ap.add_argument("--road-h", type=float, default=0.1, help="sampling of the road map, mm")
    ap.add_argument("--histories", nargs="+", default=["creep", "cycle"], choices=["creep", "cycle"])
    ap.add_argument("--ratio", type=float, default=20.0, help="glassy / relaxed modulus")
    ap.add_argument("--h", type=float, default=None, help="cell size of the tips, mm (default: the history's rule)")
    ap.add_argument(
        "--far-tol", type=float, default=None, help="far-field coupling of the two-scale history (default: exact)"
    )
    ap.add_argument("--reference", action="store_true", help="also the full-grid reference with the same steps")
    ap.add_argument("--reference-max-cells", type=float, default=4e6, help="largest memory grid for --reference")
    ap.add_argument("--halved", action="store_true", help="also a run with every step halved")
    ap.add_argument("--exact", action="store_true", help="creep: approach against elastic solves at 1 / J(t)")
    ap.add_argument("--tamaas", action="store_true", help="also Tamaas' MaxwellViscoelastic (periodic box)")
    ap.add_argument("--tamaas-h", type=float, default=0.1, help="cell size of the Tamaas comparison on tips, mm")
    ap.add_argument("--tamaas-max-cells", type=float, default=4e6, help="largest Tamaas box, cells")
    args = ap.parse_args(argv)
    names = [str(n) for n in args.tips] + (["road"] if args.road else [])
    for name in names:
        for kind in args.histories:
            run_one(name, kind, args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
