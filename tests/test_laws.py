"""Asperity laws: closed forms, inverses, tangents, the tabulated interpolant's order."""

import math

import numpy as np
import pytest

from twoscale import Material
from twoscale.indenters import Asperity
from twoscale.laws import CompliantLaw, HertzLaw, LawStack, SphereLaw, TabulatedLaw, compliant, law_for

E_STAR = 10.0 / 0.75
R = 5.0


def hertz_table(n, dmax=0.5):
    d = np.linspace(0.0, dmax, n)
    return d, 4.0 / 3.0 * E_STAR * math.sqrt(R) * d**1.5


LAWS = {
    "hertz": HertzLaw(R, E_STAR),
    "sphere": SphereLaw(R, E_STAR),
    "tabulated": TabulatedLaw(*hertz_table(30)),
    "compliant+": CompliantLaw(SphereLaw(R, E_STAR), 0.01),
    "compliant-": CompliantLaw(HertzLaw(R, E_STAR), -0.002),
}


def test_hertz_closed_form():
    d = np.array([1e-4, 0.01, 0.3, 2.0])
    expected = 4.0 / 3.0 * E_STAR * np.sqrt(R) * d**1.5
    assert np.allclose(HertzLaw(R, E_STAR).force(d), expected, rtol=1e-14)
    assert np.allclose(HertzLaw(R, E_STAR).stiffness(d), 2 * E_STAR * np.sqrt(R * d), rtol=1e-14)


def test_sphere_matches_segedin_parametric_form():
    # independent of the law's Newton solve: pick contact radii, get (delta, P) in closed form
    a = np.array([0.01, 0.5, 2.0, 4.0, 4.9]) * R / 5.0
    delta = 0.5 * a * np.log((R + a) / (R - a))
    P = 0.5 * E_STAR * ((a**2 + R**2) * np.log((R + a) / (R - a)) - 2 * a * R)
    law = SphereLaw(R, E_STAR)
    assert np.allclose(law.force(delta), P, rtol=1e-11)
    assert np.allclose(law.stiffness(delta), 2 * E_STAR * a, rtol=1e-11)
    assert np.allclose(law.penetration(P), delta, rtol=1e-11)


def test_sphere_tends_to_hertz_for_small_penetration():
    h, s = HertzLaw(R, E_STAR), SphereLaw(R, E_STAR)
    d = R * np.array([1e-5, 1e-4, 1e-3, 1e-2])
    rel = (h.force(d) - s.force(d)) / h.force(d)
    # the cap rises faster than the paraboloid by ~r^4/8R^3: the deficit is O(delta/R)
    assert np.all(rel > 0)
    ratio = rel / (d / R)
    assert np.all((ratio > 0.05) & (ratio < 1.0))
    assert rel[0] < 1e-5


@pytest.mark.parametrize("name", sorted(LAWS))
def test_round_trip(name):
    law = LAWS[name]
    d = np.array([1e-6, 1e-3, 0.05, 0.2, 0.45, 0.8])  # 0.8 is beyond the table
    assert np.allclose(law.penetration(law.force(d)), d, rtol=1e-9, atol=0)
    P = np.array([1e-5, 0.1, 3.0, 20.0, 120.0])
    assert np.allclose(law.force(law.penetration(P)), P, rtol=1e-9, atol=0)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_stiffness_matches_finite_differences(name):
    law = LAWS[name]
    d = np.array([0.02, 0.1, 0.33, 0.6])
    eps = 1e-6
    fd = (law.force(d + eps) - law.force(d - eps)) / (2 * eps)
    assert np.allclose(law.stiffness(d), fd, rtol=1e-6)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_zero_force_and_stiffness_out_of_contact(name):
    law = LAWS[name]
    d = np.array([-1.0, -1e-9, 0.0])
    assert np.all(law.force(d) == 0) and np.all(law.stiffness(d) == 0)
    assert law.penetration(0.0) == 0.0
    with pytest.raises(ValueError, match="-1"):
        law.penetration(-1.0)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_monotone(name):
    law = LAWS[name]
    d = np.linspace(-0.1, 1.0, 2001)
    assert np.all(np.diff(law.force(d)) >= 0)
    assert np.all(law.stiffness(d) >= 0)


