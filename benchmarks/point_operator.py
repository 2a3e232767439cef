"""Point-operator benchmark: the half-space Ewald operator against the exact dense one.

Scenes, N tips uniformly random in a 300 x 300 mm square (E = 10 MPa, nu = 0.5):

* ``macro``: targets = sources = the N tips (coincident pairs give nothing);
* ``far``: the micro step's far field, 9 stencil points (+-1 mm) around each tip as
  targets (M = 9 N), excluding for each stencil its own tip and the tips within 6 mm.

Per scene and ``rtol``: build time, best apply time for one and three right-hand sides,
the chosen parameters, stored numbers, and the error relative to ``max |u|`` (forces
uniform in [0.1, 1] N) against :class:`DensePointOperator` on every target row for
N <= 1000, on ``--rows`` random rows otherwise (bounded memory). The dense time is per
full product (scaled from the rows computed).

Run: ``python benchmarks/point_operator.py [--sizes 1000 10000] [--rtol 1e-4 1e-6]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import _common  # noqa: F401  (sets single-threaded defaults before numpy loads)
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

try:
    import twoscale  # noqa: F401
except ImportError:  # running from a source checkout without installation
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from twoscale import Material
from twoscale.influence import HalfSpace
from twoscale.influence.halfspace_points import EwaldPointOperator
from twoscale.influence.points import DensePointOperator

from _common import best_time, print_table

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)
SIZE = 300.0  # mm
NEAR = 6.0  # mm, far-field exclusion radius


def scene(kind: str, n: int, rng):
    """(targets, sources, exclude) for the ``macro`` or ``far`` scene with ``n`` tips."""
    tips = rng.uniform(0.0, SIZE, (n, 2))
    if kind == "macro":
        return tips, tips, None
    off = np.array([(dx, dy) for dy in (-1.0, 0.0, 1.0) for dx in (-1.0, 0.0, 1.0)])
    targets = (tips[:, None, :] + off[None]).reshape(-1, 2)
    tree = cKDTree(tips)
    near = tree.sparse_distance_matrix(tree, NEAR, output_type="coo_matrix").tocsr()
    near = (near + sp.identity(n, format="csr")).tocsr()
    return targets, tips, sp.kron(near, np.ones((9, 1)), format="csr")


def bench(kind: str, n: int, rtols, rows: int, repeat: int) -> list[dict]:
    rng = np.random.default_rng(n)
    t, s, exclude = scene(kind, n, rng)
    F = rng.uniform(0.1, 1.0, (n, 3))
    sub = np.arange(len(t)) if len(t) * n <= 4e7 else np.sort(rng.choice(len(t), rows, replace=False))
    dense = DensePointOperator(HS.point_compliance, t[sub], s, None if exclude is None else exclude[sub])
    ref, t_dense = best_time(lambda: dense.apply(F[:, 0]), repeat=1)
    out = []
    for rtol in rtols:
        t0 = time.perf_counter()
        op = EwaldPointOperator(MAT.E_star, t, s, exclude=exclude, rtol=rtol)
        build = time.perf_counter() - t0
        u, t1 = best_time(lambda: op.apply(F[:, 0]), repeat=repeat)
        _, t3 = best_time(lambda: op.apply(F), repeat=repeat)
        err = np.max(np.abs(u[sub] - ref)) / np.max(np.abs(ref))
        p = op.params
        out.append(
            dict(
                scene=kind,
                N=n,
                M=len(t),
                rtol=rtol,
                build=build,
                apply=t1,
                apply3=t3,
                dense=t_dense * len(t) / len(sub),
                err=err,
                order=p.order,
                sigma=p.sigma,
                H=p.spacing,
                rcut=p.r_cut,
                mesh=f"{op.mesh_shape[0]}x{op.mesh_shape[1]}",
                mnnz=op.nnz / 1e6,
                rows=len(sub),
            )
        )
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000], help="tips N (default 1000 10000)")
    parser.add_argument("--rtol", type=float, nargs="+", default=[1e-4, 1e-6], help="accuracies (default 1e-4 1e-6)")
    parser.add_argument("--rows", type=int, default=2000, help="dense reference rows for large N (default 2000)")
    parser.add_argument("--repeat", type=int, default=3, help="apply runs, best time kept (default 3)")
    args = parser.parse_args(argv)
    print(
        f"Point operators, half-space E = {MAT.E} MPa, nu = {MAT.nu}, tips in {SIZE:g} x {SIZE:g} mm; "
        f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}"
    )
    rows = []
    for n in args.sizes:
        for kind in ("macro", "far"):
            rows += bench(kind, n, args.rtol, args.rows, args.repeat)
    print_table(
        rows,
        [
            ("scene", "scene", "s"),
            ("N", "N", "d"),
            ("M", "M", "d"),
            ("rtol", "rtol", ".0e"),
            ("build", "build s", ".3f"),
            ("apply", "apply s", ".4f"),
            ("apply3", "apply(3) s", ".4f"),
            ("dense", "dense s", ".3f"),
            ("err", "error", ".2e"),
            ("rows", "ref rows", "d"),
            ("order", "p", "d"),
            ("sigma", "sigma mm", ".2f"),
            ("H", "H mm", ".3f"),
            ("rcut", "r_cut mm", ".2f"),
            ("mesh", "FFT mesh", "s"),
            ("mnnz", "nnz 1e6", ".2f"),
        ],
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
