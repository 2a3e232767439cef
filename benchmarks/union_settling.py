"""How a Polonsky-Keer iteration's contact settles, step by step, in one solve of a case.

For each step of each kernel run (:func:`twoscale.pk.kernel.pk_solve`, first row): the
loaded cells at the step's start, the KKT residual, the cells that enter at its end (unloaded
with a negative gap) and how many of them carry pressure in that run's answer, the loaded
cells the step clipped to zero, and whether ``u = A p`` was made afresh after it (a product,
``fast`` or exact) instead of updated from the search direction's product. A step that lets
in thousands of cells off the final contact restarts the conjugate directions and costs a
fresh product; the next step clips them again.

Cases are :mod:`ab_trees`' (``sweep7:177``, ``road:100-0.1-3-6``, ...), run once in this
process with the solvers' modules imported first. Prints one line a step and a summary a run.

Usage::

    python benchmarks/union_settling.py sweep7:177
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np


def _traced(runs: list) -> None:
    """Wrap ``Iteration.step`` and ``Iteration.refresh`` to log into ``runs`` (one dict a
    kernel run: its steps, and the fresh products after each)."""
    from twoscale.pk import iteration

    step, refresh = iteration.Iteration.step, iteration.Iteration.refresh

    def run_of(it) -> dict:
        if not runs or runs[-1]["owner"] is not it:
            runs.append({"owner": it, "steps": [], "last": None})
        return runs[-1]

    def traced_step(self, it, g, m, on, g_on, gg, res):
        log = run_of(self)
        before = on[0].copy()
        entering = ~before & (g[0] < -self.gap_tolerance()[0])
        if self.masked:
            entering &= self.mask[0]
        step(self, it, g, m, on, g_on, gg, res)
        after = self.p[0] > 0.0 if len(self.p) else before
        log["steps"].append(
            {
                "step": int(it),
                "loaded": int(before.sum()),
                "residual": None if res is None else float(res.max()),
                "entering": entering,
                "clipped": int(np.count_nonzero(before & ~after)),
                "fresh": "",
            }
        )
        log["last"] = after

    def traced_refresh(self, rows, fast=False):
        refresh(self, rows, fast)
        log = run_of(self)
        if log["steps"]:
            log["steps"][-1]["fresh"] = "fast" if fast and self.ops.fast is not None else "exact"

    iteration.Iteration.step, iteration.Iteration.refresh = traced_step, traced_refresh


def report(runs: list) -> None:
    """One line a step, then a summary a run (the entering cells against the run's answer)."""
    for k, log in enumerate(runs):
        final = log["last"]
        print(f"run {k}: {len(log['steps'])} steps, {int(final.sum()) if final is not None else 0} loaded at the end")
        print("step  loaded  residual   entering  in final  clipped  fresh product")
        wasted = 0
        for s in log["steps"]:
            entering = int(s["entering"].sum())
            kept = int((s["entering"] & final).sum()) if final is not None else 0
            wasted += entering - kept
            res = "-" if s["residual"] is None else f"{s['residual']:.2e}"
            print(f"{s['step']:4d} {s['loaded']:7d}  {res:>9s} {entering:9d} {kept:9d} {s['clipped']:8d}  {s['fresh']}")
        fresh = sum(1 for s in log["steps"] if s["fresh"])
        print(
            f"summary: {fresh} fresh products after {len(log['steps'])} steps; {wasted} entries off the final contact"
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", help="an ab_trees case, e.g. sweep7:177")
    args = parser.parse_args(argv)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import ab_trees

    ab_trees._solver_imports()
    runs: list = []
    _traced(runs)
    result, cpu = ab_trees.timed(args.case)
    print(f"{args.case}: {cpu:.3f} s CPU (traced), iterations {dict(result.iterations)}")
    report(runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
