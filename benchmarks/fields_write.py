"""Time to write the fields of a full-grid solve: VTK image data (fields.vtm) per grid size.

``python benchmarks/fields_write.py [--sizes 600 1200] [--tips 25]``

The result is built directly (Hertz-like pressure on one n x n grid of 0.05 mm cells
under a square of spheres), so only the writing is timed: ``write_vtk`` with the
indenter height, as ``twoscale solve --out`` writes it, best of three; then the file is
read back with ``read_vtk`` and compared. docs/outputs.md quotes the 1200 x 1200 line.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import _common  # noqa: E402
import numpy as np  # noqa: E402  (after _common: OpenBLAS reads its thread count when loaded)

from twoscale.grid import Grid  # noqa: E402
from twoscale.indenters import Asperity, surface_on  # noqa: E402
from twoscale.io.vtk import read_vtk, write_vtk  # noqa: E402
from twoscale.results import ContactResult, PressureField, summarise  # noqa: E402


def _result(n: int, tips: int) -> tuple[ContactResult, list]:
    h = 0.05
    half = n * h / 2
    side = int(np.ceil(np.sqrt(tips)))
    pos = np.linspace(-0.8 * half, 0.8 * half, side)
    asps = [Asperity(float(x), float(y), 0.0, 4.0) for y in pos for x in pos][:tips]
    g = Grid(-half + h / 2, -half + h / 2, h, n, n)
    s = surface_on(g, asps)
    depth = np.where(np.isfinite(s.height), 0.2 - s.height, -1.0)
    p = np.sqrt(np.clip(depth, 0.0, None))
    field = PressureField(g, p, s.owner, np.where(np.isfinite(s.height), np.clip(-depth, 0, None), np.inf))
    sm = summarise((field,), len(asps))
    return ContactResult("cg", (field,), 0.2, None, float(sm.forces.sum()), sm, True), asps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[600, 1200], help="grid side, cells")
    ap.add_argument("--tips", type=int, default=25, help="spheres on the grid")
    _common.add_quiet(ap)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp, _common.progress(len(args.sizes), "sizes", args.quiet) as bar:
        for n in args.sizes:
            res, asps = _result(n, args.tips)
            path = pathlib.Path(tmp) / f"f{n}.vtm"
            _, t = _common.best_time(lambda: write_vtk(res, path, asperities=asps), repeat=3)
            back = read_vtk(path)
            same = bool(np.array_equal(back.fields[0].pressure, res.fields[0].pressure))
            size = sum(f.stat().st_size for f in path.with_suffix("").iterdir()) / 1e6
            rows.append({"cells": n * n, "write_s": t, "MB": size, "same": str(same)})
            bar.update()
    _common.print_table(
        rows, [("cells", "cells", "d"), ("write_s", "write s", ".3f"), ("MB", "MB", ".1f"), ("same", "read back", "s")]
    )


if __name__ == "__main__":
    main()
