"""Layer theory (docs/method.md section 6): its limits (thick layer, long waves) and its
Hankel integral against adaptive quadrature."""

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


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.45, 0.5])
def test_long_wave_limit_is_the_layer_compressed_as_a_whole(nu):
    # Under pressure of wavelength >> t the layer is compressed uniformly through its
    # thickness: u_hat = t c p_hat, with c the compliance of a unit column, against the
    # half-space's u_hat = 2 p_hat / (E* xi); so K(s) / s -> E* c / 2 (s = xi t).
    # Bonded base: no lateral strain (confined): c = (1 + nu)(1 - 2 nu) / (E (1 - nu)).
    # Sliding base: no shear on either face, so no lateral stress along the wave and plane
    # strain across it: c = (1 - nu^2) / E = 1 / E*. Elementary elasticity, not this code.
    E = 1.0
    E_star = E / (1 - nu**2)
    confined = (1 + nu) * (1 - 2 * nu) / (E * (1 - nu))
    s = 1e-5
    assert layer_factor(s, nu, "bonded") / s == pytest.approx(E_star * confined / 2, abs=1e-6)
    assert layer_factor(s, nu, "sliding") / s == pytest.approx(E_star * (1 / E_star) / 2, abs=1e-6)


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
