"""Seeded sweep of random realistic scenes (twoscale.synthetic) against the full-grid
reference on the same grid: the default two-scale solve (the policy's choice) must
converge with every tip's force within 0.5 % of the largest force and the total within
0.5 %. A fast subset runs by default (coarse cells); the rest is marked slow."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale.api import solve_scene
from twoscale.synthetic import random_scene

FAST = [
    # (n, kind, control, shape, seed, h)
    (30, "dense", "load", "sphere", 0, 0.1),
    (30, "dense", "penetration", "paraboloid", 1, 0.1),
    (40, "sparse", "load", "sphere", 2, 0.08),
    (40, "sparse", "penetration", "paraboloid", 3, 0.08),
]
SLOW = [
    (200, "dense", "load", "sphere", 4, 0.05),
    (200, "dense", "penetration", "sphere", 5, 0.05),
    (100, "dense", "load", "paraboloid", 6, 0.05),
    (300, "sparse", "load", "sphere", 7, 0.04),
    (300, "sparse", "penetration", "paraboloid", 8, 0.04),
]


def _check(n, kind, control, shape, seed, h):
    scene = random_scene(n, kind=kind, control=control, shape=shape, seed=seed, h=h)
    res = solve_scene(scene)
    assert res.converged, res.message
    ref = solve_scene(scene, method="reference")
    assert ref.converged, ref.message
    F, Fr = np.asarray(res.asperities.forces), np.asarray(ref.asperities.forces)
    assert np.max(np.abs(F - Fr)) <= 5e-3 * Fr.max(), (
        res.details.micro.choice.reason,
        np.max(np.abs(F - Fr)) / Fr.max(),
    )
    assert res.total_load == pytest.approx(ref.total_load, rel=5e-3)
    # the policy's record: what it chose, why, and every attempt
    choice = res.details.micro.choice
    assert choice.reason and not choice.by_caller
    assert res.details.micro.attempts[-1].converged
    return res


@pytest.mark.parametrize("n,kind,control,shape,seed,h", FAST)
def test_default_solve_matches_the_reference(n, kind, control, shape, seed, h):
    _check(n, kind, control, shape, seed, h)


@pytest.mark.slow
@pytest.mark.parametrize("n,kind,control,shape,seed,h", SLOW)
def test_default_solve_matches_the_reference_on_larger_scenes(n, kind, control, shape, seed, h):
    _check(n, kind, control, shape, seed, h)
