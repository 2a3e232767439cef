"""Layer theory (docs/method.md section 6): limits and the figures quoted there."""
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import j0

from fem_influence.layer import layer_factor, point_displacement, point_ratio
from twoscale.material import Material


@pytest.mark.parametrize("base", ["bonded", "sliding"])
def test_thick_layer_is_halfspace(base):
    # r/t -> 0: the correction term is (r/t) * int (g - 1) ds -> 0 linearly
    r = np.array([1.0, 2.0])
    ratio = point_ratio(r, 1e4, 0.5, base)
    np.testing.assert_allclose(ratio, 1.0, atol=5e-4)


def test_factor_limits():
    for base in ["bonded", "sliding"]:
        assert layer_factor(39.0, 0.3, base) == pytest.approx(1.0, abs=1e-15)
        assert layer_factor(1e-4, 0.5, base) == pytest.approx(0.0, abs=1e-3)


@pytest.mark.parametrize("base,expected", [("bonded", [0.57, 0.22, -0.13]), ("sliding", [0.71, 0.46, 0.13])])
def test_method_section6_figures(base, expected):
    # docs/method.md section 6: t = 20 mm, nu = 0.5, r = 5, 10, 20 mm, +-0.02
    ratio = point_ratio(np.array([5.0, 10.0, 20.0]), 20.0, 0.5, base)
    np.testing.assert_allclose(ratio, expected, atol=0.02)


def test_small_r_slope_bonded():
    # docs/method.md section 6: u ~ (1/(pi E*)) (1/r - 1.77/t) for r << t (bonded, nu = 0.5)
    t = 20.0
    r = np.array([0.05, 0.1])
    slope = (point_ratio(r, t, 0.5) - 1.0) / (r / t)
    np.testing.assert_allclose(slope, -1.77, atol=0.01)


def test_quadrature_against_adaptive():
    # independent evaluation of the same Hankel integral with adaptive quadrature
    t, r, nu = 20.0, 13.0, 0.45
    f = lambda s: (layer_factor(s, nu, "bonded") - 1.0) * j0(s * r / t)
    val = 1.0 + (r / t) * quad(f, 0, 60, limit=400)[0]
    assert point_ratio(r, t, nu) == pytest.approx(val, abs=1e-9)


def test_displacement_units_and_invalid():
    mat = Material(E=2.0, nu=0.5)
    u = point_displacement(10.0, 20.0, mat, "sliding")
    assert u == pytest.approx(point_ratio(10.0, 20.0, 0.5, "sliding") / (np.pi * mat.E_star * 10.0))
    with pytest.raises(ValueError, match="base"):
        layer_factor(1.0, 0.5, "glued")
    with pytest.raises(ValueError, match="thickness"):
        point_ratio(1.0, 0.0, 0.5)
