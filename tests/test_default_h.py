"""The default cell size (twoscale.scene.default_h) for any number of asperities: the
smallest contact it resolves gets 32 cells across (rounded down to two digits), checked
against an independent Hertz estimate computed here; the examples keep their h."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from twoscale import Material
from twoscale.indenters import Asperity
from twoscale.io.scene_file import read_scene
from twoscale.scene import CELL_BUDGET, MIN_FORCE_FRACTION, Scene, SceneError, default_h

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

#: default_h of each example with its [grid] h removed, per load (the scene's load,
#: then each load case): the values of the rule "1 % of the total load", which the rule
#: "1 % of the largest tip force" must keep (every example's tips carry similar loads).
EXAMPLE_H = {
    "S1.toml": (0.098, 0.098, 0.12, 0.13),
    "S2.toml": (0.095, 0.095, 0.1, 0.1),
    "S3.toml": (0.086, 0.086, 0.092, 0.098),
    "hertz_sphere.toml": (0.13,),
    "paper_seven_spheres.toml": (0.19,),
    "paper_two_spheres.toml": (0.13,),
}


def random_scene(n: int, *, side: float, total: float, seed: int = 0) -> Scene:
    """``n`` spheres, R uniform in 3-6 mm, tips uniform on a side x side mm square,
    recesses z uniform in [0, 0.1] mm, under a total load (N)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, side, size=(n, 2))
    R = rng.uniform(3.0, 6.0, n)
    z = rng.uniform(0.0, 0.1, n)
    asps = [Asperity(x=float(x), y=float(y), z=float(zz), R=float(r)) for (x, y), zz, r in zip(xy, z, R)]
    return Scene(material=Material(E=10.0, nu=0.5), asperities=asps, total_load=total)


def hertz_forces(R: np.ndarray, z: np.ndarray, W: float, E_star: float) -> np.ndarray:
    """Forces (N) of independent Hertz contacts P = 4/3 E* sqrt(R) delta^1.5 at the
    common level d where they sum to W (delta = d - z)."""

    def load(d):
        return 4.0 / 3.0 * E_star * np.sqrt(R) * np.maximum(d - z, 0.0) ** 1.5

    d = brentq(lambda d: load(d).sum() - W, z.min(), z.max() + 10.0, xtol=1e-14)
    return load(d)


def test_300_similar_tips_get_24_to_32_cells_across_the_smallest_resolved_contact():
    scene = random_scene(300, side=60.0, total=450.0, seed=14)
    h = default_h(scene, cell_budget=None)  # the rule alone (its patches carry ~2 M cells)
    R = np.array([a.R for a in scene.asperities])
    z = np.array([a.z for a in scene.asperities])
    E_star = scene.material.E_star
    P = hertz_forces(R, z, 450.0, E_star)
    assert P.max() < MIN_FORCE_FRACTION * P.sum()  # none carries 1 % of the total: the old rule failed
    resolved = P >= MIN_FORCE_FRACTION * P.max()
    a = (3.0 * P[resolved] * R[resolved] / (4.0 * E_star)) ** (1.0 / 3.0)
    cells = 2.0 * a.min() / h
    # h is the estimated diameter / 32 rounded down to two digits (at most 10 % down), so
    # the estimate gets 32-35.2 cells; the rule sizes spheres by their exact contact,
    # about 1 % smaller than Hertz's. Real contacts are smaller still (interaction lowers
    # the approach): README "Default cell size".
    assert 32.0 <= cells <= 36.0, (h, cells)


@pytest.mark.parametrize("n", [1, 7, 200, 1000])
def test_any_number_of_tips_gets_a_cell_size(n):
    scene = random_scene(n, side=3.5 * math.sqrt(n) + 10.0, total=1.5 * n, seed=n)
    h = default_h(scene)
    assert math.isfinite(h) and h > 0


def test_a_light_tip_does_not_set_h():
    # two tips share the load; a third, 0.39 mm higher, carries under 1 % of their force
    scene = Scene(
        material=Material(E=10.0, nu=0.5),
        total_load=20.0,
        asperities=[Asperity(0.0, 0.0, 0.0, 5.0), Asperity(20.0, 0.0, 0.0, 5.0), Asperity(40.0, 0.0, 0.39, 5.0)],
    )
    h = default_h(scene)
    assert default_h(scene, min_force_fraction=0.0) < h / 3  # resolving it would cost 10x the cells


@pytest.mark.parametrize("name", sorted(EXAMPLE_H))
def test_examples_keep_their_default_h(name):
    scene = dataclasses.replace(read_scene(EXAMPLES / name), h=None)
    cases = [scene] + [dataclasses.replace(scene, total_load=w) for w in scene.load_cases]
    assert tuple(default_h(c) for c in cases) == EXAMPLE_H[name]


def test_no_loaded_tip_is_a_scene_error():
    scene = random_scene(3, side=20.0, total=1.0)
    with pytest.raises(SceneError, match="grid.h"):
        default_h(scene, min_force_fraction=2.0)


def _patch_cells(scene: Scene, h: float) -> float:
    """Cells of squares of half-width 1.3 a + 2 h around every independent Hertz contact
    (computed here from :func:`hertz_forces`, not by the library)."""
    R = np.array([a.R for a in scene.asperities])
    z = np.array([a.z for a in scene.asperities])
    P = hertz_forces(R, z, scene.total_load, scene.material.E_star)
    a = (3.0 * P * R / (4.0 * scene.material.E_star)) ** (1.0 / 3.0)
    a = a[P > 0]
    return float(np.sum((np.floor(2.0 * (1.3 * a + 2.0 * h) / h) + 1.0) ** 2))


def test_a_light_load_on_many_tips_keeps_the_patches_within_the_cell_budget():
    # 300 spheres whose heights spread over 0.1 mm under 0.1 N each: 32 cells across the
    # smallest contact that matters would carry several million cells
    scene = random_scene(300, side=60.0, total=30.0, seed=3)
    rule = default_h(scene, cell_budget=None)
    h = default_h(scene)
    assert _patch_cells(scene, rule) > 1.5 * CELL_BUDGET  # the rule alone is over budget
    # paraboloid Hertz radii are within 1 % of the spheres' exact caps at these loads
    assert _patch_cells(scene, h) <= 1.01 * CELL_BUDGET
    # and h is not coarser than it must be: 3 % finer (less than the two-digit rounding
    # step of 1/0.93 ... 1/0.99) would be over budget
    assert _patch_cells(scene, 0.96 * h) > 0.99 * CELL_BUDGET
    # a scene within the budget keeps the rule's h
    small = random_scene(20, side=40.0, total=30.0, seed=3)
    assert default_h(small) == default_h(small, cell_budget=None)
