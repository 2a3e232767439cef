"""Figure creation and atomic PNG saving shared by the plotting modules."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Mapping

from .._version import __version__
from ..io.atomic import atomic_output

FOOTER = f"twoscale {__version__} - units mm, N, MPa"


def new_figure(size: tuple[float, float], dpi: int):
    """A matplotlib Figure on an Agg canvas (no pyplot, no global state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    w, h = size
    if not (w > 0 and h > 0 and dpi > 0):
        raise ValueError(f"figure size and dpi must be > 0, got size={size!r}, dpi={dpi!r}")
    fig = Figure(figsize=(w, h), dpi=dpi)
    FigureCanvasAgg(fig)
    fig.text(0.995, 0.005, FOOTER, ha="right", va="bottom", fontsize=6, color="0.4")
    return fig


def figure_and_axes(ax, size: tuple[float, float], dpi: int, rect=(0.1, 0.1, 0.8, 0.8)):
    """``(ax.figure, ax)`` when an Axes is given (a notebook's, say), else a new Figure
    of ``size`` inches (:func:`new_figure`) with one Axes at ``rect`` (figure fractions)."""
    if ax is not None:
        return getattr(ax.figure, "figure", ax.figure), ax  # the root Figure, also of a SubFigure
    fig = new_figure(size, dpi)
    return fig, fig.add_axes(list(rect))


def save_png(
    fig, path: str | Path, *, title: str, scene: Mapping[str, Any] | None = None, meta: Mapping[str, Any] | None = None
) -> Path:
    """Write ``fig`` to ``path`` (PNG) atomically with version, title and scene metadata.

    ``meta``: further JSON-ready entries for the ``Description`` chunk, beside ``units``
    and ``scene`` (e.g. the bodies and loads of a comparison); it may not replace them.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"figure path must end in .png, got {str(path)!r}")
    description = {
        "units": {"length": "mm", "force": "N", "pressure": "MPa"},
        "scene": None if scene is None else dict(scene),
    }
    clash = sorted(set(meta or {}) & set(description))
    if clash:
        raise ValueError(f"meta may not replace {clash} of the PNG description")
    description.update(meta or {})
    meta_png = {"Title": title, "Software": f"twoscale {__version__}", "Description": json.dumps(description)}
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", metadata=meta_png)
    return path
