"""Half-space influence: Love's rectangle against Boussinesq, and the provider's three views.

* Love's closed form against numerical quadrature of the Boussinesq kernel over the cell
  (relative 1e-8): off the cell by ``scipy.integrate.dblquad``; on the cell, its edges and
  corners by splitting the cell at the point into rectangles with the (integrable) 1/r
  singularity at a corner and integrating in polar coordinates (radial part exact, the
  angular part by ``quad``).
* Far away Love tends to the point force ``h^2 / (pi E* r)`` with the relative
  correction ``h^2 / (24 r^2)`` for a square cell (second moment of the cell), the
  remainder being O((h/r)^4).
* ``grid_matrix`` is symmetric, equals ``cell_block`` built point by point, and the FFT
  ``grid_operator`` reproduces the dense product to 1e-12 relative.
"""

import math

import numpy as np
import pytest
from scipy import integrate

from twoscale import Grid, Material
from twoscale.analytic.halfspace import boussinesq_point, love_on_lattice, love_rectangle
from twoscale.influence import HalfSpace

E_STAR = Material(10.0, 0.5).E_star
A, B = 0.35, 0.2  # half-sides of the loaded rectangle, mm


def _corner_integral(w: float, l: float) -> float:
    """Integral of 1/r over [0, w] x [0, l], singular corner at the origin (polar)."""
    if w <= 0 or l <= 0:
        return 0.0
    th = math.atan2(l, w)
    i1 = integrate.quad(lambda t: w / math.cos(t), 0.0, th, epsabs=0, epsrel=1e-13)[0]
    i2 = integrate.quad(lambda t: l / math.sin(t), th, 0.5 * math.pi, epsabs=0, epsrel=1e-13)[0]
    return i1 + i2


def _quadrature(x: float, y: float, a: float = A, b: float = B) -> float:
    """Boussinesq kernel integrated over the rectangle |x'|<=a, |y'|<=b, by quadrature."""
    if abs(x) <= a and abs(y) <= b:
        s = sum(_corner_integral(w, l) for w in (a - x, a + x) for l in (b - y, b + y))
    else:
        s = integrate.dblquad(lambda yy, xx: 1.0 / math.hypot(x - xx, y - yy), -a, a, -b, b, epsabs=0, epsrel=1e-12)[0]
    return s / (math.pi * E_STAR)


POINTS = {
    "centre": (0.0, 0.0),
    "inside": (0.1, -0.07),
    "edge_x": (A, 0.05),
    "edge_y": (-0.12, B),
    "corner": (A, -B),
    "near_outside": (0.5, 0.3),
    "outside_axis": (0.0, 0.9),
    "far": (4.0, -3.0),
    "very_far": (30.0, 12.0),
}


@pytest.mark.parametrize("name", list(POINTS))
def test_love_matches_quadrature_of_boussinesq(name):
    x, y = POINTS[name]
    ref = _quadrature(x, y)
    got = float(love_rectangle(x, y, A, B, E_STAR))
    assert got == pytest.approx(ref, rel=1e-8)


def test_love_is_even_in_x_and_y():
    x, y = 0.27, 0.61
    vals = [float(love_rectangle(sx * x, sy * y, A, B, E_STAR)) for sx in (1, -1) for sy in (1, -1)]
    assert np.ptp(vals) <= 1e-14 * vals[0]


@pytest.mark.parametrize("direction", [0.0, 0.3, math.pi / 4, 1.2])
def test_love_tends_to_point_force_with_second_moment_correction(direction):
    h = 0.1
    r = h * np.array([5.0, 10.0, 20.0, 40.0, 80.0, 200.0, 1000.0])  # 1000 h uses the far expansion
    x, y = r * math.cos(direction), r * math.sin(direction)
    love = love_rectangle(x, y, h / 2, h / 2, E_STAR)
    point = h * h * boussinesq_point(r, E_STAR)
    rel = love / point - 1.0
    corr = h * h / (24.0 * r * r)
    # leading correction: the cell's second moment h^2/12 per axis, isotropic for a square
    assert np.all(np.abs(rel - corr) <= 0.05 * corr)
    # the remainder is fourth order in h/r (up to rounding at 1e-13)
    remainder = np.abs(rel - corr)
    assert np.all(remainder <= 0.02 * (h / r) ** 4 + 1e-13)


def test_boussinesq_point_force():
    r = np.array([0.5, 1.0, 7.0])
    assert np.allclose(boussinesq_point(r, E_STAR) * math.pi * E_STAR * r, 1.0, rtol=1e-15)
    assert np.isinf(boussinesq_point(0.0, E_STAR))


def test_boussinesq_point_force_in_place():
    """``out``: the same values written into the given array (here the distances themselves)."""
    r = np.array([[0.0, 0.5], [1.0, 7.0]])
    expected = np.array(
        [[np.inf, 1.0 / (math.pi * E_STAR * 0.5)], [1.0 / (math.pi * E_STAR), 1.0 / (math.pi * E_STAR * 7.0)]]
    )
    out = boussinesq_point(r, E_STAR, out=r)
    assert out is r
    assert np.isinf(out[0, 0])
    assert np.allclose(out.ravel()[1:], expected.ravel()[1:], rtol=1e-15, atol=0.0)


