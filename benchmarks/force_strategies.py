"""Each micro-step strategy forced on sweep scenes, against the policy's own prediction.

For each scene of the sweep (``benchmarks/sweep.py``'s draws of ``--seed``) the default solve runs
once to read the policy's choice and its predicted CPU seconds per candidate
(``details.micro.choice.estimates["seconds"]``), then every variant runs ``--repeat`` times,
interleaved (the variants' order rotated each round), each in a fresh process,
single-threaded, its CPU time limited (``--cpu-limit``). Variants:

* ``auto``: the default solve (the policy's choice and its fallbacks);
* ``union-cg``: ``iteration="union-cg"``;
* ``block-gs``: ``iteration="block-gs"``, exact coupling;
* ``two-level``: ``iteration="two-level"``, exact coupling (what the policy runs for its
  ``block-gs`` candidate under load control);
* ``far``: ``iteration="two-level", far_tol=0.3`` (its ``two-level`` candidate).

Printed per scene and variant (one JSON line, and with ``--table`` a markdown table): the
median CPU seconds of the whole solve and of the micro step's attempts (their wall time
at the solve's CPU/wall share), converged, the
largest per-tip force difference from the default solve's over its largest force, and the
prediction of the candidate the variant stands for. Each row carries the seed and the
policy's figures (``figures``: patches, coverage, box cells, merged contacts, height map),
so its choice can be made again under another cost model (:func:`twoscale.micro.policy.decide`).
A scene's map texture is written before the clock starts, as the sweep times it.

Variants that cannot finish are not run: the exact ones (``block-gs``, ``two-level``) on
more patches than the policy couples exactly (``exact_max_patches``, N^2 pairs), the union
CG on a box of over ``--max-union-cells`` cells (about 0.5 kB a cell: the machine's memory),
and with ``--max-ratio`` a candidate predicted over that many times the policy's choice.

Usage::

    python benchmarks/force_strategies.py 28 109 151 --seed 0 --repeat 2 --out forced.jsonl --table forced.md
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

VARIANTS = {
    "auto": {},
    "union-cg": {"iteration": "union-cg"},
    "block-gs": {"iteration": "block-gs"},
    "two-level": {"iteration": "two-level"},
    "far": {"iteration": "two-level", "far_tol": 0.3},
}
#: The policy's candidate whose prediction a variant is compared with.
CANDIDATE = {"union-cg": "union-cg", "block-gs": "block-gs", "two-level": "block-gs", "far": "two-level"}


def child(index: int, variant: str, seed: int = 0) -> dict:
    """One solve of scene ``index`` of seed ``seed`` in this process; the figures as a dict."""
    import tempfile

    import twoscale
    import twoscale.driver  # noqa: F401  (imports outside the timed call, as the sweep does)
    import twoscale.micro.driver  # noqa: F401
    from twoscale import scenespace
    from twoscale.io.scene_file import scene_from_dict

    (spec,) = [s for s in scenespace.sweep(200, seed) if s.index == index]
    folder = tempfile.mkdtemp()
    if spec.kind == "tips":
        scene = scenespace.build(spec)
        read = lambda: scene  # noqa: E731
    else:
        table = scenespace.map_table(spec, folder)
        read = lambda: scene_from_dict(table, base_dir=folder)  # noqa: E731
    t0, c0 = time.perf_counter(), time.process_time()
    sc = read()
    popts = {"progress": False} if sc.influence["kind"] == "block" else None
    res = twoscale.solve(sc, method="twoscale", provider_options=popts, **VARIANTS[variant])
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    micro = getattr(res.details, "micro", None)
    out = {
        "cpu": cpu,
        "wall": wall,
        "converged": bool(res.converged),
        "forces": np.asarray(res.asperities.forces, dtype=float).tolist(),
        "method": res.method,
        "control": spec.control,
        "tilt": bool(spec.tilt),
    }
    if micro is not None:
        est = micro.choice.estimates
        out.update(
            choice=micro.choice.iteration,
            far_tol=micro.choice.far_tol,
            seconds=est.get("seconds"),
            work=est.get("work"),
            patches=est.get("patches"),
            coverage=est.get("coverage"),
            figures={k: v for k, v in est.items() if k not in ("work", "seconds")},
            attempts=[[a.iteration, a.far_tol, a.converged, a.sweeps, round(a.seconds, 3)] for a in micro.attempts],
            # the attempts' wall time at the solve's share of a core (the machine is shared)
            micro_s=sum(a.seconds for a in micro.attempts) * min(cpu / wall, 1.0),
        )
    return out


def _run(index: int, variant: str, cpu_limit: float, seed: int = 0) -> dict:
    def limit():
        resource.setrlimit(resource.RLIMIT_CPU, (int(cpu_limit), int(cpu_limit) + 1))
        os.nice(5)

    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    proc = subprocess.run(
        [sys.executable, os.path.abspath(__file__), "--child", str(index), variant, str(seed)],
        env=env,
        capture_output=True,
        text=True,
        preexec_fn=limit,
    )
    if proc.returncode != 0:
        return {"failed": proc.stderr.strip().splitlines()[-1:] or [f"exit {proc.returncode}"]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def chosen_candidate(auto: dict) -> str:
    """The policy's candidate behind the default solve's choice (its far field or not)."""
    choice = auto.get("choice", "")
    return "two-level" if choice == "two-level" and auto.get("far_tol") is not None else CANDIDATE.get(choice, "")


def runnable(auto: dict, variant: str, max_union_cells: float, max_ratio: float = math.inf) -> bool:
    """Whether ``variant`` can finish on the scene whose default solve gave ``auto``: within
    the bounds above, and predicted at most ``max_ratio`` times the policy's choice."""
    from twoscale.micro.costmodel import FITTED

    figures, seconds = auto.get("figures") or {}, auto.get("seconds") or {}
    chosen = seconds.get(chosen_candidate(auto), 0.0)
    if variant != "auto" and chosen and seconds.get(CANDIDATE[variant], 0.0) > max_ratio * chosen:
        return False
    if variant in ("block-gs", "two-level"):
        return (auto.get("patches") or 0) <= FITTED.exact_max_patches
    if variant == "union-cg":
        return figures.get("box_cells", 0) <= max_union_cells
    return True


