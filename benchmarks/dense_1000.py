"""A dense road-like scene: 1,000 spheres on 120 x 120 mm at 1.5 N each, h = 0.06 mm.

The default two-scale solve against the full-grid FFT reference (and ContactMechanics on
the same grid with ``--comparators``, about 5 minutes), each in its own process.
Target: the default solve in <= 60 s. Recorded: docs/records/scenes.md.

Usage::

    cd benchmarks && python dense_1000.py [--tips 1000] [--side 120] [--h 0.06] [--comparators]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tips", type=int, default=1000)
    ap.add_argument("--side", type=float, default=120.0, help="side of the square of tips, mm")
    ap.add_argument("--h", type=float, default=0.06, help="cell size, mm")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--load-per-tip",
        type=float,
        default=1.5,
        help="N per tip (default 1.5: 1,500 N on 1,000 tips, a tread block's load)",
    )
    ap.add_argument("--comparators", action="store_true", help="also run ContactMechanics (slow)")
    args = ap.parse_args(argv)
    spec = {
        "n": args.tips,
        "kind": "dense",
        "control": "load",
        "shape": "sphere",
        "body": "halfspace",
        "seed": args.seed,
        "h": args.h,
        "side": args.side,
        "load_per_tip": args.load_per_tip,
    }
    out = {}
    for method in ["twoscale", "reference"] + (["CM"] if args.comparators else []):
        cmd = [sys.executable, os.path.join(HERE, "scenes.py"), "--single", method, "--spec", json.dumps(spec)]
        text = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.strip().splitlines()[-1]
        out[method] = json.loads(text)
        rec = out[method]
        extra = rec.get("strategy", {}).get("micro_iteration", "")
        print(
            f"{method:10s} {rec['time_s']:8.1f} s  converged {rec['converged']}  peak {rec['peak_mb']:.0f} MB  {extra}"
        )
    f, r = np.asarray(out["twoscale"]["forces"]), np.asarray(out["reference"]["forces"])
    print(
        f"default / reference: {out['twoscale']['time_s'] / out['reference']['time_s']:.3f}; "
        f"per-tip error {100 * np.abs(f - r).max() / r.max():.3g} % of the largest force"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
