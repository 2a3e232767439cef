"""Before/after on one machine in one run: the same solves with two source trees, interleaved.

Each case runs ``--repeat`` times with each tree, alternating which goes first, each solve in
a fresh process (``PYTHONPATH`` = the tree), single-threaded, the solvers' modules imported
before the clock starts (as the sweep does). Printed per case (one JSON line):
median CPU time of each tree and the median of the per-pair CPU-time ratios after/before
(CPU time, and pairs run back to back, because the machine is shared and noisy), whether the
pressure fields are bit-identical, the largest per-tip force difference over the largest
force, iterations and convergence of both.

Cases (``KIND:ARG``):

* ``hertz:load|pen|tilt|mixedpc`` — :func:`twoscale.reference.solve_cg` on a Hertz sphere
  (R 10 mm, E 10 MPa, nu 0.5, 160 x 160 cells; ``bigload``/``bigpen`` 480 x 480), load 5 N or
  penetration 0.08 mm; ``tilt``: two tips, free tilt; ``mixedpc``: mixed precision, preconditioned;
* ``stack:stacked|single`` — two-level micro step, 80 spheres (h 0.04 mm, dense blocks up to
  60 cells), the FFT blocks solved in stacks or, ``single``, one by one;
* ``family:KIND-CONTROL-SHAPE-N`` / ``family_ref:...`` — a scene of
  :func:`twoscale.synthetic.scene_family`, default two-scale solve / the reference;
* ``space:I`` — :func:`twoscale.scenespace.draw` ``(I, seed 0)``, tips only, half-space, at most 300;
* ``sweep:I`` / ``sweep_ref:I`` — scene ``I`` of the sweep itself (``benchmarks/sweep.py``'s draws:
  maps and blocks too), default two-scale solve / the reference; ``sweep1:I`` / ``sweep1_ref:I``
  the same with the held-out draws (``--seed 1``), ``sweep2:I`` / ``sweep2_ref:I`` with ``--seed 2``,
  ``sweep3:I`` / ``sweep3_ref:I`` with ``--seed 3``, and so on up to ``sweep11:I`` / ``sweep11_ref:I``;
* ``road:SIZE-H-RMIN-RMAX`` — the synthetic road of ``benchmarks/surfaces.py`` (e.g.
  ``road:100-0.1-3-6``, its 161 stones), segmentation and default solve;
* ``file:PATH`` / ``file_ref:PATH`` — a scene file (e.g. the paper's ``examples/S1.toml``, the
  road ``examples/road/road.toml``), read and solved with the default options / the reference.

Both trees need not spell the API alike: the cases import the one-shot scene solve and
the two-scale driver from where each tree keeps them.

Usage::

    git -C REPO archive OLD_COMMIT | tar -x -C /tmp/before
    python benchmarks/ab_trees.py --before /tmp/before --after . --repeat 3 hertz:bigload stack:single space:3
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import time
import warnings

import numpy as np

from _common import BODY_MODULES, import_solver_modules  # noqa: F401  (BODY_MODULES: the sweep's list, shared)


def _hertz(mode: str):
    from twoscale import Material
    from twoscale.grid import Grid
    from twoscale.indenters import Asperity, surface_on
    from twoscale.influence import HalfSpace
    from twoscale.reference import solve_cg

    big = mode.startswith("big")
    mode = mode.removeprefix("big")
    g = Grid.covering(-1.2, 1.2, -1.2, 1.2, 2.4 / (480 if big else 160))
    tips = [Asperity(0.0, 0.0, 0.0, 10.0)] + ([Asperity(0.5, 0.3, 0.01, 6.0)] if mode == "tilt" else [])
    kw = {
        "load": dict(total_load=5.0),
        "pen": dict(penetration=0.08),
        "mixedpc": dict(total_load=5.0, precision="mixed", precondition=True),
        "tilt": dict(total_load=5.0, tilt=True, pivot=(0.1, -0.05)),
    }[mode]
    surf = surface_on(g, tips)
    hs = HalfSpace(Material(10.0, 0.5))
    return lambda: solve_cg(hs, surf, **kw)


def _solve_scene():
    try:
        from twoscale.api import solve_scene
    except ImportError:  # trees before the scene solve moved to the API module
        from twoscale.scene import solve_scene
    return solve_scene


def _solve_twoscale():
    try:
        from twoscale.driver import solve_twoscale
    except ImportError:  # trees before the driver's module was named for what it holds
        from twoscale.twoscale import solve_twoscale
    return solve_twoscale


def _stack(which: str):
    from twoscale import Material
    from twoscale.indenters import Asperity
    from twoscale.influence import HalfSpace
    from twoscale.micro import pk_stack

    solve_twoscale = _solve_twoscale()
    rng = np.random.default_rng(4)
    pts: list = []
    while len(pts) < 80:
        c = rng.uniform(0.0, 30.0, 2)
        if not pts or np.min(np.hypot(*(np.array(pts) - c).T)) >= 1.5:
            pts.append(c)
    R, z = rng.uniform(2.0, 6.0, 80), rng.uniform(0.0, 0.06, 80)
    asp = [Asperity(float(x), float(y), float(zz), float(r)) for (x, y), zz, r in zip(pts, z, R)]
    hs = HalfSpace(Material(10.0, 0.5))
    if which == "single":
        pk_stack.BlockStacks.usable = staticmethod(lambda provider: False)
    return lambda: solve_twoscale(
        hs, asp, h=0.04, total_load=4.0, tol=1e-8, max_sweeps=200, far_tol=0.05, coarse=True, dense_max_cells=60
    )


def _family(name: str, method: str = "twoscale"):
    solve_scene = _solve_scene()
    from twoscale.synthetic import scene_family

    kind, control, shape, n = name.split("-")
    ((_, scene),) = dict(scene_family((int(n),), kinds=(kind,), controls=(control,), shapes=(shape,))).items()
    return lambda: solve_scene(scene, method=method)


def _space(index: str):
    from twoscale import scenespace

    solve_scene = _solve_scene()
    scene = scenespace.build(scenespace.draw(int(index), 0, max_tips=300, maps=0.0, block=0.0))
    return lambda: solve_scene(scene)


def _sweep(index: str, method: str = "twoscale", seed: int = 0):
    """Scene ``index`` of the sweep itself (``scenespace.sweep(200, seed)``: tips, maps, blocks),
    a map's texture written before the clock starts, as the sweep times it."""
    import tempfile

    from twoscale import scenespace
    from twoscale.io.scene_file import scene_from_dict

    solve_scene = _solve_scene()
    (spec,) = [s for s in scenespace.sweep(200, seed) if s.index == int(index)]
    if spec.kind == "tips":
        scene = scenespace.build(spec)
        return lambda: solve_scene(scene, method=method)
    folder = tempfile.mkdtemp()
    table = scenespace.map_table(spec, folder)
    return lambda: solve_scene(scene_from_dict(table, base_dir=folder), method=method)


