"""Check the micro-step policy's cost model against the sweep's measured runs.

The policy (:mod:`twoscale.micro.policy`) estimates each iteration's cost in work units
(grid-product work, ``n log2 n`` per padded FFT) and picks the cheapest, the union CG only
where its estimate is below ``UNION_MARGIN`` of the block iterations'. Every sweep record
(``benchmarks/sweep.py``) holds the estimates of all three iterations and the measured time
of each attempt the driver made. This script turns them into CPU nanoseconds per work unit
(an attempt's wall time scaled by the solve's CPU / wall ratio, the machine being shared),
per iteration, and prints:

* the median and spread of ns per unit of each iteration (a cost model right to a
  constant has one number per iteration);
* the margin the measurements give: ``median ns(block iterations) / median ns(union CG)``,
  against the policy's ``UNION_MARGIN`` (the union CG should be chosen when
  ``work(union) < margin x work(blocks)``);
* every scene where an attempt's ns per unit is more than 2x off its iteration's median
  (the cost model wrong by more than 2x there).

Only attempts that converged and took at least ``--min-seconds`` count (short runs are
all fixed cost).

Usage::

    python benchmarks/calibrate_policy.py sweep_a.jsonl [sweep_b.jsonl ...]
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def samples(records: list[dict], min_seconds: float) -> list[dict]:
    """One sample per converged attempt: iteration, ns per work unit, scene label."""
    from twoscale.scenespace import SceneSpec
    out = []
    for rec in records:
        ts = rec.get("ts", {})
        work, attempts = ts.get("work"), ts.get("attempts")
        if not work or not attempts or not ts.get("time_s"):
            continue
        scale = ts["cpu_s"] / ts["time_s"]  # the solve's share of a core while it ran
        for iteration, far_tol, converged, sweeps, seconds in attempts:
            if not converged or seconds < min_seconds or not work.get(iteration):
                continue
            out.append({"iteration": iteration, "ns": 1e9 * seconds * scale / work[iteration],
                        "scene": SceneSpec(**rec["spec"]).label, "seconds": seconds * scale})
    return out


def fit(rows: list[dict]) -> dict:
    """Median ns per unit by iteration and the margin they give."""
    by = {}
    for r in rows:
        by.setdefault(r["iteration"], []).append(r["ns"])
    med = {k: float(np.median(v)) for k, v in by.items()}
    blocks = [v for k, v in by.items() if k != "union-cg"]
    margin = None
    if "union-cg" in med and blocks:
        margin = float(np.median(np.concatenate(blocks))) / med["union-cg"]
    return {"median_ns": med, "count": {k: len(v) for k, v in by.items()},
            "spread": {k: (float(np.percentile(v, 10)), float(np.percentile(v, 90))) for k, v in by.items()},
            "margin": margin}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("files", nargs="+")
    p.add_argument("--min-seconds", type=float, default=0.5)
    args = p.parse_args(argv)
    from twoscale.micro.policy import UNION_MARGIN
    records = {}
    for f in args.files:
        with open(f, encoding="utf-8") as fh:
            for line in fh:
                if line.strip():
                    r = json.loads(line)
                    records[r["spec"]["index"]] = r
    rows = samples(list(records.values()), args.min_seconds)
    if not rows:
        print("no converged attempt long enough to time")
        return 1
    res = fit(rows)
    print(f"{len(rows)} timed attempts from {len(records)} scenes")
    for k, m in sorted(res["median_ns"].items()):
        lo, hi = res["spread"][k]
        print(f"  {k:10s} {res['count'][k]:4d} attempts: median {m:.3g} ns a unit (10-90 %: {lo:.3g}-{hi:.3g})")
    if res["margin"] is not None:
        print(f"margin measured: {res['margin']:.3g} (block iterations' ns / union CG's); policy UNION_MARGIN "
              f"{UNION_MARGIN:g}")
    off = [r for r in rows if not 0.5 <= r["ns"] / res["median_ns"][r["iteration"]] <= 2.0]
    print(f"{len(off)} attempts off their iteration's median by more than 2x:")
    for r in sorted(off, key=lambda r: -r["ns"] / res["median_ns"][r["iteration"]]):
        print(f"  {r['iteration']:10s} {r['ns'] / res['median_ns'][r['iteration']]:6.2f}x  {r['seconds']:7.2f} s  "
              f"{r['scene']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