def test_tabulated_reproduces_hertz_to_interpolation_order():
    hertz = HertzLaw(R, E_STAR)
    ns = np.array([11, 21, 41, 81])
    inner, near0 = [], []
    for n in ns:
        law = TabulatedLaw(*hertz_table(n))
        d = np.linspace(0.125, 0.5, 3001)  # away from the singular curvature at 0
        inner.append(np.max(np.abs(law.force(d) - hertz.force(d))) / hertz.force(0.5))
        d0 = np.linspace(0.0, 0.5, 3001)
        near0.append(np.max(np.abs(law.force(d0) - hertz.force(d0))) / hertz.force(0.5))
    h = 0.5 / (ns - 1)
    rate_inner = np.polyfit(np.log(h), np.log(inner), 1)[0]
    rate_all = np.polyfit(np.log(h), np.log(near0), 1)[0]
    # PCHIP is third order on smooth data; delta^(3/2) limits it to order 3/2 near 0
    assert rate_inner > 2.7, rate_inner
    assert rate_all > 1.4, rate_all
    assert near0[-1] < 1e-4


def test_tabulated_extrapolation_is_power_law_and_c1():
    law = TabulatedLaw(*hertz_table(81))
    assert law.exponent == pytest.approx(1.5, rel=1e-3)
    dn = 0.5
    for f in (law.force, law.stiffness):
        assert f(dn * (1 + 1e-12)) == pytest.approx(float(f(dn * (1 - 1e-12))), rel=1e-8)
    hertz = HertzLaw(R, E_STAR)
    assert law.force(1.0) == pytest.approx(float(hertz.force(1.0)), rel=2e-3)


@pytest.mark.parametrize(
    "delta, P, shown",
    [
        ([0.0, 0.1, 0.2], [1.0, 2.0, 3.0], "start at"),
        ([0.1, 0.2], [0.0, 1.0], "start at"),
        ([0.0, 0.2, 0.1], [0.0, 1.0, 2.0], "delta must be strictly increasing"),
        ([0.0, 0.1, 0.2], [0.0, 2.0, 1.0], "P must be strictly increasing"),
        ([0.0, 0.1, 0.2], [0.0, 1.0, 1.0], "P must be strictly increasing"),
        ([0.0, 0.1, np.nan], [0.0, 1.0, 2.0], "non-finite"),
        ([0.0], [0.0], "length >= 2"),
        ([0.0, 0.1], [0.0, 1.0, 2.0], "equal length"),
    ],
)
def test_tabulated_rejects_invalid_tables(delta, P, shown):
    with pytest.raises(ValueError, match=shown):
        TabulatedLaw(delta, P)


@pytest.mark.parametrize("law", [HertzLaw, SphereLaw])
@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf, math.nan])
def test_closed_form_laws_refuse_a_radius_or_modulus_that_is_not_a_positive_number(law, bad):
    # a float takes a check of its own (no array per tip): the same refusals as arrays
    with pytest.raises(ValueError, match="R \\(mm\\) must be finite and > 0"):
        law(bad, E_STAR)
    with pytest.raises(ValueError, match="E_star \\(MPa\\) must be finite and > 0"):
        law(R, bad)
    with pytest.raises(ValueError, match="R \\(mm\\) must be finite and > 0"):
        law(np.array([R, bad]), E_STAR)
    assert law(R, E_STAR).R == R and law(2, E_STAR).R == 2  # an int too


def test_compliant_law_is_the_law_in_series_with_c():
    base = SphereLaw(R, E_STAR)
    P = np.array([0.0, 0.5, 5.0, 50.0])
    for c in (0.02, -0.003):
        law = CompliantLaw(base, c)
        assert np.allclose(law.penetration(P), base.penetration(P) + c * P, rtol=1e-14)
        d = law.penetration(P)
        assert np.allclose(law.force(d), P, rtol=1e-10, atol=1e-12)
        k = base.stiffness(base.penetration(P[1:]))
        assert np.allclose(law.stiffness(d[1:]), k / (1 + c * k), rtol=1e-9)
    assert compliant(base, 0.0) is base
    d = np.array([0.01, 0.3])
    assert np.array_equal(CompliantLaw(base, 0.0).force(d), base.force(d))
    with pytest.raises(ValueError, match="nan"):
        CompliantLaw(base, float("nan"))


def test_compliant_law_too_negative_raises():
    law = CompliantLaw(HertzLaw(R, E_STAR), -0.5)  # 1/|c| = 2 N/mm: Hertz passes it at delta ~ 1e-3
    with pytest.raises(ValueError, match="not monotone"):
        law.force(1.0)


