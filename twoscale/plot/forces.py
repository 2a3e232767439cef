"""Force per asperity as bars: one result (:func:`force_bars`) or several side by side
(:func:`compare_forces`, the paper's Figs. 10-11)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..results import ContactResult
from ._figure import new_figure, save_png


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


def force_bars(result: ContactResult, path: str | Path, *, macro_forces: Sequence[float] | None = None,
               title: str | None = None, scene: Mapping[str, Any] | None = None,
               size: tuple[float, float] = (6.4, 4.0), dpi: int = 100) -> Path:
    """Force per asperity (integral of the final pressure over its cells) as PNG.

    Parameters
    ----------
    result : ContactResult
    path : path-like
        Output ``.png``.
    macro_forces : (N,) array, optional
        Macro-step tip forces, N, drawn beside the final forces.
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
    series = {"final pressure": np.asarray(result.asperities.forces, float)}
    if macro_forces is not None:
        macro = np.asarray(macro_forces, float).ravel()
        if macro.shape != series["final pressure"].shape:
            raise ValueError(f"macro_forces has {macro.size} values, expected "
                             f"{series['final pressure'].size} (one per asperity)")
        series = {"macro step": macro, **series}
    fig = new_figure(size, dpi)
    ax = fig.add_axes([0.11, 0.14, 0.86, 0.76])
    _grouped_bars(ax, series)
    if title is None:
        title = f"{result.method}: force per asperity, total {result.total_load:.4g} N"
    ax.set_title(title, fontsize=10)
    return save_png(fig, path, title=title, scene=scene)


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
    series.update({name: np.asarray(r.asperities.forces, float) for name, r in results.items()})
    fig = new_figure(size, dpi)
    ax = fig.add_axes([0.1, 0.14, 0.87, 0.76])
    _grouped_bars(ax, series)
    title = title or "force per asperity"
    ax.set_title(title, fontsize=10)
    return save_png(fig, path, title=title, scene=scene, meta=meta)
