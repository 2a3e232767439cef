"""Figures of a study, drawn from its tidy tables (PNG; units mm, N, MPa).

* ``load_approach_<scene>.png``: total load and contact area against the approach, one
  line per body (first position);
* ``asperity_forces_<scene>_<body>.png``: each tip's force against the total load (first
  position; the 10 most loaded tips when there are more);
* ``track_<scene>_<body>.png`` (with several positions): along the positions, each tip's
  force and the total, one panel per load;
* ``indicators_<scene>.png`` (with several bodies): e_M and e_m of each body against the
  first, per load (a point per position, the line through their means).

Each panel is a function that takes ``ax=`` and returns the Figure (``plot_*``); the
writers compose them. Tips keep the CSV's numbers (from 1) and one colour each (at most
ten lines, ten distinct colours); legends sit beside the plot, never over a line.
matplotlib is imported here only. Cases without a result are left out of every figure.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Mapping

import numpy as np

from ..plot._figure import figure_and_axes, new_figure, save_png
from ..plot.labels import body_text

#: Tips drawn individually at most (the most loaded are kept): one distinct colour each.
MAX_TIPS = 10
#: Distinct colours of the tips' lines (matplotlib's qualitative "tab10").
TIP_COLOURS = tuple(f"C{k}" for k in range(10))
_LEGEND = {"fontsize": 7, "loc": "upper left", "bbox_to_anchor": (1.02, 1.0), "borderaxespad": 0.0, "frameon": False}


def _solved(case_rows: list) -> list:
    return [r for r in case_rows if r["total_load_N"] is not None]


def _load_axis(kind: str) -> str:
    return "total load W (N)" if kind == "total" else "approach d (mm)"


def _on(body: str, bodies: Mapping | None) -> str:
    """``left (140 x 140 x 20 mm block, bonded base)`` from the study's body tables; the
    description alone where the name says no more (``halfspace``: ``half-space``)."""
    inf = (bodies or {}).get(body)
    if inf is None:
        return body
    text = body_text(inf)
    bare = "".join(c for c in text.lower() if c.isalnum())
    return text if "".join(c for c in body.lower() if c.isalnum()) == bare else f"{body} ({text})"


def plot_load_approach(case_rows: list, scene: str, *, quantity: str = "load", ax=None):
    """Total load (``quantity="load"``) or contact area (``"area"``) against the
    approach, one line per body (first position). Returns the Figure."""
    col, label = {"load": ("total_load_N", "total load (N)"), "area": ("contact_area_mm2", "contact area (mm$^2$)")}[
        quantity
    ]
    fig, ax = figure_and_axes(ax, (5.0, 3.8), 110, rect=(0.15, 0.13, 0.6, 0.75))
    lines = defaultdict(list)
    for r in _solved(case_rows):
        if r["scene"] == scene and r["position"] == 0:
            lines[r["body"]].append((r["approach_mm"], r[col]))
    for k, (body, pts) in enumerate(lines.items()):
        d, v = np.array(sorted(pts)).T
        ax.plot(d, v, "o-", color=TIP_COLOURS[k % 10], label=body)
    ax.set(xlabel="approach d (mm)", ylabel=label)
    ax.grid(lw=0.3)
    return fig


def load_approach(case_rows: list, scene: str, path: Path, meta: dict, bodies: Mapping | None = None) -> Path:
    fig = new_figure((10.0, 3.8), 110)
    left, right = fig.add_axes([0.07, 0.14, 0.36, 0.72]), fig.add_axes([0.5, 0.14, 0.36, 0.72])
    plot_load_approach(case_rows, scene, quantity="load", ax=left)
    plot_load_approach(case_rows, scene, quantity="area", ax=right)
    right.legend(**_LEGEND)
    title = f"{scene}: total load and contact area against the approach, per body"
    fig.suptitle(title + _bodies_line(case_rows, scene, bodies), fontsize=9)
    return save_png(fig, path, title=title, meta=meta)


def _bodies_line(case_rows: list, scene: str, bodies: Mapping | None) -> str:
    names = dict.fromkeys(r["body"] for r in _solved(case_rows) if r["scene"] == scene)
    return "\n" + "; ".join(_on(b, bodies) for b in names) if bodies else ""


def _top_tips(tips: list, n: int = MAX_TIPS) -> list:
    """The ``n`` tips of largest force (CSV numbers), most loaded first."""
    peak = defaultdict(float)
    for t in tips:
        peak[t["asperity"]] = max(peak[t["asperity"]], t["force_N"])
    return sorted(peak, key=lambda k: (-peak[k], k))[:n]


def plot_tip_forces(case_rows: list, tip_rows: list, scene: str, body: str, *, ax=None):
    """Each tip's force against the total load (first position; the ``MAX_TIPS`` most
    loaded), one distinct colour per tip, legend in load order. Returns the Figure."""
    total = {r["key"]: r["total_load_N"] for r in _solved(case_rows)}
    tips = [t for t in tip_rows if t["scene"] == scene and t["body"] == body and t["position"] == 0]
    fig, ax = figure_and_axes(ax, (6.4, 4.4), 110, rect=(0.1, 0.12, 0.68, 0.76))
    for c, k in enumerate(_top_tips(tips)):
        W, F = np.array(sorted((total[t["key"]], t["force_N"]) for t in tips if t["asperity"] == k)).T
        ax.plot(W, F, ".-", lw=0.9, color=TIP_COLOURS[c], label=f"tip {k}")
    ax.set(xlabel="total load (N)", ylabel="tip force (N)")
    ax.grid(lw=0.3)
    if ax.lines:
        ax.legend(**_LEGEND)
    return fig


def asperity_forces(
    case_rows: list, tip_rows: list, scene: str, body: str, path: Path, meta: dict, bodies: Mapping | None = None
) -> Path:
    fig = plot_tip_forces(case_rows, tip_rows, scene, body)
    tips = {t["asperity"] for t in tip_rows if t["scene"] == scene and t["body"] == body and t["position"] == 0}
    note = f" ({MAX_TIPS} most loaded of {len(tips)} tips)" if len(tips) > MAX_TIPS else ""
    title = f"{scene} on {_on(body, bodies)}: force per tip against load{note}"
    fig.axes[0].set_title(title.replace(": ", ":\n", 1), fontsize=9)
    return save_png(fig, path, title=title, meta=meta)


def plot_track(case_rows: list, tip_rows: list, scene: str, body: str, load: tuple, *, ax=None):
    """Along the positions at one load ``(kind, value)``: each of the ``MAX_TIPS`` most
    loaded tips' force (left axis; 0 off the footprint) and the total (right axis,
    dashed black). Returns the Figure."""
    fig, ax = figure_and_axes(ax, (6.4, 3.2), 110, rect=(0.1, 0.15, 0.62, 0.72))
    rows = [
        r
        for r in _solved(case_rows)
        if r["scene"] == scene and r["body"] == body and (r["load_kind"], r["load"]) == tuple(load)
    ]
    s = np.array(sorted({r["distance_mm"] for r in rows}))
    where = {r["key"]: r["distance_mm"] for r in rows}
    tips = [t for t in tip_rows if t["key"] in where]
    for c, k in enumerate(_top_tips(tips)):
        F = {where[t["key"]]: t["force_N"] for t in tips if t["asperity"] == k}
        ax.plot(s, [F.get(x, 0.0) for x in s], lw=0.9, color=TIP_COLOURS[c], label=f"tip {k}")
    total = {r["distance_mm"]: r["total_load_N"] for r in rows}
    right = ax.twinx()  # the total is tens of tips' forces: its own scale
    right.plot(s, [total[x] for x in s], "k--", lw=1.5, label="total (right axis)")
    right.set_ylim(0.0, 1.15 * max(total.values(), default=1.0))
    right.set_ylabel("total load (N)")
    handles = ax.get_legend_handles_labels()
    extra = right.get_legend_handles_labels()
    ax.legend(handles[0] + extra[0], handles[1] + extra[1], **{**_LEGEND, "bbox_to_anchor": (1.15, 1.0)})
    kind, value = load
    ax.set(ylabel="tip force (N)", xlabel="distance along the positions (mm)")
    ax.set_title(f"{kind} = {value:g} {'N' if kind == 'total' else 'mm'}", fontsize=9)
    ax.grid(lw=0.3)
    return fig


def track(
    case_rows: list, tip_rows: list, scene: str, body: str, path: Path, meta: dict, bodies: Mapping | None = None
) -> Path:
    mine = [r for r in _solved(case_rows) if r["scene"] == scene and r["body"] == body]
    loads = sorted({(r["load_kind"], r["load"]) for r in mine}) or [("total", 0.0)]
    H = 2.6 * len(loads) + 0.8
    fig = new_figure((7.6, H), 110)
    for i, load in enumerate(loads):
        bottom = (H - 0.7 - 2.6 * (i + 1) + 0.55) / H
        plot_track(case_rows, tip_rows, scene, body, load, ax=fig.add_axes([0.09, bottom, 0.6, 1.75 / H]))
    title = f"{scene} on {_on(body, bodies)}: tip forces along the track"
    fig.suptitle(title, fontsize=9)
    return save_png(fig, path, title=title, meta=meta)


def plot_indicator(ind_rows: list, scene: str, name: str = "e_M_percent", *, ax=None):
    """``e_M_percent`` or ``e_m_percent`` of each body against the reference body, per
    load: a faint point per position, the line through their means. Returns the Figure."""
    rows = [r for r in ind_rows if r["scene"] == scene]
    fig, ax = figure_and_axes(ax, (5.0, 3.8), 110, rect=(0.14, 0.13, 0.6, 0.75))
    kind = rows[0]["load_kind"] if rows else "total"
    for c, body in enumerate(dict.fromkeys(r["body"] for r in rows)):
        pts = [(r["load"], r[name]) for r in rows if r["body"] == body and r[name] is not None]
        if not pts:
            continue
        x, y = np.array(pts).T
        ax.plot(x, y, ".", alpha=0.4, color=TIP_COLOURS[c % 10])
        xs = np.unique(x)
        ax.plot(
            xs,
            [y[x == v].mean() for v in xs],
            "o-",
            color=TIP_COLOURS[c % 10],
            label=f"{body} vs {rows[0]['reference']}",
        )
    ax.set(xlabel=_load_axis(kind), ylabel=name.replace("_percent", " (%)"))
    ax.grid(lw=0.3)
    return fig


def indicators(ind_rows: list, scene: str, path: Path, meta: dict, bodies: Mapping | None = None) -> Path:
    fig = new_figure((10.0, 3.8), 110)
    left, right = fig.add_axes([0.07, 0.14, 0.36, 0.72]), fig.add_axes([0.5, 0.14, 0.36, 0.72])
    plot_indicator(ind_rows, scene, "e_M_percent", ax=left)
    plot_indicator(ind_rows, scene, "e_m_percent", ax=right)
    if right.lines or left.lines:
        (right if right.lines else left).legend(**_LEGEND)
    title = f"{scene}: e_M (tip forces) and e_m (sensor map) of each body against the first, in percent"
    names = dict.fromkeys(r["body"] for r in ind_rows if r["scene"] == scene)
    line = "\n" + "; ".join(_on(b, bodies) for b in names) if bodies else ""
    fig.suptitle(title + line, fontsize=9)
    return save_png(fig, path, title=title, meta=meta)


def write_figures(
    out: Path,
    case_rows: list,
    tip_rows: list,
    ind_rows: list,
    *,
    track_positions: bool,
    meta: dict,
    bodies: Mapping | None = None,
) -> list:
    """Every figure of the study into ``out/figures``; returns the paths written.

    ``bodies``: body name -> its ``[influence]`` table, to name each body in the titles.
    """
    folder = Path(out) / "figures"
    written = []
    solved = _solved(case_rows)
    for scene in dict.fromkeys(r["scene"] for r in solved):
        names = list(dict.fromkeys(r["body"] for r in solved if r["scene"] == scene))
        written.append(load_approach(case_rows, scene, folder / f"load_approach_{scene}.png", meta, bodies))
        for body in names:
            written.append(
                asperity_forces(
                    case_rows, tip_rows, scene, body, folder / f"asperity_forces_{scene}_{body}.png", meta, bodies
                )
            )
            if track_positions:
                written.append(
                    track(case_rows, tip_rows, scene, body, folder / f"track_{scene}_{body}.png", meta, bodies)
                )
        if any(r["scene"] == scene for r in ind_rows):
            written.append(indicators(ind_rows, scene, folder / f"indicators_{scene}.png", meta, bodies))
    return written
