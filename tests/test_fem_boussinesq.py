"""Boussinesq interior fields: surface limit, Hooke's law, equilibrium, resultant force."""

import numpy as np
import pytest

from fem_influence.boussinesq import point_displacement, point_stress
from twoscale.material import Material


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.5])
def test_surface_displacement_is_boussinesq(nu):
    mat = Material(E=2.5, nu=nu)
    r = np.array([0.5, 3.0, 17.0])
    pts = np.column_stack([r * np.cos(0.7), r * np.sin(0.7), np.zeros(3)])
    u = point_displacement(pts, mat, P=2.0)
    np.testing.assert_allclose(u[:, 2], 2.0 * (1 - nu**2) / (np.pi * mat.E * r), rtol=1e-13)
    # radial surface displacement: -(1-2nu)(1+nu) P / (2 pi E r) (towards the load)
    ur = u[:, 0] * np.cos(0.7) + u[:, 1] * np.sin(0.7)
    np.testing.assert_allclose(ur, -(1 - 2 * nu) * (1 + nu) * 2.0 / (2 * np.pi * mat.E * r), atol=1e-14)


def _num_grad(f, p, eps=1e-5):
    cols = []
    for d in range(3):
        dp = np.zeros(3)
        dp[d] = eps
        cols.append((f(p + dp) - f(p - dp)) / (2 * eps))
    return np.stack(cols, axis=-1)  # [..., component, derivative]


@pytest.mark.parametrize("nu", [0.25, 0.49])
def test_stress_is_hooke_of_displacement(nu):
    mat = Material(E=3.0, nu=nu)
    lam = mat.E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = mat.E / (2 * (1 + nu))
    src = (1.0, -2.0)
    for p in [np.array([2.0, 1.0, 3.0]), np.array([1.0, -2.0, 4.0]), np.array([-5.0, 7.0, 0.5])]:
        g = _num_grad(lambda q: point_displacement(q, mat, source=src), p)
        eps = 0.5 * (g + g.T)
        sig = 2 * mu * eps + lam * np.trace(eps) * np.eye(3)
        np.testing.assert_allclose(point_stress(p, mat, source=src), sig, atol=1e-7 * np.abs(sig).max())


@pytest.mark.parametrize("nu", [0.2, 0.5])
def test_equilibrium_and_free_surface(nu):
    mat = Material(E=1.0, nu=nu)
    p = np.array([0.7, -1.3, 2.1])
    g = np.stack([_num_grad(lambda q: point_stress(q, mat)[..., i, :], p) for i in range(3)])
    div = np.einsum("ijj->i", g)
    assert np.abs(div).max() < 1e-6 * np.abs(point_stress(p, mat)).max()
    s = point_stress(np.array([[3.0, 1.0, 0.0], [-0.2, 0.1, 0.0]]), mat)
    assert np.abs(s[:, :, 2]).max() < 1e-14


def test_resultant_on_deep_plane_equals_force():
    # integral of sigma_zz over the plane z = c is -P for any depth (equilibrium of the slab above)
    mat = Material(E=1.0, nu=0.5)
    c = 2.0
    r = np.geomspace(1e-4, 1e4, 4001)
    szz = point_stress(np.column_stack([r, 0 * r, c + 0 * r]), mat)[:, 2, 2]
    total = np.trapezoid(2 * np.pi * r * szz * r, np.log(r))
    assert total == pytest.approx(-1.0, rel=1e-6)


def test_invalid_points():
    with pytest.raises(ValueError, match="depth"):
        point_displacement(np.array([0.0, 0.0, -1.0]), Material(1.0, 0.3))
    with pytest.raises(ValueError, match="coincides"):
        point_stress(np.array([0.0, 0.0, 0.0]), Material(1.0, 0.3))
