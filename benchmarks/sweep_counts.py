"""Fit the block iterations' expected sweep counts and their cost to forced runs.

The cost model (:class:`twoscale.micro.costmodel.CostModel`) charges a block iteration its work
for ``gs_sweeps`` sweeps (10) times a factor under load control and another with the tilt.
Forced on the sweep's scenes (``benchmarks/force_strategies.py``) the far-field two-level
iteration took 3-15 sweeps and the exact block iterations 3-45, so that fixed count is off
where they take few or many. Here each block candidate gets an expected sweep count from what
the policy knows before it runs (:class:`~twoscale.micro.costmodel.SweepCount`: the patches'
coverage of their box, the control, the tilt), fitted to the sweeps the forced runs took
(least squares on their logarithm), then its seconds a unit and fixed seconds with that count
(least squares on the logarithm of the time, as ``benchmarks/calibrate_policy.py``); the union
CG's coefficients are kept. Printed: the counts' fit, per candidate the median factor and the
attempts off by more than 2x under the installed model and the new one, the same with the fit
made on one half of the seeds and checked on the other, and with ``--emit`` the fields to
paste into ``twoscale/micro/costmodel.py``.

Usage::

    python benchmarks/sweep_counts.py forced.jsonl [more.jsonl] [--max-sweeps 40] [--latest] [--emit]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.calibrate_policy import MAX_FIXED, fitted, forced_rows, forced_samples  # noqa: E402

#: The block candidates whose sweeps are counted.
BLOCKS = ("block-gs", "two-level")


def _controls(rows: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    tilt = np.array([r["control"] == "tilt" for r in rows])
    return np.array([r["control"] == "load" for r in rows]) & ~tilt, tilt


def fit_counts(rows: list[dict]):
    """Per block candidate, the :class:`SweepCount` whose counts best match the sweeps its
    converged attempts took (relative error: least squares on the logarithm)."""
    from scipy.optimize import least_squares

    from twoscale.micro.costmodel import SweepCount

    out = {}
    for key in BLOCKS:
        got = [r for r in rows if r["candidate"] == key and r["converged"] and r["sweeps"]]
        if len(got) < 4:
            continue
        sweeps = np.array([r["sweeps"] for r in got], dtype=float)
        cov = [r["coverage"] for r in got]
        load, tilt = _controls(got)

        def resid(q):
            count = SweepCount(*q)
            pred = [count(c, load_control=bool(lo), tilt=bool(t)) for c, lo, t in zip(cov, load, tilt)]
            return np.log(pred) - np.log(sweeps)

        q = least_squares(resid, [float(np.median(sweeps)), 1.0, 1.0, 1.0], bounds=(0.0, np.inf)).x
        out[key] = SweepCount(*(float(f"{v:.3g}") for v in q))
    return out


def predicted(model, row: dict) -> float:
    """The seconds ``model`` predicts for a sample's candidate on its scene."""
    load, tilt = row["control"] in ("load", "tilt"), row["control"] == "tilt"
    got = {row["candidate"]: row["work"]}
    return model.seconds(got, load_control=load, tilt=tilt, coverage=row["coverage"], patches=row.get("patches"))[
        row["candidate"]
    ]


