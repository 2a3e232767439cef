"""What a better start could save a rolling position, at most: the window path's start mixed with
the position's own answer.

The section of ``benchmarks/rolling.py``'s tyre (R 300 mm, 150 mm wide, 3 kN, chip seal at
0.25 mm, 1 mm steps) is rolled once as the window path rolls it, keeping every position's
answer; then once more, each position from the third on started from the extrapolated start
(:meth:`twoscale.rolling.window.WindowState.start`) with part of it replaced by that
position's answer (``--mix``):

* ``ring``: the answer on each contact's outer ring (loaded cells with an unloaded
  neighbour) and on the cells whose state (loaded or not) the start has wrong;
* ``ring2``: the same two cells deep;
* ``set``: the answer's contact set with the start's values: the start's cells the answer
  leaves unloaded set to 0;
* ``entries``: only those of them the last position did not load (foreseen entries that
  stay out);
* ``leaving``: only those the last position loaded;
* ``new``: the answer on the contacts that enter (the islands of cells the start or the
  answer loads with no cell the last position loaded: a stone coming into contact).

Printed per position: the start's relative L2 error against the answer before and after the
mix, the cells the start has loaded that the answer does not (split as above), and the CG
iterations of the first and the second run (deterministic: a start predictor can be scored
by them without timing). Single-threaded.

Usage::

    PYTHONPATH=. python benchmarks/rolling_start_oracle.py [--length 14] [--mix set]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

import numpy as np  # noqa: E402
from scipy import ndimage  # noqa: E402

import twoscale  # noqa: E402
from twoscale.rolling import RollingOptions  # noqa: E402
from twoscale.rolling.boxes import moved  # noqa: E402
from twoscale.rolling.run import step, window_state  # noqa: E402
from twoscale.rolling.track import prepare  # noqa: E402
from twoscale.rolling.window import WindowState  # noqa: E402

MIXES = ("none", "ring", "ring2", "set", "entries", "leaving", "new")


@dataclasses.dataclass
class MixedStart(WindowState):
    """The window path's state whose start from the third position on is mixed with the
    position's answer (``answers[k]``: grid, pressure) by ``mix`` (module docstring)."""

    answers: list = dataclasses.field(default_factory=list)
    mix: str = "none"
    index: int = 0
    rows: list = dataclasses.field(default_factory=list)

    def start(self, grid, shift, pc=None, one=None):
        s = super().start(grid, shift, pc, one)
        if s is None or len(self.past) < 2:
            return s
        last = self.last_moved(grid, shift) if one is None else one
        answer = moved(*self.answers[self.index], 0.0, grid, 0.0)
        on = answer > 0.0
        wrong = (s > 0.0) & ~on
        depth = 2 if self.mix == "ring2" else 1
        ring = (on & ~ndimage.binary_erosion(on, np.ones((3, 3)), iterations=depth)) | ((s > 0.0) != on)
        islands, _ = ndimage.label(on | (s > 0.0))
        old = np.unique(islands[(last > 0.0) & (islands > 0)])
        new = (islands > 0) & ~np.isin(islands, old)
        mixed = {
            "new": np.where(new, answer, s),
            "none": s,
            "ring": np.where(ring, answer, s),
            "ring2": np.where(ring, answer, s),
            "set": np.where(wrong, 0.0, s),
            "entries": np.where(wrong & (last <= 0.0), 0.0, s),
            "leaving": np.where(wrong & (last > 0.0), 0.0, s),
        }[self.mix]
        norm = np.linalg.norm(answer)
        errors = (np.linalg.norm(s - answer) / norm, np.linalg.norm(mixed - answer) / norm)
        self.rows.append((self.index, *errors, int(np.sum(wrong & (last <= 0.0))), int(np.sum(wrong & (last > 0.0)))))
        return mixed


def roll(track, state) -> list:
    """The section's positions on ``state``: (answer grid, pressure, CG iterations) each."""
    options, last, out = RollingOptions(), None, []
    for k in range(len(track.shifts)):
        if isinstance(state, MixedStart):
            state.index = k
        last = step(track, k, last, options, state)
        f = last.result.fields[0]
        out.append((f.grid, f.pressure.copy(), last.result.iterations.get("cg", -1)))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--length", type=float, default=14.0, help="run length, mm")
    p.add_argument("--mix", choices=MIXES, default="set", help="what of the answer the start takes")
    args = p.parse_args()
    scene, _ = rolling_benchmark.tyre_scene(twoscale, args.length)
    track = prepare(scene)
    plain = roll(track, window_state(track, RollingOptions()))
    base = window_state(track, RollingOptions())
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(WindowState)}
    state = MixedStart(**fields, answers=[(g, pr) for g, pr, _ in plain], mix=args.mix)
    mixed = roll(track, state)
    print("position, start's L2 error before / after the mix, wrong entries, wrong leaving, CG iterations")
    for k, before, after, entries, leaving in state.rows:
        print(f"{k:4d} {before:.2e} / {after:.2e} {entries:5d} {leaving:5d}   {plain[k][2]} -> {mixed[k][2]}")
    its = np.array([[plain[k][2], mixed[k][2]] for k, *_ in state.rows], dtype=float)
    print(f"{args.mix}: CG iterations a position {its[:, 0].mean():.2f} -> {its[:, 1].mean():.2f}")


if __name__ == "__main__":
    main()
