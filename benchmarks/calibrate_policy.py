"""Fit the micro-step policy's cost model to the sweep's measured runs.

The policy (:mod:`twoscale.micro.policy`) estimates each candidate iteration's work in
grid-product units and turns it into CPU seconds by the cost model
(:class:`twoscale.micro.costmodel.CostModel`): ``fixed + ns_per_unit x 1e-9 x work``, one
pair of coefficients per candidate. Every sweep record (``benchmarks/sweep.py``) holds the
work estimates of all three candidates and the measured time of each attempt the driver
made; an attempt is charged to the candidate whose estimate describes it (the union CG to
``union-cg``; block iterations with exact coupling, block Gauss-Seidel or two-level, to
``block-gs``; with far-field coupling to ``two-level``), its wall time scaled by the solve's
CPU / wall ratio (the machine is shared). The script prints:

* per candidate, the fitted ``fixed`` and ``ns_per_unit`` (least squares on the logarithm
  of the time, so a 2x error counts the same at 0.1 s and at 100 s);
* how far the fit and the installed model are off: the median factor and the attempts off
  by more than 2x, and those attempts by scene;
* with ``--emit``, the ``FITTED = CostModel(...)`` block to paste into
  ``twoscale/micro/costmodel.py``.

Only attempts that converged and took at least ``--min-seconds`` count (a stalled
attempt's time is the price of its fallback, reported apart); with ``--max-sweeps`` the
block iterations' attempts of more sweeps are reported but left out of the fit (the form
costs a fixed sweep count, ``CostModel.gs_sweeps``, and cannot follow them).

``--forced FILE.jsonl`` adds the rows of ``benchmarks/force_strategies.py`` (each strategy
forced on sweep scenes, the micro step's CPU seconds): the candidates the policy did not
pick are measured there too, on the same scenes (the sweep's records hold the chosen
attempt only).

Usage::

    python benchmarks/calibrate_policy.py sweep_a.jsonl [sweep_b.jsonl ...] [--forced forced.jsonl] [--emit]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


CANDIDATES = ("union-cg", "block-gs", "two-level")
from twoscale.micro.costmodel import UNION_REFERENCE_WORK  # noqa: E402

#: Largest fixed cost per candidate the fit may give, s.
MAX_FIXED = 0.3


def candidate(iteration: str, far_tol) -> str:
    """The policy candidate whose work estimate describes an attempt."""
    if iteration == "union-cg":
        return "union-cg"
    return "block-gs" if far_tol is None else "two-level"


def samples(records: list[dict]) -> list[dict]:
    """One sample per attempt: candidate, work units, control (``penetration``, ``load`` or
    ``tilt``), CPU seconds, converged, scene label."""
    from twoscale.scenespace import SceneSpec

    out = []
    for rec in records:
        ts, spec = rec.get("ts", {}), rec["spec"]
        work, attempts = ts.get("work"), ts.get("attempts")
        if not work or not attempts or not ts.get("time_s"):
            continue
        scale = min(ts["cpu_s"] / ts["time_s"], 1.0)  # the solve's share of a core while it ran
        control = "tilt" if spec.get("tilt") else spec.get("control", "load")
        for iteration, far_tol, converged, sweeps, seconds in attempts:
            key = candidate(iteration, far_tol)
            if not work.get(key):
                continue
            out.append(
                {
                    "candidate": key,
                    "iteration": iteration,
                    "work": float(work[key]),
                    "control": control,
                    "seconds": max(seconds * scale, 1e-3),
                    "converged": bool(converged),
                    "sweeps": sweeps,
                    "scene": SceneSpec(**rec["spec"]).label,
                }
            )
    return out


#: The candidate a forced variant of ``benchmarks/force_strategies.py`` is charged to.
FORCED = {"union-cg": "union-cg", "block-gs": "block-gs", "two-level": "block-gs", "far": "two-level"}


def policy_runs(row: dict) -> dict:
    """The forced variant the policy runs for each candidate on a forced row's scene: its
    exact block iterations are the two-level one under load control without merged
    contacts (:func:`twoscale.micro.policy.decide`), block Gauss-Seidel otherwise."""
    merged = bool((row.get("figures") or {}).get("merged_contacts"))
    exact = "two-level" if row.get("control") == "load" and not merged else "block-gs"
    return {"union-cg": "union-cg", "block-gs": exact, "two-level": "far"}


def forced_samples(rows: list[dict], count: int = 200) -> list[dict]:
    """One sample per forced variant's row (``benchmarks/force_strategies.py``, each of its
    row's ``seed``, 0 where it has none): its median micro-step CPU seconds against the work
    the policy estimated on that scene. Of the exact variants only the one the policy runs
    (:func:`policy_runs`) counts, and not block Gauss-Seidel with sensitivity sweeps (merged
    contacts under load control), which the model costs with a factor this fit leaves."""
    from twoscale.scenespace import sweep

    specs: dict = {}
    out = []
    for r in rows:
        key = FORCED.get(r["variant"])
        if key is None or not r.get("work") or not r.get("work", {}).get(key) or "micro_s" not in r:
            continue
        seed = int(r.get("seed", 0))
        if seed not in specs:
            specs[seed] = {s.index: s for s in sweep(count, seed)}
        spec = specs[seed][r["scene"]]
        r = {"control": spec.control, **r}
        merged = bool((r.get("figures") or {}).get("merged_contacts"))
        if "figures" in r and (
            policy_runs(r)[key] != r["variant"] or (key == "block-gs" and merged and spec.control == "load")
        ):
            continue
        out.append(
            {
                "candidate": key,
                "iteration": r["variant"],
                "work": float(r["work"][key]),
                "control": "tilt" if spec.tilt else spec.control,
                "seconds": max(float(r["micro_s"]), 1e-3),
                "converged": bool(r.get("converged")),
                "sweeps": (r.get("attempts") or [[None, None, None, None]])[-1][3],
                "scene": f"seed {seed} " + spec.label + " (forced)",
                "seed": seed,
                "coverage": (r.get("figures") or {}).get("coverage", r.get("coverage")),
                "patches": (r.get("figures") or {}).get("patches", r.get("patches")),
            }
        )
    return out


def fitted(rows: list[dict], min_seconds: float, max_sweeps: int | None = None) -> list[dict]:
    """The samples a fit reads: at least ``min_seconds`` long, and of at most
    ``max_sweeps`` sweeps where they are block iterations (None: any)."""
    many = lambda r: max_sweeps is not None and r["candidate"] != "union-cg" and (r["sweeps"] or 0) > max_sweeps  # noqa: E731
    return [r for r in rows if r["seconds"] >= min_seconds and not many(r)]


def fit(rows: list[dict]) -> dict:
    """Least squares on the log of the time: per candidate ``fixed`` seconds and ``ns`` per
    unit; for the block iterations also the factors of load control and of the tilt on their
    work (more sweeps: sensitivity or coarse corrections of the approach and the angles),
    shared by both. The union CG solves the load and the tilt in the same iteration."""
    from scipy.optimize import least_squares

    conv = [r for r in rows if r["converged"]]
    keys = [k for k in CANDIDATES if sum(r["candidate"] == k for r in conv) >= 3]
    if not keys:
        return {}
    w = np.array([r["work"] for r in conv])
    t = np.array([r["seconds"] for r in conv])
    which = np.array([keys.index(r["candidate"]) if r["candidate"] in keys else -1 for r in conv])
    blocks = np.array([r["candidate"] != "union-cg" for r in conv])
    growth = np.where(blocks, 0.0, np.log(w / UNION_REFERENCE_WORK))
    load = np.array([r["control"] == "load" for r in conv]) & blocks
    tilt = np.array([r["control"] == "tilt" for r in conv]) & blocks
    ok = which >= 0

    def predict_(q):
        fixed, ns = np.exp(q[0 : 2 * len(keys) : 2]), np.exp(q[1 : 2 * len(keys) : 2])
        f_load, f_tilt = np.exp(q[-3]), np.exp(q[-2])
        factor = np.where(load, f_load, np.where(tilt, f_tilt, 1.0)) * np.exp(q[-1] * growth)
        return fixed[which] + 1e-9 * ns[which] * factor * w

    def resid(q):
        return (np.log(predict_(q)) - np.log(t))[ok]

    q0 = []
    for k in keys:
        sel = which == keys.index(k)
        q0 += [math.log(max(float(np.min(t[sel])) / 2, 1e-3)), math.log(float(np.median(1e9 * t[sel] / w[sel])))]
    # a fixed cost of at most MAX_FIXED s: where the data would put more there (the far
    # field's few mid-size attempts, 2-3 s each), it is scatter, not set-up
    q0 = [min(v, math.log(MAX_FIXED) - 1e-6) if i % 2 == 0 else v for i, v in enumerate(q0)]
    hi = np.array([math.log(MAX_FIXED) if i < 2 * len(keys) and i % 2 == 0 else np.inf for i in range(len(q0) + 3)])
    q = least_squares(resid, np.array(q0 + [0.0, 0.0, 0.0]), bounds=(-np.inf, hi)).x
    out = {
        k: {"fixed": math.exp(q[2 * i]), "ns": math.exp(q[2 * i + 1]), "count": int(np.sum(which == i))}
        for i, k in enumerate(keys)
    }
    out["factors"] = {"load": math.exp(q[-3]), "tilt": math.exp(q[-2]), "union_exponent": float(q[-1])}
    return out


def predict(models: dict, row: dict) -> float:
    m = models[row["candidate"]]
    if row["candidate"] == "union-cg":
        factor = (row["work"] / UNION_REFERENCE_WORK) ** models["factors"].get("union_exponent", 0.0)
    else:
        factor = models["factors"].get(row["control"], 1.0)
    return m["fixed"] + 1e-9 * m["ns"] * factor * row["work"]


def _model_from(models: dict):
    """The installed cost model with this fit's coefficients (margins and budgets kept); its
    union CG at the fixed ``union_products`` this fit's work counted (no iteration count)."""
    import dataclasses

    from twoscale.micro.costmodel import FITTED

    return dataclasses.replace(
        FITTED,
        ns_per_unit={k: models[k]["ns"] if k in models else FITTED.ns_per_unit[k] for k in CANDIDATES},
        fixed_seconds={k: models[k]["fixed"] if k in models else FITTED.fixed_seconds[k] for k in CANDIDATES},
        load_factor=models["factors"]["load"],
        tilt_factor=models["factors"]["tilt"],
        union_work_exponent=models["factors"]["union_exponent"],
        union_iterations=None,
    )