def fit_model(rows: list[dict], factors: bool = False, far_patch: bool = False):
    """The installed model with each block candidate's sweeps (:func:`fit_counts`) and, with
    them, its fixed seconds and seconds a unit refitted on ``rows`` (the union CG's kept);
    with ``factors`` also the factors of load control and of the tilt on the block
    iterations' seconds a sweep (shared by both; else 1); with ``far_patch`` the far
    field's seconds a patch and sweep in place of its products' overhead
    (``CostModel.far_patch_seconds``; else None)."""
    from scipy.optimize import least_squares

    from twoscale.micro.costmodel import FITTED

    counts = fit_counts(rows)
    keys = list(counts)
    model = dataclasses.replace(
        FITTED, sweeps=counts, load_factor=1.0, tilt_factor=1.0, far_patch_seconds=0.0 if far_patch else None
    )
    ns, fixed = dict(FITTED.ns_per_unit), dict(FITTED.fixed_seconds)
    got = [r for r in rows if r["candidate"] in counts and r["converged"]]
    t = np.array([r["seconds"] for r in got])
    which = np.array([keys.index(r["candidate"]) for r in got])
    # seconds at one ns a unit, without the fixed part, the count in; and at one second a
    # patch and sweep of the far field
    zero = dict.fromkeys(fixed, 0.0)
    bare = dataclasses.replace(model, fixed_seconds=zero, ns_per_unit=dict.fromkeys(ns, 1.0))
    unit = np.array([predicted(bare, r) for r in got])
    per = dataclasses.replace(model, fixed_seconds=zero, ns_per_unit=zero, far_patch_seconds=1.0)
    patch = np.array([predicted(per, r) for r in got]) if far_patch else np.zeros(len(got))
    load, tilt = _controls(got)
    on = [1.0 if factors else 0.0] * 2

    def resid(q):
        f = np.exp(on[0] * q[-3] * load + on[1] * q[-2] * tilt)
        fixed_, ns_ = np.exp(q[0 : 2 * len(keys) : 2][which]), np.exp(q[1 : 2 * len(keys) : 2][which])
        return np.log(fixed_ + (ns_ * unit + np.exp(q[-1]) * patch) * f) - np.log(t)

    q0 = []
    for i in range(len(keys)):
        sel = which == i
        q0 += [math.log(min(float(np.min(t[sel])) / 2, MAX_FIXED / 2)), math.log(float(np.median(t[sel] / unit[sel])))]
    q0 += [0.0, 0.0, math.log(1e-4)]
    hi = [math.log(MAX_FIXED) if i % 2 == 0 else np.inf for i in range(2 * len(keys))] + [np.inf] * 3
    q = least_squares(resid, q0, bounds=(-np.inf, hi)).x
    for i, key in enumerate(keys):
        fixed[key], ns[key] = float(f"{math.exp(q[2 * i]):.3g}"), float(f"{math.exp(q[2 * i + 1]):.3g}")
    lf, tf = (float(f"{math.exp(v):.3g}") if factors else 1.0 for v in q[-3:-1])
    patch_s = float(f"{math.exp(q[-1]):.3g}") if far_patch else None
    return dataclasses.replace(
        model, ns_per_unit=ns, fixed_seconds=fixed, load_factor=lf, tilt_factor=tf, far_patch_seconds=patch_s
    )


def fit_far(rows: list[dict], model=None):
    """``model`` (default: the installed one) with the far field's seconds a unit and its
    seconds a patch and sweep (``CostModel.far_patch_seconds``, in place of its products'
    overhead) fitted to its converged attempts in ``rows`` (least squares on the
    logarithm); its fixed seconds and sweep count, and every other candidate's
    coefficients, kept."""
    from scipy.optimize import least_squares

    from twoscale.micro.costmodel import FITTED

    model = FITTED if model is None else model
    got = [r for r in rows if r["candidate"] == "two-level" and r["converged"] and r.get("patches")]
    t = np.array([r["seconds"] for r in got])
    zero = dict.fromkeys(model.ns_per_unit, 0.0)
    at_unit = dataclasses.replace(
        model, ns_per_unit=dict.fromkeys(zero, 1.0), fixed_seconds=zero, far_patch_seconds=0.0
    )
    at_patch = dataclasses.replace(model, ns_per_unit=zero, fixed_seconds=zero, far_patch_seconds=1.0)
    unit = np.array([predicted(at_unit, r) for r in got])
    patch = np.array([predicted(at_patch, r) for r in got])
    fixed = model.fixed_seconds["two-level"]

    def resid(q):
        return np.log(fixed + np.exp(q[0]) * unit + np.exp(q[1]) * patch) - np.log(t)

    q = least_squares(resid, [math.log(float(np.median(t / unit))), math.log(1e-4)]).x
    ns = {**model.ns_per_unit, "two-level": float(f"{math.exp(q[0]):.3g}")}
    return dataclasses.replace(model, ns_per_unit=ns, far_patch_seconds=float(f"{math.exp(q[1]):.3g}"))


