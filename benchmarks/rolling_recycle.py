"""Two preconditioning levers on a steady rolling position weighed on its own linear system:
the last position's search space deflated from the CG (Krylov recycling), and one inverse of
the window built once for the run instead of the stones' blocks.

The section of ``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip seal at
0.25 mm, 1 mm steps) is rolled on the window path, single-threaded. At each position from the
fourth on, after its solve, the answer's contact ``C`` is held fixed and the linear system
``A_CC x = b`` (``b = (A p)_C``, ``p`` the answer: its solution is known) is solved from the
position's own start (clipped, on ``C``, scaled to the load) by preconditioned CG in float64,
until the residual's largest entry is below ``--tol`` of ``b``'s (the position's stopping
test is the KKT residual at 1e-8 of the largest displacement), with:

* ``blocks``: the position's stone blocks (the code's preconditioner);
* ``deflated``: the same, deflated by the last position's search directions moved with the
  road and restricted to ``C`` (Saad, Yeung, Erhel and Guyomarc'h 2000, SIAM J. Sci. Comput.
  21, 1909, Algorithm 3.6: the start corrected by the Galerkin projection on ``W``, each
  direction made ``A``-orthogonal to ``W``); ``A W`` by float64 products, outside the count
  (in a solver they cost a product each, or the last ones moved where the columns allow);
* ``circulant``: the window's circulant inverse (built once for the run: the window does not
  move in the body frame), restricted to ``C``;
* ``tiles``: the window cut into squares of ``--tile`` cells a side, the inverse of the
  operator on one whole square (the same for all: the half-space is translation-invariant;
  built once for the run) applied to each square's rows and restricted to ``C``;
* ``diagonal``: the kernel's diagonal (a floor).

The active set is held, so the counts are below the position's own (its contact settles
too): they compare with each other. Printed per position and as means.

Usage::

    PYTHONPATH=. python benchmarks/rolling_recycle.py [--length 24] [--tol 1e-8] [--most 80] [--tile 8]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402
from rolling_levers import on_grid, record_search_directions  # noqa: E402

import numpy as np  # noqa: E402

import twoscale.reference.cg as cg_module  # noqa: E402
from twoscale.rolling import run  # noqa: E402
from twoscale.rolling.boxes import moved  # noqa: E402

#: Positions rolled before the counts start.
SKIP = 3
VARIANTS = ("blocks", "deflated", "circulant", "tiles", "diagonal")


def pcg(apply, b: np.ndarray, x0: np.ndarray, precondition, tol: float, most: int, w=None) -> float:
    """Iterations of (deflated, with the rows of ``w``) preconditioned CG on ``apply(x) = b``
    from ``x0`` until ``max|r| <= tol max|b|``, interpolated in the residual's logarithm over
    the last iteration (a finer measure than the count); ``most + 1`` when not within
    ``most``."""
    x = x0.copy()
    if w is not None:
        aw = np.array([apply(v) for v in w])
        gram = w @ aw.T
        solve = np.linalg.pinv(gram, rcond=1e-10, hermitian=True)
        x += w.T @ (solve @ (w @ (b - apply(x))))  # the start's Galerkin correction on W
    r = b - apply(x)
    goal = tol * np.abs(b).max()
    z = precondition(r)
    d = z if w is None else z - w.T @ (solve @ (aw @ z))
    rz = float(r @ z)
    before = np.abs(r).max()
    for k in range(most + 1):
        now = np.abs(r).max()
        if now <= goal:
            return k if k == 0 else k - 1 + np.log(before / goal) / np.log(before / now)
        before = now
        ad = apply(d)
        alpha = rz / float(d @ ad)
        x += alpha * d
        r -= alpha * ad
        z = precondition(r)
        rz, old = float(r @ z), rz
        d = (rz / old) * d + z
        if w is not None:
            d -= w.T @ (solve @ (aw @ z))
    return most + 1


class RecycleProbe:
    """Per position, the fixed-contact systems of the module docstring solved four ways."""

    def __init__(self, tol: float, most: int, tile: int):
        self.tol, self.most, self.tile, self.shift, self.solve = tol, most, tile, 0.0, cg_module.solve_cg
        self.steps, self.last, self.rows = [], None, []
        record_search_directions(self)

    def solve_cg(self, body, surface, **kw):
        grid, start, reach = surface.grid, kw.get("start"), kw.get("reach")
        self.steps = []
        result = self.solve(body, surface, **kw)
        if start is None or not result.fields or result.fields[0].grid != grid or kw.get("preconditioner") is None:
            self.last = None
            return result
        cells = np.flatnonzero(reach.ravel() & np.isfinite(surface.height).ravel()) if reach is not None else None
        directions = [on_grid(t, cells, grid) for t in self.steps]
        if self.last is not None:
            self.rows.append(self._counts(body, surface, kw["preconditioner"], start, result.fields[0].pressure))
        self.last = (grid, self.shift, directions)
        return result

    def _counts(self, body, surface, factory, start: np.ndarray, p: np.ndarray) -> tuple:
        grid = surface.grid
        on = p > 0.0
        exact = body.grid_operator(grid).single_precision().exact

        def apply(x: np.ndarray) -> np.ndarray:
            full = np.zeros(grid.shape)
            full[on] = x
            return exact(full)[on].copy()

        b = apply(p[on])
        x0 = np.maximum(np.where(np.isfinite(surface.height), start, 0.0), 0.0)[on]
        x0 *= p.sum() / x0.sum()
        blocks = factory(surface)
        circulant = body.grid_operator(grid).preconditioner()

        def by_blocks(r: np.ndarray) -> np.ndarray:
            full = np.zeros(grid.shape)
            full[on] = r
            return blocks.apply(full, on)[on]

        def by_circulant(r: np.ndarray) -> np.ndarray:
            full = np.zeros(grid.shape)
            full[on] = r
            return circulant.apply(full)[on]

        diagonal = float(exact(_unit(grid))[grid.ny // 2, grid.nx // 2])
        by_tiles = _tiles(body.grid_operator(grid).op.offset_table(), grid, on, self.tile)
        g, shift, directions = self.last
        w = np.array([moved(g, t, shift, grid, self.shift)[on] for t in directions])
        w = w[np.linalg.norm(w, axis=1) > 0.0]
        counts = {
            "blocks": pcg(apply, b, x0, by_blocks, self.tol, self.most),
            "deflated": pcg(apply, b, x0, by_blocks, self.tol, self.most, w=w) if len(w) else -1,
            "circulant": pcg(apply, b, x0, by_circulant, self.tol, self.most),
            "tiles": pcg(apply, b, x0, by_tiles, self.tol, self.most),
            "diagonal": pcg(apply, b, x0, lambda r: r / diagonal, self.tol, self.most),
        }
        return counts, len(w), int(on.sum())


def _tiles(table: np.ndarray, grid, on: np.ndarray, n: int):
    """The ``tiles`` preconditioner on the rows of ``on`` (module docstring): ``table`` the
    operator's offsets (offset 0 at ``(ny - 1, nx - 1)``), squares of ``n`` cells a side."""
    i, j = (a.ravel() for a in np.mgrid[0:n, 0:n])
    inverse = np.linalg.inv(table[grid.ny - 1 + i[:, None] - i[None, :], grid.nx - 1 + j[:, None] - j[None, :]])
    ty, tx = -(-grid.ny // n), -(-grid.nx // n)

    def apply(r: np.ndarray) -> np.ndarray:
        full = np.zeros((ty * n, tx * n))
        full[: grid.ny, : grid.nx][on] = r
        squares = full.reshape(ty, n, tx, n).transpose(0, 2, 1, 3).reshape(-1, n * n)
        out = (squares @ inverse.T).reshape(ty, tx, n, n).transpose(0, 2, 1, 3).reshape(ty * n, tx * n)
        return out[: grid.ny, : grid.nx][on]

    return apply


def _unit(grid) -> np.ndarray:
    out = np.zeros(grid.shape)
    out[grid.ny // 2, grid.nx // 2] = 1.0
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--length", type=float, default=24.0, help="run length, mm")
    p.add_argument("--tol", type=float, default=1e-8, help="the residual's largest entry over b's at the stop")
    p.add_argument("--most", type=int, default=80, help="most iterations of a variant")
    p.add_argument("--tile", type=int, default=8, help="the tiles' side, cells")
    args = p.parse_args()
    track, options, state = rolling_benchmark.tyre_window(args.length)
    probe = RecycleProbe(args.tol, args.most, args.tile)
    cg_module.solve_cg = probe.solve_cg
    last = None
    its = []
    for k in range(len(track.shifts)):
        probe.shift = float(track.shifts[k])
        last = run.step(track, k, last, options, state)
        its.append(last.result.iterations.get("cg", -1))
    rows = probe.rows[SKIP:]
    for counts, n, cells in rows:
        print(f"  C {cells} cells, W {n} vectors: " + ", ".join(f"{v} {counts[v]:.2f}" for v in VARIANTS))
    means = {v: np.mean([r[0][v] for r in rows]) for v in VARIANTS}
    print(
        f"{len(rows)} positions, the contact held: PCG iterations a position, means: "
        + ", ".join(f"{v} {means[v]:.2f}" for v in VARIANTS)
        + f"; the positions' own CG iterations {np.mean(its[SKIP + 2 :]):.2f}"
    )


if __name__ == "__main__":
    main()
