"""Far-field coupling of distant patches (many, dense and measured-surface tips): nine moment-matching sources.

Independent check: the displacement a distant patch's pressure causes on another patch,
from :class:`~twoscale.micro.farfield.LaggedFarField`, against the exact cross-patch product
(:class:`~twoscale.micro.blocks.Coupling`, the Love cell-to-cell influence). Nine sources
that carry the load's moments ``x^i y^j`` (``i, j <= 2``) leave an error of order
``(r / d)^3``; a single resultant at the patch centre, for an off-centre load, of order
``r / d``.
"""

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.micro.blocks import Coupling
from twoscale.micro.farfield import LaggedFarField
from twoscale.micro.sources import source_frame, source_nodes, source_strengths, source_weights
from twoscale.micro.patches import Patch

HS = HalfSpace(Material(10.0, 0.5))
H = 0.05


def _patch(k, x0, y0, n):
    g = Grid(x0, y0, H, n, n)
    return Patch(k, g, np.zeros(g.shape), np.full(g.shape, k))


def _off_centre_pressure(n, seed):
    """A Hertz-like bump centred off the patch centre, plus noise (MPa)."""
    rng = np.random.default_rng(seed)
    i = np.arange(n) - 0.5 * (n - 1)
    X, Y = np.meshgrid(i, i)
    c = rng.uniform(-0.3, 0.3, 2) * n
    p = np.sqrt(np.clip(1.0 - ((X - c[0]) ** 2 + (Y - c[1]) ** 2) / (0.35 * n) ** 2, 0.0, None))
    return (p + 0.1 * rng.random(p.shape)).ravel()


def _errors(distances, seed=0, n=41):
    """Relative far-field error on patch 0 from patch 1 at each centre distance (mm)."""
    out = []
    v1 = _off_centre_pressure(n, seed)
    for d in distances:
        patches = [_patch(0, 0.0, 0.0, n), _patch(1, d, 0.3 * d, n)]
        values = [None, v1]
        exact = Coupling(HS, patches).patch_displacement(0, values)
        far = LaggedFarField(HS, patches, far_tol=0.99)
        assert len(far.near(0)) == 0
        approx = far.patch_displacement(0, values)
        out.append(np.abs(approx - exact).max() / np.abs(exact).max())
    return np.array(out)


def test_sources_carry_the_moments_up_to_second_order():
    g = Grid(1.0, 2.0, 0.1, 31, 21)
    X, Y = g.centres()
    pts = np.column_stack([X.ravel(), Y.ravel()])
    p = np.random.default_rng(1).random(len(pts))
    nodes, centre, delta = source_nodes(g)
    S = source_strengths(pts, p[:, None], centre, delta, g.h)[:, 0]
    for i in range(3):
        for j in range(3):
            m_cells = np.sum(g.h**2 * p * pts[:, 0] ** i * pts[:, 1] ** j)
            assert np.isclose(S @ (nodes[:, 0] ** i * nodes[:, 1] ** j), m_cells, rtol=1e-12)


@pytest.mark.parametrize("shape", [(21, 31), (1, 9), (7, 1)])
def test_separable_strengths_carry_the_moments_of_the_owned_cells(shape):
    """The tensor-product form of the sources (large patches keep no weights) carries the
    moments ``x^i y^j`` (``i, j <= 2``) of the pressure on the owned cells alone."""
    from twoscale.micro.sources import separable_strengths

    g = Grid(1.0, 2.0, 0.1, shape[1], shape[0])
    rng = np.random.default_rng(sum(shape))
    owned = rng.random(g.shape) < 0.7
    owned.flat[0] = True
    X, Y = g.centres()
    p = rng.random(int(owned.sum()))
    nodes, centre, delta = source_nodes(g)
    S = separable_strengths(g, owned, p[:, None])[:, 0]
    want = source_strengths(np.column_stack([X[owned], Y[owned]]), p[:, None], centre, delta, g.h)[:, 0]
    assert np.allclose(S, want, rtol=1e-12, atol=1e-15 * np.abs(want).max())
    for i in range(3 if shape[1] > 2 else 1):
        for j in range(3 if shape[0] > 2 else 1):
            m_cells = np.sum(g.h**2 * p * X[owned] ** i * Y[owned] ** j)
            assert np.isclose(S @ (nodes[:, 0] ** i * nodes[:, 1] ** j), m_cells, rtol=1e-12)


