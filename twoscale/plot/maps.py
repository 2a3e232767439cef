"""Pressure maps: one result (:func:`plot_pressure_map`, :func:`pressure_map`) or several
side by side on one colour scale (:func:`compare_maps`).

Markers go on the loaded tips only (a tip that carries nothing is not drawn); the colour
scale ends at a high percentile of the loaded cells when a single peak (a punch corner at
a map's edge) would otherwise flatten it, and the peak is given in the title and the
colour bar.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..results import ContactResult
from ._figure import figure_and_axes, new_figure, save_png
from .labels import X_MM, Y_MM, body_text, join_title, scene_text
from .scale import ColourScale, robust_scale
from .style import NO_CAPTION, PLAIN, Caption, FigureStyle
from .tips import FEW_TIPS, labelled, marker_size, number_tips, tip_positions

#: With more loaded patches than this, a map draws them as one raster (see :func:`_raster`).
MANY_PATCHES = 50
#: Largest side of that raster, pixels.
RASTER_PX = 1500


def _content_box(results: Sequence[ContactResult], tips_xy, margin: float = 0.1):
    """Box around the loaded cells of all results (and the loaded tips), mm, with a margin."""
    xs, ys = [], []
    for r in results:
        for f in r.fields:
            loaded = f.pressure > 0
            if np.any(loaded):
                X, Y = f.grid.centres()
                xs += [X[loaded].min() - f.grid.h, X[loaded].max() + f.grid.h]
                ys += [Y[loaded].min() - f.grid.h, Y[loaded].max() + f.grid.h]
    if tips_xy is not None and len(tips_xy):
        xs += list(tips_xy[:, 0])
        ys += list(tips_xy[:, 1])
    if not xs:
        b = np.array([f.grid.bounds for r in results for f in r.fields])
        xs, ys = [b[:, 0].min(), b[:, 1].max()], [b[:, 2].min(), b[:, 3].max()]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    pad = margin * max(x1 - x0, y1 - y0, 1e-6)
    return x0 - pad, x1 + pad, y0 - pad, y1 + pad


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


def _loaded_values(result: ContactResult, sensor) -> np.ndarray:
    """The values a map draws (MPa): the loaded cells, or the sensor-cell means."""
    if sensor is not None:
        return np.asarray(sensor.average(result), float).ravel()
    parts = [f.pressure[f.pressure > 0] for f in result.fields]
    return np.concatenate(parts) if parts else np.zeros(0)


def map_scale(results: Sequence[ContactResult], sensor=None) -> ColourScale:
    """One robust colour scale (MPa) for the maps of ``results`` (see :func:`robust_scale`)."""
    return robust_scale(np.concatenate([_loaded_values(r, sensor) for r in results] or [np.zeros(0)]))


def _peak_text(result: ContactResult, sensor) -> str:
    """``peak 20.8 MPa at tip 12`` (the owning tip of the largest cell, numbered from 1)."""
    if sensor is not None:
        return f"peak cell mean {float(np.max(sensor.average(result), initial=0.0)):.3g} MPa"
    best, owner = 0.0, -1
    for f in result.fields:
        if f.pressure.size and f.pressure.max() > best:
            j = np.unravel_index(int(np.argmax(f.pressure)), f.pressure.shape)
            best, owner = float(f.pressure[j]), int(f.owner[j])
    return f"peak {best:.3g} MPa" + (f" at tip {owner + 1}" if owner >= 0 else "")


def _draw(ax, result: ContactResult, norm, *, tips_xy, sensor, cmap: str):
    """Draw one result's pressure (micro patches, or sensor-cell means) and its loaded tips."""
    image = None
    if sensor is not None:
        P = sensor.average(result)
        image = ax.imshow(
            np.ma.masked_less_equal(P, 0),
            extent=sensor.grid.bounds,
            origin="lower",
            norm=norm,
            cmap=cmap,
            interpolation="nearest",
        )
    else:
        loaded = [f for f in result.fields if np.any(f.pressure > 0)]
        if len(loaded) > MANY_PATCHES:
            P, extent = _raster(loaded)
            image = ax.imshow(
                np.ma.masked_less_equal(P, 0),
                extent=extent,
                origin="lower",
                norm=norm,
                cmap=cmap,
                interpolation="nearest",
            )
        for f in loaded if len(loaded) <= MANY_PATCHES else ():
            image = ax.imshow(
                np.ma.masked_less_equal(f.pressure, 0),
                extent=f.grid.bounds,
                origin="lower",
                norm=norm,
                cmap=cmap,
                interpolation="nearest",
            )
    if tips_xy is not None:
        _draw_tips(ax, result, tips_xy)
    ax.set_aspect("equal")
    ax.set_xlabel(X_MM)
    ax.set_ylabel(Y_MM)
    return image


