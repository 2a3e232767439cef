"""A position's stones (twoscale.rolling.stones): their summits laid out once in the
selection, each basin's distances from its summit and extent found when first asked for,
equal to the basin's own samples measured afresh, and a window position that asks for
none of them."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.rolling import RollingOptions, RollingSpec, road_strip
from twoscale.scene import Scene
from twoscale.surface import RawMap, build_surface

MAT = Material(10.0, 0.5)
SPEC = RollingSpec(start=-6.0, end=-3.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))


@pytest.fixture(scope="module")
def track():
    from twoscale.rolling.track import prepare

    strip = build_surface(RawMap(road_strip(60.0, 20.0, 0.25, seed=3), spacing=0.25, units="mm"))
    return prepare(Scene(material=MAT, surface=strip, rolling=SPEC, total_load=60.0))


def test_a_basins_distances_and_extent_are_its_samples_measured_from_its_summit(track):
    """Each stone's ``dist`` is the distance of its basin's samples (the height map's cell
    centres of its label, in raster order) from its summit moved back to the road, ``extent``
    the largest over those inside the face's window (finite ``fall``), and the road's bound
    of it is never less."""
    road = track.road
    selection = road.stones_at(0.5, 1.0)
    assert len(selection.stones) > 10
    X, Y = road.surface.hmap.grid.centres()
    labels = road.basins.labels
    for stone in selection.stones:
        mine = labels == stone.label
        dx, dy = X[mine] - (stone.x - selection.shift), Y[mine] - stone.y
        assert np.allclose(stone.dist, np.hypot(dx, dy), rtol=1e-12, atol=1e-12)
        inside = np.isfinite(stone.fall)
        assert stone.extent == pytest.approx(np.hypot(dx, dy)[inside].max(), rel=1e-12)
    assert np.all(road.farthest(selection) >= [s.extent for s in selection.stones])


def test_the_selections_summits_are_its_stones(track):
    """The summits laid out once are each stone's ``(x, y, z)``, and ``low`` the lowest ``z``."""
    selection = track.road.stones_at(0.5, 1.0)
    xyz = [(s.x, s.y, s.z) for s in selection.stones]
    assert selection.summits.tolist() == [list(t) for t in xyz]
    assert selection.low == min(s.z for s in selection.stones)
    assert all(s.group is selection.group for s in selection.stones)


def test_a_window_position_finds_no_extent(track):
    """The window's positions after the first (which builds the window over the stones'
    reach) check their cover on the road's bound of the extents: no stone's distances or
    extent are found (their passes over every sample are saved)."""
    from twoscale.rolling.run import step, window_state

    options = RollingOptions()
    state, last = window_state(track, options), None
    for k in range(len(track.shifts)):
        last = step(track, k, last, options, state)
        assert last.result.converged
        assert k == 0 or not any("extent" in vars(s) or "dist" in vars(s) for s in last.selection.stones)
