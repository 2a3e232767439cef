"""Where one solve's CPU time goes, stage by stage, in fresh processes without a profiler.

Each case (``benchmarks/ab_trees.py``'s: ``sweep1:193``, ``sweep1_ref:193``, ``road:...``,
``file:...``) runs ``--repeat`` times, each in a fresh single-threaded process whose solvers'
modules are imported before the clock starts (as the sweep times a solve). Named calls are
wrapped by process-time timers (``STAGES``: the map's reading and segmentation, the body's
build, the macro step (its matrix-free interaction, stability check and operator error
check), the patches (their box's sampling), the bulge check, the union CG and its kernel,
the operator and its transforms); one JSON
line per run gives the case, the solve's CPU seconds, its iterations and, per stage, the
calls and their CPU seconds (a stage's time includes the stages it calls).

``cProfile`` is not used: it made the per-stone Python of a map's set-up 3-5 times dearer
and moved the shares. The timers cost a few microseconds a call (about 200 calls a road).

Usage::

    python benchmarks/stage_split.py --repeat 2 sweep1:193 sweep1_ref:193
"""

from __future__ import annotations

import argparse
import functools
import importlib
import json
import os
import subprocess
import sys
import time

#: (module, attribute[, label]) of the calls timed; ``Class.method`` for methods; a label sums
#: several calls under one name.
STAGES = (
    ("twoscale.io.scene_file", "scene_from_dict"),
    ("twoscale.surface.measured", "condition"),
    ("twoscale.surface.measured", "segment"),
    ("twoscale.surface.segmentation", "_watershed"),
    ("twoscale.surface.measured", "map_asperities"),
    ("twoscale.scene", "Scene.provider"),
    ("twoscale.driver", "macro_step"),
    ("twoscale.macro.solve", "_matrix_free_interaction"),
    ("twoscale.macro.system", "MacroSystem.stable"),
    ("twoscale.macro.solve", "sampled_operator_error"),
    ("twoscale.driver", "run_micro"),
    ("twoscale.micro.driver", "one_asperity_patches"),
    ("twoscale.micro.sampling", "box_surface"),
    ("twoscale.micro.sampling", "patch_grids"),
    ("twoscale.bulge_rounds", "lifted_among", "bulge check"),
    ("twoscale.bulge", "lifted_tips", "bulge check"),
    ("twoscale.micro.strategies", "solve_union"),
    ("twoscale.reference", "solve_reference"),
    ("twoscale.reference.cg", "solve_cg"),
    ("twoscale.influence.halfspace", "HalfSpace.grid_operator"),
    ("fem_influence.provider", "BlockProvider.grid_operator"),
    ("twoscale.influence.convolution", "ConvolutionOperator.offset_table"),
    ("twoscale.reference.cg", "pk_solve"),
    ("twoscale.pk.iteration", "Iteration.check"),
    ("twoscale.pk.iteration", "Iteration.direction"),
    ("twoscale.pk.iteration", "Iteration.refresh"),
    ("twoscale.influence.on_cells", "CellProduct.forward"),
    ("twoscale.influence.on_cells", "CellProduct.finish"),
    ("twoscale.influence.on_cells", "CellProduct.energy"),
    ("twoscale.pk.products", "_Modelled.energy"),
    ("twoscale.influence.circulant", "CirculantInverse.energy_on_cells"),
    ("twoscale.influence.convolution", "ConvolutionOperator.apply"),
    ("twoscale.influence.convolution", "_SingleConvolution.exact"),
    ("twoscale.influence.convolution", "_SingleConvolution._spectrum_in_place"),
    ("twoscale.influence.convolution", "_SingleConvolution._back_in_place"),
    ("twoscale.influence.circulant", "CirculantInverse._pruned"),
    ("twoscale.influence.on_cells", "parseval_sum"),
    # pocketfft's calls alone, by the module that makes them (the kernel's time outside
    # them is ``pk_solve`` less these, where the CG runs on the float32 operator)
    ("twoscale.influence.convolution", "rfft_into", "padded FFTs"),
    ("twoscale.influence.convolution", "fft_in_place", "padded FFTs"),
    ("twoscale.influence.convolution", "irfft_into", "padded FFTs"),
    ("twoscale.influence.circulant", "rfft_into", "torus FFTs"),
    ("twoscale.influence.circulant", "fft_in_place", "torus FFTs"),
    ("twoscale.influence.circulant", "irfft_into", "torus FFTs"),
)


def _wrap(totals: dict, module: str, attribute: str, label: str | None = None) -> None:
    """Time ``module.attribute`` into ``totals[label or attribute]`` = [calls, CPU s] (absent:
    skipped; calls wrapped under one label add up)."""
    try:
        owner = importlib.import_module(module)
    except ImportError:
        return
    *path, name = attribute.split(".")
    for part in path:
        owner = getattr(owner, part, None)
    call = getattr(owner, name, None) if owner is not None else None
    if call is None:
        return

    @functools.wraps(call)
    def timed(*args, **kwargs):
        t0 = time.process_time()
        try:
            return call(*args, **kwargs)
        finally:
            entry = totals.setdefault(label or attribute, [0, 0.0])
            entry[0] += 1
            entry[1] += time.process_time() - t0

    setattr(owner, name, timed)


def child(case: str) -> dict:
    """One run of ``case`` in this process (the tree on ``sys.path``)."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import ab_trees

    ab_trees._solver_imports()
    totals: dict = {}
    for stage in STAGES:
        _wrap(totals, *stage)
    res, cpu = ab_trees.timed(case)
    stages = {k: [n, round(s, 4)] for k, (n, s) in totals.items()}
    return {"case": case, "cpu": round(cpu, 4), "iterations": {k: int(v) for k, v in res.iterations.items()}, **stages}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.cases[0])))
        return 0
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    for _ in range(args.repeat):
        for case in args.cases:
            out = subprocess.run(
                [sys.executable, os.path.abspath(__file__), "--child", case],
                env=env,
                capture_output=True,
                text=True,
                check=True,
            )
            print(out.stdout.strip().splitlines()[-1], flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