def scene(index: int, variants: list, repeat: int, cpu_limit: float, seed: int = 0, bounds=(4e6, math.inf)) -> list:
    """The variants on scene ``index`` of seed ``seed``: one row per variant (``bounds``:
    :func:`runnable`'s ``max_union_cells`` and ``max_ratio``)."""
    auto = _run(index, "auto", cpu_limit, seed)
    variants = [v for v in variants if runnable(auto, v, *bounds)]
    runs: dict = {v: [] for v in variants}
    for r in range(repeat):
        order = variants[r % len(variants) :] + variants[: r % len(variants)]
        for v in order:
            runs[v].append(auto if (v == "auto" and r == 0) else _run(index, v, cpu_limit, seed))
    ref = np.array(auto.get("forces", []))
    rows = []
    for v in variants:
        ok = [x for x in runs[v] if "cpu" in x]
        row = {"seed": seed, "scene": index, "variant": v, "choice": auto.get("choice", auto.get("method"))}
        row["runs"] = len(ok)
        if ok:
            f = np.array(ok[0]["forces"])
            row.update(
                cpu=statistics.median(x["cpu"] for x in ok),
                micro_s=statistics.median(x.get("micro_s", 0.0) for x in ok),
                converged=all(x["converged"] for x in ok),
                attempts=ok[0].get("attempts"),
                force_diff=float(np.max(np.abs(f - ref)) / max(np.abs(ref).max(), 1e-300)) if ref.size else None,
            )
        else:
            row["failed"] = runs[v][0].get("failed")
        seconds = auto.get("seconds") or {}
        row["predicted"] = seconds.get(CANDIDATE[v] if v in CANDIDATE else chosen_candidate(auto))
        row.update(patches=auto.get("patches"), coverage=auto.get("coverage"), work=auto.get("work"))
        row.update(figures=auto.get("figures"), control=auto.get("control"), tilt=auto.get("tilt"))
        rows.append(row)
    return rows


def table(rows: list) -> str:
    out = [
        "| scene | policy | variant | CPU s | micro s | predicted s | meas./pred. | converged | force diff |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        cpu, pred = r.get("cpu"), r.get("predicted")
        factor = f"{r['micro_s'] / pred:.2f}" if cpu is not None and pred else "-"
        out.append(
            f"| #{r['scene']} | {r['choice']} | {r['variant']} | "
            + (f"{cpu:.2f} | {r['micro_s']:.2f}" if cpu is not None else f"failed | {r.get('failed')}")
            + f" | {pred if pred is not None else '-'} | {factor} | {r.get('converged', '-')} | "
            + (f"{r['force_diff']:.1e}" if r.get("force_diff") is not None else "-")
            + " |"
        )
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenes", nargs="*", type=int)
    p.add_argument("--variants", nargs="*", default=list(VARIANTS))
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--seed", type=int, default=0, help="the sweep's seed (benchmarks/sweep.py)")
    p.add_argument("--cpu-limit", type=float, default=60.0, help="s of CPU a solve may take")
    p.add_argument("--max-union-cells", type=float, default=4e6, help="largest box the union CG is forced on")
    p.add_argument("--max-ratio", type=float, default=math.inf, help="largest predicted s over the choice's to run")
    p.add_argument("--out", default="forced.jsonl")
    p.add_argument("--table")
    p.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        print(json.dumps(child(int(args.child[0]), args.child[1], int(args.child[2]))))
        return 0
    rows = []
    for index in args.scenes:
        got = scene(
            index, args.variants, args.repeat, args.cpu_limit, args.seed, (args.max_union_cells, args.max_ratio)
        )
        rows += got
        with open(args.out, "a") as fh:
            for r in got:
                fh.write(json.dumps(r) + "\n")
                print(
                    json.dumps(
                        {k: r.get(k) for k in ("seed", "scene", "variant", "choice", "cpu", "micro_s", "predicted")}
                    )
                )
        if args.table:
            with open(args.table, "w") as fh:
                fh.write(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