def _figures(ts: dict) -> dict | None:
    """The patches' figures a record keeps (older records: the patch count from the
    choice's reason, which always starts with it)."""
    n = ts.get("patches")
    if n is None:
        head = (ts.get("reason") or "").split(" ")[0]
        n = int(head) if head.isdigit() else None
    if n is None or ts.get("coverage") is None:
        return None
    return {"patches": n, "coverage": ts["coverage"], "box_cells": 0, "carried_cells": 0, "largest_patch": 0}


def replay(records: list[dict], model) -> None:
    """Choose each record's micro iteration again (:func:`twoscale.micro.policy.decide`)
    under the installed model and under ``model``; print the scenes whose choice changes.
    Where the installed model's replay does not give the recorded choice (older records
    do not keep whether contacts merged), the scene is listed as not replayed."""
    from twoscale.micro.policy import decide
    from twoscale.scenespace import SceneSpec

    changed, unknown = [], []
    for rec in records:
        ts, spec = rec.get("ts", {}), rec["spec"]
        figures = _figures(ts)
        if not ts.get("work") or figures is None:
            continue
        figures["height_map"] = ts.get("height_map", spec.get("kind", "tips") != "tips")  # older records: the kind
        kw = {"load_control": spec.get("control") == "load", "tilt": bool(spec.get("tilt"))}
        kw["merged_contacts"] = bool(ts.get("merged_contacts", False))
        before = decide(figures, ts["work"], **kw).iteration
        after = decide(figures, ts["work"], model=model, **kw).iteration
        label = SceneSpec(**spec).label
        if before != ts.get("choice"):
            unknown.append(f"  {label}: recorded {ts.get('choice')}, replayed {before}")
        elif after != before:
            changed.append(f"  {label}: {before} -> {after} ({ts.get('cpu_s', 0):.2f} s of CPU now)")
    print(f"replayed under the fit: {len(changed)} choices change")
    print("\n".join(changed))
    if unknown:
        print(f"{len(unknown)} not replayed (the installed model's replay differs from the record):")
        print("\n".join(unknown))


