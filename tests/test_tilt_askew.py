"""Faces set askew under a free tilt, seeded random scenes against the full-grid reference.

A ball-and-socket indenter whose tips' heights lie on a sloping plane (plus a tenth of that
relief at random) turns until tips on every side of the pivot carry load. Untilted, only
the low side's tips touch: the reference's grid, sized by each tip's reach at the untilted
approach, left the high tips off (seed 7 came out 51 % wrong without a word), and the
two-scale solve refused three of these ten scenes ("no tilt balances the moments"). Both
solvers must now agree, at the same cell size, to the reference's own tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

import twoscale
from twoscale import Asperity, Material

MATERIAL = Material(10.0, 0.5)


def askew_scene(seed: int) -> tuple[tuple, tuple, float]:
    """4-12 spheres (R 3-6 mm) on a jittered 8 mm lattice, heights on a plane of slope
    0.005-0.05 in a random direction plus up to a tenth of its relief, the pivot within
    1 mm of their centroid: the tips, the pivot and the slope."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 13))
    side = int(np.ceil(np.sqrt(n)))
    xy = np.array([(i, j) for i in range(side) for j in range(side)][:n], dtype=float) * 8.0
    xy += rng.uniform(-1.5, 1.5, xy.shape)
    xy -= xy.mean(axis=0)
    slope, angle = rng.uniform(0.005, 0.05), rng.uniform(0.0, 2.0 * np.pi)
    along = xy @ np.array([np.cos(angle), np.sin(angle)])
    z = slope * along + rng.uniform(0.0, 0.1 * slope * np.ptp(along), n)
    z -= z.min()
    radii = rng.uniform(3.0, 6.0, n)
    tips = tuple(Asperity(float(x), float(y), float(zk), float(r)) for (x, y), zk, r in zip(xy, z, radii))
    return tips, tuple(rng.uniform(-1.0, 1.0, 2)), float(slope)


@pytest.mark.parametrize("seed", range(10))
def test_a_face_set_askew_matches_the_reference(seed):
    tips, pivot, slope = askew_scene(seed)
    load = dict(material=MATERIAL, total_load=float(len(tips)), tilt=True, pivot=pivot, h=0.1)
    res = twoscale.solve(tips, **load)
    ref = twoscale.solve(tips, method="reference", **load)
    assert res.converged and ref.converged, (res.message, ref.message)
    # every tip carries load: the face turned until the high side touched
    assert np.all(ref.forces > 0)
    # the turn is of the order of the heights' slope (a tenth of the relief is random)
    assert 0.5 * slope < np.hypot(*ref.tilt) < 1.5 * slope
    np.testing.assert_allclose(res.forces, ref.forces, rtol=0, atol=1e-6 * ref.forces.max())
    np.testing.assert_allclose(res.tilt, ref.tilt, rtol=0, atol=1e-6 * slope)