def _draw_tips(ax, result: ContactResult, tips_xy) -> None:
    """Crosses on the loaded tips only; numbers on all of them when few, else on the most
    loaded. (No circles of radius R: on a height map the fitted radius is a law
    parameter, and on spheres the base circle is mostly far outside the contact.)"""
    forces = np.asarray(result.forces, float)
    if forces.shape != (len(tips_xy),):
        raise ValueError(f"{len(tips_xy)} tips given for a result of {forces.size} asperities")
    on = np.flatnonzero(forces > 0)
    if on.size == 0:
        return
    few = len(on) <= FEW_TIPS
    ax.scatter(
        tips_xy[on, 0],
        tips_xy[on, 1],
        marker="+",
        color="red",
        s=36 if few else marker_size(len(on)) / 4,
        linewidths=1.0 if few else 0.4,
        label="loaded tips",
    )
    number_tips(ax, tips_xy, on[labelled(forces[on])])


def _colourbar(fig, image, scale: ColourScale, cmap, sensor, *, cax=None, ax=None):
    from matplotlib.cm import ScalarMappable

    mappable = image if image is not None else ScalarMappable(norm=scale.norm(), cmap=cmap)
    cb = fig.colorbar(mappable, cax=cax, ax=None if cax is not None else ax, extend=scale.extend)
    what = "sensor-cell mean pressure" if sensor is not None else "pressure"
    cb.set_label(scale.label(what, "MPa"), fontsize=8)
    return cb


def pressure_title(result: ContactResult, *, scene=None, name: str | None = None, sensor=None) -> str:
    """Default title of a pressure map: the scene and body, the load, the contact area,
    the peak and how many tips carry load."""
    n, loaded = result.n_asperities, int(np.count_nonzero(np.asarray(result.forces) > 0))
    area = float(np.sum(result.asperities.contact_areas))
    ratio = getattr(result, "contact_ratio", None)
    share = f" ({100 * ratio:.3g} % of the nominal)" if ratio is not None else ""
    what = (
        f"total load {result.total_load:.4g} N, contact area {area:.4g} mm²{share}\n{_peak_text(result, sensor)}, "
        f"{loaded} of {n} tips loaded" + ("" if result.converged else " (NOT converged)")
    )
    head = scene_text(scene, name, result=result)
    return f"{head}\n{what}" if head else what


def plot_pressure_map(
    result: ContactResult, *, ax=None, tips=None, sensor=None, caption: Caption = NO_CAPTION, style: FigureStyle = PLAIN
):
    """Map of the contact pressure with the loaded tips; returns the matplotlib Figure.

    Parameters
    ----------
    result : ContactResult
    ax : matplotlib Axes, optional
        Draw into this Axes (e.g. in a notebook); default a new Figure of ``style.size``.
    tips : (N, 2) array of mm or sequence of Asperity, optional
        One per asperity of ``result``. The loaded tips (force > 0) are drawn as crosses:
        numbered from 1 (scene order, as in the CSV files) when at most ``FEW_TIPS``
        (30), else the ``LABELLED`` (10) most loaded.
    sensor : twoscale.sensor.Sensor, optional
        Draw the sensor-cell means instead of the micro cells.
    caption : Caption, optional
        ``title`` (default :func:`pressure_title`: scene and body, load, contact area,
        peak, loaded tips), the ``scene`` solved (a Scene or mapping: its ``influence``
        names the body in the title) and its ``name``.
    style : FigureStyle, optional
        ``scale`` (default :func:`map_scale` of this result, robust to a single peak),
        ``colourbar`` (True), ``cmap`` ("viridis"), ``size`` ((6.4, 5.2) inches, when
        ``ax`` is None), ``dpi`` (100).

    Returns
    -------
    matplotlib.figure.Figure
    """
    cmap = style.pick("cmap", "viridis")
    tips_xy, _ = tip_positions(tips)
    scale = style.scale or map_scale([result], sensor)
    own = ax is None
    fig, ax = figure_and_axes(ax, style.pick("size", (6.4, 5.2)), style.pick("dpi", 100), rect=(0.1, 0.1, 0.68, 0.78))
    image = _draw(ax, result, scale.norm(), tips_xy=tips_xy, sensor=sensor, cmap=cmap)
    on = None if tips_xy is None else tips_xy[np.asarray(result.forces) > 0]
    x0, x1, y0, y1 = _content_box([result], on)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    if style.colourbar:
        _colourbar(fig, image, scale, cmap, sensor, cax=fig.add_axes([0.82, 0.1, 0.03, 0.78]) if own else None, ax=ax)
    title = caption.title
    ax.set_title(
        title if title is not None else pressure_title(result, scene=caption.scene, name=caption.name, sensor=sensor),
        fontsize=9,
    )
    return fig


