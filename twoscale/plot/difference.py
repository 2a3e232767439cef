"""Where two bodies disagree: a map of the per-tip force difference (e.g. block minus
half-space), one panel per body against a reference body, on one diverging colour scale."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from ..results import ContactResult
from ._figure import new_figure, save_png
from .forces import plot_tip_values
from .labels import join_title
from .scale import ColourScale
from .style import NO_CAPTION, PLAIN, Caption, FigureStyle
from .tips import tip_positions


def difference_text(diff: np.ndarray, ref: np.ndarray, reference: str) -> str:
    """``largest |dF| 1.2 N at tip 4 = 13.9 % of the largest half-space tip force (8.6 N)``."""
    k = int(np.argmax(np.abs(diff)))
    worst, scale = float(abs(diff[k])), float(np.max(np.abs(ref), initial=0.0))
    share = f" = {100 * worst / scale:.3g} % of the largest {reference} tip force ({scale:.3g} N)" if scale > 0 else ""
    return f"largest |dF| {worst:.3g} N at tip {k + 1}{share}"


def difference_map(
    results: Mapping[str, ContactResult],
    path: str | Path,
    *,
    tips,
    reference: str | None = None,
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Per-tip force differences ``F_body - F_reference`` (N) at the tips, as PNG.

    Each panel (:func:`~twoscale.plot.plot_tip_values`, diverging) colours the tips
    loaded in either body by the difference (red: the body carries more than the
    reference, blue: less; every tip numbered when few, else the ten largest changes) on
    a scale symmetric about 0 shared by all panels; its title gives the largest
    difference in N, the tip, and its share of the reference's largest tip force.

    Parameters
    ----------
    results : mapping name -> ContactResult
        At least two results of the same scene (same tips, same order).
    path : path-like
        Output ``.png``.
    tips : (N, 2) array of mm or sequence of Asperity
        Tip positions.
    reference : str, optional
        The body subtracted; default the first of ``results``.
    caption : Caption, optional
        ``title`` (default "force difference per tip", after the scene's ``name`` when
        given); ``scene`` and ``meta`` recorded in the PNG metadata (as in
        :func:`~twoscale.plot.compare_maps`).
    style : FigureStyle, optional
        ``panel_size`` (3.8 inches, width and height of one panel), ``dpi`` (100),
        ``cmap`` ("RdBu_r": a diverging colour map, white at zero).

    Returns
    -------
    Path of the PNG written.
    """
    panel_size, dpi, cmap = style.pick("panel_size", 3.8), style.pick("dpi", 100), style.pick("cmap", "RdBu_r")
    names = list(results)
    reference = names[0] if reference is None else reference
    if reference not in results or len(names) < 2:
        raise ValueError(
            f"difference_map needs a reference among at least two results, got "
            f"reference={reference!r} and results {names!r}"
        )
    xy, _ = tip_positions(tips)
    if xy is None:
        raise ValueError("difference_map needs the tip positions (tips=...)")
    ref = np.asarray(results[reference].forces, dtype=float)
    diffs, loaded = {}, ref > 0
    for key in names:
        if key != reference:
            f = np.asarray(results[key].forces, dtype=float)
            if f.shape != ref.shape or len(xy) != ref.size:
                raise ValueError(f"{key!r} has {f.size} forces, {reference!r} {ref.size}, tips {len(xy)}")
            diffs[key] = f - ref
            loaded |= f > 0
    m = max(float(np.max(np.abs(d))) for d in diffs.values())
    n = len(diffs)
    W, H = n * panel_size + 1.5, panel_size + 1.0
    fig = new_figure((W, H), dpi)
    sc = None
    for k, (key, d) in enumerate(diffs.items()):
        ax = fig.add_axes([(0.6 + k * panel_size) / W, 0.55 / H, 0.8 * panel_size / W, (panel_size - 0.4) / H])
        plot_tip_values(
            xy[loaded],
            d[loaded],
            ax=ax,
            numbers=np.flatnonzero(loaded) + 1,
            diverging=True,
            label="force difference (N)",
            style=FigureStyle(scale=ColourScale(m, m), cmap=cmap, colourbar=False),
        )
        sc = ax.collections[0]
        text = difference_text(d, ref, reference).replace(" = ", "\n= ")
        ax.set_title(f"{key} - {reference}: {text}", fontsize=7)
        if k:
            ax.set_ylabel("")
    cb = fig.colorbar(
        sc, cax=fig.add_axes([(0.7 + (n - 0.15) * panel_size) / W, 0.55 / H, 0.12 / W, (panel_size - 0.4) / H])
    )
    cb.set_label(f"F - F_{reference} (N)")
    title = join_title(caption.name or "", caption.title or "force difference per tip")
    fig.suptitle(title, fontsize=10, y=0.995, va="top")
    return save_png(fig, path, title=title, scene=caption.scene, meta=caption.meta)
