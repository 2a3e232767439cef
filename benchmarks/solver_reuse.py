"""What a solver object saves: a second solve, and a solve shifted by one cell, against cold.

For each scene (the examples S2 and the paper's seven spheres, and the random family's
sphere scenes at the sizes asked), in one process, single-threaded, this measures the CPU
time of

* ``cold``: ``twoscale.solve(scene)`` with a fresh body (nothing kept);
* ``again``: ``solver.solve(scene)`` on a :class:`twoscale.ContactSolver` whose last solve
  was this very scene (the body and the last answer kept);
* ``shifted``: ``solver.solve(scene moved by one cell along x)`` after the scene;

each ``--repeat`` times, interleaved (cold, again, shifted, cold, ...), and reports the
median ratios again/cold and shifted/cold with the micro iterations, the operators between
patches the second and the shifted solve took over from earlier solves (and built), and the
largest force difference against the cold solve of the same scene (relative to the largest
force). Targets: again <= 0.3, shifted <= 0.5.

Usage::

    python benchmarks/solver_reuse.py [--sizes 50 200] [--repeat 3] [--only seven sparse]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time

# single-threaded BLAS/FFT: set before numpy is imported (after it, the thread counts no
# longer change, and idle BLAS threads spinning on a loaded machine count as CPU time)
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks import _common  # noqa: E402,F401,I001

import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _scenes(sizes):
    import twoscale
    from twoscale.io.scene_file import read_scene
    from twoscale.synthetic import scene_family

    out = [
        ("S2", read_scene(os.path.join(ROOT, "examples", "S2.toml"))),
        ("seven spheres", read_scene(os.path.join(ROOT, "examples", "paper_seven_spheres.toml"))),
    ]
    out += list(scene_family(sizes=sizes, shapes=("sphere",)))
    return [
        (name, dataclasses.replace(s, h=s.h if s.h is not None else twoscale.scene.default_h(s))) for name, s in out
    ]


def shifted(scene, dx: float):
    """``scene`` with every tip (and the pivot of a tilt) moved by ``dx`` mm along x."""
    tips = tuple(dataclasses.replace(a, x=a.x + dx) for a in scene.asperities)
    if scene.tilt:
        return dataclasses.replace(scene, asperities=tips, pivot=(scene.pivot[0] + dx, scene.pivot[1]))
    return dataclasses.replace(scene, asperities=tips)


def _cpu(fn):
    t = time.process_time()
    out = fn()
    return time.process_time() - t, out


def measure(scene, repeat: int) -> dict:
    import twoscale

    moved = shifted(scene, scene.h)
    rows: dict = {"cold": [], "again": [], "shifted": [], "it": {}}
    for _ in range(repeat):
        t_cold, cold = _cpu(lambda: twoscale.solve(scene, provider=scene.provider()))
        solver = twoscale.ContactSolver()
        solver.solve(scene)
        t_again, again = _cpu(lambda: solver.solve(scene))
        solver.solve(scene)
        t_shift, moved_r = _cpu(lambda: solver.solve(moved))
        rows["cold"].append(t_cold)
        rows["again"].append(t_again)
        rows["shifted"].append(t_shift)
        rows["it"] = {
            "cold": cold.iterations["micro"],
            "again": again.iterations["micro"],
            "shifted": moved_r.iterations["micro"],
            "strategy": cold.details.micro.strategy,
        }
        rows["operators"] = {
            k: (sum(r.reuse.operators_kept.values()), sum(r.reuse.operators_built.values()))
            for k, r in (("again", again), ("shifted", moved_r))
        }
        ref_moved = twoscale.solve(moved, provider=scene.provider())
        scale = cold.asperities.forces.max()
        rows["error"] = max(
            float(np.abs(again.asperities.forces - cold.asperities.forces).max() / scale),
            float(np.abs(moved_r.asperities.forces - ref_moved.asperities.forces).max() / scale),
        )
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[50, 200], help="family sizes (tips)")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved repetitions per scene")
    ap.add_argument("--only", nargs="*", default=None, help="scenes whose name contains one of these")
    args = ap.parse_args(argv)
    print(
        f"{'scene':42s} {'tips':>5s} {'micro':>10s} {'cold s':>8s} {'again':>6s} {'shifted':>7s} "
        f"{'iterations c/a/s':>17s} {'kept/built a':>12s} {'kept/built s':>12s} {'force diff':>10s}"
    )
    worst = {"again": 0.0, "shifted": 0.0}
    for name, scene in _scenes(tuple(args.sizes)):
        if args.only and not any(part in name for part in args.only):
            continue
        r = measure(scene, args.repeat)
        cold = statistics.median(r["cold"])
        again = statistics.median(a / c for a, c in zip(r["again"], r["cold"]))
        shift = statistics.median(s / c for s, c in zip(r["shifted"], r["cold"]))
        worst = {"again": max(worst["again"], again), "shifted": max(worst["shifted"], shift)}
        it, ops = r["it"], {k: "%d/%d" % v for k, v in r["operators"].items()}
        print(
            f"{name:42s} {len(scene.asperities):5d} {it['strategy']:>10s} {cold:8.3f} {again:6.2f} {shift:7.2f} "
            f"{it['cold']:>7d}/{it['again']}/{it['shifted']:<7d} {ops['again']:>12s} {ops['shifted']:>12s} "
            f"{r['error']:10.1e}",
            flush=True,
        )
    print(f"worst: again {worst['again']:.2f} (target 0.3), shifted {worst['shifted']:.2f} (target 0.5)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