def report(name: str, models: dict, rows: list[dict]) -> list[dict]:
    conv = [r for r in rows if r["converged"] and r["candidate"] in models]
    factors = [predict(models, r) / r["seconds"] for r in conv]
    off = [(f, r) for f, r in zip(factors, conv) if not 0.5 <= f <= 2.0]
    med = float(np.exp(np.median(np.abs(np.log(factors))))) if factors else float("nan")
    print(f"{name}: median factor {med:.2f}, {len(off)} of {len(conv)} attempts off by more than 2x")
    for k in CANDIDATES:
        got = [f for f, r in zip(factors, conv) if r["candidate"] == k]
        if got:
            mk = float(np.exp(np.median(np.abs(np.log(got)))))
            print(f"  {k:10s} median factor {mk:.2f}, {sum(not 0.5 <= f <= 2.0 for f in got)} of {len(got)} off by >2x")
    return off


def rescale(installed: dict, rows: list[dict]) -> None:
    """The installed model's seconds scaled by one factor (the median of measured over
    predicted), and by one per candidate: the scale alone keeps every choice."""
    conv = [r for r in rows if r["converged"]]
    logs = np.array([math.log(r["seconds"] / predict(installed, r)) for r in conv])
    if not len(logs):
        return
    scale = float(np.exp(np.median(logs)))
    scaled = {k: {n: v * scale for n, v in m.items()} for k, m in installed.items() if k != "factors"}
    report(f"the installed model x {scale:.3g}", {**scaled, "factors": installed["factors"]}, conv)
    each = {k: np.exp(np.median([g for g, r in zip(logs, conv) if r["candidate"] == k])) for k in CANDIDATES}
    print("  one scale per candidate: " + ", ".join(f"{k} x {v:.3g}" for k, v in each.items() if np.isfinite(v)))


