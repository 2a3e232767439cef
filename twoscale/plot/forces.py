"""Force per asperity: one result (:func:`force_bars`) or several side by side
(:func:`compare_forces`, the paper's Figs. 10-11).

With at most ``FEW_TIPS`` (30) asperities each gets a bar, numbered from 1 as in the
CSV files. With more, bars would be unreadable: the figure shows instead the force
histogram (how many tips carry how much) beside a map of the tips coloured by force
(one result), or beside each body's tip forces against the first body's (several).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..results import ContactResult
from ._figure import new_figure, save_png
from .tips import FEW_TIPS, tip_positions, tips_coloured


def _grouped_bars(ax, series: Mapping[str, np.ndarray]) -> None:
    """Bars of every series for each asperity, numbered from 1 as in the paper."""
    n = len(next(iter(series.values())))
    for name, v in series.items():
        if len(v) != n:
            raise ValueError(f"{name!r} has {len(v)} forces, expected {n} (one per asperity)")
    m = len(series)
    width = 0.8 / m
    x = np.arange(1, n + 1)
    for j, (name, v) in enumerate(series.items()):
        ax.bar(x + (j - (m - 1) / 2) * width, v, width=width, label=name)
    ax.set_xticks(x if n <= 30 else x[::max(1, n // 15)])
    ax.set_xlim(0.4, n + 0.6)
    ax.set_xlabel("asperity")
    ax.set_ylabel("force (N)")
    top = max(float(np.max(v)) for v in series.values())
    ax.set_ylim(0.0, 1.25 * top if top > 0 else 1.0)   # headroom for the legend
    if m > 1:
        ax.legend(fontsize=8, ncol=m, loc="upper center")
    ax.grid(axis="y", lw=0.3)


def force_bars(result: ContactResult, path: str | Path, *, tips=None, macro_forces: Sequence[float] | None = None,
               title: str | None = None, scene: Mapping[str, Any] | None = None,
               size: tuple[float, float] = (6.4, 4.0), dpi: int = 100) -> Path:
    """Force per asperity (integral of the final pressure over its cells) as PNG.

    Parameters
    ----------
    result : ContactResult
    path : path-like
        Output ``.png``.
    tips : (N, 2) array of mm or sequence of Asperity, optional
        Tip positions: with more than ``FEW_TIPS`` tips, the map of tips coloured by
        force is drawn beside the histogram.
    macro_forces : (N,) array, optional
        Macro-step tip forces, N, drawn beside the final forces (a second histogram
        with many tips).
    title : str, optional
        Default: method and total load.
    scene : mapping, optional
        Recorded in the PNG metadata.
    size : (float, float), default (6.4, 4.0)
        Figure size, inches.
    dpi : int, default 100

    Returns
    -------
    Path of the PNG written.
    """
    forces = np.asarray(result.forces, dtype=float)
    series = {"final pressure": forces}
    if macro_forces is not None:
        macro = np.asarray(macro_forces, float).ravel()
        if macro.shape != forces.shape:
            raise ValueError(f"macro_forces has {macro.size} values, expected "
                             f"{forces.size} (one per asperity)")
        series = {"macro step": macro, **series}
    if title is None:
        title = f"{result.method}: force per asperity, total {float(result.total_load):.4g} N"
    n = forces.size
    if n <= FEW_TIPS:
        fig = new_figure(size, dpi)
        ax = fig.add_axes([0.11, 0.14, 0.86, 0.76])
        _grouped_bars(ax, series)
        ax.set_title(title, fontsize=10)
        return save_png(fig, path, title=title, scene=scene)
    xy, _ = tip_positions(tips)
    fig = new_figure((size[0] * 1.6, size[1] * 1.1) if xy is not None else size, dpi)
    ax = fig.add_axes([0.08, 0.13, 0.36, 0.72] if xy is not None else [0.11, 0.14, 0.86, 0.72])
    _histograms(ax, series)
    if xy is not None:
        from matplotlib.colors import Normalize

        mx = fig.add_axes([0.52, 0.13, 0.36, 0.72])
        top = float(forces.max())
        sc = tips_coloured(mx, xy, forces, norm=Normalize(0.0, top if top > 0 else 1.0),
                           cmap="viridis", label="force (N)")
        fig.colorbar(sc, cax=fig.add_axes([0.90, 0.13, 0.015, 0.72])).set_label("force (N)")
        mx.set_title("tips coloured by force", fontsize=9)
    fig.suptitle(f"{title} ({n} tips)", fontsize=10)
    return save_png(fig, path, title=title, scene=scene)


def _histograms(ax, series: Mapping[str, np.ndarray]) -> None:
    """Step histograms of the tip forces of every series on shared bins (no bars)."""
    allv = np.concatenate([np.asarray(v, float) for v in series.values()])
    edges = np.histogram_bin_edges(allv, bins=min(60, max(10, int(np.sqrt(allv.size)))))
    for j, (name, v) in enumerate(series.items()):
        counts, _ = np.histogram(v, bins=edges)
        ax.stairs(counts, edges, label=name, fill=(j == len(series) - 1 and len(series) == 1),
                  linewidth=1.2)
    ax.set_xlabel("force per tip (N)")
    ax.set_ylabel("number of tips")
    ax.grid(lw=0.3)
    if len(series) > 1:
        ax.legend(fontsize=8)


def compare_forces(results: Mapping[str, ContactResult], path: str | Path, *,
                   measured: Sequence[float] | None = None, title: str | None = None,
                   scene: Mapping[str, Any] | None = None, meta: Mapping[str, Any] | None = None,
                   size: tuple[float, float] = (7.2, 4.0), dpi: int = 100) -> Path:
    """Forces per asperity of several results side by side (paper Figs. 10-11), as PNG.

    Parameters
    ----------
    results : mapping name -> ContactResult
        One bar per asperity each, in mapping order (at least one; same asperity count).
    path : path-like
        Output ``.png``.
    measured : (N,) array, optional
        Measured tip forces, N, drawn first.
    title : str, optional
        Default "force per asperity".
    scene : mapping, optional
        Recorded in the PNG metadata.
    meta : mapping, optional
        Further JSON-ready entries of the PNG ``Description`` (e.g. the bodies compared).
    size : (float, float), default (7.2, 4.0)
        Figure size, inches.
    dpi : int, default 100

    Returns
    -------
    Path of the PNG written.
    """
    if not results:
        raise ValueError("compare_forces needs at least one result, got none")
    series = {}
    if measured is not None:
        series["measured"] = np.asarray(measured, float)
    series.update({name: np.asarray(r.forces, dtype=float) for name, r in results.items()})
    title = title or "force per asperity"
    n = len(next(iter(series.values())))
    if n <= FEW_TIPS:
        fig = new_figure(size, dpi)
        ax = fig.add_axes([0.1, 0.14, 0.87, 0.76])
        _grouped_bars(ax, series)
        ax.set_title(title, fontsize=10)
        return save_png(fig, path, title=title, scene=scene, meta=meta)
    fig = new_figure((size[0] * 1.4, size[1] * 1.1), dpi)
    _histograms(fig.add_axes([0.08, 0.13, 0.38, 0.72]), series)
    _parity(fig.add_axes([0.58, 0.13, 0.38, 0.72]), series)
    fig.suptitle(f"{title} ({n} tips)", fontsize=10)
    return save_png(fig, path, title=title, scene=scene, meta=meta)


def _parity(ax, series: Mapping[str, np.ndarray]) -> None:
    """Each series' tip forces against the first series' (one dot per tip; y = x dashed)."""
    names = list(series)
    ref = np.asarray(series[names[0]], float)
    for name in names[1:]:
        v = np.asarray(series[name], float)
        if v.shape != ref.shape:
            raise ValueError(f"{name!r} has {v.size} forces, expected {ref.size} (one per asperity)")
        ax.scatter(ref, v, s=4, label=name, alpha=0.7, linewidths=0)
    top = max(float(np.max(v)) for v in series.values())
    top = top if top > 0 else 1.0
    ax.plot([0, top], [0, top], "--", color="0.4", lw=0.8)
    ax.set_xlim(0, 1.05 * top)
    ax.set_ylim(0, 1.05 * top)
    ax.set_aspect("equal")
    ax.set_xlabel(f"force per tip, {names[0]} (N)")
    ax.set_ylabel("force per tip (N)")
    ax.grid(lw=0.3)
    if len(names) > 1:
        ax.legend(fontsize=8, markerscale=2)
