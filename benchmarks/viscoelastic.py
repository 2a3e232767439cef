"""Viscoelastic histories on the scene family: cost, steps and accuracy.

A 10-branch Prony series over six decades (relaxation times 1e-3 ... 1e3 s, glassy
modulus ``--ratio`` times the relaxed one, the family's E = 6 MPa relaxed) on the family's
dense scenes (``twoscale.synthetic.random_scene(n, kind="dense", seed=0)``), under

* ``creep``: the family's load (2.5 N a tip) applied at t = 0 and held 1e3 s, 13 output
  times (0 and 1e-4 ... 1e3 s, two a decade);
* ``cycle``: load ramped up in 1 s, held 10 s, down to a fifth in 1 s (contacts shrink).

Printed per scene and history: the default run's CPU time and steps (redone), its cost in
elastic solves (CPU of one default solve of the elastic scene at the relaxed modulus), the
largest error estimate; the largest difference of forces (relative to the largest force),
total load and approach against a run with every step halved (the time-stepping error),
and against the full-grid reference with the same steps (``--reference``) with its CPU
time and the ratio; for ``creep`` the approach against the correspondence principle's
(elastic solves at modulus 1 / J(t), same grid) at three output times (``--exact``).
Tamaas' ``MaxwellViscoelastic`` (periodic, one surface at rest) is not run here: see
docs/viscoelastic.md.

Run: ``cd benchmarks && python viscoelastic.py [--tips 50 200] [--histories creep cycle]
[--reference] [--halved] [--exact]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import _common  # noqa: F401  (single-threaded defaults before numpy loads)
import numpy as np

import twoscale
import twoscale.viscoelastic.solve
from twoscale.material import Material
from twoscale.synthetic import random_scene
from twoscale.viscoelastic import (
    LoadHistory,
    TimeSteps,
    creep_compliance,
    solve_history,
)


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
    scale = float(np.abs(b.forces).max())
    return {"forces": float(np.abs(a.forces - b.forces).max() / scale),
            "load": float(np.abs(a.total_load - b.total_load).max() / np.abs(b.total_load).max()),
            "approach": float(np.abs(a.penetration - b.penetration).max() / np.abs(b.penetration).max())}


def run_one(n: int, kind: str, args) -> None:
    base = random_scene(n, kind="dense", seed=0, h=args.h)
    material = Material(base.material.E, base.material.nu, prony=prony(base.material.E, args.ratio))
    scene = dataclasses.replace(base, material=material, total_load=None, history=history(kind, base.total_load))
    h = twoscale.viscoelastic.solve.history_h(scene) if args.h is None else args.h
    _el, t_el = cpu(lambda: twoscale.solve(dataclasses.replace(base, h=h)))
    res, t_ts = cpu(lambda: solve_history(scene, method="twoscale", h=h))
    print(f"\n{n} tips, {kind}: h = {h:.4g} mm, {len(res.steps)} steps ({res.rejected} redone), "
          f"error estimate {res.error_estimate:.2g}, converged {res.converged}")
    print(f"  two-scale history  CPU {t_ts:8.2f} s = {t_ts / t_el:6.2f} elastic solves ({t_el:.2f} s each); "
          f"memory {res.memory['peak_cells']} cells x {res.memory['bytes_per_cell']} B")
    ends = tuple(s.t for s in res.steps)
    if args.halved:
        half, t_half = cpu(lambda: solve_history(scene, method="twoscale", h=h, steps=TimeSteps.halved(ends)))
        d = compare(res, half)
        print(f"  halved steps       CPU {t_half:8.2f} s; max difference forces {100 * d['forces']:.3g} %, "
              f"load {100 * d['load']:.3g} %, approach {100 * d['approach']:.3g} %")
    if args.reference:
        ref, t_ref = cpu(lambda: solve_history(scene, method="reference", h=h, steps=TimeSteps(at=ends)))
        d = compare(res, ref)
        print(f"  reference, same steps CPU {t_ref:8.2f} s; two-scale / reference {t_ts / t_ref:.3f}; "
              f"difference forces {100 * d['forces']:.3g} %, load {100 * d['load']:.3g} %, "
              f"approach {100 * d['approach']:.3g} %")
    if args.exact and kind == "creep":
        J = creep_compliance(material)
        worst = 0.0
        for k in (0, len(res.times) // 2, len(res.times) - 1):
            e = twoscale.solve(dataclasses.replace(base, h=h, material=Material(1.0 / float(J(res.times[k])), 0.5)))
            worst = max(worst, abs(res.penetration[k] / e.penetration - 1))
        print(f"  approach against the correspondence principle (3 times): {100 * worst:.3g} %")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tips", type=int, nargs="+", default=[50, 200])
    ap.add_argument("--histories", nargs="+", default=["creep", "cycle"], choices=["creep", "cycle"])
    ap.add_argument("--ratio", type=float, default=20.0, help="glassy / relaxed modulus")
    ap.add_argument("--h", type=float, default=None, help="cell size, mm (default: the history's rule)")
    ap.add_argument("--reference", action="store_true", help="also the full-grid reference with the same steps")
    ap.add_argument("--halved", action="store_true", help="also a run with every step halved")
    ap.add_argument("--exact", action="store_true", help="creep: approach against elastic solves at 1 / J(t)")
    args = ap.parse_args(argv)
    for n in args.tips:
        for kind in args.histories:
            run_one(n, kind, args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
