"""Two levers on a steady rolling position weighed: the start's product from the last two
displacements moved with the road, and why the stones' blocks are made afresh.

The section of ``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip seal at
0.25 mm, 1 mm steps) is rolled on the window path, single-threaded; positions from the
fourth on are counted.

``--lever start``: the half-space is translation-invariant, so the last two answers'
displacements moved with the road give ``A (2 p_k - p_(k-1))`` (both moved) exactly but on
the columns entering the cut; the start (:meth:`twoscale.rolling.window.WindowState.start`)
differs from that by its correction ``c`` (the cells clipped at 0 and those the extrapolated
gap lets in). Here the kernel's first product (the start's, float32) is replaced by the moved
displacements plus ``A c``: ``--correction product`` (its float64 product), ``local`` (the
kernel's table within ``--radius`` cells of each cell of ``c``), ``none`` (the moved
displacements alone), or ``off`` (the code's own product, for comparison). The columns
entering the cut (8) take the start's exact product in every mode (the moved fields do
not hold them: this favours the lever). The displacements are made by float64 products of
the answers (outside the counted work). Printed per position: the cells of ``c``, its
product's largest value and the moved displacements' error (both over the largest
displacement, on the CG's part), the replaced product's error; then the CG iterations a
position (deterministic), the products, and the last approach.

``--lever blocks``: each stone's block found at a position's build, by how: its cells the
same as its kept inverse's, the same offsets as another's kept one (a whole-cell shift),
updated, or afresh (a stone new to the blocks; a small one, below
:data:`twoscale.rolling.inverses.UPDATE_MIN_CELLS`, by the cells it gained and lost; a large
one changed too much or updated :data:`twoscale.rolling.blocks.MAX_UPDATES` times). Means a
position; ``--step``: the road's step (a step that is not a whole number of cells forgets the
kept inverses at every position, :meth:`twoscale.rolling.blocks.StoneBlocks.at`, and moves
the start to the nearest cell).

``--lever directions``: the share of each position's start error (the answer less the start
scaled to the load) in the energy norm ``e.A e`` that the best combination of the last
position's correction (its answer less its start) moved with the road, of the last
position's search directions moved, or of both could take off (float64 products of the
fields, outside the counted work; the directions on the CG's part).

``--lever correction``: each start plus ``--weight`` times that last correction moved (``best``:
the weight minimising the energy along it, by float64 products outside the counted work),
clipped at 0; the CG iterations a position.

Usage::

    PYTHONPATH=. python benchmarks/rolling_levers.py --lever start [--length 30] [--correction local] [--radius 8]
    PYTHONPATH=. python benchmarks/rolling_levers.py --lever blocks [--length 30] [--step 1.0]
    PYTHONPATH=. python benchmarks/rolling_levers.py --lever directions [--length 30]
    PYTHONPATH=. python benchmarks/rolling_levers.py --lever correction [--length 30] [--weight best]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

import numpy as np  # noqa: E402

import twoscale.reference.cg as cg_module  # noqa: E402
from twoscale.pk import iteration  # noqa: E402
from twoscale.rolling import blocks, inverses, run  # noqa: E402
from twoscale.rolling.boxes import moved  # noqa: E402

#: The cut's columns on the side the road enters from that the moved fields do not hold
#: (two steps of 4 cells).
ENTERING = 8
#: Positions rolled before the counts start.
SKIP = 3


def local_product(c: np.ndarray, grid, table: np.ndarray, radius: int) -> np.ndarray:
    """``A c`` from the kernel's ``table`` (offset 0 at ``(ny - 1, nx - 1)``) within
    ``radius`` cells of each cell of ``c`` (the far field left out)."""
    rows, cols = np.divmod(np.flatnonzero(c), grid.nx)
    dy, dx = (a.ravel() for a in np.mgrid[-radius : radius + 1, -radius : radius + 1])
    ty, tx = rows[:, None] + dy, cols[:, None] + dx
    ok = (ty >= 0) & (ty < grid.ny) & (tx >= 0) & (tx < grid.nx)
    w = c[rows, cols][:, None] * table[grid.ny - 1 + dy, grid.nx - 1 + dx][None, :]
    return np.bincount((ty * grid.nx + tx)[ok], w[ok], minlength=grid.size).reshape(grid.shape)


class StartProbe:
    """The start's product replaced as ``--correction`` says (module docstring)."""

    def __init__(self, state, correction: str, radius: int):
        self.state, self.correction, self.radius = state, correction, radius
        self.shift, self.past, self.pending, self.rows = 0.0, [], {}, []
        self.solve = cg_module.solve_cg
        self.product = iteration.Iteration.product

    def solve_cg(self, body, surface, **kw):
        grid, start, reach = surface.grid, kw.get("start"), kw.get("reach")
        exact = body.grid_operator(grid).single_precision().exact
        self.pending.clear()
        if self.correction != "off" and start is not None and reach is not None and len(self.past) == 2:
            self._replace(body, surface, exact, start, reach)
        result = self.solve(body, surface, **kw)
        if result.fields:
            f = result.fields[0]
            self.past = [*self.past, (f.grid, exact(f.pressure).copy(), self.shift)][-2:]
        return result

    def _replace(self, body, surface, exact, start, reach) -> None:
        grid, (one, two) = surface.grid, (moved(*p, surface.grid, self.shift) for p in self.state.past[-2:][::-1])
        c = start - (2.0 * np.maximum(one, 0.0) - np.maximum(two, 0.0))
        u = 2.0 * moved(*self.past[-1], grid, self.shift) - moved(*self.past[-2], grid, self.shift)
        true, ac = exact(start).copy(), exact(c).copy()
        if self.correction == "product":
            u += ac
        elif self.correction == "local":
            u += local_product(c, grid, body.grid_operator(grid).op.offset_table(), self.radius)
        part = reach & np.isfinite(surface.height)
        part[:, :ENTERING] = False
        scale = np.abs(true[part]).max()
        self.rows.append((np.count_nonzero(c), np.abs(ac[part]).max() / scale, np.abs((u - true)[part]).max() / scale))
        u[:, :ENTERING] = true[:, :ENTERING]
        cells = np.flatnonzero(reach.ravel() & np.isfinite(surface.height).ravel())
        self.pending.update(cells=cells, u=u.ravel()[cells], p=np.maximum(start, 0.0).ravel()[cells])

    def first_product(self, it, v: np.ndarray, fast: bool = False) -> np.ndarray:
        """The kernel's first product (the start's, scaled to the load) replaced."""
        pending, self.pending = self.pending, {}
        if pending and v.shape[1] == len(pending["cells"]):
            factor = float(v[0].sum() / pending["p"].sum())
            if np.allclose(v[0], factor * pending["p"]):
                return (factor * pending["u"])[None]
        return self.product(it, v, fast)


