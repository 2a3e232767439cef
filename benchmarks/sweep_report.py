"""The scene-space sweep's report: each record's verdict, its row and the run's table and summary.

A record is one scene of ``benchmarks/sweep.py`` (one JSON line: the default solve ``ts``,
the full-grid reference ``ref`` where it fits, ContactMechanics ``cm``). The verdicts and
targets are those of the sweep's record (docs/records/sweep.md): converged or refused in
seconds, within 1.5x the memory estimate, forces within 0.5 % of the reference, CPU time at
most the reference's, and at most 0.3x of it where less than 20 % of the reference's box is
in contact and the reference takes over 1 s of CPU (the sparse-contact target, a column of
its own and a line of the summary naming the scenes that missed it).
"""

from __future__ import annotations

import json
import os

import numpy as np

#: The speed target where contact is sparse: a default solve at most this fraction of the
#: reference's CPU time where less than ``SPARSE_CONTACT`` of the reference's box is in
#: contact and the reference takes over ``SPARSE_REF_CPU_S`` of CPU.
SPARSE_RATIO = 0.3
SPARSE_CONTACT = 0.2
SPARSE_REF_CPU_S = 1.0


def contact_fraction(rec: dict) -> float | None:
    """The share of the reference's box in contact: its loaded cells' area over the box's
    (None without a reference answer)."""
    ref = rec.get("ref", {})
    if "forces" not in ref or not ref.get("cells") or not ref.get("h"):
        return None
    return float(ref["area"]) / (float(ref["cells"]) * float(ref["h"]) ** 2)


def sparse_target(rec: dict) -> str | None:
    """``met`` or ``missed`` where the sparse-contact target applies (default CPU time at
    most ``SPARSE_RATIO`` of the reference's), None where it does not."""
    frac = contact_fraction(rec)
    if frac is None or frac >= SPARSE_CONTACT or rec["ref"]["cpu_s"] <= SPARSE_REF_CPU_S:
        return None
    return "met" if rec["ratio_cpu"] <= SPARSE_RATIO else "missed"


def route_estimate_mb(ts: dict) -> float:
    """The estimate of the route that ran, MB: where the policy could take either the union
    CG or a block iteration, the estimate counts the block iteration and says what the union
    CG would need (``estimate_union_mb``); a union CG that ran is held to that figure, any
    other route to the main one."""
    union = ts.get("estimate_union_mb")
    return float(union) if union is not None and ts.get("choice") == "union-cg" else float(ts["estimate_mb"])


def verdict(rec: dict) -> str:
    """``ok``, ``refused`` or what went wrong, one word."""
    ts = rec["ts"]
    if "error" in ts:
        return "timeout" if ts["error"].startswith("timeout") else "crash"
    if "refused" in ts:
        return "refused" if ts["time_s"] < 10.0 else "slow-refusal"
    if not ts["converged"]:
        return "not-converged"
    if ts["peak_mb"] > 1.5 * route_estimate_mb(ts):
        return "over-estimate"
    if rec.get("err", {}).get("tip_pct", 0.0) > 0.5:
        return "inaccurate"
    if "ref" in rec and "forces" in rec["ref"]:
        if rec["ratio_cpu"] > 1.0 and ts["cpu_s"] > 1.0:  # CPU seconds, as the ratio
            return "slower-than-ref"
    elif ts["cpu_s"] > 60.0:  # CPU seconds: the machine is shared, its wall time is not the code's
        return "over-60s"
    return "ok"


def row(rec: dict) -> dict:
    ts, ref = rec["ts"], rec.get("ref", {})
    from twoscale.scenespace import SceneSpec

    return {
        "scene": SceneSpec(**rec["spec"]).label,
        "verdict": verdict(rec),
        "h": ts.get("h"),
        "choice": ts.get("choice") or ("refused" if "refused" in ts else ts.get("error", "")[:40]),
        "ts_s": ts.get("time_s"),
        "ts_cpu": ts.get("cpu_s"),
        "ref_s": ref.get("time_s"),
        "ratio": rec.get("ratio_cpu"),
        "contact_pct": None if contact_fraction(rec) is None else 100.0 * contact_fraction(rec),
        "sparse": sparse_target(rec),
        "tip_pct": rec.get("err", {}).get("tip_pct"),
        "peak_mb": ts.get("peak_mb"),
        "est_mb": route_estimate_mb(ts) if "estimate_mb" in ts else None,
        "cm_s": rec.get("cm", {}).get("time_s"),
    }


