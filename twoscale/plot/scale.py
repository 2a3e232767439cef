"""Colour scales that a single peak cannot flatten.

A punch corner at the edge of a height map, or one tip pressed much harder than the
rest, puts a few cells far above all others: a scale from 0 to that peak paints every
other contact the same dark colour. :func:`robust_scale` ends the scale at a high
percentile of the loaded cells instead, when the peak is far above it, and keeps the
peak to report it (colour bar label and arrow, figure title).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Percentile of the loaded cells where a clipped scale ends.
CLIP_PERCENTILE = 99.0
#: The scale is clipped only when the peak exceeds the percentile by more than this factor.
CLIP_FACTOR = 1.5


@dataclass(frozen=True)
class ColourScale:
    """A colour scale from 0 to ``top`` and the largest value it was made for.

    Attributes
    ----------
    top : float
        Value at the end of the scale (> 0).
    peak : float
        Largest value drawn (>= 0); above ``top`` when the scale is clipped.
    """

    top: float
    peak: float

    @property
    def clipped(self) -> bool:
        """Whether values above ``top`` are drawn in the scale's last colour."""
        return self.peak > self.top

    def norm(self):
        """A matplotlib ``Normalize`` from 0 to ``top``."""
        from matplotlib.colors import Normalize

        return Normalize(vmin=0.0, vmax=self.top)

    def label(self, quantity: str, unit: str) -> str:
        """Colour bar label: ``quantity (unit)``, with the clip and the peak when clipped."""
        if not self.clipped:
            return f"{quantity} ({unit})"
        return f"{quantity} ({unit}), clipped: peak {self.peak:.3g}"

    @property
    def extend(self) -> str:
        """``extend=`` of the colour bar: an arrow at the top when clipped."""
        return "max" if self.clipped else "neither"


def robust_scale(values, *, percentile: float = CLIP_PERCENTILE, factor: float = CLIP_FACTOR) -> ColourScale:
    """The colour scale of the positive ``values`` (e.g. the loaded cells' pressures, MPa).

    Ends at the peak unless the peak exceeds the ``percentile``-th percentile of the
    positive values by more than ``factor``; then ends at that percentile.

    Parameters
    ----------
    values : array_like
        Values drawn; zeros and negatives (unloaded cells) are left out of the percentile.
    percentile : float, default 99
    factor : float, default 1.5

    Returns
    -------
    ColourScale
        ``top`` is 1 when nothing is positive (an empty map still gets a scale).
    """
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return ColourScale(1.0, 0.0)
    peak = float(v.max())
    q = float(np.percentile(v, percentile))
    return ColourScale(q if peak > factor * q else peak, peak)
