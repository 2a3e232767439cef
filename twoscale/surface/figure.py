"""The segmentation drawn over the height map (PNG): heights in grey, basin boundaries
in orange, summits as red dots, numbered as in the CSV (plotting module: matplotlib is
imported here only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plot._figure import figure_and_axes, save_png
from ..plot.labels import X_MM, Y_MM
from ..plot.tips import labelled, number_tips


def plot_segmentation(surface, *, ax=None, title: str | None = None, dpi: int = 150):
    """The segmentation of ``surface`` (a :class:`~twoscale.surface.MeasuredSurface`)
    over its height map; returns the matplotlib Figure.

    Summits are numbered from 1 as in the CSV: every one when at most 30, else the ten
    highest (the stones that touch first).

    Parameters
    ----------
    surface : MeasuredSurface
    ax : matplotlib Axes, optional
        Draw into this Axes; default a new 7 x 6 inch Figure (11 inches wide and as high
        as the map's aspect needs for a strip less than 0.6 as high as it is long).
    title : str, optional
        Default: the height map's file, the number of asperities and the segmentation's
        settings.
    dpi : int, default 150
    """
    hm, seg = surface.hmap, surface.segmentation
    extent = hm.grid.bounds
    size, rect = _layout((extent[3] - extent[2]) / (extent[1] - extent[0]))
    fig, ax = figure_and_axes(ax, size, dpi, rect=rect)
    image = ax.imshow(hm.heights, origin="lower", extent=extent, cmap="gray", interpolation="nearest")
    bar = fig.colorbar(image, ax=ax, shrink=min(1.0, size[1] / 4.0))
    low = size[1] < 4.0  # a strip's short bar: the label on three lines
    bar.set_label("height (mm);\nlarger: closer\nto the body" if low else "height (mm); larger: closer to the body")
    edges = np.zeros(seg.labels.shape, dtype=bool)
    edges[:, 1:] |= seg.labels[:, 1:] != seg.labels[:, :-1]
    edges[1:, :] |= seg.labels[1:, :] != seg.labels[:-1, :]
    overlay = np.ma.masked_where(~edges, np.ones(edges.shape))
    ax.imshow(overlay, origin="lower", extent=extent, cmap="autumn", alpha=0.9, interpolation="nearest")
    xy = np.array([[a.x, a.y] for a in surface.asperities], dtype=float).reshape(-1, 2)
    z = np.array([a.z for a in surface.asperities], dtype=float)
    ax.plot(xy[:, 0], xy[:, 1], "o", color="tab:red", markersize=2.5)
    number_tips(ax, xy, labelled(-z))  # z is the recess below the highest summit: smallest first
    ax.set_xlabel(X_MM)
    ax.set_ylabel(Y_MM)
    if title is None:
        title = (
            f"{Path(hm.source).name}: {len(seg)} asperities (min distance {seg.min_distance:g} mm, "
            f"prominence {seg.min_prominence:g} mm)"
        )
    ax.set_title(title, fontsize=8)
    return fig


def _layout(aspect: float) -> tuple[tuple[float, float], tuple[float, float, float, float]]:
    """Figure size (inches) and axes rectangle for a map ``aspect`` (height over width) high:
    7 x 6 inches for a squarish map; a road strip gets a wide, low figure, so that it is not
    a thin band in the middle of a square."""
    if aspect >= 0.6:
        return (7.0, 6.0), (0.1, 0.08, 0.7, 0.84)
    width = 11.0
    height = min(6.0, max(2.6, 0.78 * width * aspect + 1.3))
    bottom, top = 0.9 / height, 0.45 / height  # room for the x label below and the title above
    return (width, height), (0.07, bottom, 0.78, 1.0 - bottom - top)


def segmentation_figure(surface, path: str | Path, *, scene: dict | None = None, dpi: int = 150) -> Path:
    """Write :func:`plot_segmentation` of ``surface`` to ``path`` (PNG, with the version
    and scene in its metadata)."""
    fig = plot_segmentation(surface, dpi=dpi)
    return save_png(fig, path, title=fig.axes[0].get_title(), scene=scene)