def roll_start(length: float, correction: str, radius: int) -> None:
    """``--lever start``: the positions rolled with the start's product replaced."""
    track, options, state = rolling_benchmark.tyre_window(length)
    probe = StartProbe(state, correction, radius)
    cg_module.solve_cg = probe.solve_cg
    iteration.Iteration.product = lambda it, v, fast=False: probe.first_product(it, v, fast)
    last, its, products = None, [], []
    for k in range(len(track.shifts)):
        probe.shift = float(track.shifts[k])
        last = run.step(track, k, last, options, state)
        if k >= SKIP:
            its.append(last.result.iterations.get("cg", 0))
            products.append(last.result.iterations.get("products", 0))
    for n_c, ac, err in probe.rows:
        print(f"  correction cells {n_c:5d}  |A c| {ac:.2e}  the product replaced, error {err:.1e}")
    print(
        f"{correction} (radius {radius}): {len(its)} positions, CG iterations {np.mean(its):.2f} a position, "
        f"products {np.mean(products):.2f}, last approach {last.result.penetration!r} mm"
    )
    print("  iterations:", " ".join(map(str, its)))


def _reason(blocks_of, stone, keys, found, out) -> str:
    """How :meth:`~twoscale.rolling.blocks.StoneBlocks._known` found ``stone``'s block."""
    if found is not None and found[0].size == keys.size and found[0].tobytes() == keys.tobytes():
        return "the same cells"
    if out[0] is not None:
        kept = blocks_of._kept[stone]
        return "updated" if found is not None and kept[3] == found[3] + 1 else "the same offsets elsewhere"
    if found is None:
        return "afresh: a stone new to the blocks"
    changed = np.setxor1d(keys, found[0]).size
    if min(found[0].size, keys.size) < inverses.UPDATE_MIN_CELLS:
        return f"afresh: small, {min(changed, 4)}{'+' if changed >= 4 else ''} cells gained or lost"
    if found[3] >= blocks.MAX_UPDATES:
        return "afresh: large, updated too often"
    return "afresh: large, changed too much"