def test_source_weights_are_the_nodes_lagrange_products_cell_by_cell():
    # row 3 j + i is node (y_j, x_i): h^2 L_j(eta) L_i(xi) of each cell, the quadratic
    # Lagrange functions of the nodes -1, 0, 1 written out one cell at a time
    rng = np.random.default_rng(4)
    pts = rng.uniform(-1.0, 3.0, (57, 2))
    centre, delta, h = np.array([0.7, 1.1]), np.array([0.9, 0.4]), 0.03

    def L(t):
        return [t * (t - 1.0) / 2.0, (1.0 - t) * (1.0 + t), t * (t + 1.0) / 2.0]

    W = source_weights(pts, centre, delta, h)
    assert W.shape == (9, 57)
    for c, (x, y) in enumerate(pts):
        lx, ly = L((x - centre[0]) / delta[0]), L((y - centre[1]) / delta[1])
        want = [h * h * ly[j] * lx[i] for j in range(3) for i in range(3)]
        assert np.allclose(W[:, c], want, rtol=1e-13, atol=1e-17)
    assert source_weights(pts[:0], centre, delta, h).shape == (9, 0)


def test_patch_source_weights_over_many_patches_are_each_patchs_own(monkeypatch):
    from twoscale.micro import sources

    rng = np.random.default_rng(6)
    patches = []
    for k in range(9):
        g = Grid(rng.uniform(-1, 1), rng.uniform(-1, 1), H, int(rng.integers(1, 15)), int(rng.integers(1, 15)))
        owner = np.where(rng.random(g.shape) < 0.6, k, -1)
        patches.append(Patch(k, g, np.zeros(g.shape), owner))
    monkeypatch.setattr(sources, "WEIGHTS_CHUNK_CELLS", 40)  # several passes, some of one patch
    got = sources.patch_source_weights(patches)
    assert len(got) == len(patches)
    for pt, W in zip(patches, got):
        X, Y = pt.grid.centres()
        centre, delta = source_frame(pt.grid)
        want = source_weights(np.column_stack([X[pt.owned], Y[pt.owned]]), centre, delta, pt.grid.h)
        assert W.shape == want.shape == (9, int(pt.owned.sum()))
        assert np.array_equal(W, want) and W.strides == want.strides


def test_far_patch_error_falls_as_the_cube_of_size_over_distance():
    r = 0.5 * np.hypot(40 * H, 40 * H)  # half-diagonal of a 41 x 41 patch
    d = np.array([4.0, 8.0, 16.0]) * r
    err = _errors(d / np.hypot(1.0, 0.3))
    order = np.log(err[:-1] / err[1:]) / np.log(2.0)
    assert np.all(order > 2.6), (err, order)
    # and the constant of the (r / d)^3 law is below one at every distance
    assert np.all(err < (r / d) ** 3), (err, (r / d) ** 3)


@pytest.mark.parametrize("seed", [2, 3])
def test_far_field_beats_a_resultant_at_the_centre(seed):
    """The error of the old representation (resultant at the patch centre), computed
    independently from Boussinesq's point load, is several times the new one's."""
    n = 41
    d = 6.0 * 0.5 * np.hypot(40 * H, 40 * H)
    err = _errors([d], seed=seed, n=n)[0]
    patches = [_patch(0, 0.0, 0.0, n), _patch(1, d, 0.0, n)]
    v1 = _off_centre_pressure(n, seed)
    exact = Coupling(HS, patches).patch_displacement(0, [None, v1])
    X, Y = patches[0].grid.centres()
    centre = np.array([d, 0.0]) + 0.5 * (n - 1) * H
    r = np.hypot(X - centre[0], Y - centre[1])
    resultant = H * H * v1.sum() / (np.pi * HS.material.E_star * r)  # Boussinesq, nu-free form
    old = np.abs(resultant - exact).max() / np.abs(exact).max()
    assert err < old / 5.0, (err, old)


def test_the_held_far_field_follows_a_patch_that_changed():
    # the refresh keeps each patch's source weights; a patch that grows (``replace``) gets
    # new ones: the held field equals a new coupling's on the new patches, and the exact
    # product within its (r / d)^3 error
    n, d = 21, 8.0
    v = [_off_centre_pressure(n, 4), _off_centre_pressure(n, 5)]
    patches = [_patch(0, 0.0, 0.0, n), _patch(1, d, 0.3 * d, n)]
    held = LaggedFarField(HS, patches, far_tol=0.99)
    held.refresh(v)
    bigger = _patch(1, d - 5 * H, 0.3 * d - 5 * H, n + 10)
    big_v = np.zeros((n + 10, n + 10))
    big_v[5:-5, 5:-5] = v[1].reshape(n, n)
    big_v[5:-5, 5:-5] *= 1.5
    held.replace(1, bigger)
    new = [v[0], big_v.ravel()]
    held.refresh(new)
    fresh = LaggedFarField(HS, [patches[0], bigger], far_tol=0.99)
    fresh.refresh(new)
    assert np.allclose(held.patch_displacement(0, new), fresh.patch_displacement(0, new), rtol=1e-12, atol=0.0)
    exact = Coupling(HS, [patches[0], bigger]).patch_displacement(0, new)
    r = 0.5 * np.hypot(30 * H, 30 * H)
    assert np.abs(held.patch_displacement(0, new) - exact).max() < (r / d) ** 3 * np.abs(exact).max()
