"""Figures of a study, drawn from its tidy tables (PNG; units mm, N, MPa).

* ``load_approach_<scene>.png``: total load and contact area against the approach, one
  line per body (first position);
* ``asperity_forces_<scene>_<body>.png``: each tip's force against the total load (first
  position; the 30 most loaded tips when there are more);
* ``track_<scene>_<body>.png`` (with several positions): along the positions, each tip's
  force and the total, one panel per load;
* ``indicators_<scene>.png`` (with several bodies): e_M and e_m of each body against the
  first, per load (a point per position, the line through their means).

matplotlib is imported here only. Cases without a result are left out of every figure.
"""
from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from ..plot._figure import new_figure, save_png

#: Tips drawn individually at most; the most loaded are kept.
MAX_TIPS = 12   # lines per figure: each gets a legend entry


def _solved(case_rows: list) -> list:
    return [r for r in case_rows if r["total_load_N"] is not None]


def _load_axis(kind: str) -> str:
    return "total load W (N)" if kind == "total" else "approach d (mm)"


def load_approach(case_rows: list, scene: str, path: Path, meta: dict) -> Path:
    fig = new_figure((9.0, 3.8), 110)
    ax_w, ax_a = fig.subplots(1, 2)
    lines = defaultdict(list)
    for r in _solved(case_rows):
        if r["scene"] == scene and r["position"] == 0:
            lines[r["body"]].append((r["approach_mm"], r["total_load_N"], r["contact_area_mm2"]))
    for body, pts in lines.items():
        d, W, A = np.array(sorted(pts)).T
        ax_w.plot(d, W, "o-", label=body)
        ax_a.plot(d, A, "o-", label=body)
    ax_w.set(xlabel="approach d (mm)", ylabel="total load (N)", title=f"{scene}: load against approach")
    ax_a.set(xlabel="approach d (mm)", ylabel="contact area (mm$^2$)", title="contact area against approach")
    ax_w.legend(fontsize=8)
    fig.tight_layout()
    return save_png(fig, path, title=f"{scene}: load and contact area against approach", meta=meta)


def _top_tips(tips: list, n: int = MAX_TIPS) -> set:
    peak = defaultdict(float)
    for t in tips:
        peak[t["asperity"]] = max(peak[t["asperity"]], t["force_N"])
    return set(sorted(peak, key=lambda k: -peak[k])[:n])


def asperity_forces(case_rows: list, tip_rows: list, scene: str, body: str, path: Path, meta: dict) -> Path:
    total = {r["key"]: r["total_load_N"] for r in _solved(case_rows)}
    tips = [t for t in tip_rows if t["scene"] == scene and t["body"] == body and t["position"] == 0]
    keep = _top_tips(tips)
    series = defaultdict(list)
    for t in tips:
        if t["asperity"] in keep:
            series[t["asperity"]].append((total[t["key"]], t["force_N"]))
    fig = new_figure((6.4, 4.4), 110)
    ax = fig.subplots()
    for k in sorted(series):
        W, F = np.array(sorted(series[k])).T
        ax.plot(W, F, ".-", lw=0.8, label=f"tip {k}")
    note = f" ({len(keep)} most loaded tips)" if len({t['asperity'] for t in tips}) > len(keep) else ""
    ax.set(xlabel="total load (N)", ylabel="tip force (N)", title=f"{scene} on {body}: force per tip{note}")
    if len(series) <= 12:
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return save_png(fig, path, title=f"{scene} on {body}: force per tip against load", meta=meta)


