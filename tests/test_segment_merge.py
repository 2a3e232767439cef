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


@pytest.mark.parametrize("quantum", [0.0, 0.05])
def test_the_basins_flood_is_scikit_images_watershed_label_for_label(quantum):
    """The flood called with the arrays made once (``_watershed``) labels every sample as
    the public ``watershed`` does, plateaus (heights rounded to ``quantum`` mm, ties the
    flood's order settles) and a non-square map included."""
    from twoscale.surface.segmentation import _candidates, _watershed

    z = road(30.0, 0.1, seed=2)[:, :257]
    if quantum:
        z = np.round(z / quantum) * quantum
    seeds = _candidates(z, 20.0)
    markers = np.zeros(z.shape, dtype=np.int64)
    markers[seeds[:, 0], seeds[:, 1]] = np.arange(1, len(seeds) + 1)
    assert np.array_equal(_watershed(z, seeds), watershed(-z, markers, connectivity=2) - 1)
