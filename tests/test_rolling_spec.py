"""The [rolling] table: positions, times, the tyre's face, the lattice a height map is
resampled to, and the refusals that name the field."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from twoscale.errors import SceneError
from twoscale.rolling import RollingSpec, rolling_from_table
from twoscale.rolling.track import lattice


def test_positions_and_times():
    spec = RollingSpec(start=-100.0, end=100.0, step=0.4, speed=50.0)
    assert spec.count == 501
    s = spec.shifts()
    assert s[0] == -100.0 and s[-1] == pytest.approx(100.0)
    # 50 km/h = 13,888.9 mm/s: 200 mm take 14.4 ms
    assert spec.times()[-1] == pytest.approx(200.0 / (50.0 / 3.6 * 1000.0), rel=1e-12)


def test_last_position_not_beyond_end():
    spec = RollingSpec(start=0.0, end=1.0, step=0.3, speed=10.0)
    assert np.allclose(spec.shifts(), [0.0, 0.3, 0.6, 0.9])


def test_face_parabola_and_circle():
    R = 300.0
    x = np.array([0.0, 10.0, 100.0])
    par = RollingSpec(0.0, 1.0, 1.0, 1.0, tyre_radius=R)
    circ = RollingSpec(0.0, 1.0, 1.0, 1.0, tyre_radius=R, tyre_shape="circle")
    assert np.allclose(par.face(x), x**2 / (2 * R))
    assert np.allclose(circ.face(x), R - np.sqrt(R**2 - x**2), rtol=1e-12)
    assert math.isinf(float(circ.face(np.array(400.0))))
    assert np.all(RollingSpec(0.0, 1.0, 1.0, 1.0).face(x) == 0.0)


@pytest.mark.parametrize(
    "step, spacing, cell", [(0.4, 0.25, 0.2), (1.0, 0.25, 0.25), (0.3, 0.1, 0.1), (0.1, 0.25, 0.1)]
)
def test_lattice_makes_the_step_a_multiple(step, spacing, cell):
    spec = RollingSpec(start=-10.03, end=10.0, step=step, speed=1.0)
    h, shifts = lattice(spec, spacing)
    assert h == pytest.approx(cell)
    assert h <= spacing * (1 + 1e-12)
    k = shifts / h
    assert np.allclose(k, np.round(k), atol=1e-9)  # every shift on the map's lattice
    assert abs(shifts[0] - spec.start) <= h / 2 + 1e-12


@pytest.mark.parametrize(
    "table, field",
    [
        ({"start": 1.0, "end": 0.0, "step": 1.0, "speed": 1.0}, "rolling.end"),
        ({"start": 0.0, "end": 1.0, "step": 0.0, "speed": 1.0}, "rolling.step"),
        ({"start": 0.0, "end": 1.0, "step": 1.0, "speed": -1.0}, "rolling.speed"),
        ({"start": 0.0, "end": 1.0, "step": 1.0, "speed": 1.0, "tyre_radius": 0.0}, "rolling.tyre_radius"),
        ({"start": 0.0, "end": 1.0, "step": 1.0, "speed": 1.0, "tyre_shape": "oval"}, "rolling.tyre_shape"),
        ({"start": 0.0, "end": 1.0, "step": 1.0, "speed": 1.0, "footprint": [1.0]}, "rolling.footprint"),
        ({"start": 0.0, "end": 1.0, "step": 1.0}, "rolling.speed"),
        ({"start": "a", "end": 1.0, "step": 1.0, "speed": 1.0}, "rolling.start"),
        ({"start": 0.0, "end": 1e6, "step": 1e-3, "speed": 1.0}, "rolling.step"),
    ],
)
def test_refusals_name_the_field(table, field):
    with pytest.raises(SceneError, match=field.replace(".", r"\.")):
        rolling_from_table(table)


def test_a_rolling_scene_is_not_solved_as_one_static_position_by_solve():
    import dataclasses

    import twoscale
    from twoscale.io.scene_file import read_scene

    scene = read_scene(Path(__file__).resolve().parents[1] / "examples" / "rolling" / "tyre.toml")
    with pytest.raises(ValueError, match=r"twoscale.rolling.roll\(scene\)"):
        twoscale.solve(scene)
    assert dataclasses.replace(scene, rolling=None).rolling is None
