"""Segmentation: the basins of summits dropped for their prominence merged across their
highest pass, against a second flooding from the kept summits alone (scikit-image's
watershed, the independent answer)."""

from __future__ import annotations

import numpy as np
import pytest
from skimage.segmentation import watershed

from twoscale.surface import HeightMap, segment
from twoscale.surface.texture import road


@pytest.mark.parametrize("prominence", [0.1, 1.0])
def test_dropped_basins_go_where_a_flood_from_the_kept_summits_takes_them(prominence):
    z = road(40.0, 0.1, seed=0, stone_radius=(3.0, 6.0))
    seg = segment(HeightMap(z, 0.1), prominence=prominence)
    assert len(seg) < seg.candidates  # some basins were merged
    markers = np.zeros(z.shape, dtype=np.int64)
    markers[seg.summits[:, 0], seg.summits[:, 1]] = np.arange(1, len(seg) + 1)
    flooded = watershed(-z, markers, connectivity=2) - 1
    assert np.count_nonzero(flooded != seg.labels) <= 1e-4 * z.size
    for k, (j, i) in enumerate(seg.summits):  # each basin tops at its own summit
        assert z[j, i] == z[seg.labels == k].max()