def _fmt(v, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def table(records: list[dict]) -> str:
    """A Markdown table of the records, worst first (failures, then by time ratio)."""
    order = {"ok": 1, "refused": 1}
    rows = sorted((row(r) for r in records), key=lambda x: (order.get(x["verdict"], 0), -(x["ratio"] or 0)))
    lines = [
        "| scene | verdict | h mm | micro step | default s | default CPU s | ref s | CPU ratio | contact % "
        f"| {SPARSE_RATIO:g}x target | tip err % | peak MB | est. MB | CM s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for x in rows:
        lines.append(
            f"| {x['scene']} | {x['verdict']} | {_fmt(x['h'], '.3g')} | {x['choice']} | "
            f"{_fmt(x['ts_s'], '.2f')} | {_fmt(x['ts_cpu'], '.2f')} | {_fmt(x['ref_s'], '.2f')} | "
            f"{_fmt(x['ratio'], '.3f')} | {_fmt(x['contact_pct'], '.3g')} | {x['sparse'] or '-'} | "
            f"{_fmt(x['tip_pct'], '.2g')} | {_fmt(x['peak_mb'], '.0f')} | {_fmt(x['est_mb'], '.0f')} | "
            f"{_fmt(x['cm_s'], '.2f')} |"
        )
    return "\n".join(lines) + "\n"


def _route(record: dict) -> str:
    """What the default ran: a default route's full grid is the reference's own solver on
    the smallest grids (its ratio to the reference is the host's noise) and otherwise the
    reference's grid with a preconditioned or float32 CG (the message says which)."""
    choice = record["ts"].get("choice")
    if choice != "full-grid":
        return str(choice)
    own = "the reference's own solver" in str(record["ts"].get("message", ""))
    return "the reference's own solver" if own else "the full grid's CG"


def summary(records: list[dict]) -> str:
    from collections import Counter

    v = Counter(verdict(r) for r in records)
    rat = [r["ratio_cpu"] for r in records if "ratio_cpu" in r]
    err = [r["err"]["tip_pct"] for r in records if "tip_pct" in r.get("err", {})]
    over = [r["ts"]["peak_mb"] / route_estimate_mb(r["ts"]) for r in records if "estimate_mb" in r["ts"]]
    refused = [r["ts"]["time_s"] for r in records if "refused" in r["ts"]]
    free = [r["ts"]["cpu_s"] for r in records if "ref" not in r and "cpu_s" in r["ts"]]
    parts = [f"{len(records)} scenes: " + ", ".join(f"{k} {n}" for k, n in v.most_common())]
    if rat:
        parts.append(
            f"CPU ratio default/reference: median {np.median(rat):.3f}, worst {max(rat):.3f} "
            f"({len(rat)} scenes with a reference)"
        )
    above = sorted((r for r in records if r.get("ratio_cpu", 0.0) > 1.0), key=lambda r: -r["ratio_cpu"])
    if rat:
        named = ", ".join(f"#{r['spec']['index']} {r['ratio_cpu']:.2f}x ({_route(r)})" for r in above)
        parts.append(f"above 1.0x: {len(above)}" + (f": {named}" if named else ""))
    sparse = [(r["spec"]["index"], r["ratio_cpu"]) for r in records if sparse_target(r) is not None]
    if sparse:
        missed = sorted((x for x in sparse if x[1] > SPARSE_RATIO), key=lambda x: -x[1])
        parts.append(
            f"{SPARSE_RATIO:g}x target (contact under {100 * SPARSE_CONTACT:g} % of the reference's box, reference over "
            f"{SPARSE_REF_CPU_S:g} s of CPU): {len(sparse)} scenes, met {len(sparse) - len(missed)}, missed "
            f"{len(missed)}" + (": " + ", ".join(f"#{i} {v:.2f}x" for i, v in missed) if missed else "")
        )
    if err:
        parts.append(f"per-tip force error: median {np.median(err):.2g} %, worst {max(err):.2g} %")
    if over:
        parts.append(f"peak / estimate: median {np.median(over):.2f}, worst {max(over):.2f}")
    if refused:
        parts.append(f"refusals: {len(refused)}, slowest {max(refused):.2f} s")
    if free:
        parts.append(f"without a reference: {len(free)} scenes solved, slowest default {max(free):.1f} s of CPU")
    cm = _against_cm(records)
    if cm:
        parts.append(cm)
    return "\n".join(parts)


def _against_cm(records: list[dict]) -> str:
    """ContactMechanics in the same run: its CPU time against the default's, and its forces
    against the reference's where it says it converged (a run that stops at its iteration cap
    is counted apart: its forces are not an answer)."""
    ran = [r for r in records if "forces" in r.get("cm", {}) and "cpu_s" in r["ts"]]
    if not ran:
        return ""
    done = [r for r in ran if r["cm"].get("converged", True)]
    stalled = sorted(r["spec"]["index"] for r in ran if r not in done)
    ratio = [r["ts"]["cpu_s"] / r["cm"]["cpu_s"] for r in done if r["cm"].get("cpu_s")]
    # ContactMechanics has no tilt: it solves a tilted scene untilted, so only the time counts there
    err = [r["cm_err"]["tip_pct"] for r in done if "cm_err" in r and not r["spec"].get("tilt")]
    text = f"against ContactMechanics: {len(ran)} scenes, converged on {len(done)}"
    if stalled:
        text += " (not converged: " + ", ".join(f"#{i}" for i in stalled) + ")"
    if ratio:
        text += f"; CPU default/ContactMechanics median {np.median(ratio):.3f}, worst {max(ratio):.3f}"
    if err:
        text += f"; its forces against the reference's (untilted scenes): worst {max(err):.2g} % of the largest tip's"
    return text


def _load(path: str) -> list[dict]:
    if not path or not os.path.exists(path):
        return []
    with open(path, encoding="utf-8") as fh:
        return [json.loads(line) for line in fh if line.strip()]
