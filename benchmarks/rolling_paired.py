"""Rolling before/after in one process: the tyre's positions stepped by two source trees in turn.

On a shared host two runs of ``benchmarks/rolling.py`` minutes apart differ by ±15 % (the
load moves), more than a change of a few per cent to a position. Here both trees solve the
same section in one process: the ``--before`` tree's package is copied, renamed
``twoscale_before`` (its own names rewritten), into a temporary directory and imported beside
this one's (``twoscale`` as found on ``PYTHONPATH``), each with its own strip, track and run
state (:func:`twoscale.rolling.run.window_state`), and each position is solved by one tree
then the other (which goes first alternates from position to position; ``--before-first``
gives the first position to the before tree), its CPU time taken around
:func:`~twoscale.rolling.run.step`. The load of the moment falls on both alike.

Printed: each position's CPU time after / before, the median and 90th percentile of the
positions after the first, the median of the per-position ratios, the first and second
positions, how the two trees' times of a position correlate (the host's moment, which both
share, against what is the position's own), and the answers' agreement (largest approach and drag difference, areas and CG
iterations equal). The first position of the process pays the FFT plans and first pages: it
compares only with ``--before-first`` and without it, averaged.

The scene is ``benchmarks/rolling.py``'s (R 300 mm, 150 mm wide, 3 kN, chip seal at 0.25 mm,
1 mm steps). Single-threaded.

Usage::

    git archive OLD_COMMIT | tar -x -C /tmp/before
    PYTHONPATH=. python benchmarks/rolling_paired.py --before /tmp/before [--length 20] [--before-first]
"""

from __future__ import annotations

import argparse
import importlib
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401,I001
import rolling as rolling_benchmark  # noqa: E402

import numpy as np  # noqa: E402

RENAMED = "twoscale_before"


def copy_renamed(tree: Path, into: Path) -> None:
    """``tree``'s package as ``RENAMED`` under ``into``, its absolute names rewritten (the
    package imports itself relatively; the lazy attributes and providers name it in strings)."""
    target = into / RENAMED
    shutil.copytree(tree / "twoscale", target)
    word = re.compile(r"(?<![\w.])twoscale(?=[.\s]|$)", re.MULTILINE)
    for path in target.rglob("*.py"):
        text = path.read_text()
        path.write_text(word.sub(RENAMED, text))


def section(name: str, length: float) -> dict:
    """The run state of package ``name`` on the benchmark's scene (``length`` mm of run)."""
    scene, _ = rolling_benchmark.tyre_scene(importlib.import_module(name), length)
    run = importlib.import_module(name + ".rolling.run")
    track = importlib.import_module(name + ".rolling.track").prepare(scene)
    options = importlib.import_module(name + ".rolling").RollingOptions()
    return {"run": run, "track": track, "options": options, "state": run.window_state(track, options), "last": None}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", required=True, help="the before source tree (a directory holding twoscale/)")
    p.add_argument("--length", type=float, default=20.0, help="run length, mm")
    p.add_argument("--before-first", action="store_true", help="the before tree solves the first position first")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        copy_renamed(Path(args.before), Path(tmp))
        sys.path.insert(0, tmp)
        importlib.import_module("twoscale.cli.heap").keep_heap()
        runs = {"after": section("twoscale", args.length), "before": section(RENAMED, args.length)}
        cpu: dict = {w: [] for w in runs}
        out: dict = {w: [] for w in runs}
        for k in range(len(runs["after"]["track"].shifts)):
            order = ("after", "before") if (k + args.before_first) % 2 == 0 else ("before", "after")
            for w in order:
                r = runs[w]
                c0 = time.process_time()
                r["last"] = r["run"].step(r["track"], k, r["last"], r["options"], r["state"])
                cpu[w].append(time.process_time() - c0)
                res = r["last"].result
                out[w].append((res.penetration, res.contact_area, r["last"].drag, res.iterations.get("cg", -1)))
    a, b = np.array(cpu["after"]), np.array(cpu["before"])
    print("per position after / before, s of CPU:", " ".join(f"{x:.3f}/{y:.3f}" for x, y in zip(a, b)))
    for w, t in (("after", a), ("before", b)):
        print(
            f"{w}: first {t[0]:.3f} s, second {t[1]:.3f} s; after the first: median {np.median(t[1:]):.4f} s, "
            f"90th percentile {np.percentile(t[1:], 90):.4f} s, mean {t[1:].mean():.4f} s"
        )
    print(
        f"after / before: median of the positions' ratios {np.median(a[1:] / b[1:]):.3f}, "
        f"first {a[0] / b[0]:.3f}, second {a[1] / b[1]:.3f}"
    )
    if len(a) > 3:  # what the positions' spread owes to the host's moment, which both trees share
        ratio = a[1:] / b[1:]
        print(
            f"the two trees' CPU of a position correlate at {np.corrcoef(a[1:], b[1:])[0, 1]:.2f}; 90th percentile "
            f"over median: after {np.percentile(a[1:], 90) / np.median(a[1:]):.3f}, before "
            f"{np.percentile(b[1:], 90) / np.median(b[1:]):.3f}, their ratio {np.percentile(ratio, 90) / np.median(ratio):.3f}"
        )
    x, y = np.array(out["after"]), np.array(out["before"])
    print(
        f"approaches within {np.abs(x[:, 0] - y[:, 0]).max():.2e} mm, drags within {np.abs(x[:, 2] - y[:, 2]).max():.2e} N, "
        f"areas equal: {np.array_equal(x[:, 1], y[:, 1])}, CG iterations equal: {np.array_equal(x[:, 3], y[:, 3])}"
    )


if __name__ == "__main__":
    main()
