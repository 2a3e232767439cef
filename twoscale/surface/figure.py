"""The segmentation drawn over the height map (PNG): heights in colour, basin boundaries
in black, summits numbered (plotting module: matplotlib is imported here only)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plot._figure import new_figure, save_png

#: Summits numbered on the figure up to this many (beyond, dots only).
MAX_NUMBERED = 150


def segmentation_figure(surface, path: str | Path, *, scene: dict | None = None, dpi: int = 150) -> Path:
    """Write the segmentation of ``surface`` (a :class:`~twoscale.surface.MeasuredSurface`)
    to ``path`` (PNG, with the version and scene in its metadata)."""
    hm, seg = surface.hmap, surface.segmentation
    xmin, xmax, ymin, ymax = hm.grid.bounds
    fig = new_figure((7.0, 6.0), dpi)
    ax = fig.add_subplot(1, 1, 1)
    image = ax.imshow(hm.heights, origin="lower", extent=(xmin, xmax, ymin, ymax), cmap="gray",
                      interpolation="nearest")
    fig.colorbar(image, ax=ax, label="height, mm (larger: closer to the body)")
    edges = np.zeros(seg.labels.shape, dtype=bool)
    edges[:, 1:] |= seg.labels[:, 1:] != seg.labels[:, :-1]
    edges[1:, :] |= seg.labels[1:, :] != seg.labels[:-1, :]
    overlay = np.ma.masked_where(~edges, np.ones(edges.shape))
    ax.imshow(overlay, origin="lower", extent=(xmin, xmax, ymin, ymax), cmap="autumn", alpha=0.9,
              interpolation="nearest")
    x = np.array([a.x for a in surface.asperities])
    y = np.array([a.y for a in surface.asperities])
    ax.plot(x, y, "o", color="tab:red", markersize=2.5)
    if len(x) <= MAX_NUMBERED:
        for k, (xk, yk) in enumerate(zip(x, y)):
            ax.annotate(str(k + 1), (xk, yk), fontsize=5, color="tab:red", xytext=(2, 2), textcoords="offset points")
    ax.set_xlabel("x, mm")
    ax.set_ylabel("y, mm")
    title = (f"{Path(hm.source).name}: {len(seg)} asperities (min distance {seg.min_distance:g} mm, "
             f"prominence {seg.min_prominence:g} mm)")
    ax.set_title(title, fontsize=8)
    return save_png(fig, path, title=title, scene=scene)