def tyre(length: float, step: float) -> tuple:
    """The benchmark's tyre over ``length`` mm in steps of ``step`` mm, ready to roll:
    ``(track, options, state)`` (:func:`rolling.tyre_window`'s, the step given)."""
    if step == 1.0:
        return rolling_benchmark.tyre_window(length)
    import twoscale

    track = rolling_benchmark.prepare(rolling_benchmark.tyre_scene(twoscale, length, step=step)[0])
    options = rolling_benchmark.RollingOptions()
    return track, options, rolling_benchmark.window_state(track, options)


def roll_blocks(length: float, step: float) -> None:
    """``--lever blocks``: the census of the stones' blocks a position, and the CG iterations."""
    track, options, state = tyre(length, step)
    census, sizes, known = Counter(), Counter(), blocks.StoneBlocks._known

    def counted(self, stone, keys, flat, entries, centre, fresh):
        found = self._kept.get(stone)
        out = known(self, stone, keys, flat, entries, centre, fresh)
        reason = _reason(self, stone, keys, found, out)
        census[reason] += 1
        sizes[reason] += keys.size
        return out

    blocks.StoneBlocks._known = counted
    last, n, its = None, 0, 0
    for k in range(len(track.shifts)):
        last = run.step(track, k, last, options, state)
        if k == SKIP - 1:
            census.clear()
            sizes.clear()
        n += k >= SKIP
        its += last.result.iterations.get("cg", 0) if k >= SKIP else 0
    print(f"{n} positions of {step} mm, CG iterations {its / n:.2f} a position")
    print("stones' blocks a position, by how they were found (their mean cells)")
    for reason, count in sorted(census.items(), key=lambda kv: -kv[1]):
        print(f"  {reason:48s} {count / n:7.1f}  ({sizes[reason] / count:.0f})")


def record_search_directions(probe) -> None:
    """Append each CG step's search direction (its first field) to ``probe.steps``, by
    wrapping the kernel's :meth:`Iteration.step` for the rest of the process."""
    step = iteration.Iteration.step

    def recorded(it, *live):
        step(it, *live)
        if len(it.t):
            probe.steps.append(np.array(it.t[0]))

    iteration.Iteration.step = recorded


def on_grid(t: np.ndarray, cells, grid) -> np.ndarray:
    """A field on ``cells`` of ``grid`` (None: every cell) as the grid's whole array."""
    out = np.zeros(grid.size)
    out[slice(None) if cells is None or t.size == grid.size else cells] = t
    return out.reshape(grid.shape)


class DirectionsProbe:
    """Per position, the share of its start's error (in the energy norm) that spans of the
    last position's fields moved with the road could take off (module docstring)."""

    def __init__(self, state):
        self.state, self.shift, self.solve = state, 0.0, cg_module.solve_cg
        self.steps, self.last, self.rows = [], None, []
        record_search_directions(self)

    def solve_cg(self, body, surface, **kw):
        grid, start, reach = surface.grid, kw.get("start"), kw.get("reach")
        self.steps = []
        result = self.solve(body, surface, **kw)
        if start is None or not result.fields or result.fields[0].grid != grid:
            self.last = None
            return result
        p = result.fields[0].pressure
        p0 = np.where(np.isfinite(surface.height), np.maximum(start, 0.0), 0.0)
        p0 *= p.sum() / p0.sum()  # (the kernel's start: scaled to the load)
        cells = np.flatnonzero(reach.ravel() & np.isfinite(surface.height).ravel()) if reach is not None else None
        directions = [on_grid(t, cells, grid) for t in self.steps]
        if self.last is not None:
            self.rows.append(self._shares(body.grid_operator(grid).single_precision().exact, grid, p - p0))
        self.last = (grid, p - p0, self.shift, directions)
        return result

    def _shares(self, exact, grid, error: np.ndarray) -> tuple:
        """The energy shares of ``error`` in the spans of the last correction and the last
        position's search directions, moved with the road."""
        g, e_last, shift, directions = self.last
        last = moved(g, e_last, shift, grid, self.shift)
        dirs = [moved(g, t, shift, grid, self.shift) for t in directions]
        ae = exact(error).copy()
        energy = float(np.vdot(error, ae))

        def share(span: list) -> float:
            a_span = np.array([exact(v).ravel().copy() for v in span])
            v = np.array([s.ravel() for s in span])
            gram, rhs = v @ a_span.T, a_span @ error.ravel()
            alpha = np.linalg.lstsq(gram, rhs, rcond=1e-12)[0]
            return float(rhs @ alpha) / energy

        return share([last]), share(dirs), share(dirs + [last]), len(dirs)


