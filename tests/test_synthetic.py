"""The seeded random scenes of twoscale.synthetic: determinism, layout, load level."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twoscale.scene import Scene
from twoscale.synthetic import MIN_SPACING, random_scene, scene_family, square_side


def _arrays(scene: Scene):
    a = scene.asperities
    return (np.array([[t.x, t.y] for t in a]), np.array([t.z for t in a]), np.array([t.R for t in a]))


def _hertz_total(scene: Scene, d: float) -> float:
    # written out here (not the library's hertz.load): P = 4/3 E* sqrt(R) delta^1.5
    E_star = scene.material.E / (1.0 - scene.material.nu**2)
    _, z, R = _arrays(scene)
    delta = np.clip(d - z, 0.0, None)
    return float(np.sum(4.0 / 3.0 * E_star * np.sqrt(R) * delta**1.5))


@pytest.mark.parametrize("kind", ["dense", "sparse"])
def test_same_seed_same_scene_other_seed_other_scene(kind):
    a = random_scene(60, kind=kind, control="penetration", seed=3)
    b = random_scene(60, kind=kind, control="penetration", seed=3)
    c = random_scene(60, kind=kind, control="penetration", seed=4)
    assert a == b
    assert a.asperities != c.asperities


@pytest.mark.parametrize("kind", ["dense", "sparse"])
@pytest.mark.parametrize("n", [1, 50, 400])
def test_tips_distinct_spaced_and_inside_the_square(kind, n):
    scene = random_scene(n, kind=kind, seed=1)
    tips, _, _ = _arrays(scene)
    assert tips.shape == (n, 2)
    half = square_side(n, kind) / 2
    assert np.all(np.abs(tips) <= half)
    if n > 1:
        gaps = np.hypot(*(tips[:, None, :] - tips[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(gaps, np.inf)
        assert gaps.min() >= MIN_SPACING


def test_dense_layout_and_material():
    scene = random_scene(200, seed=2)
    tips, z, R = _arrays(scene)
    assert math.isclose(square_side(200, "dense"), 60.0)
    assert tips.min() < -25 and tips.max() > 25  # spread over the 60 mm square
    assert 3.0 <= R.min() and R.max() <= 6.0 and 0.0 <= z.min() and z.max() <= 0.1
    assert (scene.material.E, scene.material.nu) == (6.0, 0.5)
    assert scene.total_load == pytest.approx(200 * 2.5)  # a tread's 2-3 N per tip
    assert {a.shape for a in scene.asperities} == {"sphere"}
    assert {a.shape for a in random_scene(5, shape="paraboloid").asperities} == {"paraboloid"}


@pytest.mark.parametrize("load_per_tip", [1.5, 2.5])
def test_dense_penetration_carries_the_load_by_independent_hertz(load_per_tip):
    n = 150
    scene = random_scene(n, control="penetration", load_per_tip=load_per_tip, seed=5)
    assert scene.total_load is None
    load = _hertz_total(scene, scene.penetration)
    assert abs(load - n * load_per_tip) <= 0.10 * n * load_per_tip


@pytest.mark.parametrize("n", [50, 333])
def test_sparse_touching_fraction(n):
    scene = random_scene(n, kind="sparse", control="penetration", seed=7)
    _, z, _ = _arrays(scene)
    fraction = float(np.mean(scene.penetration - z > 0))
    assert 0.20 <= fraction <= 0.40
    assert _hertz_total(scene, scene.penetration) == pytest.approx(0.05 * n, rel=1e-6)
    assert scene.h == 0.04


def test_sparse_load_control_same_tips_as_penetration_control():
    by_load = random_scene(80, kind="sparse", control="load", seed=9)
    by_d = random_scene(80, kind="sparse", control="penetration", seed=9)
    assert by_load.asperities == by_d.asperities
    assert by_load.total_load == pytest.approx(80 * 0.05)


def test_block_scene_fits_on_the_block_top_face():
    scene = random_scene(50, body="block", seed=0)
    assert scene.influence["kind"] == "block"
    assert tuple(scene.influence["size"]) == (140.0, 140.0, 20.0)
    tips, _, _ = _arrays(scene)
    assert np.abs(tips).max() <= 60.0
    with pytest.raises(ValueError, match="n_tips = 900"):
        random_scene(900, body="block")  # dense side 127 mm > 120 mm


@pytest.mark.parametrize(
    "kwargs, named",
    [
        ({"n_tips": 0}, "n_tips"),
        ({"n_tips": 2.5}, "2.5"),
        ({"kind": "medium"}, "'medium'"),
        ({"control": "force"}, "'force'"),
        ({"shape": "cone"}, "'cone'"),
        ({"body": "layer"}, "'layer'"),
        ({"seed": -1}, "seed"),
        ({"h": 0.0}, "h must"),
        ({"load_per_tip": -1.0}, "-1.0"),
        ({"touching": 1.5}, "1.5"),
    ],
)
def test_bad_arguments_raise_naming_the_value(kwargs, named):
    args = {"n_tips": 10, **kwargs}
    n = args.pop("n_tips")
    with pytest.raises(ValueError, match=named):
        random_scene(n, **args)


def test_scene_family_names_and_count():
    family = list(scene_family(sizes=(10, 20), shapes=("sphere",)))
    assert len(family) == 2 * 2 * 2  # sizes x kinds x controls
    names = [name for name, _ in family]
    assert names[0] == "dense-load-sphere-halfspace-n10"
    assert len(set(names)) == len(names)
    assert all(len(s.asperities) == int(name.rsplit("-n", 1)[1]) for name, s in family)