def _road(spec: str):
    """``SIZE-H-RMIN-RMAX``: the synthetic road of ``benchmarks/surfaces.py`` (seed 1, 0.2 MPa
    nominal), timed as it times the default: the map's segmentation, then the solve."""
    from twoscale import Material
    from twoscale.influence import HalfSpace
    from twoscale.surface import RawMap, SurfaceOptions, build_surface
    from twoscale.surface.texture import road

    solve_twoscale = _solve_twoscale()
    size, h, rmin, rmax = (float(v) for v in spec.split("-"))
    z = road(size, h, seed=1, stone_radius=(rmin, rmax))

    def run():
        surface = build_surface(RawMap(z, h, "mm", None, "synthetic road"), SurfaceOptions())
        return solve_twoscale(HalfSpace(Material(10.0, 0.5)), surface.asperities, h=h, total_load=0.2 * size**2)

    return run


def _file(path: str, method: str = "twoscale"):
    from twoscale.io.scene_file import read_scene

    solve_scene = _solve_scene()
    scene = read_scene(path)
    return lambda: solve_scene(scene, method=method)


CASES = {
    "hertz": _hertz,
    "stack": _stack,
    "family": _family,
    "space": _space,
    "file": _file,
    "road": _road,
    "sweep": _sweep,
    "sweep_ref": lambda index: _sweep(index, "reference"),
    "family_ref": lambda name: _family(name, "reference"),
    "file_ref": lambda path: _file(path, "reference"),
}
# sweepN:I / sweepN_ref:I: the draws of --seed N
CASES.update({f"sweep{n}": (lambda index, n=n: _sweep(index, seed=n)) for n in range(1, 12)})
CASES.update({f"sweep{n}_ref": (lambda index, n=n: _sweep(index, "reference", seed=n)) for n in range(1, 12)})


