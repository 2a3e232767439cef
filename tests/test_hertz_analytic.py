"""Closed-form Hertz (paraboloid) and exact-sphere (Segedin) laws: round trips and limits.

Expected figures are derived here, not copied from the code:
* Hertz: ``a^2 = R d``, ``P = 4/3 E* sqrt(R) d^1.5``, ``p0 = 3 P / (2 pi a^2)``,
  ``dP/dd = 2 E* a``, and the pressure integrates to P.
* Exact sphere: expanding Segedin's law in a/R gives
  ``d = a^2/R + a^4/(3 R^3)``, ``P = E* (4 a^3/(3R) + 8 a^5/(15 R^3))``, hence at the same
  penetration ``P_sphere / P_Hertz = 1 - d/(10 R) + O((d/R)^2)``: first order in d/R, the
  sphere carrying less (0.5 % at d = R/20).
"""

import decimal
import math

import numpy as np
import pytest
from scipy import integrate

from twoscale.analytic import hertz

R = 10.0
E_STAR = 10.0 / (1 - 0.25)  # E = 10 MPa, nu = 0.5
DS = np.array([1e-4, 3e-3, 0.05, 0.5, 2.0])


def test_radius_and_area():
    assert np.allclose(hertz.contact_radius(R, DS) ** 2, R * DS, rtol=1e-14)
    assert np.allclose(hertz.contact_area(R, DS), math.pi * R * DS, rtol=1e-14)


def test_penetration_load_round_trip():
    P = hertz.load(R, DS, E_STAR)
    assert np.allclose(hertz.penetration(R, P, E_STAR), DS, rtol=1e-13)
    loads = np.array([1e-3, 0.7, 25.0, 400.0])
    assert np.allclose(hertz.load(R, hertz.penetration(R, loads, E_STAR), E_STAR), loads, rtol=1e-13)


def test_load_is_zero_without_penetration():
    assert hertz.load(R, 0.0, E_STAR) == 0.0
    assert hertz.load(R, -0.3, E_STAR) == 0.0
    assert hertz.load_derivative(R, -0.3, E_STAR) == 0.0


@pytest.mark.parametrize("d", [0.01, 0.5, 1.7])
def test_load_derivative_matches_finite_difference(d):
    eps = 1e-5 * d
    fd = (hertz.load(R, d + eps, E_STAR) - hertz.load(R, d - eps, E_STAR)) / (2 * eps)
    assert hertz.load_derivative(R, d, E_STAR) == pytest.approx(fd, rel=1e-8)
    assert hertz.load_derivative(R, d, E_STAR) == pytest.approx(2 * E_STAR * math.sqrt(R * d), rel=1e-14)


@pytest.mark.parametrize("d", [0.05, 0.5])
def test_pressure_integrates_to_load_and_peak(d):
    a = math.sqrt(R * d)
    P = float(hertz.load(R, d, E_STAR))
    # substitution r = a sin(t) removes the square-root edge for the quadrature
    integral = integrate.quad(
        lambda t: (
            2 * math.pi * float(hertz.pressure(a * math.sin(t), R, d, E_STAR)) * a * math.sin(t) * a * math.cos(t)
        ),
        0.0,
        0.5 * math.pi,
        epsabs=0,
        epsrel=1e-12,
    )[0]
    assert integral == pytest.approx(P, rel=1e-10)
    p0 = float(hertz.max_pressure(R, d, E_STAR))
    assert p0 == pytest.approx(3 * P / (2 * math.pi * a * a), rel=1e-13)
    assert float(hertz.pressure(0.0, R, d, E_STAR)) == pytest.approx(p0, rel=1e-15)
    assert float(hertz.pressure(1.0001 * a, R, d, E_STAR)) == 0.0


def test_sphere_radius_inverts_penetration():
    a = np.array([1e-3, 0.3, 2.0, 6.0, 9.5])
    d = hertz.sphere_penetration_from_radius(R, a)
    assert np.allclose(hertz.sphere_contact_radius(R, d), a, rtol=1e-10)


def test_sphere_tends_to_hertz_at_first_order():
    d = R * np.array([1e-4, 3e-4, 1e-3, 3e-3, 1e-2])
    rel = hertz.sphere_load(R, d, E_STAR) / hertz.load(R, d, E_STAR) - 1.0
    assert np.all(rel < 0)  # the cap rises faster than the paraboloid: less load
    rate = np.polyfit(np.log(d / R), np.log(-rel), 1)[0]
    assert rate == pytest.approx(1.0, abs=0.02)
    # leading coefficient -1/10 (module docstring)
    assert rel[0] / (d[0] / R) == pytest.approx(-0.1, rel=2e-3)
    # about 0.5 % less at d = R/20
    at20 = float(hertz.sphere_load(R, R / 20, E_STAR) / hertz.load(R, R / 20, E_STAR) - 1.0)
    assert -0.0055 < at20 < -0.0045


@pytest.mark.parametrize("d", [0.05, 0.5, 2.0])
def test_sphere_load_derivative_is_2_E_a(d):
    eps = 1e-5 * d
    fd = (hertz.sphere_load(R, d + eps, E_STAR) - hertz.sphere_load(R, d - eps, E_STAR)) / (2 * eps)
    a = float(hertz.sphere_contact_radius(R, d))
    assert fd == pytest.approx(2 * E_STAR * a, rel=1e-7)
    assert hertz.sphere_load_derivative(R, d, E_STAR) == pytest.approx(fd, rel=1e-7)


def _sphere_load_40_digits(a: float) -> float:
    """``E* R^2 [e^2 atanh(e) + atanh(e) - e]``, ``e = a/R``, in 40-digit decimals
    (``atanh(e) = ln((1 + e) / (1 - e)) / 2``)."""
    with decimal.localcontext() as ctx:
        ctx.prec = 40
        e = decimal.Decimal(a) / decimal.Decimal(R)
        atanh = ((1 + e) / (1 - e)).ln() / 2
        return float(decimal.Decimal(E_STAR) * decimal.Decimal(R) ** 2 * (e * e * atanh + atanh - e))


def test_sphere_load_is_exact_to_rounding_for_small_and_large_contacts():
    """Segedin's load against 40 digits: the series for ``atanh(e) - e`` below e = 0.1 and
    the direct difference above, in arrays that mix both, in a 2-D array and as a scalar."""
    e = np.array([[0.0, 1e-7, 3e-4, 0.02], [0.0999, 0.1, 0.35, 0.95]])
    a = e * R
    got = hertz.sphere_load_from_radius(R, a, E_STAR)
    assert got.shape == e.shape
    for i, j in np.ndindex(e.shape):
        assert got[i, j] == pytest.approx(_sphere_load_40_digits(float(a[i, j])), rel=1e-14, abs=0.0)
    assert float(hertz.sphere_load_from_radius(R, 0.5, E_STAR)) == pytest.approx(_sphere_load_40_digits(0.5), rel=1e-14)
