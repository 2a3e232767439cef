"""The micro-step policy's choices against the measured costs of every candidate.

``benchmarks/force_strategies.py`` measures each candidate iteration forced on a scene and
keeps what the policy decided from (its figures and every candidate's work). Here each such
scene is decided again by the policy's own function (:func:`twoscale.micro.policy.decide`,
margins and all) under the installed cost model and under the fit of
``benchmarks/calibrate_policy.py`` on the same rows (or under ``--union-margin`` /
``--far-union-margin`` on top of it), and the pick is compared with the candidate measured
fastest (the micro step's CPU seconds of the variant the policy runs for it:
:func:`calibrate_policy.policy_runs`; a variant that did not converge counts as never
finishing). Printed: per scene the three picks and the measured seconds; how often each
model picks the fastest or one within ``--within`` (or within ``SLACK`` seconds), and the
fit's picks when each scene is left out of its own fit; the scenes where the fit's pick is over
``--worse`` times slower than the installed model's; the picks' measured seconds summed
over the fastest's (1: always the fastest); and, with ``--margins``, the same for a range of
each margin, so the margins can be chosen from the measured costs.

Usage::

    python benchmarks/forced_choices.py forced.jsonl [more.jsonl] [--latest] [--margins]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.calibrate_policy import _model_from, fit, fitted, forced_rows, forced_samples, policy_runs  # noqa: E402


def scenes(rows: list[dict]) -> list[dict]:
    """Per forced scene (seed, index): the default run's row and each candidate's measured
    micro-step seconds (infinite where its variant did not converge)."""
    by: dict = {}
    for r in rows:
        by.setdefault((int(r.get("seed", 0)), r["scene"]), {})[r["variant"]] = r
    out = []
    for (seed, index), variants in sorted(by.items()):
        auto = variants.get("auto")
        if auto is None or not auto.get("figures") or not auto.get("work"):
            continue  # the full grid's route, or rows without the policy's figures
        seconds = {}
        for key, variant in policy_runs(auto).items():
            got = variants.get(variant)
            if got is not None and "micro_s" in got:
                seconds[key] = got["micro_s"] if got.get("converged") else math.inf
        out.append({"seed": seed, "scene": index, "auto": auto, "measured": seconds})
    return out


def pick(scene: dict, model) -> str:
    """The candidate the policy picks on ``scene`` under ``model``."""
    from twoscale.micro.policy import decide

    auto = scene["auto"]
    figures = dict(auto["figures"])
    merged = bool(figures.pop("merged_contacts", False))
    kw = {"load_control": auto.get("control") == "load", "tilt": bool(auto.get("tilt")), "merged_contacts": merged}
    choice = decide(figures, auto["work"], model=model, **kw)
    if choice.iteration == "two-level":
        return "two-level" if choice.far_tol is not None else "block-gs"
    return choice.iteration


#: Seconds within which two micro steps count as equally fast whatever their ratio (the
#: clock's and a loaded host's scatter on the smallest scenes).
SLACK = 0.01


def right(measured: dict, candidate: str, within: float) -> bool:
    """Whether ``candidate`` is the measured fastest or within ``within`` (or ``SLACK``) of it."""
    best = min(measured.values())
    return measured[candidate] <= max(within * best, best + SLACK)


def score(found: list[dict], model, within: float) -> tuple[int, int, list, float]:
    """Scenes where ``model`` (or per scene ``model(scene)``) picks the measured fastest or
    one within ``within`` of it, scenes counted (the pick measured), each scene's pick, and
    the picks' measured seconds over the fastest's, summed over the scenes counted."""
    hits, counted, picks, spent, best = 0, 0, [], 0.0, 0.0
    for sc in found:
        p = pick(sc, model(sc) if callable(model) else model)
        picks.append(p)
        got = sc["measured"].get(p)
        if got is None:
            continue
        counted += 1
        hits += right(sc["measured"], p, within)
        spent, best = spent + got, best + min(sc["measured"].values())
    return hits, counted, picks, spent / max(best, 1e-300)


def refitted(rows: list[dict], bounds: tuple, sweeps: bool = False, far_patch: bool = False, union: bool = False):
    """The fit on ``rows``: ``benchmarks/calibrate_policy.py``'s, or with ``sweeps`` the
    block iterations' expected sweep counts (``benchmarks/sweep_counts.py``), or with
    ``far_patch`` the installed model with the far field's seconds a unit and seconds a
    patch refitted (``sweep_counts.fit_far``), or with ``union`` the union CG's expected
    iterations and seconds (``sweep_counts.fit_union``; with ``far_patch`` both)."""
    if not (sweeps or far_patch or union):
        return _model_from(fit(fitted(forced_samples(rows), *bounds)))
    from benchmarks.sweep_counts import fit_far, fit_model, fit_union

    samples = fitted([s for s in forced_samples(rows) if s["seconds"] >= bounds[0]], 0.0, bounds[1])
    if union:
        base = fit_union(samples)
        return fit_far(samples, base) if far_patch else base
    return fit_far(samples) if far_patch else fit_model(samples)


def left_out(rows: list[dict], bounds: tuple, kept: dict, *flags: bool):
    """Per scene, the fit on the other scenes' rows (a cross-validated pick; ``flags`` as
    :func:`refitted`'s)."""

    def model(sc: dict):
        others = [r for r in rows if (int(r.get("seed", 0)), r["scene"]) != (sc["seed"], sc["scene"])]
        return dataclasses.replace(refitted(others, bounds, *flags), **kept)

    return model


