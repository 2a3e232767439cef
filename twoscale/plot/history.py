"""``history.png``: load, approach, contact area and the most loaded asperities' forces
against time (log time axis when the output times span decades)."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from ._figure import new_figure, save_png
from .labels import join_title, scene_text

#: Asperities whose force is drawn (the most loaded at the last output time).
MOST_LOADED = 8


def _log_axis(times: np.ndarray) -> bool:
    positive = times[times > 0]
    return positive.size >= 2 and positive.max() / positive.min() >= 100.0


def history_figure(result, path, *, scene=None, name: str | None = None) -> Path:
    """Four panels against time: total load (N), approach (mm), contact area (mm^2), and
    the forces (N) of the :data:`MOST_LOADED` most loaded asperities (numbered from 1).
    With a log time axis, the instant t = 0 is drawn at the first positive time's tenth.
    The title names the scene (``name``, e.g. the scene file's stem) and its body."""
    t = np.asarray(result.times, dtype=float)
    log = _log_axis(t)
    if log:
        first = t[t > 0].min()
        t = np.where(t > 0, t, 0.1 * first)
    fig = new_figure((9.0, 6.5), 110)
    axes = fig.subplots(2, 2, sharex=True)
    panels = [
        (axes[0, 0], result.total_load, "total load (N)"),
        (axes[0, 1], result.penetration, "approach (mm)"),
        (axes[1, 0], result.contact_area, "contact area (mm$^2$)"),
    ]
    for ax, y, label in panels:
        ax.plot(t, y, ".-", lw=1.2, ms=3)
        ax.set_ylabel(label)
    ax = axes[1, 1]
    order = np.argsort(-result.forces[-1])[:MOST_LOADED]
    for k in order:
        ax.plot(t, result.forces[:, k], lw=1.0, label=f"{k + 1}")
    ax.set_ylabel("asperity force (N)")
    if len(order) > 1:
        ax.legend(title="asperity", fontsize=7, title_fontsize=7, ncol=2)
    for a in axes.ravel():
        if log:
            a.set_xscale("log")
        a.grid(alpha=0.3)
    for a in axes[1]:
        a.set_xlabel("time (s)" + (" (t = 0 drawn at the left)" if log and result.times[0] == 0 else ""))
    what = f"history, {result.history.kind} control, {len(result.steps)} steps, {result.method}"
    fig.suptitle(join_title(scene_text(scene, name), what))
    fig.tight_layout(rect=(0, 0.02, 1, 0.97))
    record = scene if isinstance(scene, Mapping) else None  # a Scene object names the body only
    return save_png(fig, path, title="history", scene=record)
