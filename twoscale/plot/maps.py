"""Pressure maps: one result (:func:`pressure_map`) or several side by side (:func:`compare_maps`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..results import ContactResult
from ._figure import new_figure, save_png
from .tips import FEW_TIPS, draw_bases, marker_size, number_tips, tip_positions


def _content_box(results: Sequence[ContactResult], tips_xy, margin: float = 0.1):
    """Box around the loaded cells of all results (and the tips), mm, with a margin."""
    xs, ys = [], []
    for r in results:
        for f in r.fields:
            loaded = f.pressure > 0
            if np.any(loaded):
                X, Y = f.grid.centres()
                xs += [X[loaded].min() - f.grid.h, X[loaded].max() + f.grid.h]
                ys += [Y[loaded].min() - f.grid.h, Y[loaded].max() + f.grid.h]
    if tips_xy is not None:
        xs += list(tips_xy[:, 0])
        ys += list(tips_xy[:, 1])
    if not xs:
        b = np.array([f.grid.bounds for r in results for f in r.fields])
        xs, ys = [b[:, 0].min(), b[:, 1].max()], [b[:, 2].min(), b[:, 3].max()]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    pad = margin * max(x1 - x0, y1 - y0, 1e-6)
    return x0 - pad, x1 + pad, y0 - pad, y1 + pad


#: With more loaded patches than this, a map draws them as one raster (see :func:`_raster`).
MANY_PATCHES = 50
#: Largest side of that raster, pixels.
RASTER_PX = 1500


def _raster(fields) -> tuple[np.ndarray, tuple]:
    """The loaded cells of many patches on one raster (one image instead of thousands):
    pixels of the smallest cell size, or coarser so that no side exceeds ``RASTER_PX``;
    each pixel shows the largest pressure of the cells whose centres it holds, MPa.
    Returns the image and its extent (x0, x1, y0, y1), mm."""
    b = np.array([f.grid.bounds for f in fields])
    x0, y0 = b[:, 0].min(), b[:, 2].min()
    wx, wy = b[:, 1].max() - x0, b[:, 3].max() - y0
    cell = max(min(f.grid.h for f in fields), max(wx, wy) / RASTER_PX)
    nx, ny = max(1, int(np.ceil(wx / cell - 1e-9))), max(1, int(np.ceil(wy / cell - 1e-9)))
    image = np.zeros((ny, nx))
    for f in fields:
        X, Y = f.grid.centres()
        m = f.pressure > 0
        i = np.clip(((X[m] - x0) / cell).astype(int), 0, nx - 1)
        j = np.clip(((Y[m] - y0) / cell).astype(int), 0, ny - 1)
        np.maximum.at(image, (j, i), f.pressure[m])
    return image, (x0, x0 + nx * cell, y0, y0 + ny * cell)


def _draw(ax, result: ContactResult, norm, *, tips_xy, radii, sensor, cmap: str):
    """Draw one result's pressure (micro patches, or sensor-cell means) on ``ax``."""
    image = None
    if sensor is not None:
        P = sensor.average(result)
        b = sensor.grid.bounds
        image = ax.imshow(np.ma.masked_less_equal(P, 0), extent=b, origin="lower", norm=norm,
                          cmap=cmap, interpolation="nearest")
    else:
        loaded = [f for f in result.fields if np.any(f.pressure > 0)]
        if len(loaded) > MANY_PATCHES:
            P, extent = _raster(loaded)
            image = ax.imshow(np.ma.masked_less_equal(P, 0), extent=extent, origin="lower", norm=norm,
                              cmap=cmap, interpolation="nearest")
        for f in loaded if len(loaded) <= MANY_PATCHES else ():
            image = ax.imshow(np.ma.masked_less_equal(f.pressure, 0), extent=f.grid.bounds,
                              origin="lower", norm=norm, cmap=cmap, interpolation="nearest")
    if tips_xy is not None:  # numbered crosses and bases when few; small crosses only when many
        few = len(tips_xy) <= FEW_TIPS
        ax.scatter(tips_xy[:, 0], tips_xy[:, 1], marker="+", color="red",
                   s=36 if few else marker_size(len(tips_xy)) / 4, linewidths=1.0 if few else 0.4, label="tips")
        if few and radii is not None:
            draw_bases(ax, tips_xy, radii)
        if few:
            number_tips(ax, tips_xy)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    return image


def _norm(results, sensor):
    from matplotlib.colors import Normalize

    vmax = 0.0
    for r in results:
        if sensor is not None:
            vmax = max(vmax, float(sensor.average(r).max()))
        else:
            vmax = max([vmax] + [float(f.pressure.max()) for f in r.fields])
    return Normalize(vmin=0.0, vmax=vmax if vmax > 0 else 1.0)