def fit_union(rows: list[dict], model=None):
    """``model`` (default: the installed one) with the union CG's expected iterations
    (``CostModel.union_iterations``: its ``base`` and ``interaction`` fitted to the CG
    iterations its converged attempts in ``rows`` took, least squares on their logarithm)
    and, with them, its fixed seconds, seconds a unit, growth exponent and the tilt's
    iterations' worth of products (the count's ``tilt``: with the tilt free an iteration
    also fits and restores the plane; least squares on the logarithm of the time); every
    other candidate's coefficients kept."""
    from scipy.optimize import least_squares

    from twoscale.micro.costmodel import FITTED, SweepCount
    from twoscale.micro.costmodel import UNION_REFERENCE_WORK as REF

    model = FITTED if model is None else model
    got = [r for r in rows if r["candidate"] == "union-cg" and r["converged"] and r["sweeps"]]
    its = np.array([r["sweeps"] for r in got], dtype=float)
    t, w = np.array([r["seconds"] for r in got]), np.array([r["work"] for r in got])
    cov = [r["coverage"] for r in got]
    _, tilt = _controls(got)

    def counted(base, interaction, tilted=0.0):
        count = SweepCount(base, interaction, tilt=tilted)
        return np.array([count(c, tilt=bool(ti)) for c, ti in zip(cov, tilt)])

    q = least_squares(lambda q: np.log(counted(*q)) - np.log(its), [float(np.median(its)), 1.0], bounds=(0.0, np.inf)).x
    q = [float(f"{v:.3g}") for v in q]

    def resid(p):
        unit = w * counted(*q, p[3]) / model.union_products
        return np.log(np.exp(p[0]) + 1e-9 * np.exp(p[1]) * unit * (w / REF) ** p[2]) - np.log(t)

    lo, hi = [-np.inf, -np.inf, -1.0, 0.0], [math.log(MAX_FIXED), np.inf, 1.0, np.inf]
    p = least_squares(resid, [math.log(0.02), 0.0, 0.2, 1.0], bounds=(lo, hi)).x
    fixed = {**model.fixed_seconds, "union-cg": float(f"{math.exp(p[0]):.3g}")}
    ns = {**model.ns_per_unit, "union-cg": float(f"{math.exp(p[1]):.3g}")}
    count = SweepCount(*q, tilt=float(f"{p[3]:.3g}"))
    return dataclasses.replace(
        model, union_iterations=count, fixed_seconds=fixed, ns_per_unit=ns, union_work_exponent=float(f"{p[2]:.3g}")
    )


def factors(model, rows: list[dict]) -> dict:
    """Per candidate (and ``all``): the median factor between predicted and measured seconds
    and the converged attempts off by more than 2x, as ``(median, off, count)``."""
    out = {}
    for key in ("all",) + BLOCKS + ("union-cg",):
        got = [r for r in rows if r["converged"] and key in ("all", r["candidate"])]
        f = np.array([predicted(model, r) / r["seconds"] for r in got])
        if len(f):
            out[key] = (float(np.exp(np.median(np.abs(np.log(f))))), int(np.sum((f < 0.5) | (f > 2.0))), len(f))
    return out


def count_factors(model, rows: list[dict]) -> dict:
    """Per block candidate: the median factor between expected and measured sweeps and the
    attempts off by more than 1.5x, as ``(median, off, count)``."""
    out = {}
    for key, count in (model.sweeps or {}).items():
        got = [r for r in rows if r["candidate"] == key and r["converged"] and r["sweeps"]]
        f = np.array(
            [
                count(r["coverage"], load_control=r["control"] in ("load", "tilt"), tilt=r["control"] == "tilt")
                / r["sweeps"]
                for r in got
            ]
        )
        out[key] = (float(np.exp(np.median(np.abs(np.log(f))))), int(np.sum((f < 2 / 3) | (f > 1.5))), len(f))
    return out