def test_law_for_and_stack():
    mat = Material(10.0, 0.5)
    hz = law_for(Asperity(0, 0, 0, 4.0, shape="paraboloid"), mat)
    sp = law_for(Asperity(0, 0, 0, 6.0, shape="sphere"), mat)
    assert isinstance(hz, HertzLaw) and hz.R == 4.0 and hz.E_star == pytest.approx(mat.E_star)
    assert isinstance(sp, SphereLaw) and sp.R == 6.0
    tab = LAWS["tabulated"]
    laws = [hz, sp, tab, HertzLaw(6.0, 3.0), tab, LAWS["compliant+"]]
    d = np.array([0.1, 0.2, 0.3, 0.4, 0.7, 0.05])
    stack = LawStack(laws)
    for m in ("force", "stiffness"):
        assert np.allclose(getattr(stack, m)(d), [getattr(l, m)(x) for l, x in zip(laws, d)], rtol=1e-14)
    P = stack.force(d)
    assert np.allclose(stack.penetration(P), d, rtol=1e-9)
    with pytest.raises(ValueError, match="shape"):
        stack.force(d[:3])


def test_invalid_parameters_raise():
    with pytest.raises(ValueError, match="-1"):
        HertzLaw(-1.0, E_STAR)
    with pytest.raises(ValueError, match="inf"):
        SphereLaw(R, float("inf"))
    with pytest.raises(ValueError, match="NaN"):
        HertzLaw(R, E_STAR).force(float("nan"))


@pytest.mark.parametrize("name", sorted(LAWS))
def test_complementary_energy_integrates_the_inverse_law(name):
    from scipy.integrate import quad

    law = LAWS[name]
    P = np.array([0.0, 0.05, 2.0, 30.0, 90.0])  # 90 N is beyond the table
    phi = law.complementary_energy(P)
    assert phi[0] == 0.0
    kinks = getattr(law, "P_table", np.zeros(0))
    for p, value in zip(P[1:], phi[1:]):
        ref = quad(
            lambda s: float(law.penetration(s)),
            0.0,
            p,
            points=kinks[(kinks > 0) & (kinks < p)],
            epsabs=0.0,
            epsrel=1e-12,
            limit=400,
        )[0]
        assert value == pytest.approx(ref, rel=1e-9)
    eps = 1e-5
    fd = (law.complementary_energy(P[2:] + eps) - law.complementary_energy(P[2:] - eps)) / (2 * eps)
    assert np.allclose(fd, law.penetration(P[2:]), rtol=1e-7)


def test_sphere_law_inverts_near_the_caps_edge():
    # a cap pressed to a/R = 0.9-0.99999 (the macro step's safe path can ask): Segedin's
    # closed forms and the law's two inversions agree
    R, E = 4.0, 3.0
    e = np.array([0.5, 0.9, 0.95, 0.99, 0.999, 0.99999])
    d = R * e * np.arctanh(e)
    P = E * R * R * ((1 + e * e) * np.arctanh(e) - e)
    law = SphereLaw(R, E)
    assert np.allclose(law.force(d), P, rtol=1e-9)
    assert np.allclose(law.penetration(P), d, rtol=1e-9)


def test_sphere_energy_by_parts_equals_the_generic_quadrature():
    # the sphere's own rule (one inversion, integral over the contact radius) against the
    # generic rule (16 inversions, integral over the load), from Hertz's range to a/R 0.95
    from twoscale.laws.base import AsperityLaw

    law = SphereLaw(np.full(7, 4.0), np.full(7, 3.0))
    a = 4.0 * np.array([1e-4, 0.01, 0.2, 0.5, 0.8, 0.89, 0.95])
    P = 3.0 * (a * a * np.arctanh(a / 4.0) + 16.0 * (np.arctanh(a / 4.0) - a / 4.0))  # Segedin
    own, generic = law.complementary_energy(P), AsperityLaw.complementary_energy(law, P)
    assert np.allclose(own, generic, rtol=1e-10, atol=0.0)


def test_sphere_law_keeps_its_last_inversion_from_the_load_exactly():
    # the safe path asks for the energy and then the penetration at the same forces: the
    # second reuses the first's contact radii, with the values of a fresh law, and a
    # change of any force (or a caller writing into a result) does not reach the kept ones
    R, E = np.array([0.7, 0.9, 1.1]), 2.0
    law = SphereLaw(R, E)
    P = np.array([0.01, 0.05, 0.2])
    law.complementary_energy(P)
    first = law.penetration(P)
    assert np.array_equal(first, SphereLaw(R, E).penetration(P))
    first[:] = -1.0
    assert np.array_equal(law.penetration(P), SphereLaw(R, E).penetration(P))
    Q = P.copy()
    Q[1] *= 2.0
    assert np.array_equal(law.penetration(Q), SphereLaw(R, E).penetration(Q))
    assert law.penetration(Q)[1] > law.penetration(P)[1]
