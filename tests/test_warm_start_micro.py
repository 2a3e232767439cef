"""The micro step's warm start from a neighbouring solve's pressure: same answer, less work."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import twoscale
from twoscale.synthetic import random_scene
from twoscale.warm_start import WarmStart, warm_start

H = 0.05
# the scenes are coarse on purpose (the starts, not the resolution, are under test)
pytestmark = pytest.mark.filterwarnings("ignore::twoscale.errors.ResolutionWarning")


def _scene(control: str, kind: str = "sparse", n: int = 12, shift: float = 0.0):
    sc = random_scene(n, kind=kind, control=control, shape="sphere", seed=3)
    tips = tuple(dataclasses.replace(a, x=a.x + shift) for a in sc.asperities)
    return dataclasses.replace(sc, asperities=tips, h=H)


def _tips(scene) -> np.ndarray:
    return np.array([[a.x, a.y] for a in scene.asperities])


@pytest.mark.parametrize("control", ["load", "penetration"])
@pytest.mark.parametrize("iteration", ["auto", "block-gs", "union-cg", "two-level"])
def test_a_second_solve_from_the_first_gives_its_answer_at_once(control, iteration):
    scene = _scene(control)
    cold = twoscale.solve(scene, iteration=iteration)
    warm = twoscale.solve(scene, iteration=iteration, start=warm_start(cold, _tips(scene), len(_tips(scene)), H))
    assert warm.converged
    scale = cold.asperities.forces.max()
    # both stop at the solver's tolerance (1e-6 relative change): agreement well inside it
    assert np.abs(warm.asperities.forces - cold.asperities.forces).max() <= 1e-5 * scale
    assert warm.penetration == pytest.approx(cold.penetration, rel=1e-6, abs=1e-9)
    # started at the answer: at most one sweep (or no CG iteration) to confirm it
    assert warm.iterations["micro"] <= 1 < cold.iterations["micro"]


def test_a_start_moved_with_the_tips_serves_the_shifted_scene():
    scene, moved = _scene("load"), _scene("load", shift=3 * H)
    first = twoscale.solve(scene)
    cold = twoscale.solve(moved)
    warm = twoscale.solve(moved, start=warm_start(first, _tips(scene), len(_tips(scene)), H))
    assert np.abs(warm.asperities.forces - cold.asperities.forces).max() <= 1e-5 * cold.asperities.forces.max()
    assert warm.iterations["micro"] < cold.iterations["micro"]


def test_a_changed_load_scales_the_start_and_still_converges_to_the_cold_answer():
    scene = _scene("load")
    first = twoscale.solve(scene)
    heavier = dataclasses.replace(scene, total_load=1.5 * scene.total_load)
    cold = twoscale.solve(heavier)
    warm = twoscale.solve(heavier, start=warm_start(first, _tips(scene), len(_tips(scene)), H))
    assert warm.total_load == pytest.approx(1.5 * scene.total_load, rel=1e-6)
    assert np.abs(warm.asperities.forces - cold.asperities.forces).max() <= 1e-5 * cold.asperities.forces.max()


def test_new_tips_start_from_eq_7_and_lost_tips_are_dropped():
    scene = _scene("penetration")
    fewer = dataclasses.replace(scene, asperities=scene.asperities[2:])
    first = twoscale.solve(fewer)
    index = np.array([-1, -1] + list(range(len(fewer.asperities))))
    start = warm_start(first, _tips(fewer), len(scene.asperities), H, index=index)
    cold = twoscale.solve(scene)
    warm = twoscale.solve(scene, start=start)
    assert np.abs(warm.asperities.forces - cold.asperities.forces).max() <= 1e-5 * cold.asperities.forces.max()


def test_a_start_at_another_cell_size_starts_the_macro_step_only():
    scene = _scene("load")
    first = twoscale.solve(scene)
    start = warm_start(first, _tips(scene), len(_tips(scene)), 2 * H)
    assert isinstance(start, WarmStart) and start.macro is not None and start.micro is None


def test_a_bad_index_is_refused_naming_it():
    scene = _scene("load")
    first = twoscale.solve(scene)
    with pytest.raises(ValueError, match="index"):
        warm_start(first, _tips(scene), 3, H)
    with pytest.raises(ValueError, match="index must hold"):
        warm_start(first, _tips(scene), 2, H, index=np.array([0, 99]))
