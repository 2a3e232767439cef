"""Many asperities: time, peak memory and per-asperity force error against N.

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
runs where its grid has at most ``--reference-max-cells`` cells.

Comparators (``--comparators``, default on when importable; ``--no-comparators`` skips
them), at the same cell size, each in its own subprocess, under the same cell limit
(counted on the scene grid; both they and our reference zero-pad or double it inside):

* ``CM``: ContactMechanics ``FreeFFTElasticHalfSpace`` (non-periodic: the same discrete
  problem as our reference, uniform pressure on square cells) on the same full grid,
  ``NonSmoothContactSystem.minimize_proxy(external_force=W, pentol=..., forcetol=...)``
  (its Polonsky-Keer constrained CG under load control), E* of our material; its forces
  per pixel are summed over the cells each asperity owns. Agrees with our reference to
  the solvers' tolerances.
* ``Tamaas``: ``PolonskyKeerRey`` on its periodic ``basic_2d`` model (spectral kernel),
  the scene grid placed in a periodic cell twice as wide in x and in y (4x the cells,
  padding never touches) to limit the periodic images: *not the same problem* (periodic
  images and a different kernel), its force error is labelled periodic.

Both take rigid heights peak up, ``-min(height, CLIP)``: the cells without material
(``inf``) and those more than ``CLIP`` = 1 mm above the lowest tip (none of them can touch:
the approach is ~0.1 mm; checked after the solve) sit 1 mm down, which keeps Tamaas's
error scale (normalised by the surface's rms height) meaningful.

Usage::

    OMP_NUM_THREADS=1 python benchmarks/many_asperities.py --sizes 100 1000
    python benchmarks/many_asperities.py --sizes 100 --no-reference --options '{"far_tol": 0.05}'
    python benchmarks/many_asperities.py --sizes 100 --no-comparators

Measured figures: docs/records/scaling_status.md.
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

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks import _common  # noqa: E402,F401  (single-threaded BLAS/FFT by default)
import numpy as np  # noqa: E402  (after _common: OpenBLAS reads its thread count when loaded)

from twoscale.grid import Grid  # noqa: E402
from twoscale.indenters import Asperity, surface_on  # noqa: E402
from twoscale.influence.halfspace import HalfSpace  # noqa: E402
from twoscale.material import Material  # noqa: E402

MATERIAL = Material(10.0, 0.5)
H = 0.04  # mm: mean R (4 mm) / 100
SPREAD = 0.06  # mm: tip recesses uniform in [0, SPREAD]
LOAD_PER_ASPERITY = 0.05  # N: W = this * N (53 % touch at N = 100, 57 % at 1,000, macro step)


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
    from twoscale.driver import solve_twoscale

    asp, side = scene(n, seed=seed)
    provider = HalfSpace(MATERIAL)
    t0 = time.perf_counter()
    res = solve_twoscale(provider, asp, h=H, total_load=LOAD_PER_ASPERITY * n, tol=1e-6, max_sweeps=200, **options)
    t = time.perf_counter() - t0
    forces = np.asarray(res.asperities.forces)
    cells = int(sum(f.grid.size for f in res.fields))
    return {
        "method": "twoscale",
        "n": n,
        "time_s": t,
        "peak_mb": _peak_mb(),
        "cells": cells,
        "forces": forces.tolist(),
        "converged": bool(res.converged),
        "message": res.message,
        "touching": float(np.mean(forces > 0)),
        "timings": dict(res.timings_s),
        "iterations": {k: int(v) for k, v in res.iterations.items()},
        "side_mm": side,
    }


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
    return {
        "method": "fft-cg",
        "n": n,
        "time_s": t,
        "peak_mb": _peak_mb(),
        "cells": int(grid.size),
        "forces": forces.tolist(),
        "converged": bool(res.converged),
        "message": res.message,
        "touching": float(np.mean(forces > 0)),
        "side_mm": side,
    }


CLIP = 1.0  # mm: heights above this (and inf) sit this far down for the comparators
TAMAAS_TOL = 1e-12  # Tamaas's relative complementarity error


def _scene_surface(n: int, seed: int):
    """Scene, its full grid (as run_reference's) and the sampled surface."""
    asp, side = scene(n, seed=seed)
    grid = Grid.covering(-6.0, side + 6.0, -6.0, side + 6.0, H)
    return asp, side, grid, surface_on(grid, asp)


def _owned_forces(surf, pixel_forces: np.ndarray) -> np.ndarray:
    """Sum of pixel forces (N) over the cells each asperity owns, as summarise() does."""
    own, f = surf.owner.ravel(), np.asarray(pixel_forces).ravel()
    ok = own >= 0
    return np.bincount(own[ok], weights=f[ok], minlength=surf.n_asperities)


def _clip_check(surf, pixel_forces: np.ndarray) -> int:
    """Loaded cells among those clipped at CLIP (0 when the clipping changed nothing)."""
    return int(np.count_nonzero((np.asarray(pixel_forces) > 0) & ~(surf.height < CLIP)))


def run_contact_mechanics(n: int, seed: int, options: dict) -> dict:
    from benchmarks._cm import contact_mechanics

    W = LOAD_PER_ASPERITY * n
    t0 = time.perf_counter()
    asp, side, grid, surf = _scene_surface(n, seed)
    cm = contact_mechanics(surf.height, grid.h, MATERIAL.E_star, total_load=W, maxiter=20_000)
    t = time.perf_counter() - t0
    pix = cm.force  # forces per pixel, N (pressure * h^2), >= 0
    forces = _owned_forces(surf, pix)
    return {
        "method": "CM",
        "n": n,
        "time_s": t,
        "peak_mb": _peak_mb(),
        "cells": int(grid.size),
        "forces": forces.tolist(),
        "converged": cm.converged,
        "message": cm.message,
        "iterations": cm.iterations,
        "total_load": float(pix.sum()),
        "clipped_loaded": _clip_check(surf, pix),
        "touching": float(np.mean(forces > 0)),
        "side_mm": side,
    }


def run_tamaas(n: int, seed: int, options: dict) -> dict:
    import tamaas as tm

    tm.set_log_level(tm.LogLevel.error)
    W = LOAD_PER_ASPERITY * n
    t0 = time.perf_counter()
    asp, side, grid, surf = _scene_surface(n, seed)
    ny, nx = 2 * grid.ny, 2 * grid.nx  # periodic cell twice the scene grid in x and y
    Ly, Lx = ny * grid.h, nx * grid.h
    heights = np.full((ny, nx), -CLIP)
    heights[: grid.ny, : grid.nx] = -np.minimum(surf.height, CLIP)
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [Ly, Lx], [ny, nx])
    model.E, model.nu = MATERIAL.E, MATERIAL.nu
    solver = tm.PolonskyKeerRey(model, heights, TAMAAS_TOL)
    solver.setMaxIterations(20_000)
    err = float(solver.solve(W / (Lx * Ly)))
    t = time.perf_counter() - t0
    p = np.array(model.traction).reshape(ny, nx)
    pix = p * grid.h**2
    scene_pix = pix[: grid.ny, : grid.nx]
    forces = _owned_forces(surf, scene_pix)
    return {
        "method": "Tamaas",
        "n": n,
        "time_s": t,
        "peak_mb": _peak_mb(),
        "cells": int(nx * ny),
        "forces": forces.tolist(),
        "converged": bool(err <= TAMAAS_TOL),
        "message": f"error {err:.2e}",
        "total_load": float(pix.sum()),
        "padding_load": float(pix.sum() - scene_pix.sum()),
        "clipped_loaded": _clip_check(surf, scene_pix),
        "touching": float(np.mean(forces > 0)),
        "side_mm": side,
    }


