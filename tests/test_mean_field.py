"""The neighbours' mean push on each tip's approach under penetration control
(twoscale.mean_field), against its closed form on two tips and its limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from twoscale import Material
from twoscale.analytic import hertz
from twoscale.indenters import Asperity
from twoscale.mean_field import pushed_approaches
from twoscale.resolution import expected_approaches
from twoscale.scene import Scene

MATERIAL = Material(E=10.0, nu=0.5)


def test_two_equal_tips_sink_by_what_the_others_force_lifts_them():
    # two paraboloids L apart at penetration d: each carries F = P_H(R, d - F / (pi E* L))
    # (Boussinesq's lift of the other's point force, L beyond both contacts)
    R, d, L = 5.0, 0.05, 8.0
    scene = Scene(material=MATERIAL, penetration=d, asperities=[Asperity(0.0, 0.0, 0.0, R), Asperity(L, 0.0, 0.0, R)])
    E_star = MATERIAL.E_star
    F = brentq(lambda f: hertz.load(R, d - f / (math.pi * E_star * L), E_star) - f, 0.0, hertz.load(R, d, E_star))
    want = d - F / (math.pi * E_star * L)
    assert pushed_approaches(scene) == pytest.approx([want, want], rel=1e-9)
    assert want < d


def test_the_push_fades_with_distance_and_leaves_load_control_alone():
    R, d = 5.0, 0.05
    near, far = (
        pushed_approaches(
            Scene(material=MATERIAL, penetration=d, asperities=[Asperity(0.0, 0.0, 0.0, R), Asperity(L, 0.0, 0.0, R)])
        )[0]
        for L in (5.0, 500.0)
    )
    assert near < far < d and d - far < 0.02 * (d - near)  # 1 / L: a hundredth of the push
    loaded = Scene(
        material=MATERIAL, total_load=2.0, asperities=[Asperity(0.0, 0.0, 0.0, R), Asperity(5.0, 0.0, 0.0, R)]
    )
    np.testing.assert_array_equal(pushed_approaches(loaded), expected_approaches(loaded))