def _solver_imports() -> None:
    """The solvers' own modules and the block's imported before the clock starts, as
    ``benchmarks/sweep.py`` times a solve (:func:`_common.import_solver_modules`): their
    compilation in the timed call pulled a road's ratio towards 1 (0.43 against the
    sweep's 0.36 on seed 1's #193)."""
    import_solver_modules()


def timed(case: str):
    """``case`` (``KIND:ARG``, a file case's path made absolute) solved once with its warnings
    silenced: ``(result, CPU seconds)``; the caller imports the solvers first."""
    kind, arg = case.split(":", 1)
    run = CASES[kind](os.path.abspath(arg) if kind.startswith("file") else arg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.process_time()
        result = run()
        return result, time.process_time() - t0


def child(kind: str, arg: str) -> None:
    """Run one case with the twoscale on ``sys.path``; print one JSON line."""
    _solver_imports()
    run = CASES[kind](arg)
    t0 = time.process_time()
    res = run()
    cpu = time.process_time() - t0
    digest = hashlib.sha256(b"".join(np.ascontiguousarray(f.pressure).tobytes() for f in res.fields)).hexdigest()
    forces = [] if res.asperities is None else np.asarray(res.asperities.forces, dtype=float).tolist()
    print(
        json.dumps(
            {
                "cpu": cpu,
                "digest": digest[:16],
                "converged": bool(res.converged),
                "forces": forces,
                "iterations": {k: int(v) for k, v in res.iterations.items()},
            }
        )
    )


def compare(case: str, trees: dict, repeat: int) -> dict:
    kind, arg = case.split(":", 1)
    if kind.startswith("file"):
        arg = os.path.abspath(arg)
    runs: dict = {"before": [], "after": []}
    for r in range(repeat):
        for tag in ("before", "after") if r % 2 == 0 else ("after", "before"):
            env = dict(os.environ, PYTHONPATH=trees[tag], OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
            out = subprocess.run(
                [sys.executable, os.path.abspath(__file__), "--child", kind, arg],
                env=env,
                capture_output=True,
                text=True,
                check=True,
            )
            runs[tag].append(json.loads(out.stdout.strip().splitlines()[-1]))
    b, a = runs["before"][0], runs["after"][0]
    fb, fa = np.array(b["forces"]), np.array(a["forces"])
    return {
        "case": case,
        "cpu_before": statistics.median(x["cpu"] for x in runs["before"]),
        "cpu_after": statistics.median(x["cpu"] for x in runs["after"]),
        "ratio": statistics.median(y["cpu"] / x["cpu"] for x, y in zip(runs["before"], runs["after"])),
        "bit_identical": b["digest"] == a["digest"],
        "force_diff": float(np.max(np.abs(fb - fa)) / max(np.abs(fb).max(), 1e-300)) if fb.size else 0.0,
        "iterations": [b["iterations"], a["iterations"]],
        "converged": [b["converged"], a["converged"]],
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*")
    parser.add_argument("--before", help="source tree (holding twoscale/) before the change")
    parser.add_argument("--after", default=".", help="source tree after the change (default: .)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--child", nargs=2, metavar=("KIND", "ARG"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(*args.child)
        return 0
    if not args.before or not args.cases:
        parser.error("give --before TREE and at least one case")
    trees = {"before": os.path.abspath(args.before), "after": os.path.abspath(args.after)}
    for case in args.cases:
        print(json.dumps(compare(case, trees, args.repeat)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