RUNNERS = {"twoscale": run_twoscale, "fft-cg": run_reference, "CM": run_contact_mechanics, "Tamaas": run_tamaas}
COMPARATORS = {"CM": ("ContactMechanics", "SurfaceTopography"), "Tamaas": ("tamaas",)}
#: cells each comparator solves on, per cell of the scene grid (Tamaas: periodic cell 2x in x and y)
COMPARATOR_CELLS = {"CM": 1, "Tamaas": 4}


def _subprocess(method: str, n: int, seed: int, options: dict, timeout: float) -> dict:
    cmd = [
        sys.executable,
        os.path.abspath(__file__),
        "--single",
        method,
        "--sizes",
        str(n),
        "--seed",
        str(seed),
        "--options",
        json.dumps(options),
    ]
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
    return {
        "max_rel_pct": 100 * rel,
        "max_over_mean_pct": 100 * float(np.max(np.abs(f - r))) / mean,
        "total_pct": 100 * abs(f.sum() - r.sum()) / r.sum(),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-reference", action="store_true", help="skip the full-grid FFT solve")
    ap.add_argument(
        "--reference-max-cells", type=float, default=6e6, help="largest full grid attempted (cells), default 6e6"
    )
    ap.add_argument("--timeout", type=float, default=1800.0, help="per solve, s")
    ap.add_argument(
        "--options",
        default="{}",
        help="JSON keyword arguments for solve_twoscale, default {} (what a user gets: "
        'the policy chooses the iteration and coupling; e.g. {"far_tol": 0.2} to fix them)',
    )
    ap.add_argument(
        "--comparators",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run ContactMechanics and Tamaas where installed (default on)",
    )
    ap.add_argument(
        "--comparator-max-cells",
        type=float,
        default=None,
        help="largest grid a comparator is run on, counting its own cells (Tamaas: 4x "
        "the scene grid), default --reference-max-cells",
    )
    _common.add_quiet(ap)
    ap.add_argument("--single", choices=sorted(RUNNERS), help=argparse.SUPPRESS)
    ap.add_argument("--json", help="write all records to this file")
    args = ap.parse_args(argv)
    options = json.loads(args.options)
    if args.single:
        print(json.dumps(RUNNERS[args.single](args.sizes[0], args.seed, options)))
        return 0
    comparators = []
    for label, modules in COMPARATORS.items():
        missing = [m for m in modules if importlib.util.find_spec(m) is None]
        if not args.comparators:
            print(f"{label}: skipped (--no-comparators)")
        elif missing:
            print(f"{label}: not installed ({', '.join(missing)}; pip install -e '.[bench]'), skipped")
        else:
            comparators.append(label)
    records = []
    bar = _common.progress(len(args.sizes) * (2 + len(comparators)), "solves", args.quiet)

    def _run(method, n, opts):
        out = _subprocess(method, n, args.seed, opts, args.timeout)
        bar.update(note=f"{method} N = {n}")
        return out

    for n in args.sizes:
        ts = _run("twoscale", n, options)
        records.append(ts)
        side = 3.0 * np.sqrt(n) + 12.0
        cells = (side / H) ** 2
        ref = None
        if not args.no_reference and cells <= args.reference_max_cells:
            ref = _run("fft-cg", n, {})
            records.append(ref)
        others, skipped = {}, []
        limit = args.reference_max_cells if args.comparator_max_cells is None else args.comparator_max_cells
        for label in comparators:
            own = cells * COMPARATOR_CELLS[label]
            if own <= limit:
                others[label] = _run(label, n, {})
                records.append(others[label])
            else:
                skipped.append(f"{label} ({own:.3g} cells)")
        line = {
            k: ts.get(k)
            for k in ("n", "time_s", "peak_mb", "cells", "touching", "converged", "timings", "iterations", "error")
        }
        if ref is not None and "forces" in ref and "forces" in ts:
            line["reference"] = {k: ref.get(k) for k in ("time_s", "peak_mb", "cells", "converged")}
            line["errors"] = force_errors(ts["forces"], ref["forces"])
            line["speedup"] = ref["time_s"] / ts["time_s"]
        elif ref is not None:
            line["reference"] = ref.get("error")
        else:
            line["reference"] = f"skipped ({cells:.3g} cells)"
        for label, rec in others.items():
            entry = {
                k: rec.get(k)
                for k in (
                    "time_s",
                    "peak_mb",
                    "cells",
                    "converged",
                    "iterations",
                    "total_load",
                    "clipped_loaded",
                    "padding_load",
                    "error",
                )
                if k in rec
            }
            if "forces" in rec and "forces" in ts:
                entry["twoscale_vs_it"] = force_errors(ts["forces"], rec["forces"])
                entry["speedup"] = rec["time_s"] / ts["time_s"]
            if "forces" in rec and ref is not None and "forces" in ref:
                entry["it_vs_fft_cg"] = force_errors(rec["forces"], ref["forces"])
            line[label + (" (periodic)" if label == "Tamaas" else "")] = entry
        if skipped:
            line["comparators skipped"] = ", ".join(skipped)
        print(json.dumps(line))
        sys.stdout.flush()
    bar.close()
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(records, fh)
    return 0


if __name__ == "__main__":
    sys.exit(main())
