"""Products between well-separated patches (twoscale.influence.separated).

Checked against independent values: Love's closed form for the cell expansion, the exact
zero-padded FFT product (itself checked against the dense Love matrix in
test_reference_*) for the Chebyshev blocks.
"""

import numpy as np
import pytest

from twoscale.analytic.halfspace import love_far_field, love_rectangle
from twoscale.grid import Grid
from twoscale.influence.halfspace import HalfSpace
from twoscale.influence.separated import (
    FAR_FIELD_BOUND,
    SeparatedOperator,
    box_gap,
    chebyshev_points,
    lagrange_matrix,
    plan,
)
from twoscale.material import Material
from twoscale.micro.blocks import Coupling
from twoscale.micro.patches import Patch

HS = HalfSpace(Material(E=6.0, nu=0.5))


@pytest.mark.parametrize("order", [0, 2, 4])
def test_love_far_field_within_its_stated_bound(order):
    h, E = 0.3, 2.0
    r = np.geomspace(3 * h, 200 * h, 40)
    ang = np.linspace(0, np.pi / 2, 13)
    R, A = np.meshgrid(r, ang)
    x, y = R * np.cos(A), R * np.sin(A)
    # reference: Gauss-Legendre quadrature of Boussinesq over the cell (16 x 16 points: exact
    # to rounding at r >= 3 h, without the closed form's cancellation far away, ~1e-11 at 200 h),
    # itself checked against the closed form nearby
    g, w = np.polynomial.legendre.leggauss(16)
    g, w = 0.5 * h * g, 0.5 * h * w
    exact = sum(wa * wb / (np.pi * E * np.hypot(x - gb, y - ga)) for ga, wa in zip(g, w) for gb, wb in zip(g, w))
    near = R < 10 * h
    np.testing.assert_allclose(exact[near], love_rectangle(x, y, h / 2, h / 2, E)[near], rtol=1e-12)
    rel = np.abs(love_far_field(x, y, h, E, order) / exact - 1)
    bound = FAR_FIELD_BOUND[order] * (h / R) ** (order + 2)
    assert np.all(rel <= bound + 1e-14)
    # and the bound is not loose by orders of magnitude where the expansion error dominates
    assert (rel / bound)[R < 20 * h].max() >= 0.1


def test_love_far_field_rejects_a_bad_order():
    with pytest.raises(ValueError, match="order"):
        love_far_field(1.0, 1.0, 0.1, 1.0, order=3)


def test_lagrange_on_chebyshev_points_is_exact_for_polynomials():
    nodes = chebyshev_points(-1.0, 2.0, 7)
    x = np.linspace(-1.0, 2.0, 50)
    poly = lambda t: 3 * t**6 - t**3 + 0.5
    np.testing.assert_allclose(lagrange_matrix(nodes, x) @ poly(nodes), poly(x), rtol=1e-12, atol=1e-12)
    # a point on a node returns the node's value exactly
    np.testing.assert_array_equal(lagrange_matrix(nodes, nodes[2:3]), np.eye(7)[2:3])


def test_box_gap():
    a = Grid(0.0, 0.0, 0.1, 11, 11)  # centres 0..1
    assert box_gap(a, Grid(3.0, 0.5, 0.1, 5, 5)) == pytest.approx(2.0)
    assert box_gap(a, Grid(4.0, 5.0, 0.1, 1, 1)) == pytest.approx(5.0)
    assert box_gap(a, Grid(0.5, 0.5, 0.1, 30, 30)) == 0.0


def test_close_or_overlapping_pairs_are_not_separated():
    a = Grid(0.0, 0.0, 0.1, 30, 30)
    assert HS.separated_operator(a, a) is None
    assert HS.separated_operator(a, Grid(3.2, 0.0, 0.1, 30, 30)) is None  # gap 0.3 mm = 3 h
    assert plan(a, Grid(20.0, 0.0, 0.1, 30, 30), 1e-10) is not None
    with pytest.raises(ValueError, match="rtol"):
        plan(a, a, 0.0)


