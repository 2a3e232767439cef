"""Grid, material, indenters and result containers: the plain data everything uses."""

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.indenters import Asperity, Tilt, surface_on
from twoscale.results import PressureField, summarise, ContactResult


def test_material_E_star_and_validation():
    assert Material(10.0, 0.5).E_star == pytest.approx(10.0 / 0.75)
    for kwargs, shown in [
        (dict(E=-1.0, nu=0.3), "-1.0"),
        (dict(E=float("nan"), nu=0.3), "nan"),
        (dict(E=1.0, nu=0.51), "0.51"),
        (dict(E=1.0, nu=-1.0), "-1.0"),
    ]:
        with pytest.raises(ValueError, match=shown):
            Material(**kwargs)


def test_grid_covering_is_aligned_and_covers():
    h = 0.1
    g = Grid.covering(-0.33, 0.71, 0.02, 0.5, h)
    xmin, xmax, ymin, ymax = g.bounds
    assert xmin <= -0.33 and xmax >= 0.71 and ymin <= 0.02 and ymax >= 0.5
    assert xmax - xmin < 0.71 + 0.33 + 2 * h  # no more than one extra cell each side
    # cell centres on the lattice h*Z^2
    assert np.allclose(np.round(g.x / h), g.x / h) and np.allclose(np.round(g.y / h), g.y / h)
    sub = g.subgrid(2, 1, 3, 2)
    assert sub.offset_in(g) == (2, 1)
    with pytest.raises(ValueError, match="aligned"):
        Grid(0.05, 0.0, h, 3, 3).offset_in(g)
    with pytest.raises(ValueError, match="-0.1"):
        Grid(0.0, 0.0, -0.1, 3, 3)


def test_grid_points_row_major_x_fastest():
    g = Grid(1.0, 2.0, 0.5, 3, 2)
    pts = g.points()
    assert pts.shape == (6, 2)
    assert np.allclose(pts[1], [1.5, 2.0]) and np.allclose(pts[3], [1.0, 2.5])


def test_sphere_height_exact_cap_and_paraboloid():
    R = 5.0
    s = Asperity(1.0, -2.0, 0.1, R, "sphere")
    p = Asperity(1.0, -2.0, 0.1, R, "paraboloid")
    r = np.array([0.0, 1.0, 3.0, 4.999, 5.0, 7.0])
    hs = s.height(1.0 + r, -2.0 + 0 * r)
    expect = np.where(r < R, 0.1 + R - np.sqrt(np.clip(R * R - r * r, 0, None)), np.inf)
    assert np.allclose(hs[:-2], expect[:-2], rtol=1e-13) and np.all(np.isinf(hs[-2:]))
    assert np.allclose(p.height(1.0 + r, -2.0 + 0 * r), 0.1 + r * r / (2 * R))
    # the cap rises above the paraboloid by ~ r^4 / (8 R^3)
    rr = 0.5
    assert s.height(1.0 + rr, -2.0) - p.height(1.0 + rr, -2.0) == pytest.approx(rr**4 / (8 * R**3), rel=1e-2)
    # reach is where the height reaches the given depth above the tip
    for a in (s, p):
        rho = a.reach(0.3)
        assert a.height(1.0 + rho, -2.0) - 0.1 == pytest.approx(0.3, rel=1e-12)


def test_asperity_validation_names_value():
    with pytest.raises(ValueError, match="-1.0"):
        Asperity(0, 0, 0, -1.0)
    with pytest.raises(ValueError, match="cone"):
        Asperity(0, 0, 0, 1.0, "cone")
    with pytest.raises(ValueError, match="nan"):
        Asperity(float("nan"), 0, 0, 1.0)


def test_surface_owner_is_the_lowest_indenter_and_tilt_adds_a_plane():
    g = Grid.covering(-3, 3, -1, 1, 0.1)
    a = [Asperity(-1.0, 0.0, 0.0, 2.0), Asperity(1.0, 0.0, 0.2, 2.0)]
    s = surface_on(g, a)
    X, Y = g.centres()
    h0, h1 = a[0].height(X, Y), a[1].height(X, Y)
    assert np.array_equal(s.owner, np.where(np.isinf(np.minimum(h0, h1)), -1, np.where(h1 < h0, 1, 0)))
    assert np.allclose(s.height[np.isfinite(s.height)], np.minimum(h0, h1)[np.isfinite(s.height)])
    t = Tilt(alpha=0.01, beta=-0.02, pivot=(0.5, 0.2))
    st = surface_on(g, a, t)
    fin = np.isfinite(s.height)
    assert np.allclose(st.height[fin] - s.height[fin], (-0.02 * (X - 0.5) + 0.01 * (Y - 0.2))[fin])
    assert s.n_asperities == 2


def test_summarise_and_pressure_on():
    g = Grid(0.0, 0.0, 0.5, 4, 3)
    p = np.arange(12.0).reshape(3, 4)
    own = np.array([[0, 0, 1, 1], [0, 0, 1, 1], [-1, -1, 2, 2]])
    f = PressureField(g, p, own, np.zeros((3, 4)))
    s = summarise([f], 4)
    h2 = 0.25
    assert np.allclose(s.forces, [h2 * (0 + 1 + 4 + 5), h2 * (2 + 3 + 6 + 7), h2 * (10 + 11), 0.0])
    assert np.allclose(s.contact_areas, [3 * h2, 4 * h2, 2 * h2, 0.0])
    assert np.allclose(s.max_pressures, [5, 7, 11, 0])
    with pytest.raises(ValueError):
        f.pressure[0, 0] = 1.0  # frozen
    r = ContactResult("x", (f,), 0.1, None, float(h2 * p[own >= 0].sum()), s, True)
    big = Grid(-0.5, -0.5, 0.5, 6, 5)
    pb = r.pressure_on(big)
    assert pb.sum() == pytest.approx(p.sum()) and pb[1, 1] == 0.0 and pb[1 + 2, 1 + 3] == p[2, 3]
    assert r.n_cells == 12
