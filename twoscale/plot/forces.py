"""Force per asperity: one result (:func:`force_bars`) or several side by side
(:func:`compare_forces`, the paper's Figs. 10-11).

With at most ``FEW_TIPS`` (30) asperities each gets a bar, numbered from 1 as in the
CSV files. With more, bars would be unreadable: the figure shows instead the force
histogram (how many tips carry how much) beside a map of the loaded tips coloured by
force, the most loaded numbered (one result), or beside each body's tip forces against
the first body's (several). Each panel is a function of its own that takes ``ax=`` and
returns the Figure: :func:`plot_forces`, :func:`plot_tip_values`, :func:`plot_parity`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..results import ContactResult
from ._figure import figure_and_axes, new_figure, save_png
from .labels import join_title, scene_text
from .style import NO_CAPTION, PLAIN, Caption, FigureStyle
from .tips import FEW_TIPS, LABELLED, tip_positions, tips_coloured


def _series(forces: Mapping[str, Any]) -> dict:
    """name -> (N,) float array, all of one length."""
    series = {k: np.asarray(getattr(v, "forces", v), dtype=float).ravel() for k, v in forces.items()}
    if not series:
        raise ValueError("no forces to plot, got none")
    n = len(next(iter(series.values())))
    for name, v in series.items():
        if len(v) != n:
            raise ValueError(f"{name!r} has {len(v)} forces, expected {n} (one per asperity)")
    return series


def _grouped_bars(ax, series: Mapping[str, np.ndarray]) -> None:
    """Bars of every series for each asperity, numbered from 1 as in the paper."""
    n = len(next(iter(series.values())))
    m = len(series)
    width = 0.8 / m
    x = np.arange(1, n + 1)
    for j, (name, v) in enumerate(series.items()):
        ax.bar(x + (j - (m - 1) / 2) * width, v, width=width, label=name)
    ax.set_xticks(x if n <= 30 else x[:: max(1, n // 15)])
    ax.set_xlim(0.4, n + 0.6)
    ax.set_xlabel("asperity (number as in the CSV)")
    ax.set_ylabel("force (N)")
    top = max(float(np.max(v)) for v in series.values())
    ax.set_ylim(0.0, 1.25 * top if top > 0 else 1.0)  # headroom: the legend sits above the bars
    if m > 1:
        ax.legend(fontsize=8, ncol=m, loc="upper center", frameon=False)
    ax.grid(axis="y", lw=0.3)


def _histograms(ax, series: Mapping[str, np.ndarray]) -> None:
    """Step histograms of the tip forces of every series on shared bins (no bars)."""
    allv = np.concatenate([np.asarray(v, float) for v in series.values()])
    edges = np.histogram_bin_edges(allv, bins=min(60, max(10, int(np.sqrt(allv.size)))))
    for j, (name, v) in enumerate(series.items()):
        counts, _ = np.histogram(v, bins=edges)
        ax.stairs(counts, edges, label=name, fill=(j == len(series) - 1 and len(series) == 1), linewidth=1.2)
    ax.set_xlabel("force per tip (N)")
    ax.set_ylabel("number of tips")
    ax.grid(lw=0.3)
    if len(series) > 1:
        ax.legend(fontsize=8)


def plot_forces(forces: Mapping[str, Any], *, ax=None, title: str | None = None, style: FigureStyle = PLAIN):
    """Tip forces of one or several series: bars per asperity (at most ``FEW_TIPS``
    tips) or step histograms on shared bins (more). Returns the matplotlib Figure.

    Parameters
    ----------
    forces : mapping name -> ContactResult or (N,) array of N
        One series each (e.g. ``{"macro step": ..., "final pressure": result}``).
    ax : matplotlib Axes, optional
        Draw into this Axes; default a new Figure of ``style.size`` inches.
    title : str, optional
    style : FigureStyle, optional
        ``size`` ((6.4, 4.0) inches), ``dpi`` (100).
    """
    series = _series(forces)
    fig, ax = figure_and_axes(ax, style.pick("size", (6.4, 4.0)), style.pick("dpi", 100), rect=(0.11, 0.14, 0.86, 0.74))
    if len(next(iter(series.values()))) <= FEW_TIPS:
        _grouped_bars(ax, series)
    else:
        _histograms(ax, series)
    if title:
        ax.set_title(title, fontsize=9)
    return fig


def plot_tip_values(
    tips,
    values,
    *,
    ax=None,
    numbers=None,
    label: str = "force (N)",
    diverging: bool = False,
    title: str | None = None,
    style: FigureStyle = PLAIN,
):
    """Tips as dots coloured by a value, the ``LABELLED`` (10) largest numbered from 1
    (every tip when at most ``FEW_TIPS``). Returns the matplotlib Figure.

    Parameters
    ----------
    tips : (N, 2) array of mm or sequence of Asperity
    values : (N,) array
        One value per tip (e.g. its force, N).
    ax : matplotlib Axes, optional
    numbers : (N,) array of int, optional
        The tips' numbers as in the CSV files (default 1..N: ``tips`` are every tip in
        scene order); give them when drawing a subset, e.g. the loaded tips.
    label : str, default "force (N)"
        Colour bar label.
    diverging : bool, default False
        A scale symmetric about 0 (red above, blue below; numbers on the largest
        ``|value|``) instead of 0 to the largest value.
    title : str, optional
    style : FigureStyle, optional
        ``scale`` (its ``top`` ends the scale; default the largest ``|value|``),
        ``cmap`` ("viridis", or "RdBu_r" when diverging), ``colourbar`` (True), ``size``
        ((5.6, 4.8) inches), ``dpi`` (100).
    """
    from matplotlib.colors import Normalize

    xy, _ = tip_positions(tips)
    v = np.asarray(values, dtype=float).ravel()
    if xy is None or len(xy) != v.size:
        raise ValueError(
            f"plot_tip_values needs one tip per value, got {0 if xy is None else len(xy)} tips and {v.size} values"
        )
    top = float(np.max(np.abs(v), initial=0.0)) if style.scale is None else float(style.scale.top)
    top = top if top > 0 else 1.0
    norm = Normalize(-top, top) if diverging else Normalize(0.0, top)
    fig, ax = figure_and_axes(ax, style.pick("size", (5.6, 4.8)), style.pick("dpi", 100), rect=(0.12, 0.1, 0.7, 0.8))
    sc = tips_coloured(
        ax,
        xy,
        v,
        norm=norm,
        cmap=style.pick("cmap", "RdBu_r" if diverging else "viridis"),
        label=label,
        rank=np.abs(v) if diverging else v,
        numbers=numbers,
    )
    if style.colourbar:
        fig.colorbar(sc, ax=ax).set_label(label)
    if title:
        ax.set_title(title, fontsize=9)
    return fig


def plot_parity(forces: Mapping[str, Any], *, ax=None, title: str | None = None, style: FigureStyle = PLAIN):
    """Each series' tip forces against the first series' (one dot per tip; y = x
    dashed). Returns the matplotlib Figure.

    Parameters
    ----------
    forces : mapping name -> ContactResult or (N,) array of N
        The first is the x axis (at least two series).
    ax : matplotlib Axes, optional
    title : str, optional
    style : FigureStyle, optional
        ``size`` ((4.8, 4.8) inches), ``dpi`` (100).
    """
    series = _series(forces)
    names = list(series)
    fig, ax = figure_and_axes(ax, style.pick("size", (4.8, 4.8)), style.pick("dpi", 100), rect=(0.15, 0.12, 0.8, 0.78))
    ref = series[names[0]]
    for name in names[1:]:
        ax.scatter(ref, series[name], s=4, label=name, alpha=0.7, linewidths=0)
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
        ax.legend(fontsize=8, markerscale=2, loc="upper left")
    if title:
        ax.set_title(title, fontsize=9)
    return fig


def force_bars(
    result: ContactResult,
    path: str | Path,
    *,
    tips=None,
    macro_forces: Sequence[float] | None = None,
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Force per asperity (integral of the final pressure over its cells) as PNG.

    Parameters
    ----------
    result : ContactResult
    path : path-like
        Output ``.png``.
    tips : (N, 2) array of mm or sequence of Asperity, optional
        Tip positions: with more than ``FEW_TIPS`` tips, the map of the loaded tips
        coloured by force (the ten most loaded numbered) is drawn beside the histogram.
    macro_forces : (N,) array, optional
        Macro-step tip forces, N, drawn beside the final forces (a second histogram
        with many tips).
    caption : Caption, optional
        ``title`` (default: the scene and body, then the total load); ``scene`` recorded
        in the PNG metadata, its ``influence`` naming the body in the title; ``name`` the
        scene's name for the title (e.g. the scene file's stem).
    style : FigureStyle, optional
        ``size`` ((6.4, 4.0) inches), ``dpi`` (100).

    Returns
    -------
    Path of the PNG written.
    """
    forces = np.asarray(result.forces, dtype=float)
    series = {"final pressure": forces}
    if macro_forces is not None:
        macro = np.asarray(macro_forces, float).ravel()
        if macro.shape != forces.shape:
            raise ValueError(f"macro_forces has {macro.size} values, expected {forces.size} (one per asperity)")
        series = {"macro step": macro, **series}
    n, loaded = forces.size, int(np.count_nonzero(forces > 0))
    title, scene, size, dpi = caption.title, caption.scene, style.pick("size", (6.4, 4.0)), style.pick("dpi", 100)
    if title is None:
        title = join_title(
            scene_text(scene, caption.name, result=result),
            f"force per asperity, total {float(result.total_load):.4g} N ({loaded} of {n} tips loaded)",
        )
    xy, _ = tip_positions(tips)
    if n <= FEW_TIPS or xy is None:
        fig = plot_forces(series, style=FigureStyle(size=size, dpi=dpi))
    else:
        fig = new_figure((size[0] * 1.6, size[1] * 1.1), dpi)
        plot_forces(series, ax=fig.add_axes([0.08, 0.13, 0.36, 0.72]))
        on = forces > 0
        mx = fig.add_axes([0.52, 0.13, 0.36, 0.72])
        plot_tip_values(
            xy[on],
            forces[on],
            ax=mx,
            numbers=np.flatnonzero(on) + 1,
            style=FigureStyle(colourbar=False),
            title=f"loaded tips coloured by force ({min(LABELLED, loaded)} most loaded numbered)",
        )
        fig.colorbar(mx.collections[0], cax=fig.add_axes([0.90, 0.13, 0.015, 0.72])).set_label("force (N)")
    fig.suptitle(title, fontsize=9, y=0.995, va="top")
    return save_png(fig, path, title=title, scene=scene)