def test_point_compliance_closed_form():
    """The half-space's compliance between two different point sets: ``1 / (pi E* |t - s|)``
    pair by pair, ``inf`` where two coincide."""
    rng = np.random.default_rng(3)
    targets, sources = rng.uniform(-5.0, 5.0, (7, 2)), rng.uniform(-5.0, 5.0, (4, 2))
    sources[2] = targets[5]
    T = HalfSpace(Material(10.0, 0.5)).point_compliance(targets, sources)
    assert T.shape == (7, 4)
    for i, t in enumerate(targets):
        for j, s in enumerate(sources):
            if (i, j) == (5, 2):
                assert np.isinf(T[i, j])
            else:
                assert T[i, j] == pytest.approx(1.0 / (math.pi * E_STAR * math.dist(t, s)), rel=1e-14)


# ------------------------------------------------------------------ provider views
HS = HalfSpace(Material(10.0, 0.5))


@pytest.mark.parametrize("shape", [(6, 6), (5, 9), (7, 4)])
def test_grid_matrix_is_symmetric_and_equals_cell_block(shape):
    ny, nx = shape
    g = Grid(0.3, -0.1, 0.07, nx, ny)
    M = HS.grid_matrix(g)
    assert M.shape == (g.size, g.size)
    # symmetric up to rounding of the cell coordinates (x0 + i h)
    assert np.allclose(M, M.T, rtol=1e-13, atol=0)
    C = HS.cell_block(g.points(), g.points(), g.h)
    assert np.allclose(M, C, rtol=1e-12, atol=0)
    # self compliance: Love at the centre of a square cell, 4 h asinh(1) / (pi E*)
    assert M[0, 0] == pytest.approx(4 * g.h * math.asinh(1.0) / (math.pi * HS.E_star), rel=1e-14)


def test_cross_grid_blocks_are_transposes_and_match_cell_block():
    h = 0.05
    src = Grid(0.0, 0.0, h, 9, 6)
    tgt = Grid(-3 * h, 2 * h, h, 5, 11)
    Mts = HS.grid_matrix(tgt, src)
    Mst = HS.grid_matrix(src, tgt)
    assert Mts.shape == (tgt.size, src.size)
    assert np.allclose(Mts, Mst.T, rtol=1e-13, atol=0)
    assert np.allclose(Mts, HS.cell_block(tgt.points(), src.points(), h), rtol=1e-12, atol=0)


def _dense_product(tgt, src, p):
    return (HS.cell_block(tgt.points(), src.points(), src.h) @ p.ravel()).reshape(tgt.shape)


@pytest.mark.parametrize(
    "tgt_src",
    [
        ((0.0, 0.0, 32, 32), None),  # square, self
        ((0.1, 0.2, 17, 23), None),  # odd, non-square, self
        ((-0.3, 0.5, 13, 7), (0.0, 0.0, 21, 15)),  # target inside/overlapping the source
        ((2.0, -1.0, 9, 12), (0.0, 0.0, 11, 5)),  # disjoint target, far away
    ],
)
def test_fft_operator_equals_dense_product(tgt_src):
    h = 0.1
    t, s = tgt_src
    tgt = Grid(t[0], t[1], h, t[2], t[3])
    src = tgt if s is None else Grid(s[0], s[1], h, s[2], s[3])
    rng = np.random.default_rng(7)
    p = rng.random(src.shape)
    op = HS.grid_operator(tgt, None if s is None else src)
    u = op.apply(p)
    ref = _dense_product(tgt, src, p)
    assert u.shape == tgt.shape
    assert np.linalg.norm(u - ref) <= 1e-12 * np.linalg.norm(ref)
    assert np.max(np.abs(u - ref)) <= 1e-12 * np.max(np.abs(ref))
    # also through grid_matrix
    M = HS.grid_matrix(tgt, src)
    assert np.linalg.norm((M @ p.ravel()).reshape(tgt.shape) - u) <= 1e-12 * np.linalg.norm(ref)


def test_fft_operator_rejects_wrong_shape():
    g = Grid(0.0, 0.0, 0.1, 5, 4)
    with pytest.raises(ValueError, match="shape"):
        HS.grid_operator(g).apply(np.ones((5, 4)))


@pytest.mark.parametrize(
    "ox0, oy0, mx, my, h, b",
    [
        (0, 0, 700, 700, 0.1, 0.05),
        (-350, -20, 701, 50, 0.1, 0.05),
        (-400, 300, 50, 800, 0.1, 0.03),
        (0, 0, 20000, 3, 0.1, 0.05),
    ],
)
def test_love_on_a_lattice_is_the_pointwise_closed_form_to_the_bit(ox0, oy0, mx, my, h, b):
    """Block by block, the entries within 600 half-sides by the closed form and the rest
    by the multipole, as ``love_rectangle`` takes them point by point (each lattice
    crosses that switch)."""
    x, y = (ox0 + np.arange(mx)) * h, (oy0 + np.arange(my)) * h
    lattice = love_on_lattice(x, y, 0.5 * h, b, 10.0)
    assert np.array_equal(lattice, love_rectangle(x[None, :], y[:, None], 0.5 * h, b, 10.0))