def _line(name: str, got: dict) -> str:
    return f"  {name:28s} " + "; ".join(f"{k} {m:.2f}, {off} of {n} off" for k, (m, off, n) in got.items())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("forced", nargs="+", help="rows of benchmarks/force_strategies.py")
    p.add_argument("--min-seconds", type=float, default=0.02, help="shorter samples are left out")
    p.add_argument("--max-sweeps", type=int, default=40, help="block attempts of more sweeps are left out")
    p.add_argument("--split", type=int, default=3, help="cross-validation: seeds up to this one against the rest")
    p.add_argument("--emit", action="store_true", help="print the fields for twoscale/micro/costmodel.py")
    p.add_argument("--latest", action="store_true", help="a variant's last row per scene (re-runs replace)")
    args = p.parse_args(argv)
    from twoscale.micro.costmodel import FITTED

    rows = forced_rows(args.forced, args.latest)
    samples = fitted([s for s in forced_samples(rows) if s["seconds"] >= args.min_seconds], 0.0, args.max_sweeps)
    model = fit_model(samples)
    print(f"{len(samples)} forced attempts of {len({s['scene'] for s in samples})} scenes")
    for key, count in model.sweeps.items():
        print(f"  {key}: {count}; {model.fixed_seconds[key]:.3g} s + {model.ns_per_unit[key]:.3g} ns a unit")
    print("predicted against measured seconds: median factor, off by more than 2x")
    print(_line("installed", factors(FITTED, samples)))
    print(_line("with the sweep counts", factors(model, samples)))
    far = fit_far(samples)
    print(_line("far field's seconds a patch", factors(far, samples)))
    print(f"    far field: {far.ns_per_unit['two-level']:.3g} ns a unit + {1e6 * far.far_patch_seconds:.3g} us a patch")
    print(f"    and sweep (fixed {far.fixed_seconds['two-level']:.3g} s, sweeps {far.sweeps['two-level']})")
    union = fit_union(samples)
    print(_line("union CG's iterations", factors(union, samples)))
    u = union.union_iterations
    print(f"    union CG: {u}; {union.fixed_seconds['union-cg']:.3g} s + {union.ns_per_unit['union-cg']:.3g} ns a unit")
    print(f"    of a box product an iteration, growth exponent {union.union_work_exponent:g}")
    both = fit_far(samples, union)
    print(_line("both", factors(both, samples)))
    print("expected against measured sweeps: median factor, off by more than 1.5x")
    print(_line("with the sweep counts", count_factors(model, samples)))
    low = [s for s in samples if s["seed"] <= args.split]
    high = [s for s in samples if s["seed"] > args.split]
    for name, train, test in ((f"seeds <= {args.split}", low, high), (f"seeds > {args.split}", high, low)):
        print(f"fitted on {name}, checked on the others ({len(test)} attempts):")
        print(_line("installed", factors(FITTED, test)))
        held = fit_model(train)
        print(_line("with the sweep counts", factors(held, test)))
        print(_line("their sweeps", count_factors(held, test)))
        print(_line("far field's seconds a patch", factors(fit_far(train), test)))
        print(_line("union CG's iterations", factors(fit_union(train), test)))
        print(_line("both", factors(fit_far(train, fit_union(train)), test)))
    if args.emit:
        print("\n    sweeps={")
        for key, c in model.sweeps.items():
            print(f'        "{key}": SweepCount({c.base:g}, {c.interaction:g}, {c.load:g}, {c.tilt:g}),')
        print("    },")
        print(f"    ns_per_unit={dict(model.ns_per_unit)},\n    fixed_seconds={dict(model.fixed_seconds)},")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