def roll_directions(length: float) -> None:
    """``--lever directions``: the energy shares a position."""
    track, options, state = rolling_benchmark.tyre_window(length)
    probe = DirectionsProbe(state)
    cg_module.solve_cg = probe.solve_cg
    last = None
    for k in range(len(track.shifts)):
        probe.shift = float(track.shifts[k])
        last = run.step(track, k, last, options, state)
    rows = probe.rows[SKIP:]
    for one, dirs, both, n in rows:
        print(f"  the last correction {one:.3f}  the last {n} directions {dirs:.3f}  both {both:.3f}")
    one, dirs, both = (np.mean([r[i] for r in rows]) for i in range(3))
    print(
        f"{len(rows)} positions: energy shares, means: the last correction {one:.3f}, directions {dirs:.3f}, both {both:.3f}"
    )


class CorrectedStart:
    """Each start from the fourth position on plus ``weight`` times the last position's
    correction (its answer less its start scaled to the load) moved with the road, the weight
    ``best`` minimising the energy along it (float64 products), then clipped at 0."""

    def __init__(self, weight: str):
        self.weight, self.shift, self.last, self.weights = weight, 0.0, None, []
        self.solve = cg_module.solve_cg

    def solve_cg(self, body, surface, **kw):
        grid, start, reach = surface.grid, kw.get("start"), kw.get("reach")
        material = np.isfinite(surface.height)
        if start is not None and self.last is not None:
            e = np.where(material, moved(*self.last, grid, self.shift), 0.0)
            w = self._weight(body.grid_operator(grid).single_precision().exact, surface.height, start, e)
            self.weights.append(w)
            kw["start"] = np.where(start == 0.0, 0.0, np.maximum(start + w * e, 0.0))
            kw["reach"] = None if reach is None else reach | (kw["start"] > 0.0)
        result = self.solve(body, surface, **kw)
        self.last = None
        if start is not None and result.fields and result.fields[0].grid == grid:
            p = result.fields[0].pressure
            p0 = np.where(material, np.maximum(start, 0.0), 0.0)
            self.last = (grid, p - p0 * (p.sum() / p0.sum()), self.shift)
        return result

    def _weight(self, exact, height, start, e) -> float:
        if self.weight != "best":
            return float(self.weight)
        on = np.isfinite(height)
        gradient = exact(np.where(on, np.maximum(start, 0.0), 0.0)).copy() + np.where(on, height, 0.0)
        e = e - np.where(on, e.sum() / np.count_nonzero(on), 0.0)  # (the load's direction out)
        return float(-np.vdot(e, gradient) / np.vdot(e, exact(e)))


def roll_corrected(length: float, weight: str) -> None:
    """``--lever correction``: the CG iterations with the corrected starts."""
    track, options, state = rolling_benchmark.tyre_window(length)
    probe = CorrectedStart(weight)
    cg_module.solve_cg = probe.solve_cg
    last, its = None, []
    for k in range(len(track.shifts)):
        probe.shift = float(track.shifts[k])
        last = run.step(track, k, last, options, state)
        its.append(last.result.iterations.get("cg", 0)) if k >= SKIP else probe.__setattr__("last", None)
    w = np.array(probe.weights)
    print(f"weight {weight}: {len(its)} positions, CG iterations {np.mean(its):.2f} a position", end="")
    print(f" (weights {w.min():.2f}-{w.max():.2f}, median {np.median(w):.2f})" if w.size else "")
    print("  iterations:", " ".join(map(str, its)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--lever", choices=("start", "blocks", "directions", "correction"), required=True)
    p.add_argument("--length", type=float, default=30.0, help="run length, mm")
    p.add_argument("--correction", choices=("off", "product", "local", "none"), default="local")
    p.add_argument("--radius", type=int, default=8, help="cells of the local correction's stencil")
    p.add_argument("--weight", default="best", help="the last correction's weight, or best (--lever correction)")
    p.add_argument("--step", type=float, default=1.0, help="the road's step, mm (--lever blocks)")
    args = p.parse_args()
    if args.lever == "start":
        roll_start(args.length, args.correction, args.radius)
    elif args.lever == "blocks":
        roll_blocks(args.length, args.step)
    elif args.lever == "directions":
        roll_directions(args.length)
    else:
        roll_corrected(args.length, args.weight)


if __name__ == "__main__":
    main()