def track(case_rows: list, tip_rows: list, scene: str, body: str, path: Path, meta: dict) -> Path:
    mine = [r for r in _solved(case_rows) if r["scene"] == scene and r["body"] == body]
    loads = sorted({(r["load_kind"], r["load"]) for r in mine})
    fig = new_figure((6.4, 2.6 * max(1, len(loads)) + 0.6), 110)
    axes = np.atleast_1d(fig.subplots(max(1, len(loads)), 1, sharex=True))
    for ax, (kind, value) in zip(axes, loads):
        rows = [r for r in mine if (r["load_kind"], r["load"]) == (kind, value)]
        s = np.array(sorted({r["distance_mm"] for r in rows}))
        where = {r["key"]: r["distance_mm"] for r in rows}
        tips = [t for t in tip_rows if t["key"] in where]
        for k in sorted(_top_tips(tips)):  # at most MAX_TIPS lines, each in the legend  # a tip off the footprint carries nothing: 0
            F = dict((where[t["key"]], t["force_N"]) for t in tips if t["asperity"] == k)
            ax.plot(s, [F.get(x, 0.0) for x in s], lw=0.8, label=f"tip {k}")
        total = dict((r["distance_mm"], r["total_load_N"]) for r in rows)
        right = ax.twinx()  # the total is tens of tips' forces: its own scale
        right.plot(s, [total[x] for x in s], "k--", lw=1.5, label="total (right axis)")
        right.set_ylim(0.0, 1.15 * max(total.values()))
        right.set_ylabel("total load (N)")
        right.legend(fontsize=7, loc="upper right")
        ax.legend(fontsize=6, ncol=2, loc="upper left")
        ax.set(ylabel="tip force (N)", title=f"{scene} on {body}, {kind} = {value:g} {'N' if kind == 'total' else 'mm'}")
    axes[-1].set_xlabel("distance along the positions (mm)")
    fig.tight_layout()
    return save_png(fig, path, title=f"{scene} on {body}: tip forces along the track", meta=meta)


def indicators(ind_rows: list, scene: str, path: Path, meta: dict) -> Path:
    rows = [r for r in ind_rows if r["scene"] == scene]
    fig = new_figure((9.0, 3.8), 110)
    axes = fig.subplots(1, 2)
    kind = rows[0]["load_kind"] if rows else "total"
    for ax, name in zip(axes, ("e_M_percent", "e_m_percent")):
        for body in dict.fromkeys(r["body"] for r in rows):
            pts = [(r["load"], r[name]) for r in rows if r["body"] == body and r[name] is not None]
            if not pts:
                continue
            x, y = np.array(pts).T
            ax.plot(x, y, ".", alpha=0.4)
            xs = np.unique(x)
            ax.plot(xs, [y[x == v].mean() for v in xs], "o-", color=ax.lines[-1].get_color(),
                    label=f"{body} vs {rows[0]['reference']}")
        ax.set(xlabel=_load_axis(kind), ylabel=name.replace("_percent", " (%)"), title=f"{scene}: {name[:3]}")
        if ax.lines:
            ax.legend(fontsize=8)
    fig.tight_layout()
    return save_png(fig, path, title=f"{scene}: e_M and e_m between bodies", meta=meta)


def write_figures(out: Path, case_rows: list, tip_rows: list, ind_rows: list, *, track_positions: bool,
                  meta: dict) -> list:
    """Every figure of the study into ``out/figures``; returns the paths written."""
    folder = Path(out) / "figures"
    written = []
    solved = _solved(case_rows)
    for scene in dict.fromkeys(r["scene"] for r in solved):
        bodies = list(dict.fromkeys(r["body"] for r in solved if r["scene"] == scene))
        written.append(load_approach(case_rows, scene, folder / f"load_approach_{scene}.png", meta))
        for body in bodies:
            written.append(asperity_forces(case_rows, tip_rows, scene, body,
                                           folder / f"asperity_forces_{scene}_{body}.png", meta))
            if track_positions:
                written.append(track(case_rows, tip_rows, scene, body, folder / f"track_{scene}_{body}.png", meta))
        if any(r["scene"] == scene for r in ind_rows):
            written.append(indicators(ind_rows, scene, folder / f"indicators_{scene}.png", meta))
    return written
