"""A dense scene: the default solve over the full-grid FFT reference, interleaved.

``twoscale.synthetic.random_scene(n, kind="dense", control="load", seed, h, side)``
(spheres R 3-6 mm, tips 0-0.1 mm deep, 2.5 N each (the family's default), half-space E 6 MPa, nu 0.5; ``--E``
to change the modulus), solved ``--repeat`` times by the default two-scale solve and by
``method="reference"`` alternately (order swapped every repeat) in this process, after one
warm-up solve of a small scene by each (imports and first-call costs are paid by neither).
Printed per solve: wall and CPU time (``time.process_time``, the steadier figure on a
shared machine); then the ratios and the largest per-tip force difference.
Target on dense scenes of >= 200 tips: default / reference <= 0.5.

Run: ``cd benchmarks && python dense_ratio.py [--tips 300] [--side 45] [--h 0.05] [--repeat 2]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import _common  # noqa: F401  (single-threaded defaults before numpy loads)
import numpy as np

from twoscale.material import Material
from twoscale.api import solve_scene
from twoscale.synthetic import random_scene

METHODS = ("twoscale", "reference")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tips", type=int, default=300)
    ap.add_argument("--side", type=float, default=45.0, help="side of the square of tips, mm")
    ap.add_argument("--h", type=float, default=0.05, help="cell size, mm")
    ap.add_argument("--E", type=float, default=None, help="Young's modulus, MPa (default the family's 6)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)
    scene = random_scene(args.tips, kind="dense", control="load", seed=args.seed, h=args.h, side=args.side)
    if args.E is not None:
        scene = dataclasses.replace(scene, material=Material(E=args.E, nu=scene.material.nu))
    warm = random_scene(5, kind="dense", control="load", seed=0, h=0.1)
    for method in METHODS:
        solve_scene(warm, method=method)
    times: dict = {m: [] for m in METHODS}
    results: dict = {}
    for rep in range(args.repeat):
        for method in METHODS if rep % 2 == 0 else METHODS[::-1]:
            c0, t0 = time.process_time(), time.perf_counter()
            res = solve_scene(scene, method=method)
            times[method].append((time.perf_counter() - t0, time.process_time() - c0))
            results[method] = res
            print(
                f"{method:10s} wall {times[method][-1][0]:7.2f} s  CPU {times[method][-1][1]:7.2f} s  "
                f"converged {res.converged}  iterations {res.iterations}",
                flush=True,
            )
    wall = sum(t[0] for t in times["twoscale"]) / sum(t[0] for t in times["reference"])
    cpu = sum(t[1] for t in times["twoscale"]) / sum(t[1] for t in times["reference"])
    f, g = results["twoscale"].asperities.forces, results["reference"].asperities.forces
    micro = results["twoscale"].details.micro
    print(
        f"default / reference: CPU {cpu:.3f}, wall {wall:.3f}; iteration {micro.strategy}; "
        f"per-tip difference {100 * np.abs(f - g).max() / g.max():.2g} % of the largest force"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