@pytest.mark.parametrize("rtol", [1e-4, 1e-6, 1e-8, 1e-10])
def test_separated_product_within_rtol_of_the_exact_product(rtol):
    rng = np.random.default_rng(1)
    checked = 0
    worst = 0.0
    for _ in range(120):
        nt, ns = rng.integers(1, 40, 2), rng.integers(1, 40, 2)
        h = float(rng.choice([0.05, 0.1, 0.25]))
        t = Grid(0.0, 0.0, h, int(nt[0]), int(nt[1]))
        off = rng.integers(-150, 150, 2)
        s = Grid(off[0] * h, off[1] * h, h, int(ns[0]), int(ns[1]))
        op = HS.separated_operator(t, s, rtol=rtol)
        if op is None:
            continue
        p = rng.random(s.shape)
        exact = HS.grid_operator(t, s).apply(p)
        err = np.abs(op.apply(p) - exact).max() / np.abs(exact).max()
        worst = max(worst, err / rtol)
        checked += 1
    assert checked >= 30
    assert worst <= 1.0


def test_transposed_equals_the_reverse_build():
    t, s = Grid(0.0, 0.0, 0.1, 25, 18), Grid(9.0, -4.0, 0.1, 12, 30)
    fwd = HS.separated_operator(t, s, rtol=1e-10)
    back = fwd.transposed()
    fresh = SeparatedOperator(
        s, t, lambda dx, dy: love_far_field(dx, dy, 0.1, HS.E_star, fwd.plan.order), plan(s, t, 1e-10)
    )
    q = np.random.default_rng(0).random(t.shape)
    np.testing.assert_allclose(back.apply(q), fresh.apply(q), rtol=1e-12)
    # and the two directions agree with reciprocity: <p, A_ts q> = <A_st p, q>
    p = np.random.default_rng(1).random(s.shape)
    assert np.sum(q * fwd.apply(p)) == pytest.approx(np.sum(back.apply(q) * p), rel=1e-12)


def _patches(h=0.1):
    centres = [(0.0, 0.0), (8.0, 1.0), (-3.0, 9.0), (1.5, 0.5)]  # the last one is close to the first
    out = []
    for a, (x, y) in enumerate(centres):
        g = Grid.covering(x - 1.2, x + 1.2, y - 1.0, y + 1.0, h)
        X, Y = g.centres()
        owner = np.where(np.hypot(X - x, Y - y) < 1.1, a, -1)
        out.append(Patch(asperity=a, grid=g, height=np.zeros(g.shape), owner=owner))
    return out


def test_coupling_rhs_with_separated_pairs_equals_the_fft_coupling():
    patches = _patches()
    rng = np.random.default_rng(2)
    fast = Coupling(HS, patches, dense_max_entries=0)
    exact = Coupling(HS, patches, dense_max_entries=0, separated_rtol=None)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    for k in range(len(patches)):
        b = rng.random(int(patches[k].owned.sum()))
        ref = exact.rhs(k, values, b)
        np.testing.assert_allclose(fast.rhs(k, values, b), ref, atol=1e-9 * np.abs(b - ref).max())
    assert fast.separated_pairs >= 6 and exact.separated_pairs == 0
    # a new vector on block 1 is seen (the moments are not reused)
    values[1] = 3.0 * values[1]
    b = np.zeros(int(patches[0].owned.sum()))
    np.testing.assert_allclose(fast.rhs(0, values, b), exact.rhs(0, values, b), rtol=1e-9)
    # several right-hand sides at once
    many = [np.column_stack([v, 2 * v + 1]) for v in values]
    b2 = np.zeros((int(patches[2].owned.sum()), 2))
    np.testing.assert_allclose(fast.rhs(2, many, b2), exact.rhs(2, many, b2), rtol=1e-9)


def test_separated_rtol_is_checked():
    with pytest.raises(ValueError, match="separated_rtol"):
        Coupling(HS, _patches(), separated_rtol=2.0)