def pressure_map(
    result: ContactResult,
    path: str | Path,
    *,
    tips=None,
    sensor=None,
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Write :func:`plot_pressure_map` to ``path`` (PNG; the caption's scene record in its metadata).

    Parameters are those of :func:`plot_pressure_map`. Returns the Path written.
    """
    fig = plot_pressure_map(result, tips=tips, sensor=sensor, caption=caption, style=style)
    return save_png(fig, path, title=fig.axes[0].get_title().replace("\n", " - "), scene=caption.scene)


def _panel_body(meta: Mapping | None, name: str) -> str:
    """A compared body's words from ``meta["bodies"][name]["influence"]`` (compare's record)."""
    body = ((meta or {}).get("bodies") or {}).get(name)
    return body_text(body.get("influence")) if isinstance(body, Mapping) and "influence" in body else ""


def compare_maps(
    results: Mapping[str, ContactResult],
    path: str | Path,
    *,
    tips=None,
    sensor=None,
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Pressure maps of several results side by side on one colour scale, as PNG.

    Each panel is :func:`plot_pressure_map` on the shared scale (:func:`map_scale` of
    all results); its title names the body (from ``caption.meta["bodies"]`` when given,
    as ``twoscale compare`` writes it), the load and the peak.

    Parameters
    ----------
    results : mapping name -> ContactResult
        One panel each, in mapping order (at least one).
    path : path-like
        Output ``.png``.
    tips, sensor
        As in :func:`plot_pressure_map`.
    caption : Caption, optional
        ``title`` (default "pressure maps", after the scene's ``name`` when given), the
        ``scene`` record and further ``meta`` entries of the PNG ``Description`` (e.g.
        the bodies compared).
    style : FigureStyle, optional
        ``panel_size`` (3.6 inches: the figure is ``(n * panel_size + 1.5) x
        (panel_size + 0.8)`` inches), ``dpi`` (100), ``cmap`` ("viridis").

    Returns
    -------
    Path of the PNG written.
    """
    panel_size, dpi, cmap = style.pick("panel_size", 3.6), style.pick("dpi", 100), style.pick("cmap", "viridis")
    meta = caption.meta
    if not results:
        raise ValueError("compare_maps needs at least one result, got none")
    names = list(results)
    n = len(names)
    tips_xy, _ = tip_positions(tips)
    W, H = n * panel_size + 1.5, panel_size + 0.8
    fig = new_figure((W, H), dpi)
    scale = map_scale(list(results.values()), sensor)
    on = None
    if tips_xy is not None:
        on = tips_xy[np.any([np.asarray(r.forces) > 0 for r in results.values()], axis=0)]
    box = _content_box(list(results.values()), on)
    for k, key in enumerate(names):
        r = results[key]
        ax = fig.add_axes([(0.6 + k * panel_size) / W, 0.55 / H, 0.82 * panel_size / W, (panel_size - 0.45) / H])
        body = _panel_body(meta, key)
        same = body.replace("-", "") == key.replace("-", "")  # "halfspace" is the half-space
        head = f"{key}" + (f" ({body})" if body and not same else "")
        sub = f"{r.total_load:.4g} N, {_peak_text(r, sensor)}" + ("" if r.converged else " (NOT converged)")
        plot_pressure_map(
            r,
            ax=ax,
            tips=tips,
            sensor=sensor,
            caption=Caption(title=f"{head}\n{sub}"),
            style=FigureStyle(scale=scale, colourbar=False, cmap=cmap),
        )
        ax.title.set_fontsize(8)
        ax.set_xlim(box[0], box[1])
        ax.set_ylim(box[2], box[3])
        if k:
            ax.set_ylabel("")
    cax = fig.add_axes([(W - 0.85) / W, 0.55 / H, 0.12 / W, (panel_size - 0.45) / H])
    _colourbar(fig, None, scale, cmap, sensor, cax=cax)
    title = join_title(caption.name or "", caption.title or "pressure maps")
    fig.suptitle(title, fontsize=10, y=0.995, va="top")
    return save_png(fig, path, title=title, scene=caption.scene, meta=meta)
