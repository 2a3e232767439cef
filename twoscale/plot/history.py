"""``history.png``: load, approach, contact area and the most loaded asperities' forces
against time (log time axis when the output times span decades and the history has no short
late segment, such as an unloading after a long hold, that it would squeeze)."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from ._figure import new_figure, save_png
from .labels import join_title, scene_text

#: Asperities whose force is drawn (the most loaded at the last output time).
MOST_LOADED = 8


#: A log time axis needs the output times to span this ratio ...
LOG_SPAN = 100.0
#: ... and every segment of the history after t = 0 to end at least this ratio past its
#: start (a tenth of a decade): an unloading from 10 to 12 s, after a hold from 0.5 s,
#: would be a sliver at the right edge of a log axis.
LOG_SEGMENT = 10.0**0.1


def _log_axis(times: np.ndarray, kinks=()) -> bool:
    """Whether the time axis is logarithmic: the output times span decades and no segment of
    the history (between its points ``kinks``, s) after t = 0 is squeezed to a sliver."""
    positive = times[times > 0]
    if not (positive.size >= 2 and positive.max() / positive.min() >= LOG_SPAN):
        return False
    starts = np.asarray(kinks, dtype=float)
    late = starts[:-1] > 0
    return bool(np.all(starts[1:][late] / starts[:-1][late] >= LOG_SEGMENT))


def history_figure(result, path, *, scene=None, name: str | None = None) -> Path:
    """Four panels against time: total load (N), approach (mm), contact area (mm^2), and
    the forces (N) of the :data:`MOST_LOADED` most loaded asperities (numbered from 1).
    With a log time axis (:func:`_log_axis`), the instant t = 0 is drawn at the first
    positive time's tenth.
    The title names the scene (``name``, e.g. the scene file's stem) and its body."""
    t = np.asarray(result.times, dtype=float)
    log = _log_axis(t, result.history.kinks)
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
