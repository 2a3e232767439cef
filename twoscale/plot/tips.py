"""Drawing tips so a figure stays readable from one to thousands of them.

Tips are numbered from 1 in scene order, as in every table and file. With at most
:data:`FEW_TIPS` tips every tip that is drawn gets its number; with more, numbers would
cover the figure, so only the :data:`LABELLED` tips of largest value (the most loaded,
the largest change) are numbered, and the CSV gives every tip's number and position.
"""

from __future__ import annotations

import numpy as np

from .labels import X_MM, Y_MM

#: Up to this many tips, figures write each tip's number and draw one bar per tip.
FEW_TIPS = 30
#: With more tips, this many (those of largest value) are numbered.
LABELLED = 10


def tip_positions(tips) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Tip positions (N, 2) mm and sphere radii (N,) mm from an array or Asperity list.

    The radii are None for plain positions and for the basins of a height map (their
    fitted radius is a law parameter, not a shape worth drawing).
    """
    if tips is None:
        return None, None
    seq = list(tips)
    if seq and hasattr(seq[0], "R"):
        xy = np.array([[a.x, a.y] for a in seq], float)
        return xy, None if hasattr(seq[0], "basins") else np.array([a.R for a in seq], float)
    return np.asarray(seq, dtype=float).reshape(-1, 2), None


def labelled(values, k: int = LABELLED) -> np.ndarray:
    """Indices (0-based) of the tips to number: every tip when at most ``FEW_TIPS``,
    else the ``k`` of largest ``values`` (ties: scene order)."""
    v = np.asarray(values, dtype=float).ravel()
    if v.size <= FEW_TIPS:
        return np.arange(v.size)
    return np.sort(np.argsort(-v, kind="stable")[:k])


def number_tips(ax, xy: np.ndarray, which=None, numbers=None) -> None:
    """Write tip numbers beside the tips ``which`` (0-based indices into ``xy``; default
    all), outlined so they read on any colour. ``numbers``: each row's number as in the
    CSV files (default ``1..N``, for ``xy`` holding every tip in scene order)."""
    from matplotlib import patheffects

    outline = [patheffects.withStroke(linewidth=2.0, foreground="white")]
    idx = range(len(xy)) if which is None else which
    for k in idx:
        x, y = xy[k]
        label = int(k) + 1 if numbers is None else int(numbers[k])
        ax.annotate(
            str(label),
            (x, y),
            xytext=(3, 3),
            textcoords="offset points",
            fontsize=7,
            color="black",
            path_effects=outline,
            clip_on=True,
        )


def marker_size(n: int) -> float:
    """Scatter marker area (points^2): about 0.7 of the spacing of ``n`` tips spread over
    a 3.6-inch (260 pt) panel, so neighbours stay apart."""
    return float(np.clip((180.0 / np.sqrt(max(n, 1))) ** 2, 1.0, 60.0))


def tips_coloured(ax, xy: np.ndarray, values: np.ndarray, *, norm, cmap: str, label: str, rank=None, numbers=None):
    """Tips as dots coloured by ``values``; the tips of largest ``rank`` (default
    ``values``) numbered (all when few) with ``numbers`` (default 1..N). Returns the mappable."""
    sc = ax.scatter(
        xy[:, 0],
        xy[:, 1],
        c=values,
        norm=norm,
        cmap=cmap,
        s=marker_size(len(xy)),
        edgecolors="0.2",
        linewidths=0.3 if len(xy) <= 500 else 0.0,
    )
    number_tips(ax, xy, labelled(values if rank is None else rank), numbers)
    ax.set_aspect("equal")
    ax.set_xlabel(X_MM)
    ax.set_ylabel(Y_MM)
    pad = 0.05 * max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), 1.0)
    ax.set_xlim(xy[:, 0].min() - pad, xy[:, 0].max() + pad)
    ax.set_ylim(xy[:, 1].min() - pad, xy[:, 1].max() + pad)
    sc.set_label(label)
    return sc
