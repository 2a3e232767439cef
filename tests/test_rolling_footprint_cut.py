"""A tyre's face against its window and its load: a window shorter than the contact, a
tyre left without contact by the held approach.

The road outside the ``footprint`` window never touches, so a window shorter along x than
the tyre's contact cuts it: the load is carried on a shorter face and the approach comes
out larger. That run used to pass without a word (exit 0); it now warns, naming
``rolling.footprint``. A window longer than the contact gives no warning and the tyre's
own answer. A held approach too small for any contact wider than a cell was refused naming
only ``rolling.tyre_radius``; the refusal now names the approach too.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from twoscale import Material
from twoscale.errors import SceneError, SurfaceWarning
from twoscale.rolling import RollingSpec, road_strip, roll
from twoscale.scene import Scene
from twoscale.surface import RawMap, build_surface

MAT = Material(10.0, 0.5)
H = 0.25


@pytest.fixture(scope="module")
def strip():
    return build_surface(RawMap(road_strip(60.0, 20.0, H, seed=3), spacing=H, units="mm"))


def _run(strip, length: float):
    spec = RollingSpec(start=-6.0, end=-5.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(length, 16.0))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        run = roll(Scene(material=MAT, surface=strip, rolling=spec, total_load=60.0))
    return run, [str(w.message) for w in rec if issubclass(w.category, SurfaceWarning)]


def test_a_window_shorter_than_the_contact_is_named_in_a_warning(strip):
    long_run, long_lines = _run(strip, 30.0)
    short_run, short_lines = _run(strip, 4.0)
    assert long_run.all_converged and short_run.all_converged
    # the long window holds the contact: no cell column within a cell of its ends is loaded
    loaded = long_run.line_x[(long_run.line_load > 0).any(axis=0)]
    assert loaded.min() > -15.0 + H and loaded.max() < 15.0 - H
    assert not long_lines
    # the short one cuts it: the same load on less face, a deeper approach
    assert np.all(short_run.penetration > 1.05 * long_run.penetration)
    [line] = short_lines
    assert line.startswith("rolling.footprint = [4, 16] mm") and "at 2 of 2 positions" in line


def test_a_tyre_left_without_contact_by_a_tiny_penetration_names_the_penetration(strip):
    """The tyre's radius alone does not leave it without contact: the held approach does."""
    spec = RollingSpec(start=-6.0, end=-5.0, step=1.0, speed=30.0, tyre_radius=150.0, footprint=(30.0, 16.0))
    with pytest.raises(SceneError, match=r"with load\.penetration = 0\.0001 mm leaves no contact"):
        roll(Scene(material=MAT, surface=strip, rolling=spec, penetration=1e-4))
