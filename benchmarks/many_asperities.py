"""Many asperities (issue 6): time, peak memory and per-asperity force error against N.

Random scenes of N spherical asperities (R uniform in 2-6 mm) on a square of side
``3 sqrt(N)`` mm (30 mm at N = 100, 95 mm at 1,000, 300 mm at 10,000), tips uniform in
the square with at least ``min_spacing`` between them, tip recesses ``z`` uniform in
``[0, spread]``; the body is a half-space (E = 10 MPa, nu = 0.5) and the cell side
``h`` = mean R / 100 = 0.04 mm. Load control: the total load is chosen so that about half
of the asperities touch (``W = load_per_asperity * N``); the fraction that touches is
measured and printed.

Each solve runs in a fresh subprocess so that its peak resident memory
(``resource.getrusage(RUSAGE_SELF).ru_maxrss``, the interpreter's ~100 MB included) is its
own. The full-grid FFT reference (Polonsky-Keer CG, :func:`twoscale.reference.solve_cg`)
runs where its grid has at most ``--reference-max-cells`` cells. ContactMechanics and
Tamaas are used when importable (neither is installed here: reported as "not installed").

Usage::

    OMP_NUM_THREADS=1 python benchmarks/many_asperities.py --sizes 100 1000
    python benchmarks/many_asperities.py --sizes 100 --no-reference --options '{"far_tol": 0.05}'

Measured figures: docs/scaling_status.md.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks import _common  # noqa: E402,F401  (single-threaded BLAS/FFT by default)

from twoscale.grid import Grid  # noqa: E402
from twoscale.indenters import Asperity, surface_on  # noqa: E402
from twoscale.influence.halfspace import HalfSpace  # noqa: E402
from twoscale.material import Material  # noqa: E402

MATERIAL = Material(10.0, 0.5)
H = 0.04            # mm: mean R (4 mm) / 100
SPREAD = 0.06       # mm: tip recesses uniform in [0, SPREAD]
LOAD_PER_ASPERITY = 0.05   # N: W = this * N (53 % touch at N = 100, 57 % at 1,000, macro step)


def scene(n: int, *, seed: int = 0, min_spacing: float = 1.5):
    """Random scene of ``n`` spheres; returns (asperities, side of the square, mm)."""
    rng = np.random.default_rng(seed)
    side = 3.0 * np.sqrt(n)
    pts = np.empty((n, 2))
    count = 0
    while count < n:
        cand = rng.uniform(0.0, side, size=(4 * n, 2))
        for c in cand:
            if count == n:
                break
            if count == 0 or np.min(np.hypot(*(pts[:count] - c).T)) >= min_spacing:
                pts[count] = c
                count += 1
    R = rng.uniform(2.0, 6.0, n)
    z = rng.uniform(0.0, SPREAD, n)
    asp = [Asperity(float(x), float(y), float(zz), float(r)) for (x, y), zz, r in zip(pts, z, R)]
    return asp, side


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def run_twoscale(n: int, seed: int, options: dict) -> dict:
    from twoscale.twoscale import solve_twoscale
    asp, side = scene(n, seed=seed)
    provider = HalfSpace(MATERIAL)
    t0 = time.perf_counter()
    res = solve_twoscale(provider, asp, h=H, total_load=LOAD_PER_ASPERITY * n, tol=1e-6,
                         max_sweeps=200, **options)
    t = time.perf_counter() - t0
    forces = np.asarray(res.asperities.forces)
    cells = int(sum(f.grid.size for f in res.fields))
    return {"method": "twoscale", "n": n, "time_s": t, "peak_mb": _peak_mb(), "cells": cells,
            "forces": forces.tolist(), "converged": bool(res.converged), "message": res.message,
            "touching": float(np.mean(forces > 0)), "timings": res.timings_s,
            "iterations": {k: int(v) for k, v in res.iterations.items()}, "side_mm": side}


def run_reference(n: int, seed: int, options: dict) -> dict:
    from twoscale.reference import solve_cg
    asp, side = scene(n, seed=seed)
    provider = HalfSpace(MATERIAL)
    grid = Grid.covering(-6.0, side + 6.0, -6.0, side + 6.0, H)
    t0 = time.perf_counter()
    surf = surface_on(grid, asp)
    res = solve_cg(provider, surf, total_load=LOAD_PER_ASPERITY * n, tol=1e-8)
    t = time.perf_counter() - t0
    forces = np.asarray(res.asperities.forces)
    return {"method": "fft-cg", "n": n, "time_s": t, "peak_mb": _peak_mb(), "cells": int(grid.size),
            "forces": forces.tolist(), "converged": bool(res.converged), "message": res.message,
            "touching": float(np.mean(forces > 0)), "side_mm": side}


RUNNERS = {"twoscale": run_twoscale, "fft-cg": run_reference}


def _subprocess(method: str, n: int, seed: int, options: dict, timeout: float) -> dict:
    cmd = [sys.executable, os.path.abspath(__file__), "--single", method, "--sizes", str(n),
           "--seed", str(seed), "--options", json.dumps(options)]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"method": method, "n": n, "error": f"timeout after {timeout:.0f} s"}
    if out.returncode != 0:
        return {"method": method, "n": n, "error": out.stderr.strip().splitlines()[-1:]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def force_errors(forces, reference) -> dict:
    """Per-asperity force errors: max |dF_k| / F_ref_k over asperities carrying at least
    5 % of the mean touching force, and max |dF_k| / mean touching force."""
    f, r = np.asarray(forces), np.asarray(reference)
    touching = r > 0
    mean = float(r[touching].mean()) if touching.any() else 1.0
    big = r >= 0.05 * mean
    rel = float(np.max(np.abs(f[big] - r[big]) / r[big])) if big.any() else 0.0
    return {"max_rel_pct": 100 * rel, "max_over_mean_pct": 100 * float(np.max(np.abs(f - r))) / mean,
            "total_pct": 100 * abs(f.sum() - r.sum()) / r.sum()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-reference", action="store_true", help="skip the full-grid FFT solve")
    ap.add_argument("--reference-max-cells", type=float, default=6e6,
                    help="largest full grid attempted (cells), default 6e6")
    ap.add_argument("--timeout", type=float, default=1800.0, help="per solve, s")
    ap.add_argument("--options", default='{"far_tol": 0.2}',
                    help='JSON keyword arguments for solve_twoscale, default {"far_tol": 0.2} '
                         '(use {} for the exact cross-patch coupling: N^2 products)')
    ap.add_argument("--single", choices=sorted(RUNNERS), help=argparse.SUPPRESS)
    ap.add_argument("--json", help="write all records to this file")
    args = ap.parse_args(argv)
    options = json.loads(args.options)
    if args.single:
        print(json.dumps(RUNNERS[args.single](args.sizes[0], args.seed, options)))
        return 0
    for name in ("tamaas", "ContactMechanics"):
        if importlib.util.find_spec(name) is None:
            print(f"{name}: not installed (skipped)")
    records = []
    for n in args.sizes:
        ts = _subprocess("twoscale", n, args.seed, options, args.timeout)
        records.append(ts)
        side = 3.0 * np.sqrt(n) + 12.0
        cells = (side / H) ** 2
        ref = None
        if not args.no_reference and cells <= args.reference_max_cells:
            ref = _subprocess("fft-cg", n, args.seed, {}, args.timeout)
            records.append(ref)
        line = {k: ts.get(k) for k in ("n", "time_s", "peak_mb", "cells", "touching", "converged", "timings",
                                        "iterations", "error")}
        if ref is not None and "forces" in ref and "forces" in ts:
            line["reference"] = {k: ref.get(k) for k in ("time_s", "peak_mb", "cells", "converged")}
            line["errors"] = force_errors(ts["forces"], ref["forces"])
            line["speedup"] = ref["time_s"] / ts["time_s"]
        elif ref is not None:
            line["reference"] = ref.get("error")
        else:
            line["reference"] = f"skipped ({cells:.3g} cells)"
        print(json.dumps(line))
        sys.stdout.flush()
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(records, fh)
    return 0


if __name__ == "__main__":
    sys.exit(main())