def pressure_map(result: ContactResult, path: str | Path, *, tips=None, sensor=None,
                 title: str | None = None, scene: Mapping[str, Any] | None = None,
                 size: tuple[float, float] = (6.4, 5.2), dpi: int = 100, cmap: str = "viridis") -> Path:
    """Map of the contact pressure with the tip positions, as PNG.

    Parameters
    ----------
    result : ContactResult
    path : path-like
        Output ``.png``.
    tips : (N, 2) array of mm or sequence of Asperity, optional
        Tips drawn as crosses, numbered from 1 (scene order, as in the CSV files) when
        there are at most ``FEW_TIPS`` (30); then, with asperities, dotted circles of
        radius R as well (the base of spherical indenters, as in the paper's maps).
        With more tips, small crosses only.
    sensor : twoscale.sensor.Sensor, optional
        Draw the sensor-cell means instead of the micro cells.
    title : str, optional
        Default: method, total load and convergence.
    scene : mapping, optional
        Recorded in the PNG metadata.
    size : (float, float), default (6.4, 5.2)
        Figure size, inches; pixels = size * dpi.
    dpi : int, default 100
    cmap : str, default "viridis"

    Returns
    -------
    Path of the PNG written.
    """
    tips_xy, radii = tip_positions(tips)
    fig = new_figure(size, dpi)
    ax = fig.add_axes([0.1, 0.1, 0.68, 0.8])
    cax = fig.add_axes([0.82, 0.1, 0.03, 0.8])
    norm = _norm([result], sensor)
    image = _draw(ax, result, norm, tips_xy=tips_xy, radii=radii, sensor=sensor, cmap=cmap)
    x0, x1, y0, y1 = _content_box([result], tips_xy)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    _colourbar(fig, cax, image, norm, cmap, sensor)
    if title is None:
        title = (f"{result.method}: total load {result.total_load:.4g} N"
                 + ("" if result.converged else " (NOT converged)"))
    ax.set_title(title, fontsize=10)
    return save_png(fig, path, title=title, scene=scene)


def _colourbar(fig, cax, image, norm, cmap, sensor):
    from matplotlib.cm import ScalarMappable

    mappable = image if image is not None else ScalarMappable(norm=norm, cmap=cmap)
    cb = fig.colorbar(mappable, cax=cax)
    cb.set_label("sensor-cell mean pressure (MPa)" if sensor is not None else "pressure (MPa)")


def compare_maps(results: Mapping[str, ContactResult], path: str | Path, *, tips=None, sensor=None,
                 title: str | None = None, scene: Mapping[str, Any] | None = None,
                 meta: Mapping[str, Any] | None = None,
                 panel_size: float = 3.6, dpi: int = 100, cmap: str = "viridis") -> Path:
    """Pressure maps of several results side by side on one colour scale, as PNG.

    Parameters
    ----------
    results : mapping name -> ContactResult
        One panel each, in mapping order (at least one).
    path : path-like
        Output ``.png``.
    tips, sensor, scene, cmap
        As in :func:`pressure_map`.
    meta : mapping, optional
        Further JSON-ready entries of the PNG ``Description`` (e.g. the bodies compared).
    title : str, optional
        Figure title; default "pressure maps".
    panel_size : float, default 3.6
        Width and height of one panel, inches; the figure is
        ``(n * panel_size + 1.5) x (panel_size + 0.8)`` inches.
    dpi : int, default 100

    Returns
    -------
    Path of the PNG written.
    """
    if not results:
        raise ValueError("compare_maps needs at least one result, got none")
    names = list(results)
    n = len(names)
    tips_xy, radii = tip_positions(tips)
    W, H = n * panel_size + 1.5, panel_size + 0.8
    fig = new_figure((W, H), dpi)
    norm = _norm(results.values(), sensor)
    box = _content_box(list(results.values()), tips_xy)
    image = None
    for k, name in enumerate(names):
        left = (0.6 + k * panel_size) / W
        ax = fig.add_axes([left, 0.55 / H, 0.82 * panel_size / W, (panel_size - 0.35) / H])
        im = _draw(ax, results[name], norm, tips_xy=tips_xy, radii=radii, sensor=sensor, cmap=cmap)
        image = image or im
        ax.set_xlim(box[0], box[1])
        ax.set_ylim(box[2], box[3])
        r = results[name]
        ax.set_title(f"{name}: {r.total_load:.4g} N" + ("" if r.converged else " (NOT converged)"), fontsize=9)
        if k:
            ax.set_ylabel("")
    cax = fig.add_axes([(W - 0.85) / W, 0.55 / H, 0.12 / W, (panel_size - 0.35) / H])
    _colourbar(fig, cax, image, norm, cmap, sensor)
    title = title or "pressure maps"
    fig.suptitle(title, fontsize=10)
    return save_png(fig, path, title=title, scene=scene, meta=meta)