def forced_rows(paths, latest: bool = False) -> list[dict]:
    """Every row of ``benchmarks/force_strategies.py``'s result files ``paths``, in order;
    with ``latest`` one row per seed, scene and variant, the last one read (a variant run
    again on newer code replaces its earlier measurement)."""
    rows: list = []
    for path in paths:
        with open(path, encoding="utf-8") as fh:
            rows += [json.loads(line) for line in fh if line.strip()]
    if not latest:
        return rows
    last = {(int(r.get("seed", 0)), r["scene"], r["variant"]): i for i, r in enumerate(rows)}
    return [rows[i] for i in sorted(last.values())]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("files", nargs="*", help="records of benchmarks/sweep.py")
    p.add_argument("--forced", nargs="*", default=[], help="rows of benchmarks/force_strategies.py")
    p.add_argument("--emit", action="store_true", help="print the FITTED block for twoscale/micro/costmodel.py")
    p.add_argument("--margin", type=float, help="union_margin to emit (default: the installed one)")
    p.add_argument(
        "--replay", action="store_true", help="list the scenes whose micro iteration the fit would choose differently"
    )
    p.add_argument(
        "--min-seconds",
        type=float,
        default=0.02,
        help="attempts shorter than this are left out (their time is the clock's resolution and Python)",
    )
    p.add_argument("--max-sweeps", type=int, help="block attempts of more sweeps are left out of the fit")
    args = p.parse_args(argv)
    from twoscale.micro.costmodel import FITTED

    records = {}
    for f in args.files:
        with open(f, encoding="utf-8") as fh:
            for line in fh:
                if line.strip():
                    r = json.loads(line)
                    records[r["spec"]["index"]] = r
    forced = forced_rows(args.forced)
    rows = [r for r in samples(list(records.values())) + forced_samples(forced) if r["seconds"] >= args.min_seconds]
    if not rows:
        print("no timed attempt")
        return 1
    models = fit(fitted(rows, args.min_seconds, args.max_sweeps))
    if args.max_sweeps is not None:
        print(
            f"{len(rows) - len(fitted(rows, 0.0, args.max_sweeps))} attempts of over {args.max_sweeps} sweeps not fitted"
        )
    scenes = len(records) + len({r["scene"] for r in rows if r["scene"].endswith("(forced)")})
    print(f"{len(rows)} attempts from {scenes} scenes ({sum(r['converged'] for r in rows)} converged)")
    for k in CANDIDATES:
        if k in models:
            m = models[k]
            print(f"  {k:10s} {m['count']:4d} attempts: fixed {m['fixed']:.3g} s + {m['ns']:.3g} ns a unit")
    print(
        f"  block iterations' work x {models['factors']['load']:.3g} under load control, "
        f"x {models['factors']['tilt']:.3g} with the tilt; the union CG's x (work / "
        f"{UNION_REFERENCE_WORK:.0e}) ** {models['factors']['union_exponent']:.3g}"
    )
    installed = {k: {"fixed": FITTED.fixed_seconds[k], "ns": FITTED.ns_per_unit[k]} for k in CANDIDATES}
    installed["factors"] = {
        "load": FITTED.load_factor,
        "tilt": FITTED.tilt_factor,
        "union_exponent": FITTED.union_work_exponent,
    }
    # the installed block iterations' sweep counts are reported by benchmarks/sweep_counts.py
    report(f"installed model at {FITTED.gs_sweeps:g} sweeps ({FITTED.fitted_on})", installed, rows)
    rescale(installed, fitted(rows, args.min_seconds, args.max_sweeps))
    off = report("this fit", models, rows)
    for f, r in sorted(off, key=lambda x: -abs(math.log(x[0]))):
        print(
            f"  {r['candidate']:10s} predicted/measured {f:6.2f}  {r['seconds']:7.2f} s  {r['iteration']} "
            f"{r['sweeps']} sweeps  {r['scene']}"
        )
    wasted = [r for r in rows if not r["converged"]]
    if wasted:
        print(f"{len(wasted)} attempts did not converge ({sum(r['seconds'] for r in wasted):.1f} s before a fallback):")
        for r in sorted(wasted, key=lambda r: -r["seconds"]):
            print(f"  {r['iteration']:10s} {r['seconds']:7.2f} s  {r['sweeps']} sweeps  {r['scene']}")
    if args.replay:
        replay(list(records.values()), _model_from(models))
    if args.emit and all(k in models for k in CANDIDATES):
        ns = ", ".join(f'"{k}": {models[k]["ns"]:.3g}' for k in CANDIDATES)
        fx = ", ".join(f'"{k}": {models[k]["fixed"]:.3g}' for k in CANDIDATES)
        print(
            "\nFITTED = CostModel(\n"
            f"    ns_per_unit={{{ns}}},\n"
            f"    fixed_seconds={{{fx}}},\n"
            f"    load_factor={models['factors']['load']:.3g},\n"
            f"    tilt_factor={models['factors']['tilt']:.3g},\n"
            # not fitted here (the records do not say which scenes had merged contacts): kept
            f"    sensitivity_factor={FITTED.sensitivity_factor:g},\n"
            f"    union_work_exponent={models['factors']['union_exponent']:.3g},\n"
            f"    union_margin={args.margin if args.margin is not None else FITTED.union_margin:g},\n"
            # the bounds and the far field's margin are measured, not fitted: kept
            f"    far_union_margin={FITTED.far_union_margin:g},\n"
            f"    union_min_coverage={FITTED.union_min_coverage:g},\n"
            f"    union_margin_min_coverage={FITTED.union_margin_min_coverage:g},\n"
            f"    union_penetration_min_coverage={FITTED.union_penetration_min_coverage!r},\n"
            f"    union_penetration_min_patches={FITTED.union_penetration_min_patches:_},\n"
            f"    union_small_box_cells={FITTED.union_small_box_cells:_},\n"
            f'    fitted_on="{len(rows)} attempts of {scenes} sweep scenes",\n)'
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