def compare_forces(
    results: Mapping[str, ContactResult],
    path: str | Path,
    *,
    measured: Sequence[float] | None = None,
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Forces per asperity of several results side by side (paper Figs. 10-11), as PNG.

    Parameters
    ----------
    results : mapping name -> ContactResult
        One bar per asperity each, in mapping order (at least one; same asperity count).
    path : path-like
        Output ``.png``.
    measured : (N,) array, optional
        Measured tip forces, N, drawn first.
    caption : Caption, optional
        ``title`` (default "force per asperity", after the scene's ``name`` when given);
        ``scene`` and further ``meta`` entries (e.g. the bodies compared) recorded in the
        PNG ``Description``.
    style : FigureStyle, optional
        ``size`` ((7.2, 4.0) inches), ``dpi`` (100).

    Returns
    -------
    Path of the PNG written.
    """
    if not results:
        raise ValueError("compare_forces needs at least one result, got none")
    series = {} if measured is None else {"measured": np.asarray(measured, float)}
    series.update(results)
    series = _series(series)
    title = join_title(caption.name or "", caption.title or "force per asperity")
    size, dpi = style.pick("size", (7.2, 4.0)), style.pick("dpi", 100)
    n = len(next(iter(series.values())))
    if n <= FEW_TIPS:
        fig = plot_forces(series, style=FigureStyle(size=size, dpi=dpi))
    else:
        fig = new_figure((size[0] * 1.4, size[1] * 1.1), dpi)
        plot_forces(series, ax=fig.add_axes([0.08, 0.13, 0.38, 0.72]))
        plot_parity(series, ax=fig.add_axes([0.58, 0.13, 0.38, 0.72]))
    fig.suptitle(f"{title} ({n} tips)", fontsize=9, y=0.995, va="top")
    return save_png(fig, path, title=title, scene=caption.scene, meta=caption.meta)
