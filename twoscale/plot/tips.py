"""Drawing tips so a figure stays readable from a handful to thousands of them.

Tips are numbered from 1 in scene order, as in every table and file. With at most
:data:`FEW_TIPS` tips the numbers are written beside them; with more, numbers would
cover the figure, so tips are shown as small markers (coloured by a value where one is
drawn) and the CSV gives each tip's number and position.
"""
from __future__ import annotations

import numpy as np

#: Up to this many tips, figures write each tip's number and draw one bar per tip.
FEW_TIPS = 30


def tip_positions(tips) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Tip positions (N, 2) mm and radii (N,) mm (None) from an array or Asperity list."""
    if tips is None:
        return None, None
    seq = list(tips)
    if seq and hasattr(seq[0], "R"):
        return np.array([[a.x, a.y] for a in seq], float), np.array([a.R for a in seq], float)
    return np.asarray(seq, dtype=float).reshape(-1, 2), None


def number_tips(ax, xy: np.ndarray) -> None:
    """Write each tip's number (from 1) beside it, outlined so it reads on any colour."""
    from matplotlib import patheffects

    outline = [patheffects.withStroke(linewidth=2.0, foreground="white")]
    for k, (x, y) in enumerate(xy, start=1):
        ax.annotate(str(k), (x, y), xytext=(3, 3), textcoords="offset points", fontsize=7,
                    color="black", path_effects=outline, clip_on=True)


def marker_size(n: int) -> float:
    """Scatter marker area (points^2): about 0.7 of the spacing of ``n`` tips spread over
    a 3.6-inch (260 pt) panel, so neighbours stay apart."""
    return float(np.clip((180.0 / np.sqrt(max(n, 1))) ** 2, 1.0, 60.0))


def draw_bases(ax, xy: np.ndarray, radii: np.ndarray) -> None:
    """Dotted circles of radius R around the tips (the base of spherical indenters)."""
    from matplotlib.collections import EllipseCollection

    d = 2.0 * np.asarray(radii, float)
    ax.add_collection(EllipseCollection(d, d, np.zeros_like(d), units="xy", offsets=xy,
                                        offset_transform=ax.transData, facecolors="none",
                                        edgecolors="0.5", linestyles=":", linewidths=0.6))


def tips_coloured(ax, xy: np.ndarray, values: np.ndarray, *, norm, cmap: str, label: str):
    """Tips as dots coloured by ``values`` (numbered when few); returns the mappable."""
    sc = ax.scatter(xy[:, 0], xy[:, 1], c=values, norm=norm, cmap=cmap, s=marker_size(len(xy)),
                    edgecolors="0.2", linewidths=0.3 if len(xy) <= 500 else 0.0)
    if len(xy) <= FEW_TIPS:
        number_tips(ax, xy)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    pad = 0.05 * max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), 1.0)
    ax.set_xlim(xy[:, 0].min() - pad, xy[:, 0].max() + pad)
    ax.set_ylim(xy[:, 1].min() - pad, xy[:, 1].max() + pad)
    sc.set_label(label)
    return sc
