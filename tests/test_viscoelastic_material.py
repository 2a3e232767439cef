"""Prony-series material: relaxation modulus, exact creep compliance (checked by the
Volterra identity by quadrature, and by the standard linear solid's closed form), input
checks, and elastic scenes unchanged."""

import numpy as np
import pytest

from twoscale.io.scene_file import SceneError, scene_from_dict, scene_to_dict
from twoscale.material import Material
from twoscale.viscoelastic.prony import (
    CreepCompliance,
    creep_compliance,
    relaxation_modulus,
    volterra_residual,
)

TEN = tuple((float(E), float(t)) for E, t in zip(np.geomspace(100.0, 1.0, 10), np.geomspace(1e-6, 1e3, 10)))


def test_standard_linear_solid_closed_form():
    # one branch: J(t) = 1/E_inf - (1/E_inf - 1/E_g) exp(-t / lambda), lambda = tau E_g / E_inf
    m = Material(2.0, 0.5, prony=((8.0, 1.0),))
    J = creep_compliance(m)
    assert J.lambdas == pytest.approx([5.0], rel=1e-13)
    assert J.c == pytest.approx([0.5 - 0.1], rel=1e-13)
    t = np.array([0.0, 0.3, 2.0, 40.0])
    assert J(t) == pytest.approx(0.5 - 0.4 * np.exp(-t / 5.0), rel=1e-13)
    assert relaxation_modulus(m, t) == pytest.approx(2.0 + 8.0 * np.exp(-t), rel=1e-14)


@pytest.mark.parametrize("prony", [((8.0, 1.0),), ((3.0, 0.01), (5.0, 1.0), (20.0, 100.0)), TEN])
def test_volterra_identity(prony):
    m = Material(2.0, 0.5, prony=prony)
    J = creep_compliance(m)
    assert J.J0 == pytest.approx(1.0 / m.E_glassy, rel=1e-10)
    assert J.J_inf == 1.0 / 2.0
    assert np.all(J.c > 0) and np.all(np.diff(J.lambdas) > 0)
    taus = np.array([t for _, t in prony])
    times = np.concatenate([[0.0], taus * 0.3, taus * 3.0])
    assert np.abs(volterra_residual(m, times)).max() < 1e-4


def test_volterra_identity_detects_a_wrong_compliance(monkeypatch):
    # the check can fail: a 1 % error in one weight shows up well above the test's 1e-4
    m = Material(2.0, 0.5, prony=TEN)
    good = creep_compliance(m)
    bad = CreepCompliance(good.J_inf, good.lambdas, good.c * np.r_[np.ones(5), 1.01, np.ones(4)])
    monkeypatch.setattr("twoscale.viscoelastic.prony.creep_compliance", lambda _m: bad)
    assert np.abs(volterra_residual(m, [1e-2, 1.0, 100.0])).max() > 5e-4


def test_elastic_material_unchanged():
    assert Material(10.0, 0.5) == Material(10.0, 0.5, prony=())
    assert repr(Material(10.0, 0.5)) == "Material(E=10.0, nu=0.5)"
    assert not Material(10.0, 0.5).viscoelastic
    J = creep_compliance(Material(10.0, 0.5))
    assert J(np.array([0.0, 5.0])) == pytest.approx([0.1, 0.1])


@pytest.mark.parametrize(
    "prony, text",
    [
        (((-1.0, 1.0),), "material.prony[0]: E_k must be > 0 (MPa), got -1.0"),
        (((1.0, 0.0),), "material.prony[0]: tau_k must be > 0 (s), got 0.0"),
        (((1.0, 1.0), (2.0, float("nan"))), "material.prony[1]: tau_k must be a finite number (s), got nan"),
        (((1.0, 1.0), (2.0, 1.0)), "material.prony[1]: tau_k = 1.0 s repeats"),
        (((1.0,),), "material.prony[0] must be a pair"),
    ],
)
def test_bad_branches(prony, text):
    with pytest.raises(
        ValueError, match=text.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[").replace("]", r"\]")
    ):
        Material(2.0, 0.5, prony=prony)


SCENE = {
    "material": {"E": 2.0, "nu": 0.5, "prony": [[8.0, 1.0], [4.0, 0.1]]},
    "load": {"total": [[0, 5.0], [10, 5.0]]},
    "time": {"output": [0, 1, 10]},
    "asperity": [{"x": 0.0, "y": 0.0, "R": 10.0}],
}


def test_scene_file_round_trip_and_csv(tmp_path):
    s = scene_from_dict(SCENE)
    assert s.material.prony == ((8.0, 1.0), (4.0, 0.1)) and s.total_load == 5.0
    assert scene_from_dict(scene_to_dict(s)) == s
    (tmp_path / "branches.csv").write_text("E_k,tau_k\n8.0,1.0\n# a comment\n4.0,0.1\n")
    d = dict(SCENE, material={"E": 2.0, "nu": 0.5, "prony_file": "branches.csv"})
    assert scene_from_dict(d, base_dir=str(tmp_path)).material == s.material


@pytest.mark.parametrize(
    "change, text",
    [
        ({"material": {"E": 2.0, "nu": 0.5, "prony": [[8.0, -1.0]]}}, "material.prony[0]: tau_k must be > 0"),
        ({"load": {"total": [[0, 5.0], [0, 6.0]]}}, "load.total[1] time must be greater"),
        # a TOML array of tables ([[load.penetration]]): rows of two keys, not pairs
        ({"load": {"penetration": [{"x": 0, "y": 0}]}}, "load.penetration[0] must be a pair [t, value]"),
        ({"load": {"total": [[0, 5.0]], "penetration": [[0, 0.1]]}}, "give one of load.total and load.penetration"),
        ({"time": {"output": [11.0]}}, "time.output[0] = 11.0 s is outside the history"),
        ({"load": {"total": 5.0}, "time": {}}, "material.prony needs a load history"),
        ({"time": {"steps": 0}}, "time.steps must be an integer >= 1, got 0"),
    ],
)
def test_bad_scene_data(change, text):
    with pytest.raises(
        SceneError, match=text.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[").replace("]", r"\]")
    ):
        scene_from_dict(dict(SCENE, **change))
