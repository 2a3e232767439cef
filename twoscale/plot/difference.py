"""Where two bodies disagree: a map of the per-tip force difference (e.g. block minus
half-space), one panel per body against a reference body, on one diverging colour scale."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..results import ContactResult
from ._figure import new_figure, save_png
from .tips import tip_positions, tips_coloured


def difference_map(results: Mapping[str, ContactResult], path: str | Path, *, tips,
                   reference: str | None = None, title: str | None = None,
                   scene: Mapping[str, Any] | None = None, meta: Mapping[str, Any] | None = None,
                   panel_size: float = 3.8, dpi: int = 100, cmap: str = "RdBu_r") -> Path:
    """Per-tip force differences ``F_body - F_reference`` (N) at the tips, as PNG.

    Each panel colours the tips by the difference (red: the body carries more than the
    reference, blue: less; tips numbered from 1 when few) on a scale symmetric about 0
    shared by all panels; its title gives the largest difference in N and in percent of
    the reference's largest tip force.

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
    title : str, optional
        Default "force difference per tip".
    scene, meta : mapping, optional
        Recorded in the PNG metadata (as in :func:`~twoscale.plot.compare_maps`).
    panel_size : float, default 3.8
        Width and height of one panel, inches.
    dpi : int, default 100
    cmap : str, default "RdBu_r"
        A diverging colour map (white at zero).

    Returns
    -------
    Path of the PNG written.
    """
    names = list(results)
    reference = names[0] if reference is None else reference
    if reference not in results or len(names) < 2:
        raise ValueError(f"difference_map needs a reference among at least two results, got "
                         f"reference={reference!r} and results {names!r}")
    xy, _ = tip_positions(tips)
    if xy is None:
        raise ValueError("difference_map needs the tip positions (tips=...)")
    ref = np.asarray(results[reference].forces, dtype=float)
    diffs = {}
    for name in names:
        if name != reference:
            f = np.asarray(results[name].forces, dtype=float)
            if f.shape != ref.shape or len(xy) != ref.size:
                raise ValueError(f"{name!r} has {f.size} forces, {reference!r} {ref.size}, tips {len(xy)}")
            diffs[name] = f - ref
    from matplotlib.colors import Normalize

    m = max(float(np.max(np.abs(d))) for d in diffs.values())
    norm = Normalize(-m if m > 0 else -1.0, m if m > 0 else 1.0)
    scale = float(np.max(np.abs(ref)))
    n = len(diffs)
    W, H = n * panel_size + 1.5, panel_size + 0.9
    fig = new_figure((W, H), dpi)
    sc = None
    for k, (name, d) in enumerate(diffs.items()):
        ax = fig.add_axes([(0.6 + k * panel_size) / W, 0.55 / H, 0.8 * panel_size / W, (panel_size - 0.4) / H])
        sc = tips_coloured(ax, xy, d, norm=norm, cmap=cmap, label="force difference (N)")
        worst = float(np.max(np.abs(d)))
        share = f" ({100 * worst / scale:.3g} %)" if scale > 0 else ""
        ax.set_title(f"{name} - {reference}\nmax |dF| {worst:.3g} N{share}", fontsize=8)
        if k:
            ax.set_ylabel("")
    cb = fig.colorbar(sc, cax=fig.add_axes([(0.7 + (n - 0.15) * panel_size) / W, 0.55 / H, 0.12 / W, (panel_size - 0.4) / H]))
    cb.set_label(f"F - F_{reference} (N)")
    title = title or "force difference per tip"
    fig.suptitle(title, fontsize=10, y=0.995, va="top")
    return save_png(fig, path, title=title, scene=scene, meta=meta)
