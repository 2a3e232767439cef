"""A height map's asperities from all basins at once, each against a direct computation
on the map itself: the reach (farthest basin sample less than a depth below the summit)
from the basin's samples by label, the equivalent spheres by one least-squares fit per
basin on the samples of its cap."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale.surface import RawMap, SurfaceOptions, build_surface
from twoscale.surface.sphere_fit import MIN_CAP_SAMPLES, fit_spheres
from twoscale.surface.texture import road


@pytest.fixture(scope="module")
def surface():
    z = road(14.0, 0.1, seed=5)
    z[30:42, 50:61] = np.nan  # a hole: masked samples belong to no cap and no reach
    return build_surface(RawMap(z, 0.1, "mm", None, "road"), SurfaceOptions(fill="mask"))


def _samples(surface, k):
    """Basin ``k``'s measured samples: depth below the summit and distance from it."""
    hmap, seg = surface.hmap, surface.segmentation
    X, Y = hmap.grid.centres()
    mine = (seg.labels == k) & np.isfinite(hmap.heights)
    j, i = seg.summits[k]
    return seg.heights[k] - hmap.heights[mine], np.hypot(X[mine] - X[j, i], Y[mine] - Y[j, i])


def test_reach_is_the_farthest_basin_sample_within_the_depth(surface):
    for a in surface.asperities:
        fall, dist = _samples(surface, a.label)
        levels = np.unique(fall)
        # between two distinct depths (the rounding of recess - z_k is far below the gaps)
        gaps = np.flatnonzero(np.diff(levels) > 1e-9)[::5]
        for d in np.r_[0.5 * (levels[gaps] + levels[gaps + 1]), levels[-1] + 1.0]:
            assert a.reach(float(d)) == dist[fall < d].max()
        assert a.reach(0.0) == 0.0 and a.reach(-1.0) == 0.0
        assert a.extent >= dist.max()


def _fit_direct(surface, k, depth):
    """One basin's cap fitted by least squares as the module docstring says."""
    hmap, seg = surface.hmap, surface.segmentation
    X, Y = hmap.grid.centres()
    mine = np.flatnonzero(((seg.labels == k) & np.isfinite(hmap.heights)).ravel())
    fall = seg.heights[k] - hmap.heights.ravel()[mine]
    cap = mine[fall < depth]
    if cap.size < MIN_CAP_SAMPLES:
        cap = np.sort(mine[np.argsort(fall, kind="stable")[:MIN_CAP_SAMPLES]])
    j, i = seg.summits[k]
    x, y = X.ravel()[cap] - X[j, i], Y.ravel()[cap] - Y[j, i]
    A = np.column_stack([np.ones(x.size), x, y, -(x * x + y * y)])
    coef = np.linalg.lstsq(A, hmap.heights.ravel()[cap], rcond=None)[0]
    return 1.0 / (2.0 * coef[3]) if coef[3] > 0 else np.inf, cap.size


@pytest.mark.parametrize("depth", [0.1, 1e-4])
def test_sphere_fits_are_one_least_squares_fit_per_basin(surface, depth):
    """At 1e-4 mm every cap is below ``MIN_CAP_SAMPLES``: the nearest samples are fitted."""
    fit = fit_spheres(surface.hmap, surface.segmentation, depth=depth)
    nearest = 0
    for k in range(len(surface.segmentation)):
        R, n = _fit_direct(surface, k, depth)
        nearest += n == MIN_CAP_SAMPLES
        assert fit.samples[k] == n
        if fit.R[k] < 1e2:  # (flat caps get a nominal radius)
            assert fit.R[k] == pytest.approx(R, rel=1e-12)
    assert nearest >= (len(fit.R) if depth < 1e-3 else 0)