def margins(found: list[dict], model, within: float) -> None:
    """Hits of ``model`` for a range of each union margin, the other kept."""
    for name in ("union_margin", "far_union_margin"):
        row = []
        for m in (0.5, 0.7, 0.85, 1.0, 1.2, 1.4, 1.7, 2.0, 2.5, 3.0):
            hits, counted, _, spent = score(found, dataclasses.replace(model, **{name: m}), within)
            row.append(f"{m:g}: {hits}/{counted} ({spent:.3f})")
        print(f"  {name} (now {getattr(model, name):g}): " + ", ".join(row))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("forced", nargs="+", help="rows of benchmarks/force_strategies.py")
    p.add_argument("--min-seconds", type=float, default=0.02, help="shorter samples are left out of the fit")
    p.add_argument("--max-sweeps", type=int, help="block attempts of more sweeps are left out of the fit")
    p.add_argument("--within", type=float, default=1.1, help="a pick this close to the fastest counts as right")
    p.add_argument("--worse", type=float, default=1.5, help="the fit's pick against the installed one's")
    p.add_argument("--union-margin", type=float, help="the fit's union_margin (default: the installed one)")
    p.add_argument("--far-union-margin", type=float, help="the fit's far_union_margin (default: installed)")
    p.add_argument("--margins", action="store_true", help="the hits for a range of each margin")
    p.add_argument("--sweeps", action="store_true", help="refit with sweep counts (benchmarks/sweep_counts.py)")
    p.add_argument("--far-patch", action="store_true", help="refit the far field's seconds a unit and a patch")
    p.add_argument("--union", action="store_true", help="refit the union CG's iterations and seconds")
    p.add_argument("--latest", action="store_true", help="a variant's last row per scene (re-runs replace)")
    args = p.parse_args(argv)
    from twoscale.micro.costmodel import FITTED

    rows = forced_rows(args.forced, args.latest)
    bounds = (args.min_seconds, args.max_sweeps)
    flags = (args.sweeps, args.far_patch, args.union)
    refit = refitted(rows, bounds, *flags)
    kept = {"union_margin": args.union_margin, "far_union_margin": args.far_union_margin}
    kept = {k: v for k, v in kept.items() if v is not None}
    refit = dataclasses.replace(refit, **kept)
    found = scenes(rows)
    h0, n0, before, s0 = score(found, FITTED, args.within)
    h1, n1, after, s1 = score(found, refit, args.within)
    print("| seed | scene | patches | control | installed | refit | fastest | measured micro s (union / exact / far) |")
    print("|---|---|---|---|---|---|---|---|")
    worse = []
    for sc, b, a in zip(found, before, after):
        m = sc["measured"]
        fastest = min(m, key=m.get)
        cells = " / ".join(f"{m[k]:.3g}" if k in m else "-" for k in ("union-cg", "block-gs", "two-level"))
        ctl = sc["auto"].get("control", "?") + (" tilt" if sc["auto"].get("tilt") else "")
        print(
            f"| {sc['seed']} | #{sc['scene']} | {sc['auto'].get('patches')} | {ctl} | {b} | {a} | {fastest} | {cells} |"
        )
        if a in m and b in m and m[a] > max(args.worse * m[b], m[b] + SLACK):
            worse.append(f"  seed {sc['seed']} #{sc['scene']}: {a} {m[a]:.3g} s against {b} {m[b]:.3g} s")
    print(
        f"installed model: the fastest (or within {args.within:g}x) on {h0} of {n0} scenes; picks' s / fastest {s0:.3f}"
    )
    print(f"refit: on {h1} of {n1} ({s1:.3f}); {sum(a != b for a, b in zip(before, after))} picks change")
    h2, n2, _, s2 = score(found, left_out(rows, bounds, kept, *flags), args.within)
    print(f"refit on the other scenes' rows only (each scene left out of its own fit): on {h2} of {n2} ({s2:.3f})")
    print(f"refit's pick over {args.worse:g}x slower than the installed one's: {len(worse)}")
    print("\n".join(worse))
    if args.margins:
        print("installed model, hits by margin:")
        margins(found, FITTED, args.within)
        print("refit, hits by margin:")
        margins(found, refit, args.within)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
